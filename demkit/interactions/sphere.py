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

import inspect

import numpy as np

from .base import FIELDS


class SphereInteraction:
    """Base class of single-sphere effects (subclass it to plug in new surroundings)."""

    reads: tuple = ()
    torque: bool = False
    dissipative: bool = False
    history_size: int = 0
    energy_kind: str = "external"
    parameters: tuple = ()
    force_function = None
    energy_function = None

    def pair_functions(self):
        """(force_function, energy_function) as plain numba dispatchers (name shared with pairs)."""
        return (inspect.getattr_static(self, "force_function"),
                inspect.getattr_static(self, "energy_function"))

    def parameter_values(self):
        return np.array([float(getattr(self, name)) for name in self.parameters], dtype=np.float64)

    def bind(self, interactions):
        """Called by the scene with its pair interactions before anything else (walls find their
        contact law here)."""

    def check(self, particles):
        """Raise ValueError if the particles lack something this effect needs, or start in a
        state it cannot handle."""
        unknown = set(self.reads) - set(FIELDS)
        if unknown:
            raise ValueError(f"{type(self).__name__} reads unknown fields {sorted(unknown)}; known: {FIELDS}")
        if "dipole" in self.reads and particles.dipole is None:
            raise ValueError(f"{type(self).__name__} needs particle dipole moments: pass dipole=... to Particles")

    def max_time_step(self, particles):
        return float("inf")

    def __repr__(self):
        args = ", ".join(f"{name}={getattr(self, name)!r}" for name in self.parameters)
        return f"{type(self).__name__}({args})"


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
