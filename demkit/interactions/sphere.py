"""The plug-in contract of single-sphere effects: walls, gravity, external fields.

A sphere interaction acts on each sphere alone. Like a pair interaction it declares what it needs
and provides two numba functions, fused by the scene into one compiled loop over the spheres
(absent from the compiled code of a scene that does not use it). They see sphere i at (x, y, z),
then the particle arrays named in ``reads``, then (with history) ``history, i, offset, commit``,
then the scalars named in ``parameters``::

    force(i, x, y, z, *fields, *params) -> (fx, fy, fz)
                                           + (tx, ty, tz)   if ``torque`` is True
                                           + (power,)       if ``dissipative`` is True
    energy(i, x, y, z, *fields, *params) -> potential energy of sphere i in this effect

History is kept per sphere (``history_size`` values, e.g. a wall contact's tangential spring),
carried through re-sorting, written only when ``commit`` is True. A parameter named ``dt``
receives the integrator's time step.
"""
from __future__ import annotations

import numpy as np

from .base import Interaction


class SphereInteraction(Interaction):
    """Base class of single-sphere effects (subclass it to plug in new surroundings)."""

    energy_kind: str = "external"

    def bind(self, interactions):
        """Called by the scene with its pair interactions before anything else (walls find their
        contact law here)."""


def vector(name, value):
    """A finite 3-vector as a float array, or ValueError naming the problem."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a 3-vector of numbers, got {value!r}") from None
    if arr.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr
