"""Twisting (pivoting) resistance: a spring-dashpot-slider on the relative spin about the normal.

For a contact with unit normal n (from i to j) the relative twist rate is

    w_tw = (w_i - w_j).n        (a wall does not spin: w_tw = -w.n for the sphere, n from the wall)

and the twist angle xi_tw (history: the angle and the stiffness at its last update) is advanced by
w_tw dt at each committed step. The torque is a pure couple along n,

    M = -k_tw xi_tw - eta_tw w_tw,   |M| <= l_tw |F_n|,   tau_i = M n,  tau_j = -M n,

so forces and angular momentum are untouched; its power is tau_i.w_i + tau_j.w_j = M w_tw. Beyond
the limit M is set to +-l_tw |F_n| and the spring holds the whole limiting torque, xi_tw = -M/k_tw
(demkit's "coulomb" sliding rule, as for friction); with ``Friction(sliding="lammps")`` LAMMPS' rule,
M = -l_tw |F_n| sign(w_tw) and xi_tw = (l_tw |F_n| sign(w_tw) - eta_tw w_tw)/k_tw.

Marshall's coefficients (J. Comput. Phys. 228, 1541 (2009), eqs. 32 and 44; LAMMPS' ``twisting
marshall``) follow from the friction law and the contact radius a = sqrt(R* delta):

    k_tw = k_t a^2 / 2,   eta_tw = eta_t a^2 / 2,   l_tw = (2/3) mu a,

(the torsion of a Hertzian contact patch with uniform traction mu p: the sliding torque is
(2/3) mu a F_n). Any of them may be given instead (LAMMPS' ``twisting sds k_tw eta_tw l_tw`` when all
three are). Energy: the spring stores k_tw xi_tw^2 / 2 (reported with the contact energy); a
committed step books P = -M w_tw - dU/dt as dissipated, with dU from the stiffness kept in the
history, so kinetic + potential + dissipated is conserved when k_tw changes with a.
"""
from __future__ import annotations

from numba import njit

from ..engine.motion import HELPER_OPTIONS

from .base import non_negative, positive

#: history values of the twist spring: the twist angle, the stiffness at its last update and the
#: torque of that update (the second half of its work is booked at the next update)
TWIST_HISTORY = 3
#: the sliding torque of Marshall's model is TORQUE_FACTOR mu a |F_n|
TORQUE_FACTOR = 2.0 / 3.0


class TwistingResistance:
    """Twisting resistance for a contact law with friction (see the module docstring).

    stiffness : k_tw > 0, torque per radian of relative twist (energy units, N m/rad in SI); None:
        Marshall's k_t a^2 / 2 (k_t the friction's tangential stiffness, a = sqrt(R* delta)).
    damping : eta_tw >= 0, torque per relative spin rate (N m s/rad in SI); None: eta_t a^2 / 2.
    lever : l_tw >= 0, a length: the largest twisting torque is l_tw |F_n|; None: (2/3) mu a.

    All three None is LAMMPS' ``twisting marshall``, all three given its ``twisting sds``.
    """

    def __init__(self, stiffness=None, damping=None, lever=None):
        self.stiffness = None if stiffness is None else positive("TwistingResistance stiffness", stiffness)
        self.damping = None if damping is None else non_negative("TwistingResistance damping", damping)
        self.lever = None if lever is None else non_negative("TwistingResistance lever", lever)

    @property
    def marshall(self):
        """Are all three coefficients Marshall's (LAMMPS' ``twisting marshall``)?"""
        return self.stiffness is None and self.damping is None and self.lever is None

    @property
    def fixed(self):
        """(k_tw, eta_tw, l_tw) for the kernels: a given value, or -1 for Marshall's."""
        return tuple(-1.0 if v is None else v for v in (self.stiffness, self.damping, self.lever))

    def __repr__(self):
        return (f"TwistingResistance(stiffness={self.stiffness!r}, damping={self.damping!r}, "
                f"lever={self.lever!r})")


@njit(**HELPER_OPTIONS)
def twist_coefficients(k_fixed, eta_fixed, lever_fixed, kt, eta_t, mu, a):
    """(k_tw, eta_tw, l_tw): the given values (>= 0; k_tw > 0), else Marshall's for contact radius a."""
    k = k_fixed if k_fixed > 0.0 else 0.5 * kt * a * a
    eta = eta_fixed if eta_fixed >= 0.0 else 0.5 * eta_t * a * a
    lever = lever_fixed if lever_fixed >= 0.0 else TORQUE_FACTOR * mu * a
    return k, eta, lever


@njit(**HELPER_OPTIONS)
def twist_torque(rate, limit, k, eta, share, history, p, o, commit, dt):
    """Twisting torque M (along n, on i) and dissipated power for twist rate ``rate`` and torque
    limit ``limit``; reads history[p, o:o+TWIST_HISTORY] and writes it when ``commit``; ``share`` 1: LAMMPS'
    sliding rule."""
    xi = history[p, o]
    old = 0.5 * history[p, o + 1] * xi * xi
    if commit:
        xi += rate * dt
    torque = -k * xi - eta * rate
    sliding = abs(torque) > limit
    if sliding:
        if share > 0.0:  # LAMMPS: the limit against the twist rate, the spring less the dashpot
            sign = 1.0 if rate > 0.0 else (-1.0 if rate < 0.0 else 0.0)
            torque = -limit * sign
            xi = (limit * sign - eta * rate) / k if k > 0.0 else 0.0
        else:  # demkit: the spring holds the whole limiting torque
            torque = limit if torque > 0.0 else -limit
            xi = -torque / k if k > 0.0 else 0.0
    power = -torque * rate
    if commit:  # half this torque's work and half the last one's, at this rate (demkit.interactions.spring)
        power = 0.5 * (power - history[p, o + 2] * rate)
        history[p, o] = xi
        history[p, o + 1] = k
        history[p, o + 2] = torque
        if dt > 0.0:
            power -= (0.5 * k * xi * xi - old) / dt
    elif not sliding:
        power = eta * rate * rate
    return torque, power


@njit(**HELPER_OPTIONS)
def twisting_on_i(nx, ny, nz, wx, wy, wz, normal, a, mu, kt, eta_t, k_fixed, eta_fixed, lever_fixed, share,
                  history, p, o, commit, dt):
    """Twisting torque on i (3 values; on j it is the negative) and dissipated power, for relative
    spin w = w_i - w_j, normal force ``normal`` and contact radius a."""
    k, eta, lever = twist_coefficients(k_fixed, eta_fixed, lever_fixed, kt, eta_t, mu, a)
    torque, lost = twist_torque(wx * nx + wy * ny + wz * nz, lever * abs(normal), k, eta, share, history, p, o,
                                commit, dt)
    return torque * nx, torque * ny, torque * nz, lost


@njit(**HELPER_OPTIONS)
def twist_energy(history, p, o):
    """Elastic energy k_tw xi_tw^2 / 2 of the twist spring."""
    return 0.5 * history[p, o + 1] * history[p, o] * history[p, o]


@njit(**HELPER_OPTIONS)
def twist_release(history, p, o, dt):
    """A contact that has ended keeps no twist: zero the history, return the energy the spring held
    as a power over the step (booked as dissipated)."""
    energy = twist_energy(history, p, o)
    history[p, o] = 0.0
    history[p, o + 1] = 0.0
    history[p, o + 2] = 0.0
    return energy / dt if dt > 0.0 else 0.0

