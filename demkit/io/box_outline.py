"""A deforming periodic box as an outline at every frame, for ParaView.

A :class:`demkit.Box` with ``deform=`` changes its lengths as the run goes (L_a(t), :meth:`demkit.Box.size_at`),
so one outline drawn from the series' ``Box`` element fits one frame only. :class:`demkit.VTKWriter` writes
beside such a series ``<name>_box.pvd`` of ``<name>_box_000000.vtp``, ...: the box [0, L_x] x [0, L_y] x
[0, L_z] at each frame's time as its twelve edges (VTK lines, cell data ``axis``: 0, 1, 2 for the edges along
x, y, z), field data ``box_size`` (L_x, L_y, L_z) and ``time``. Open it in ParaView beside the spheres
(``pvpython paraview_setup.py`` does) and the outline follows the box frame by frame.
"""
from __future__ import annotations

import itertools

import numpy as np

from .polylines import write_vtp_lines

#: the edges of the unit cube: (start corner, axis); each runs one side along its axis
_EDGES = [(corner, axis) for axis in range(3)
          for corner in itertools.product((0.0, 1.0), repeat=3) if corner[axis] == 0.0]


def outline(size):
    """(points (24, 3), axis (12,)): the twelve edges of the box [0, size], two points each."""
    size = np.asarray(size, dtype=np.float64)
    points = []
    for corner, axis in _EDGES:
        start = np.asarray(corner) * size
        end = start.copy()
        end[axis] = size[axis]
        points += [start, end]
    return np.array(points), np.array([axis for _, axis in _EDGES], dtype=np.int64)


def write_outline(path, size, time, compress=False):
    """Write the box [0, size] at ``time`` as the .vtp ``path`` (see the module docstring)."""
    points, axis = outline(size)
    return write_vtp_lines(path, points, np.full(len(axis), 2), {}, {"axis": axis}, compress=compress,
                           field_data={"box_size": np.asarray(size, dtype=np.float64),
                                       "time": np.array([float(time)])})
