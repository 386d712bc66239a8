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

An effect may also carry a *table* of floats (a tabulated field, say): :meth:`table_values`
returns it as a 1-D float64 array. The scene appends every table to its ``params`` array (after
all scalar parameters and cutoffs), and the functions then receive ``params, start`` after the
history arguments and before the scalars, ``start`` being the literal index of the table's first
value: they read ``params[start:start + len(table)]`` at run time, so the table's values are never
compiled into the code. An effect without a table (the default, an empty array) is called exactly
as above.
"""
from __future__ import annotations

import numpy as np

from .base import Interaction, real_array


class SphereInteraction(Interaction):
    """Base class of single-sphere effects (subclass it to plug in new surroundings)."""

    energy_kind: str = "external"
    #: a plane contact whose first four parameters are (plane, nx, ny, nz), the wall x.n = plane:
    #: VelocityVerlet(resolve_contacts=True) locates the moments spheres reach and leave it
    plane_contact: bool = False
    #: exchanges energy with a heat bath (a thermostat): the scene's energy balance does not hold,
    #: and only the integrators the effect allows run it (see Integrator.check)
    stochastic: bool = False

    def bind(self, interactions):
        """Called by the scene with its pair interactions before anything else (walls find their
        contact law here)."""

    def table_values(self):
        """The effect's table of floats (1-D float64; empty: no table, see the module docstring)."""
        return np.zeros(0)

    def geometry_values(self):
        """A wall's geometry block (1-D float64; empty for a steady plane wall and every other effect): a
        moving wall's motion, a :class:`demkit.Cylinder`'s axis, radius, side and rate of turning, from
        which the compiled loops find the plane each sphere touches at the scene's clock
        (demkit.interactions.wall_motion.wall_plane)."""
        return np.zeros(0)

    def stop_hint(self, position):
        """Why a sphere now at ``position`` (None if not finite) made a run go non-finite because of
        this effect, as words completing "particle id <n> ..." (e.g. "left the region of ..."), or
        None. The run's error message then leads with them."""
        return None


def vector(name, value):
    """A finite 3-vector as a float array, or ValueError naming the problem."""
    arr = real_array(name, value)
    if arr.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got {arr.tolist()}")
    return arr
