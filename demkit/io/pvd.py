"""ParaView data (.pvd) collections: a list of (time, file) entries that ParaView and
``pyvista.get_reader`` read as a time series.

A collection is written whole once (:func:`write_pvd`: a temporary file, then a rename, so a
reader never sees a half-written file) and then grown by :class:`GrowingPvd`, which writes each
new entry together with the closing lines over the old closing lines: adding a frame costs the
same whatever the length of the series, and a process killed at any moment leaves a valid
collection of the frames added so far.

A series in a box also holds ``<Box size="Lx Ly Lz" periodic="1 1 0"/>`` after the collection
(lower corner at the origin; ParaView's reader ignores the element, demkit and its ParaView script
read it); a sheared box adds ``shear="rate flow gradient"`` (the sliding offset of each frame is
rate L_gradient t mod L_flow at its time, :meth:`demkit.Shear.offset`).
"""
from __future__ import annotations

import os
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

_HEAD = ('<?xml version="1.0"?>\n'
         '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
         '  <Collection>\n')


def _entry(time, name):
    return f'    <DataSet timestep="{float(time)!r}" group="" part="0" file="{name}"/>\n'


def _footer(box):
    text = "  </Collection>\n"
    if box is not None:
        size = " ".join(repr(float(x)) for x in box.size)
        periodic = " ".join(str(int(bool(f))) for f in box.periodic)
        motion = (f' shear="{float(box.shear.rate)!r} {box.shear.flow} {box.shear.gradient}"'
                  if getattr(box, "shear", None) is not None else "")
        deform = getattr(box, "deform", None)
        motion += f' deform="{" ".join(repr(float(r)) for r in deform.rates)}"' if deform is not None else ""
        if deform is not None and len(deform.history):  # a servo's changes of rates: (t, L (3), rates (3)) each
            motion += f' deform_history="{" ".join(repr(float(v)) for v in deform.history.ravel())}"'
        text += f'  <Box size="{size}" periodic="{periodic}"{motion}/>\n'
    return text + "</VTKFile>\n"


def write_pvd(path, entries, box=None):
    """Write the collection ``entries`` = [(time, relative_file), ...] to ``path`` atomically.

    Times are written with ``repr`` so that they read back exactly; ``box`` (a demkit.Box or None)
    is written as a ``Box`` element. Returns the byte offset at which the closing lines start.
    """
    path = Path(path)
    body = (_HEAD + "".join(_entry(t, name) for t, name in entries)).encode()
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(body + _footer(box).encode())
    os.replace(tmp, path)
    return len(body)


class GrowingPvd:
    """The .pvd collection ``path`` of a series being written, grown one entry at a time.

    ``append`` writes the new entry followed by the closing lines (``</Collection>``, the box,
    ``</VTKFile>``) in one ``os.pwrite`` at the offset where the old closing lines started, so
    the file only grows and the cost does not depend on the number of entries. A write of a few
    hundred bytes into the page cache is not split by a signal, so a process killed at any
    moment leaves the old or the new collection, both valid. The file is written whole
    (:func:`write_pvd`) the first time, when the box changes, and when it is not the file this
    object last wrote (size or inode changed).
    """

    def __init__(self, path, box=None):
        self.path = Path(path)
        self.box = box
        self.entries = []  # [(time, file name)] in the order written
        self._tail = None  # byte offset of the closing lines, None before the first write
        self._written = None  # (closing bytes, inode) of the last write

    def rewrite(self, entries):
        """Write the collection ``entries`` whole, atomically."""
        self.entries = [(float(t), name) for t, name in entries]
        self._tail = write_pvd(self.path, self.entries, self.box)
        self._written = (_footer(self.box).encode(), os.stat(self.path).st_ino)

    def append(self, time, name):
        """Add the entry (time, file name) at the end of the collection."""
        footer = _footer(self.box).encode()
        if self._tail is None or not self._intact(footer):
            self.rewrite(self.entries + [(time, name)])
            return
        data = _entry(time, name).encode() + footer
        fd = os.open(self.path, os.O_WRONLY)
        try:
            done = 0
            while done < len(data):  # one call in practice; loop in case of a short write
                done += os.pwrite(fd, data[done:], self._tail + done)
        finally:
            os.close(fd)
        self._tail += len(data) - len(footer)
        self.entries.append((float(time), name))

    def _intact(self, footer):
        old_footer, inode = self._written
        try:
            stat = os.stat(self.path)
        except OSError:
            return False
        return footer == old_footer and stat.st_ino == inode and stat.st_size == self._tail + len(footer)


def read_pvd(path):
    """Entries of a .pvd collection as [(time, absolute Path), ...], sorted by time.

    Raises ValueError if the file is not a VTK collection.
    """
    path = Path(path)
    entries = [(t, path.parent / name) for t, name in read_entries(path)[0]]
    return sorted(entries, key=lambda e: e[0])


def read_entries(path, salvage=False):
    """([(time, file name), ...] in file order, Box or None) of the .pvd ``path``.

    salvage : when the file is not well-formed XML (e.g. cut short by a full disk), take the
        complete ``DataSet`` elements it holds, with a warning, instead of raising ValueError.
    """
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        if not salvage or not path.is_file():
            raise ValueError(f"cannot read the ParaView collection {path}: {err}") from err
        return _salvage(path, err)
    if root.tag != "VTKFile" or root.get("type") != "Collection":
        raise ValueError(f"{path} is not a ParaView .pvd collection (root element {root.tag!r})")
    entries = [(float(ds.get("timestep", "0")), ds.get("file")) for ds in root.iter("DataSet")]
    return entries, _box(root.find("Box"), path)


def _salvage(path, err):
    text = path.read_text(encoding="utf-8", errors="replace")
    if 'type="Collection"' not in text[:200]:
        raise ValueError(f"cannot read the ParaView collection {path}: {err}") from err
    entries = []
    for element in re.findall(r"<DataSet\s[^<>]*/>", text):
        time, name = re.search(r'timestep="([^"]*)"', element), re.search(r'file="([^"]*)"', element)
        if time and name:
            entries.append((float(time.group(1)), name.group(1)))
    box = re.search(r"<Box\s[^<>]*/>", text)
    warnings.warn(f"{path} is not well-formed ({err}); kept the {len(entries)} complete entries it holds")
    return entries, _box(ET.fromstring(box.group(0)) if box else None, path)


def _box(element, path):
    from ..box import Box, Deform, Shear

    if element is None:
        return None
    try:
        size = [float(x) for x in element.get("size", "").split()]
        periodic = [bool(int(x)) for x in element.get("periodic", "").split()]
        shear = element.get("shear")
        if shear is not None:
            rate, flow, gradient = shear.split()
            shear = Shear(float(rate), flow, gradient)
        deform = element.get("deform")
        if deform is not None:
            history = [float(v) for v in element.get("deform_history", "").split()]
            deform = Deform.recorded([float(r) for r in deform.split()], history)
        return Box(size, periodic, shear=shear, deform=deform)
    except ValueError as err:
        raise ValueError(f"{path} holds a malformed Box element: {err}") from err


def read_box(path):
    """The :class:`demkit.Box` stored in the .pvd ``path``, or None when it has none."""
    return read_entries(path)[1]


#: the series a VTKWriter may write beside its particles' (demkit.io.writer): not what a folder is read for
COMPANIONS = ("contacts", "walls", "box")


def find_pvd(source):
    """The .pvd file named by ``source``: the file itself, or the only .pvd in a folder (not counting the
    contacts', walls' and a deforming box's series written beside a series, ``<name>_contacts.pvd``,
    ``<name>_walls.pvd`` and ``<name>_box.pvd``)."""
    source = Path(source)
    if source.is_dir():
        found = sorted(source.glob("*.pvd"))
        stems = {p.stem for p in found}
        found = [p for p in found if not any(p.stem == f"{stem}_{part}" for stem in stems for part in COMPANIONS)]
        if len(found) != 1:
            what = "no .pvd file" if not found else f"{len(found)} .pvd files ({', '.join(p.name for p in found)})"
            raise ValueError(f"folder {source} holds {what}; pass the .pvd file itself")
        return found[0]
    if source.suffix != ".pvd":
        raise ValueError(f"expected a .pvd file or a folder holding one, got {source}")
    if not source.exists():
        raise ValueError(f"no such series: {source}")
    return source
