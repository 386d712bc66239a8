"""The simulation box: a rectangular cell with its lower corner at the origin.

Each axis is periodic or open. Along a periodic axis of length L, positions are kept in [0, L)
(wrapped at neighbour-list rebuilds and in recorded frames) with an integer image count, so the
unwrapped position is ``position + image * size``; pair separations use the minimum image
d - L round(d / L). Along an open axis the box only states where the spheres start (a sphere
outside it is an error before the run) and frames pictures: spheres may leave it, as in open space
(walls are separate interactions). No box at all (``box=None``) is open space in every direction.
"""
from __future__ import annotations

import math

import numpy as np

from .checks import real_array


class Box:
    """Rectangular box [0, Lx) x [0, Ly) x [0, Lz).

    size : three positive lengths (or one, for a cube).
    periodic : True/False for all axes, or three booleans (x, y, z).
    """

    def __init__(self, size, periodic=False):
        arr = real_array("Box size", size)
        if arr.ndim == 0:
            arr = np.full(3, float(arr))
        if arr.shape != (3,):
            raise ValueError(f"Box size must be one length or three lengths (x, y, z), got {size!r}")
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise ValueError(f"Box size must be three positive finite lengths, got {arr.tolist()}")
        flags = np.array(periodic, dtype=object)
        if flags.ndim == 0:
            flags = np.array([periodic] * 3, dtype=object)
        if flags.shape != (3,) or not all(isinstance(f, (bool, np.bool_)) for f in flags):
            raise ValueError(f"Box periodic must be a bool or three bools (x, y, z), got {periodic!r}")
        self.size = arr
        self.size.setflags(write=False)
        self.periodic = np.array([bool(f) for f in flags])
        self.periodic.setflags(write=False)

    @property
    def any_periodic(self):
        return bool(self.periodic.any())

    @property
    def volume(self):
        return float(np.prod(self.size))

    def wrap(self, position):
        """(wrapped positions, image shifts): periodic coordinates brought into [0, L)."""
        position = np.asarray(position, dtype=np.float64)
        shift = np.zeros(position.shape, dtype=np.int64)
        wrapped = position.copy()
        for a in np.flatnonzero(self.periodic):
            k = np.floor(position[..., a] / self.size[a])
            wrapped[..., a] = position[..., a] - k * self.size[a]
            # round-off can leave exactly L: put it at 0 of the next image
            edge = wrapped[..., a] >= self.size[a]
            wrapped[..., a][edge] -= self.size[a]
            shift[..., a] = k.astype(np.int64) + edge
        return wrapped, shift

    def minimum_image(self, separation):
        """Separations (..., 3) reduced to their nearest periodic image."""
        d = np.array(separation, dtype=np.float64)
        for a in np.flatnonzero(self.periodic):
            d[..., a] -= self.size[a] * np.round(d[..., a] / self.size[a])
        return d

    def outside(self, position):
        """Indices of positions outside the box along an open (non-periodic) axis."""
        position = np.asarray(position, dtype=np.float64)
        bad = np.zeros(len(position), dtype=bool)
        for a in np.flatnonzero(~self.periodic):
            bad |= (position[:, a] < 0.0) | (position[:, a] > self.size[a])
        return np.flatnonzero(bad)

    def check_reach(self, reach, what):
        """Raise ValueError if a periodic side is not longer than twice ``reach`` (the minimum
        image would miss interactions)."""
        if not math.isfinite(reach):
            if self.any_periodic:
                raise ValueError(f"{what} has no cutoff, which a periodic box cannot hold (the sum over "
                                 f"images is not done): give it a cutoff shorter than half the box")
            return
        for a in np.flatnonzero(self.periodic):
            if self.size[a] <= 2.0 * reach:
                raise ValueError(
                    f"the periodic box side {'xyz'[a]} = {self.size[a]:.6g} is not longer than twice the reach "
                    f"{reach:.6g} of {what}: the minimum image would miss interactions; make the box longer "
                    f"than {2 * reach:.6g} or the reach shorter")

    def __eq__(self, other):
        return (isinstance(other, Box) and np.array_equal(self.size, other.size)
                and np.array_equal(self.periodic, other.periodic))

    def __repr__(self):
        flags = self.periodic.tolist()
        periodic = flags[0] if len(set(flags)) == 1 else tuple(flags)
        return f"Box(size={tuple(self.size.tolist())}, periodic={periodic})"
