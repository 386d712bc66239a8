"""VTK XML PolyData files: trajectories as polylines (one VTK poly-line per particle through its recorded
centres), contact lines, and polygons (the walls, :mod:`demkit.io.walls`).

The file is VTK XML PolyData (.vtp) with raw binary appended data (optionally zlib-compressed),
written here directly because meshio has no poly-line cells. Point data: ``time`` (the time of
each vertex) and ``id``; cell data (one value per line): ``id`` and ``radius``. Colour by ``time``
in ParaView to see the direction of motion. In a periodic box the paths are unwrapped
(position + image * size, so they do not jump across the box) and field data ``box_size`` and
``box_periodic`` (0/1) describe the box. This module writes the file; :func:`demkit.io.write_polylines`
(in :mod:`demkit.io.series`, which reads a written series back when given its path) chooses what goes in.
"""
from __future__ import annotations

import os
import zlib
from pathlib import Path

import numpy as np

_VTK_TYPES = {np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
              np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32"}
_BLOCK = 1 << 16  # bytes per compressed block (VTK reads any block size given in the header)


def _encode(array, compress):
    """Bytes of one appended array: UInt64 length header + data, or VTK's zlib block layout."""
    raw = np.ascontiguousarray(array).tobytes()
    if not compress:
        return np.uint64(len(raw)).tobytes() + raw
    blocks = [zlib.compress(raw[k:k + _BLOCK]) for k in range(0, len(raw), _BLOCK)]
    last = len(raw) - (len(blocks) - 1) * _BLOCK if blocks else 0
    header = np.array([len(blocks), _BLOCK, last] + [len(b) for b in blocks], dtype=np.uint64)
    return header.tobytes() + b"".join(blocks)


def write_vtp_lines(path, points, lengths, point_data, cell_data, compress=False, field_data=None):
    """Write poly-lines to the .vtp ``path``.

    points (P,3); lengths (L,) number of consecutive points in each line (sum = P);
    point_data {name: (P,) or (P,k)}; cell_data {name: (L,) or (L,k)}; field_data {name: (k,)}.
    """
    points = np.asarray(points, dtype=np.float64)
    return _write_vtp(path, points, "Lines", np.arange(len(points), dtype=np.int64),
                      np.cumsum(np.asarray(lengths, dtype=np.int64)), point_data, cell_data, compress, field_data)


def write_vtp_polygons(path, points, connectivity, offsets, cell_data, compress=False, field_data=None):
    """Write polygons to the .vtp ``path``: polygon k has the points ``connectivity[offsets[k-1]:offsets[k]]``
    (offsets (K,): where each polygon's point indices end), cell_data {name: (K,) or (K,k)}."""
    return _write_vtp(path, np.asarray(points, dtype=np.float64), "Polys", np.asarray(connectivity, dtype=np.int64),
                      np.asarray(offsets, dtype=np.int64), {}, cell_data, compress, field_data)


def _write_vtp(path, points, kind, connectivity, offsets, point_data, cell_data, compress, field_data):
    """A VTK XML PolyData file of ``kind`` cells ("Lines" or "Polys"), written to a temporary file and renamed."""
    arrays, offset = [], 0
    xml = {"FieldData": [], "PointData": [], "CellData": [], "Points": [], kind: []}

    def add(section, name, value):
        nonlocal offset
        value = np.asarray(value)
        if value.dtype not in _VTK_TYPES:
            value = value.astype(np.float64 if value.dtype.kind == "f" else np.int64)
        comps = value.shape[1] if value.ndim == 2 else 1
        tuples = f'NumberOfTuples="{len(value)}" ' if section == "FieldData" else ""
        xml[section].append(f'<DataArray type="{_VTK_TYPES[value.dtype]}" Name="{name}" {tuples}'
                            f'NumberOfComponents="{comps}" format="appended" offset="{offset}"/>')
        block = _encode(value, compress)
        arrays.append(block)
        offset += len(block)

    for name, value in (field_data or {}).items():
        add("FieldData", name, value)
    for name, value in point_data.items():
        add("PointData", name, value)
    for name, value in cell_data.items():
        add("CellData", name, value)
    add("Points", "Points", points)
    add(kind, "connectivity", connectivity)
    add(kind, "offsets", offsets)
    compressor = ' compressor="vtkZLibDataCompressor"' if compress else ""
    head = [
        '<?xml version="1.0"?>',
        f'<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64"{compressor}>',
        "<PolyData>"]
    if xml["FieldData"]:
        head += ["<FieldData>"] + xml["FieldData"] + ["</FieldData>"]
    lines, polys = (len(offsets), 0) if kind == "Lines" else (0, len(offsets))
    head += [
        f'<Piece NumberOfPoints="{len(points)}" NumberOfVerts="0" NumberOfLines="{lines}" '
        f'NumberOfStrips="0" NumberOfPolys="{polys}">']
    for section in ("PointData", "CellData", "Points", kind):
        head += [f"<{section}>"] + xml[section] + [f"</{section}>"]
    head += ["</Piece>", "</PolyData>", '<AppendedData encoding="raw">', "_"]
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write("\n".join(head).encode())
        for block in arrays:
            f.write(block)
        f.write(b"\n</AppendedData>\n</VTKFile>\n")
    os.replace(tmp, path)
    return path


def box_fields(box):
    """Field data describing ``box`` (None: none): box_size (3,) and box_periodic (3,) 0/1."""
    if box is None:
        return {}
    return {"box_size": np.asarray(box.size, dtype=np.float64),
            "box_periodic": np.asarray(box.periodic, dtype=np.int64)}
