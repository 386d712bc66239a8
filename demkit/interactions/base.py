"""The plug-in contract every pair interaction follows.

An interaction is a small evaluator. It declares what it needs and provides two pure numba
functions; the scene fuses the chosen interactions into one compiled pair loop
(see :mod:`demkit.engine.kernels`).

Pair functions see one pair (i, j) with separation ``d = x_j - x_i`` (``dx, dy, dz``) and
``r2 = |d|**2``, then the particle arrays named in ``reads`` (indexed with i and j), then the
scalars named in ``parameters`` in that order::

    force(i, j, dx, dy, dz, r2, *fields, *params)
        -> (fx, fy, fz)                               force on j (the force on i is its negative)
           + (tix, tiy, tiz, tjx, tjy, tjz)           if ``torque`` is True
           + (power,)                                 if ``dissipative`` is True (energy lost per time)
    energy(i, j, dx, dy, dz, r2, *fields, *params) -> pair potential energy

Interactions with per-contact history (``history_size > 0``) also receive ``history, p, offset,
commit`` before the parameters: they read ``history[p, offset:offset + history_size]`` and write
it only when ``commit`` is True, so that evaluating forces has no side effects unless asked.
Beyond ``cutoff_distance`` the pair functions are not called and, when committing, the pair's
history values are set to zero (a pair out of reach has no history). History survives
neighbour-list rebuilds and re-sorting; a pair that leaves the list loses it, one that enters
starts from zero. The pair is always presented in the same orientation (i, j).

A parameter named ``dt`` receives the integrator's time step at the start of every run (0 before
any run); history updates that integrate a rate over the step use it. Single-sphere effects
(:mod:`demkit.interactions.sphere`) may in addition read a table of floats from ``params``.
"""
from __future__ import annotations

import inspect
import math

import numpy as np

from ..checks import flag, non_negative, number, positive, real_array  # noqa: F401 (used by the interactions)

FIELDS = ("velocity", "angular_velocity", "dipole", "radius", "mass")
#: the largest omega dt a time-step limit allows for a smooth effect (dipoles, fields) that makes
#: spheres oscillate at angular frequency omega at most. Measured (docs/stability.md): a rotational
#: pendulum keeps its energy to 6 % of its oscillation energy with velocity Verlet there (32 % with
#: Euler-Cromer); they go unstable at omega dt = 2 and 1.5, three to four times further. (Contacts,
#: whose force jumps at onset, keep the stricter tenth of their duration, omega dt <= pi/10.)
SAFE_PHASE = 0.5


class Interaction:
    """What pair and single-sphere interactions share: declarations and two numba functions."""

    #: particle arrays the functions read, from :data:`FIELDS`
    reads: tuple = ()
    #: does the force function also return torques?
    torque: bool = False
    #: does the force function also return a dissipated power (>= 0)?
    dissipative: bool = False
    #: number of history values kept per pair (per sphere for single-sphere interactions)
    history_size: int = 0
    #: energy category reported by Scene.energy() ("magnetic", "contact", ...)
    energy_kind: str = "potential"
    #: names of the scalar parameters passed to the functions, in order
    parameters: tuple = ()
    #: may a scene hold two of this class (or of a subclass of it)? False: their forces would
    #: simply add up (two Gravity, two Dipole sums), which is refused; walls and tabulated fields
    #: may repeat. The same object twice is always refused.
    repeatable: bool = False
    #: how to do with one instance what two would do (said when a second one is refused)
    repeat_hint: str = "keep one of them"
    #: numba functions (set by subclasses)
    force_function = None
    energy_function = None

    def pair_functions(self):
        """(force_function, energy_function) as plain numba dispatchers.

        Looked up statically: a dispatcher stored on a class is a descriptor, and plain attribute
        access would hand back a bound method.
        """
        return (inspect.getattr_static(self, "force_function"),
                inspect.getattr_static(self, "energy_function"))

    def parameter_values(self):
        """The values of :attr:`parameters` as a float64 array (numbers; bools count as 0 and 1)."""
        values = [getattr(self, name) for name in self.parameters]
        return np.array([float(v) if isinstance(v, (bool, np.bool_)) else number(f"{type(self).__name__} {name}", v)
                         for name, v in zip(self.parameters, values)], dtype=np.float64)

    def max_time_step(self, particles):
        """Largest time step this interaction can be integrated with safely (math.inf: no limit)."""
        return math.inf

    def check(self, particles):
        """Raise ValueError if the particles lack something this interaction needs."""
        unknown = set(self.reads) - set(FIELDS)
        if unknown:
            raise ValueError(f"{type(self).__name__} reads unknown fields {sorted(unknown)}; known: {FIELDS}")
        if "dipole" in self.reads and particles.dipole is None:
            raise ValueError(f"{type(self).__name__} needs particle dipole moments: pass dipole=... to Particles")

    def __repr__(self):
        args = ", ".join(f"{name}={getattr(self, name)!r}" for name in self.parameters)
        return f"{type(self).__name__}({args})"


class PairInteraction(Interaction):
    """Base class of pair interactions (subclass it to plug in new physics)."""

    #: the pair functions have no branches (and no history): the pair loop then evaluates blocks of
    #: pairs in a loop the compiler can vectorise, and applies the cutoff as a mask
    branch_free: bool = False
    #: centre distance beyond which the pair loop skips this interaction (None: never skipped;
    #: contact laws test their own reach instead)
    cutoff_distance = None
    #: no force beyond r = R_i + R_j: when every interaction of a pair loop says so, the loop skips
    #: such pairs before any call or accumulation (a pair still holding history is passed to its law once more)
    contact_reach: bool = False
    #: a smooth, slowly varying force (dipoles): :class:`demkit.MultipleTimeStep` evaluates it once
    #: per outer step, the others (contacts, walls, gravity, fields) on every inner step
    slow: bool = False

    def cutoff(self, particles):
        """Largest centre distance at which the pair can interact (math.inf: no cutoff)."""
        return math.inf if self.cutoff_distance is None else self.cutoff_distance


def check_repeats(interactions):
    """Raise ValueError if the same object appears twice in ``interactions`` or two interactions of
    a class that is not :attr:`~Interaction.repeatable` (one an instance of the other's class) do."""
    for b, second in enumerate(interactions):
        for a, first in enumerate(interactions[:b]):
            if first is second:
                raise ValueError(f"the same {first!r} is given twice (entries {a} and {b} of interactions): its "
                                 f"forces would be counted twice; give it once")
            for one, other in ((first, second), (second, first)):
                kind = type(one)
                if not kind.repeatable and isinstance(other, kind):
                    raise ValueError(f"two {kind.__name__} interactions are given (entries {a}: {first!r} and "
                                     f"{b}: {second!r}): their forces would add up; {kind.repeat_hint}")


def inverse_inertia(particles):
    """(1/m, 1/I) per sphere, (N,) each, zero for fixed spheres (infinite mass and inertia)."""
    inv_mass, inv_inertia = 1.0 / particles.mass, 1.0 / particles.inertia
    if particles.fixed is not None:
        inv_mass = np.where(particles.fixed, 0.0, inv_mass)
        inv_inertia = np.where(particles.fixed, 0.0, inv_inertia)
    return inv_mass, inv_inertia
