"""One frame of particles as a VTK unstructured grid (.vtu), written and read with meshio.

A frame's points are the sphere centres, with one vertex cell per sphere (so ParaView shows the
points even before a Glyph filter is added). Point data: ``id`` (int64), ``radius``, ``mass``
and, when present, ``velocity``, ``angular_velocity``, ``dipole``, ``force``, ``torque`` (N,3)
and, in a periodic box, ``image`` (N,3 int64 image counts: unwrapped = position + image * size).
"""
from __future__ import annotations

import numpy as np

#: per-particle vector fields a frame may carry, in the order they are written
VECTOR_FIELDS = ("velocity", "angular_velocity", "dipole", "force", "torque")
#: per-particle fields every frame carries
CONSTANT_FIELDS = ("id", "radius", "mass")
COMPRESSORS = {False: None, None: None, True: "zlib", "zlib": "zlib", "lzma": "lzma"}
DTYPES = {"float64": np.float64, "float32": np.float32}


def compressor(compress):
    """meshio's compression name for ``compress`` (False/None, True = 'zlib', 'zlib', 'lzma')."""
    try:
        return COMPRESSORS[compress]
    except (KeyError, TypeError):
        raise ValueError(f"compress must be False, True, 'zlib' or 'lzma', got {compress!r}") from None


def float_dtype(dtype):
    """numpy float type for ``dtype`` ('float64' or 'float32', or the numpy types)."""
    try:
        return DTYPES[np.dtype(dtype).name]
    except (TypeError, KeyError):
        raise ValueError(f"dtype must be 'float64' or 'float32', got {dtype!r}") from None


def choose_fields(available, fields):
    """The vector fields to write: ``fields`` (names) checked against ``available``, or all of
    ``available`` when ``fields`` is None."""
    if fields is None:
        return tuple(f for f in VECTOR_FIELDS if f in available)
    if isinstance(fields, str):
        fields = (fields,)
    fields = tuple(fields)
    unknown = [f for f in fields if f not in VECTOR_FIELDS]
    if unknown:
        raise ValueError(f"unknown field(s) {unknown}; known: {list(VECTOR_FIELDS)} "
                         f"(id, radius and mass are always written)")
    missing = [f for f in fields if f not in available]
    if missing:
        raise ValueError(f"the scene has no {', '.join(missing)} to write "
                         f"(it has {', '.join(available) or 'none of the optional fields'})")
    return tuple(f for f in VECTOR_FIELDS if f in fields)


class FrameWriter:
    """Writes frames of a fixed set of fields; keeps the vertex cells between frames."""

    def __init__(self, compress=False, dtype="float64"):
        self.compression = compressor(compress)
        self.dtype = float_dtype(dtype)
        self._cells = None

    def write(self, path, position, data):
        """Write ``position`` (N,3) and the point-data dict ``data`` to the .vtu ``path``."""
        import meshio

        n = len(position)
        if self._cells is None or len(self._cells) != n:
            index = np.int32 if n < 2**31 - 1 else np.int64
            self._cells = np.arange(n, dtype=index).reshape(-1, 1)
        point_data = {}
        for name, value in data.items():
            value = np.asarray(value)
            point_data[name] = value if value.dtype.kind == "i" else value.astype(self.dtype, copy=False)
        mesh = meshio.Mesh(np.asarray(position).astype(self.dtype, copy=False),
                           [("vertex", self._cells)], point_data=point_data)
        meshio.write(path, mesh, file_format="vtu", binary=True, compression=self.compression,
                     header_type="UInt64")


def read_frame(path):
    """(position (N,3), point-data dict) of a .vtu frame written by demkit."""
    import meshio

    mesh = meshio.read(path, file_format="vtu")
    return np.asarray(mesh.points), {k: np.asarray(v) for k, v in mesh.point_data.items()}
