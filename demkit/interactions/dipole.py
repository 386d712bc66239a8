"""Magnetic dipole-dipole interaction between uniformly magnetised spheres.

For moments m_i, m_j and separation r = x_j - x_i (unit vector n = r/|r|), with A the prefactor
(mu0/4pi = 1e-7 in SI; 1/3 with unit moments gives the paper's units where 3 mu0 m1 m2/4pi = 1):

    U     = A [m_i.m_j - 3 (m_i.n)(m_j.n)] / r^3
    F_j   = -dU/dr_j = 3A/r^4 [(m_i.m_j) n + (m_i.n) m_j + (m_j.n) m_i - 5 (m_i.n)(m_j.n) n],  F_i = -F_j
    tau_i = m_i x B_j(x_i) = A/r^3 [3 (m_j.n)(m_i x n) - m_i x m_j]      (and i <-> j)

Head-to-tail moments (m_i = m_j = n) attract: F_j = -6 A /r^4 n. The point-dipole form is exact
for uniformly magnetised spheres (Edwards et al., Am. J. Phys. 85, 130 (2017)).

Truncation (``cutoff``): plain by default (pairs at r >= r_c are skipped, as LAMMPS'
lj/cut/dipole/cut does; the energy jumps when a pair crosses r_c). With ``switch_width`` w the pair
energy is multiplied by a smooth switch S(r), S = 1 for r <= r_on = r_c - w and, with
x = (r - r_on)/w on [r_on, r_c],

    S(x) = 1 - 10 x^3 + 15 x^4 - 6 x^5,     dS/dr = -30 x^2 (1 - x)^2 / w,

(computed as y^3 (10 - 15 y + 6 y^2) with y = 1 - x, which keeps S's relative accuracy near r_c)

so S, S' and S'' vanish at r_c and S', S'' at r_on. The switched pair is a genuine potential,

    U_s = S U,    F_j,s = -dU_s/dx_j = S F_j - U S'(r) n,    tau_s = S tau,

and a run conserves energy to the integrator's order. The switched pair functions repeat the plain
arithmetic instead of calling the plain ones: the on-disk kernel cache is keyed by the source of the
pair functions named in the scene, so a callee's later edit would not invalidate it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS

from .base import PairInteraction, inverse_inertia, positive


@njit(**KERNEL_OPTIONS)
def dipole_force(i, j, dx, dy, dz, r2, dipole, prefactor):
    """Force on j and torques on i and j for the full dipole-dipole interaction."""
    inv_r2 = 1.0 / r2
    inv_r = math.sqrt(inv_r2)
    ax = dipole[i, 0]
    ay = dipole[i, 1]
    az = dipole[i, 2]
    bx = dipole[j, 0]
    by = dipole[j, 1]
    bz = dipole[j, 2]
    # unnormalised projections on d: (m.d) = |d| (m.n)
    ad = ax * dx + ay * dy + az * dz
    bd = bx * dx + by * dy + bz * dz
    ab = ax * bx + ay * by + az * bz
    inv_r3 = prefactor * inv_r2 * inv_r
    inv_r5 = inv_r3 * inv_r2
    # F_j = 3A [ab d/r^5 + bd a/r^5 + ad b/r^5 - 5 ad bd d/r^7]
    radial = 3.0 * inv_r5 * (ab - 5.0 * ad * bd * inv_r2)
    c = 3.0 * inv_r5
    fx = radial * dx + c * (bd * ax + ad * bx)
    fy = radial * dy + c * (bd * ay + ad * by)
    fz = radial * dz + c * (bd * az + ad * bz)
    # a x b
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    # tau_i = A/r^3 [3 (b.d)/r^2 (a x d) - a x b];  tau_j = A/r^3 [3 (a.d)/r^2 (b x d) + a x b]
    si = 3.0 * bd * inv_r5
    sj = 3.0 * ad * inv_r5
    tix = si * (ay * dz - az * dy) - inv_r3 * cx
    tiy = si * (az * dx - ax * dz) - inv_r3 * cy
    tiz = si * (ax * dy - ay * dx) - inv_r3 * cz
    tjx = sj * (by * dz - bz * dy) + inv_r3 * cx
    tjy = sj * (bz * dx - bx * dz) + inv_r3 * cy
    tjz = sj * (bx * dy - by * dx) + inv_r3 * cz
    return fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz


@njit(**KERNEL_OPTIONS)
def dipole_energy(i, j, dx, dy, dz, r2, dipole, prefactor):
    """U = A [m_i.m_j - 3 (m_i.n)(m_j.n)] / r^3."""
    ad = dipole[i, 0] * dx + dipole[i, 1] * dy + dipole[i, 2] * dz
    bd = dipole[j, 0] * dx + dipole[j, 1] * dy + dipole[j, 2] * dz
    ab = dipole[i, 0] * dipole[j, 0] + dipole[i, 1] * dipole[j, 1] + dipole[i, 2] * dipole[j, 2]
    inv_r3 = 1.0 / (r2 * math.sqrt(r2))
    return prefactor * inv_r3 * (ab - 3.0 * ad * bd / r2)


@njit(**KERNEL_OPTIONS)
def power_law_force(i, j, dx, dy, dz, r2, dipole, prefactor):
    """Central force on j: F_j = -6 A |m_i||m_j| / r^4 n (attractive)."""
    mi = math.sqrt(dipole[i, 0] ** 2 + dipole[i, 1] ** 2 + dipole[i, 2] ** 2)
    mj = math.sqrt(dipole[j, 0] ** 2 + dipole[j, 1] ** 2 + dipole[j, 2] ** 2)
    s = -6.0 * prefactor * mi * mj / (r2 * r2 * math.sqrt(r2))
    return s * dx, s * dy, s * dz


@njit(**KERNEL_OPTIONS)
def power_law_energy(i, j, dx, dy, dz, r2, dipole, prefactor):
    """U = -2 A |m_i||m_j| / r^3."""
    mi = math.sqrt(dipole[i, 0] ** 2 + dipole[i, 1] ** 2 + dipole[i, 2] ** 2)
    mj = math.sqrt(dipole[j, 0] ** 2 + dipole[j, 1] ** 2 + dipole[j, 2] ** 2)
    return -2.0 * prefactor * mi * mj / (r2 * math.sqrt(r2))


@njit(**KERNEL_OPTIONS)
def switched_dipole_force(i, j, dx, dy, dz, r2, dipole, prefactor, switch_on, inv_width):
    """Force on j and torques of the switched pair S(r) U: S F_j - U S' n, S tau_i, S tau_j.

    Branch-free: x is clamped to [0, 1], so below ``switch_on`` S = 1 and S' = 0 exactly and the
    results are those of :func:`dipole_force` bit for bit; at and beyond the cutoff all are 0.
    """
    inv_r2 = 1.0 / r2
    inv_r = math.sqrt(inv_r2)
    ax = dipole[i, 0]
    ay = dipole[i, 1]
    az = dipole[i, 2]
    bx = dipole[j, 0]
    by = dipole[j, 1]
    bz = dipole[j, 2]
    ad = ax * dx + ay * dy + az * dz
    bd = bx * dx + by * dy + bz * dz
    ab = ax * bx + ay * by + az * bz
    inv_r3 = prefactor * inv_r2 * inv_r
    inv_r5 = inv_r3 * inv_r2
    radial = 3.0 * inv_r5 * (ab - 5.0 * ad * bd * inv_r2)
    c = 3.0 * inv_r5
    fx = radial * dx + c * (bd * ax + ad * bx)
    fy = radial * dy + c * (bd * ay + ad * by)
    fz = radial * dz + c * (bd * az + ad * bz)
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    si = 3.0 * bd * inv_r5
    sj = 3.0 * ad * inv_r5
    tix = si * (ay * dz - az * dy) - inv_r3 * cx
    tiy = si * (az * dx - ax * dz) - inv_r3 * cy
    tiz = si * (ax * dy - ay * dx) - inv_r3 * cz
    tjx = sj * (by * dz - bz * dy) + inv_r3 * cx
    tjy = sj * (bz * dx - bx * dz) + inv_r3 * cy
    tjz = sj * (bx * dy - by * dx) + inv_r3 * cz
    # switch: x = (r - r_on)/w in [0, 1]; S = 1 - x^3 (10 - 15 x + 6 x^2), dS/dr = -30 x^2 (1-x)^2 / w
    x = min(max((r2 * inv_r - switch_on) * inv_width, 0.0), 1.0)
    y = 1.0 - x
    s = y * y * y * (10.0 - y * (15.0 - 6.0 * y))  # = 1 - x^3 (10 - 15 x + 6 x^2), exact near the cutoff
    ds = -30.0 * x * x * y * y * inv_width
    u = inv_r3 * (ab - 3.0 * ad * bd * inv_r2)             # plain pair energy U
    g = -u * ds * inv_r                                    # -U S' n = g d
    return (s * fx + g * dx, s * fy + g * dy, s * fz + g * dz,
            s * tix, s * tiy, s * tiz, s * tjx, s * tjy, s * tjz)


@njit(**KERNEL_OPTIONS)
def switched_dipole_energy(i, j, dx, dy, dz, r2, dipole, prefactor, switch_on, inv_width):
    """S(r) U, with U = A [m_i.m_j - 3 (m_i.n)(m_j.n)] / r^3 as in :func:`dipole_energy`."""
    ad = dipole[i, 0] * dx + dipole[i, 1] * dy + dipole[i, 2] * dz
    bd = dipole[j, 0] * dx + dipole[j, 1] * dy + dipole[j, 2] * dz
    ab = dipole[i, 0] * dipole[j, 0] + dipole[i, 1] * dipole[j, 1] + dipole[i, 2] * dipole[j, 2]
    inv_r3 = 1.0 / (r2 * math.sqrt(r2))
    x = min(max((math.sqrt(r2) - switch_on) * inv_width, 0.0), 1.0)
    return prefactor * inv_r3 * (ab - 3.0 * ad * bd / r2) * (1.0 - x) ** 3 * (10.0 - (1.0 - x) * (15.0 - 6.0 * (1.0 - x)))


@njit(**KERNEL_OPTIONS)
def switched_power_law_force(i, j, dx, dy, dz, r2, dipole, prefactor, switch_on, inv_width):
    """Central force on j of the switched power law S(r) U: S F_j - U S' n."""
    mi = math.sqrt(dipole[i, 0] ** 2 + dipole[i, 1] ** 2 + dipole[i, 2] ** 2)
    mj = math.sqrt(dipole[j, 0] ** 2 + dipole[j, 1] ** 2 + dipole[j, 2] ** 2)
    r = math.sqrt(r2)
    f = -6.0 * prefactor * mi * mj / (r2 * r2 * r)         # F_j = f d
    x = min(max((r - switch_on) * inv_width, 0.0), 1.0)
    y = 1.0 - x
    s = y * y * y * (10.0 - y * (15.0 - 6.0 * y))  # = 1 - x^3 (10 - 15 x + 6 x^2), exact near the cutoff
    ds = -30.0 * x * x * y * y * inv_width
    u = -2.0 * prefactor * mi * mj / (r2 * r)
    g = s * f - u * ds / r
    return g * dx, g * dy, g * dz


@njit(**KERNEL_OPTIONS)
def switched_power_law_energy(i, j, dx, dy, dz, r2, dipole, prefactor, switch_on, inv_width):
    """S(r) U with U = -2 A |m_i||m_j| / r^3."""
    mi = math.sqrt(dipole[i, 0] ** 2 + dipole[i, 1] ** 2 + dipole[i, 2] ** 2)
    mj = math.sqrt(dipole[j, 0] ** 2 + dipole[j, 1] ** 2 + dipole[j, 2] ** 2)
    r = math.sqrt(r2)
    x = min(max((r - switch_on) * inv_width, 0.0), 1.0)
    return -2.0 * prefactor * mi * mj / (r2 * r) * (1.0 - x) ** 3 * (10.0 - (1.0 - x) * (15.0 - 6.0 * (1.0 - x)))


def switch(r, cutoff, switch_width):
    """The switching function S(r) and dS/dr (numpy, for tests and plots)."""
    r = np.asarray(r, dtype=float)
    x = np.clip((r - (cutoff - switch_width)) / switch_width, 0.0, 1.0)
    y = 1.0 - x  # S(x) = 1 - 10 x^3 + 15 x^4 - 6 x^5 = 10 y^3 - 15 y^4 + 6 y^5: no cancellation near r_c
    return y**3 * (10.0 - y * (15.0 - 6.0 * y)), -30.0 * x**2 * y**2 / switch_width


class Dipole(PairInteraction):
    """Full dipole-dipole force and torque (see module docstring).

    prefactor : A = mu0/4pi (1e-7 T m/A in SI); 1/3 with unit moments gives the seed paper's units.
    cutoff : centre distance r_c beyond which the pair is ignored (None: never).
    switch_width : None (default) truncates plainly at ``cutoff``: forces, torques and energy jump
        when a pair crosses it, so a long run's energy drifts. A width w with 0 < w < cutoff
        multiplies the pair energy by a smooth switch S(r) on [cutoff - w, cutoff] (S = 1 below,
        0 at the cutoff, continuous first and second derivatives) and derives force and torque
        from it: a genuine, energy-conserving potential, exact below cutoff - w.
    long_range : None, or a :class:`demkit.Ewald`, :class:`demkit.P3M` or :class:`demkit.FMM` sum.
    induction : a :class:`demkit.Induction` (the induced-moment solve's tolerance) for scenes with
        magnetisable spheres (``Particles(susceptibility=...)``); None: the default Induction().
    """

    reads = ("dipole",)
    torque = True
    energy_kind = "magnetic"
    parameters = ("prefactor",)
    repeat_hint = ("one Dipole (or PowerLawDipole, a kind of Dipole) already couples every pair of moments: keep "
                   "one, with the prefactor you want")
    branch_free = True
    slow = True
    force_function = dipole_force
    energy_function = dipole_energy
    #: (force, energy) pair functions of the switched form; their parameters are
    #: ("prefactor", "switch_on", "inv_switch_width")
    switched_functions = (switched_dipole_force, switched_dipole_energy)

    def __init__(self, prefactor=1e-7, cutoff=None, switch_width=None, long_range=None, induction=None):
        from .induction import Induction
        name = type(self).__name__
        self.prefactor = positive(f"{name} prefactor", prefactor)
        if induction is not None and not isinstance(induction, Induction):
            raise ValueError(f"{name} induction must be a demkit.Induction (or None), got {induction!r}")
        self.induction = induction
        self.cutoff_distance = None if cutoff is None else positive(f"{name} cutoff", cutoff)
        self.switch_width = None
        self.long_range = None
        self.tuned = None
        #: what a scene's copy uses for long_range (an FMM below its crossover: the exact sum), or None
        self.long_range_note = None
        #: False: no pair loop evaluates this interaction (a long-range sum covers every pair)
        self.pair_loop = True
        if long_range is not None:
            self._long_range(long_range, switch_width)
            return
        if switch_width is None:
            return
        if cutoff is None:
            raise ValueError(f"{name} switch_width needs a cutoff: the switch runs from cutoff - "
                             f"switch_width to cutoff (got switch_width={switch_width!r}, cutoff=None)")
        width = positive(f"{name} switch_width", switch_width)
        if not width < self.cutoff_distance:
            raise ValueError(f"{name} switch_width must be a positive finite number smaller than the "
                             f"cutoff, got switch_width={width} with cutoff={self.cutoff_distance}")
        self.switch_width = width
        self.switch_on = self.cutoff_distance - width
        self.inv_switch_width = 1.0 / width
        # instance attributes: PairInteraction.pair_functions() looks them up statically
        self.force_function, self.energy_function = self.switched_functions
        self.parameters = ("prefactor", "switch_on", "inv_switch_width")

    def _long_range(self, long_range, switch_width):
        from .ewald import Ewald
        from .fmm import FMM
        name = type(self).__name__
        if not isinstance(long_range, (Ewald, FMM)):
            raise ValueError(f"{name} long_range must be a demkit.Ewald, demkit.P3M or demkit.FMM (or None), got "
                             f"{long_range!r}")
        if not self.torque:
            raise ValueError(f"{name} has no long_range form: the paper's central power law is no dipole field; "
                             f"use dk.Dipole(long_range=...)")
        if switch_width is not None:
            raise ValueError(f"{name} with long_range takes no switch_width: the sum covers every pair (an "
                             f"Ewald-split sum's real-space pair vanishes smoothly at its cutoff, to the requested "
                             f"accuracy)")
        self.long_range = long_range
        self.user_cutoff = self.cutoff_distance

    def tuned_for(self, particles, box):
        """With ``long_range``: a copy of this Dipole tuned to these spheres in this box (the Scene
        holds it in place of this one; ``original`` is this one, which stays untuned and can join
        other scenes). :attr:`tuned` (a ``TunedEwald``, ``TunedP3M`` or ``TunedFMM``) holds the
        sum and adapts the copy: an Ewald-split sum makes it the screened real-space pair at its
        cutoff, a fast multipole sum leaves it no pair loop (below its crossover it keeps the exact
        loop and :attr:`tuned` is None; :attr:`long_range_note` says which)."""
        import copy
        self.check(particles)
        bound = copy.copy(self)
        bound.original = self
        bound.tuned = _tune(self.long_range, self.prefactor, particles, box, self.user_cutoff)
        if bound.tuned is not None:  # (None: an FMM below its crossover keeps the exact pair loop)
            bound.tuned.adapt(bound)
        note = getattr(self.long_range, "note", None)
        bound.long_range_note = note(len(particles)) if note is not None else None
        return bound

    def rate_coefficients(self, particles, i, j):
        """(a, b), arrays over the index pairs (i, j): the fastest angular frequency the pair can move
        with under this interaction at centre distance r is at most omega = sqrt(a / r^5 + b / r^3).

        a = 24 A |m_i||m_j| (1/m_i + 1/m_j): the radial force gradient |dF/dr| = 24 A |m_i||m_j| / r^5
        of head-to-tail moments (the largest of all orientations) over the reduced mass.
        b = A |m_i||m_j| (2 max(1/I_i, 1/I_j) + 1/sqrt(I_i I_j)) with torques (0 without): a
        Gershgorin bound of the rotational stiffness (2 and 1 times A |m|^2 / r^3 on and off the
        diagonal for aligned moments). Checked against the eigenvalues of the pair's mass-weighted
        Hessian for random orientations (docs/stability.md). Fixed spheres count with infinite mass
        and inertia."""
        inv_mass, inv_inertia = inverse_inertia(particles)
        strength = self.prefactor * self._moments(particles, i, j)
        a = 24.0 * strength * (inv_mass[i] + inv_mass[j])
        if not self.torque:
            return a, np.zeros_like(a)
        b = strength * (2.0 * np.maximum(inv_inertia[i], inv_inertia[j]) + np.sqrt(inv_inertia[i] * inv_inertia[j]))
        return a, b

    def touching_attraction(self, particles, i, j):
        """(force, energy), arrays over the index pairs (i, j): the pull 6 A |m_i||m_j| / r^4 of
        touching spheres (r = R_i + R_j) with head-to-tail moments, the strongest orientation, and
        the energy 2 A |m_i||m_j| / r^3 released when they snap together from far apart."""
        r = particles.radius[i] + particles.radius[j]
        strength = self.prefactor * self._moments(particles, i, j)
        return 6.0 * strength / r**4, 2.0 * strength / r**3

    @staticmethod
    def _moments(particles, i, j):
        norm = np.linalg.norm(particles.dipole, axis=1)
        return norm[i] * norm[j]

    def __repr__(self):
        args = f"prefactor={self.prefactor!r}"
        cutoff = self.user_cutoff if self.long_range is not None else self.cutoff_distance
        if cutoff is not None:
            args += f", cutoff={cutoff!r}"
        if self.long_range is not None:
            args += f", long_range={self.long_range!r}"
        if self.switch_width is not None:
            args += f", switch_width={self.switch_width!r}"
        if self.induction is not None:
            args += f", induction={self.induction!r}"
        return f"{type(self).__name__}({args})"


class PowerLawDipole(Dipole):
    """The seed paper's central approximation of the dipole force (no torque).

    F_j = -6 A |m_i||m_j| / r^4 n and U = -2 A |m_i||m_j| / r^3: the head-to-tail force, applied
    whatever the orientation. It conserves angular momentum trivially but gives the wrong spin-up.
    ``cutoff`` and ``switch_width`` as for :class:`Dipole`.
    """

    torque = False
    force_function = power_law_force
    energy_function = power_law_energy
    switched_functions = (switched_power_law_force, switched_power_law_energy)


#: tuned Ewald-split sums of this process by what their tuning reads (TUNINGS_KEPT at most): a scene
#: built again (a scene file and its Python twin, a sweep's points, a rerun) is not tuned again
_TUNINGS = {}
TUNINGS_KEPT = 16


def _tune(long_range, prefactor, particles, box, cutoff):
    """``long_range.tune(...)``, remembered for Ewald and P3M sums. Their tuning reads the settings,
    the prefactor, the cutoff asked, the box, the count, the moments (the error sample draws from
    them) and the radii (the shortest cutoff, the touching pull), never the positions; an FMM's
    tuning measures the scene itself and is not remembered."""
    import hashlib

    from .ewald import Ewald
    if not isinstance(long_range, Ewald) or box is None:
        return long_range.tune(prefactor, particles, box, cutoff)
    moments = np.ascontiguousarray(particles.dipole, dtype=np.float64)
    key = (type(long_range), repr(long_range), float(prefactor), cutoff, tuple(map(float, box.size)),
           tuple(map(bool, box.periodic)), len(particles), hashlib.sha1(moments.tobytes()).hexdigest(),
           float(np.mean(particles.radius)), float(np.max(particles.radius)))
    if key not in _TUNINGS:
        if len(_TUNINGS) >= TUNINGS_KEPT:
            del _TUNINGS[next(iter(_TUNINGS))]
        _TUNINGS[key] = _on_one_thread(long_range.tune, prefactor, particles, box, cutoff)
    return _TUNINGS[key]


def _on_one_thread(tune, *args):
    """``tune(*args)`` on one of numba's threads, the count restored after. A tuning's trial sums are small
    (a sample of the spheres, meshes of some 18^3 points): a P3M scene of 216 spheres tuned in 0.30 CPU s on
    two threads against 0.20 on one, 0.55 against 0.25 with the other core busy; the sums' bits, and so
    the tuning, do not depend on the thread count."""
    import numba
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        return tune(*args)
    finally:
        numba.set_num_threads(before)
