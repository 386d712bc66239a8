"""ParaView data (.pvd) collections: a list of (time, file) entries that ParaView and
``pyvista.get_reader`` read as a time series.

The collection is rewritten atomically (temporary file + rename), so a reader never sees a
half-written .pvd and an interrupted run leaves a valid series of the frames written so far.

A series in a box also holds ``<Box size="Lx Ly Lz" periodic="1 1 0"/>`` after the collection
(lower corner at the origin; ParaView's reader ignores the element, demkit and its ParaView script
read it).
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path


def write_pvd(path, entries, box=None):
    """Write the collection ``entries`` = [(time, relative_file), ...] to ``path`` atomically.

    Times are written with ``repr`` so that they read back exactly; ``box`` (a demkit.Box or None)
    is written as a ``Box`` element.
    """
    path = Path(path)
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for time, name in entries:
        lines.append(f'    <DataSet timestep="{float(time)!r}" group="" part="0" file="{name}"/>')
    lines.append("  </Collection>")
    if box is not None:
        size = " ".join(repr(float(x)) for x in box.size)
        periodic = " ".join(str(int(bool(f))) for f in box.periodic)
        lines.append(f'  <Box size="{size}" periodic="{periodic}"/>')
    lines += ["</VTKFile>", ""]
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("\n".join(lines), encoding="utf-8")
    os.replace(tmp, path)


def read_pvd(path):
    """Entries of a .pvd collection as [(time, absolute Path), ...], sorted by time.

    Raises ValueError if the file is not a VTK collection.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise ValueError(f"cannot read the ParaView collection {path}: {err}") from err
    if root.tag != "VTKFile" or root.get("type") != "Collection":
        raise ValueError(f"{path} is not a ParaView .pvd collection (root element {root.tag!r})")
    entries = [(float(ds.get("timestep", "0")), path.parent / ds.get("file"))
               for ds in root.iter("DataSet")]
    return sorted(entries, key=lambda e: e[0])


def read_box(path):
    """The :class:`demkit.Box` stored in the .pvd ``path``, or None when it has none."""
    from ..box import Box

    try:
        element = ET.parse(path).getroot().find("Box")
    except (ET.ParseError, OSError) as err:
        raise ValueError(f"cannot read the ParaView collection {path}: {err}") from err
    if element is None:
        return None
    try:
        size = [float(x) for x in element.get("size", "").split()]
        periodic = [bool(int(x)) for x in element.get("periodic", "").split()]
        return Box(size, periodic)
    except ValueError as err:
        raise ValueError(f"{path} holds a malformed Box element: {err}") from err


def find_pvd(source):
    """The .pvd file named by ``source``: the file itself, or the only .pvd in a folder."""
    source = Path(source)
    if source.is_dir():
        found = sorted(source.glob("*.pvd"))
        if len(found) != 1:
            what = "no .pvd file" if not found else f"{len(found)} .pvd files ({', '.join(p.name for p in found)})"
            raise ValueError(f"folder {source} holds {what}; pass the .pvd file itself")
        return found[0]
    if source.suffix != ".pvd":
        raise ValueError(f"expected a .pvd file or a folder holding one, got {source}")
    if not source.exists():
        raise ValueError(f"no such series: {source}")
    return source
