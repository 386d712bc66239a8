"""Normal contact laws.

Kelvin-Voigt (linear spring-dashpot) on the overlap delta = R_i + R_j - r > 0 along n = (x_j - x_i)/r:

    F_n = k delta + c d(delta)/dt,    F_j = F_n n,  F_i = -F_j,   U = k delta^2 / 2

With ``no_tension=True`` F_n is clamped at 0 (the dashpot cannot pull). The power dissipated is
P = (F_n - k delta) d(delta)/dt (= c delta_dot^2 without the clamp), so that
kinetic + potential + dissipated work is conserved. For the two-body problem with
m_eff = m_i m_j/(m_i + m_j), omega_0 = sqrt(k/m_eff), zeta = c / (2 sqrt(k m_eff)) the contact lasts
pi / (omega_0 sqrt(1 - zeta^2)) and the restitution coefficient is exp(-pi zeta / sqrt(1 - zeta^2)).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS

from .base import PairInteraction, flag, non_negative, positive
from .friction import HISTORY, Friction, pair_friction, release, springs_energy
from .rolling import STIFFNESS_FACTOR, RollingResistance
from .twisting import TWIST_HISTORY, TwistingResistance, twist_energy, twist_release, twisting_on_i

#: the velocity shift a pair law subtracts from v_j - v_i: (0, 0, 0), except across the sliding boundary
#: of a sheared box, where j's image moves at v_j + k gammadot L_b e_a (demkit.engine.shear gives
#: -k gammadot L_b e_a); subtracting 0.0 leaves every bit as it was
NO_SHIFT = (0.0, 0.0, 0.0)
#: kernel parameters of twisting resistance (given values, or -1 for Marshall's), before ``dt``
TWIST_PARAMETERS = ("k_tw", "eta_tw", "lever_tw")


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_normal(overlap, rate, stiffness, damping, no_tension):
    """(F_n, elastic part k delta) of the spring-dashpot, F_n clamped at 0 with ``no_tension``."""
    elastic = stiffness * overlap
    fn = elastic + damping * rate
    if no_tension > 0.0 and fn < 0.0:
        fn = 0.0
    return fn, elastic


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_force(i, j, dx, dy, dz, r2, velocity, radius, stiffness, damping, no_tension, vshift=NO_SHIFT):
    """Force on j and dissipated power of a linear spring-dashpot contact (``vshift``: see NO_SHIFT)."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0, 0.0, 0.0, 0.0
    r = math.sqrt(r2)
    inv_r = 1.0 / r
    nx = dx * inv_r
    ny = dy * inv_r
    nz = dz * inv_r
    overlap = reach - r
    # d(overlap)/dt = -(v_j - v_i).n
    rate = -((velocity[j, 0] - velocity[i, 0] - vshift[0]) * nx + (velocity[j, 1] - velocity[i, 1] - vshift[1]) * ny
             + (velocity[j, 2] - velocity[i, 2] - vshift[2]) * nz)
    fn, elastic = kelvin_voigt_normal(overlap, rate, stiffness, damping, no_tension)
    power = (fn - elastic) * rate
    return fn * nx, fn * ny, fn * nz, power


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_energy(i, j, dx, dy, dz, r2, velocity, radius, stiffness, damping, no_tension):
    """Elastic energy k delta^2 / 2 of the spring."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    overlap = reach - math.sqrt(r2)
    return 0.5 * stiffness * overlap * overlap


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_friction_force(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, history, p, offset,
                                commit, stiffness, damping, no_tension, mu, kt, eta_t, style, mu_r, kr, eta_r, k_tw,
                                eta_tw, lever_tw, dt, vshift=NO_SHIFT):
    """Force on j, torques on i and j and dissipated power of a spring-dashpot contact with
    Coulomb friction (see :mod:`demkit.interactions.friction`) and rolling resistance if mu_r > 0
    (the twisting parameters, 0, are not read: a frictional law takes the twisting law's arguments)."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        lost = release(history, p, offset, 2 if mu_r > 0.0 else 1, dt) if commit else 0.0
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lost
    r = math.sqrt(r2)
    inv_r = 1.0 / r
    nx = dx * inv_r
    ny = dy * inv_r
    nz = dz * inv_r
    overlap = reach - r
    vx = velocity[j, 0] - velocity[i, 0] - vshift[0]
    vy = velocity[j, 1] - velocity[i, 1] - vshift[1]
    vz = velocity[j, 2] - velocity[i, 2] - vshift[2]
    rate = -(vx * nx + vy * ny + vz * nz)
    fn, elastic = kelvin_voigt_normal(overlap, rate, stiffness, damping, no_tension)
    power = (fn - elastic) * rate
    ftx, fty, ftz, tix, tiy, tiz, tjx, tjy, tjz, lost = pair_friction(
        nx, ny, nz, vx, vy, vz, angular_velocity, i, j, radius, overlap, style, fn, mu, kt, eta_t, mu_r, kr, eta_r,
        history, p, offset, commit, dt)
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz, tix, tiy, tiz, tjx, tjy, tjz, power + lost


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_friction_energy(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, history, p, offset,
                                 commit, stiffness, damping, no_tension, mu, kt, eta_t, style, mu_r, kr, eta_r, k_tw,
                                 eta_tw, lever_tw, dt):
    """Elastic energy of the normal spring, of the tangential spring and of the rolling spring."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    overlap = reach - math.sqrt(r2)
    return 0.5 * stiffness * overlap * overlap + springs_energy(history, p, offset, mu_r)


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_twisting_force(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, history, p, offset,
                                commit, stiffness, damping, no_tension, mu, kt, eta_t, style, mu_r, kr, eta_r, k_tw,
                                eta_tw, lever_tw, dt, vshift=NO_SHIFT):
    """:func:`kelvin_voigt_friction_force` plus twisting resistance (:mod:`.twisting`; history after
    the friction and rolling springs; Marshall's coefficient where the given one is -1), none when lever_tw
    is 0: then the bits of :func:`kelvin_voigt_friction_force`, which tier 1 runs as this law
    (demkit.engine.catalogue: one kind for both)."""
    fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, power = kelvin_voigt_friction_force(
        i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, history, p, offset, commit, stiffness, damping,
        no_tension, mu, kt, eta_t, style, mu_r, kr, eta_r, k_tw, eta_tw, lever_tw, dt, vshift)
    if lever_tw == 0.0:  # no twisting resistance
        return fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, power
    o = offset + (2 * HISTORY if mu_r > 0.0 else HISTORY)
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        if commit:
            power += twist_release(history, p, o, dt)
        return fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, power
    r = math.sqrt(r2)
    nx = dx / r
    ny = dy / r
    nz = dz / r
    rate = -((velocity[j, 0] - velocity[i, 0] - vshift[0]) * nx + (velocity[j, 1] - velocity[i, 1] - vshift[1]) * ny
             + (velocity[j, 2] - velocity[i, 2] - vshift[2]) * nz)
    fn, _ = kelvin_voigt_normal(reach - r, rate, stiffness, damping, no_tension)
    w = angular_velocity
    mx, my, mz, lost = twisting_on_i(nx, ny, nz, w[i, 0] - w[j, 0], w[i, 1] - w[j, 1], w[i, 2] - w[j, 2], fn,
                                     math.sqrt(radius[i] * radius[j] / reach * (reach - r)), mu, kt, eta_t, k_tw,
                                     eta_tw, lever_tw, 1.0 if style >= 2.0 else 0.0, history, p, o, commit, dt)
    return fx, fy, fz, tix + mx, tiy + my, tiz + mz, tjx - mx, tjy - my, tjz - mz, power + lost


@njit(**KERNEL_OPTIONS)
def kelvin_voigt_twisting_energy(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, history, p, offset,
                                 commit, stiffness, damping, no_tension, mu, kt, eta_t, style, mu_r, kr, eta_r,
                                 k_tw, eta_tw, lever_tw, dt):
    """Elastic energy of the contact's springs, the twist spring's included (none when lever_tw is 0)."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    energy = kelvin_voigt_friction_energy(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, history, p,
                                          offset, commit, stiffness, damping, no_tension, mu, kt, eta_t, style, mu_r,
                                          kr, eta_r, k_tw, eta_tw, lever_tw, dt)
    if lever_tw == 0.0:
        return energy
    return energy + twist_energy(history, p, offset + (2 * HISTORY if mu_r > 0.0 else HISTORY))


def contact_duration(stiffness, damping, m_eff):
    """Duration of a two-body Kelvin-Voigt contact that ends when the overlap returns to zero."""
    omega0 = math.sqrt(stiffness / m_eff)
    root = math.sqrt(stiffness * m_eff)
    if not (omega0 > 0.0 and root > 0.0):  # a vanishing spring, or an infinite mass: no end to set a step by
        return math.inf
    zeta = damping / (2.0 * root)
    if zeta < 1.0:
        return math.pi / (omega0 * math.sqrt(1.0 - zeta * zeta))
    return math.pi / omega0


def restitution(stiffness, damping, m_eff):
    """Analytic normal restitution coefficient exp(-pi zeta/sqrt(1-zeta^2)) (contact ends at zero overlap)."""
    zeta = damping / (2.0 * math.sqrt(stiffness * m_eff))
    if zeta >= 1.0:
        return 0.0
    return math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta * zeta))


class KelvinVoigt(PairInteraction):
    """Linear spring-dashpot normal contact (the seed paper's contact: stiffness=1, damping=2*Gamma=0.1).

    stiffness : k > 0, force per overlap length.
    damping : c >= 0, force per overlap rate (the paper's gamma = 2 Gamma m omega_0).
    no_tension : forbid the attractive end of the contact (F_n >= 0).
    friction : a :class:`Friction` (Coulomb friction with a linear tangential spring, history per
        contact), or None (frictionless: no history, no torque).
    rolling : a :class:`RollingResistance` (needs friction) or None.
    twisting : a :class:`TwistingResistance` (needs friction) or None.
    """

    reads = ("velocity", "radius")
    dissipative = True
    energy_kind = "contact"
    contact_reach = True
    parameters = ("stiffness", "damping", "no_tension")
    repeat_hint = "one contact law acts on every touching pair: keep one, with its friction and rolling"
    force_function = kelvin_voigt_force
    energy_function = kelvin_voigt_energy

    def __init__(self, stiffness, damping=0.0, no_tension=False, friction=None, rolling=None, twisting=None):
        self.stiffness = positive("KelvinVoigt stiffness", stiffness)
        self.damping = non_negative("KelvinVoigt damping", damping)
        self.no_tension = flag("KelvinVoigt no_tension", no_tension)
        self.friction, self.rolling = check_tangential("KelvinVoigt", friction, rolling)
        self.twisting = check_twisting("KelvinVoigt", friction, twisting)
        if friction is not None:
            self.reads = ("velocity", "angular_velocity", "radius")
            self.torque = True
            self.history_size = HISTORY * (2 if self.rolling is not None else 1)
            self.parameters = self.parameters + ("mu", "kt", "eta_t", "style", "mu_r", "kr", "eta_r") + \
                TWIST_PARAMETERS + ("dt",)
            self.force_function = kelvin_voigt_friction_force
            self.energy_function = kelvin_voigt_friction_energy
            self.mu = friction.coefficient
            self.kt = friction.stiffness if friction.stiffness is not None else 2.0 / 7.0 * self.stiffness
            default = self.damping * math.sqrt(self.kt / self.stiffness)
            self.eta_t = friction.damping if friction.damping is not None else default
            self.style = friction.style
            self.mu_r = self.kr = self.eta_r = 0.0
            if self.rolling is not None:
                self.mu_r = rolling.coefficient
                default = STIFFNESS_FACTOR * self.mu_r ** 2 * self.stiffness
                self.kr = rolling.stiffness if rolling.stiffness is not None else default
                default = self.damping * math.sqrt(self.kr / self.stiffness)
                self.eta_r = rolling.damping if rolling.damping is not None else default
            self.dt = 0.0
            add_twisting(self, kelvin_voigt_twisting_force, kelvin_voigt_twisting_energy)

    def __repr__(self):
        return (f"KelvinVoigt(stiffness={self.stiffness!r}, damping={self.damping!r}, "
                f"no_tension={self.no_tension!r}, friction={self.friction!r}, rolling={self.rolling!r}"
                f"{twisting_repr(self)})")

    def cutoff(self, particles):
        return 2.0 * float(np.max(particles.radius))

    def lightest_pair_mass(self, particles):
        """Smallest reduced mass m_i m_j / (m_i + m_j) over pairs (the two lightest particles)."""
        m = np.sort(particles.mass)
        if len(m) == 1:
            return float(m[0])
        return float(m[0] * m[1] / (m[0] + m[1]))

    def max_time_step(self, particles):
        """A tenth of the shortest contact duration (and, for heavy damping, 0.2 m_eff/c); with
        friction also of the tangential period and dashpot."""
        m_eff = self.lightest_pair_mass(particles)
        limit = 0.1 * contact_duration(self.stiffness, self.damping, m_eff)
        if self.damping > 0:
            limit = min(limit, 0.2 * m_eff / self.damping)
        if self.friction is not None:
            # the tangential spring acts on the contact points: effective mass m_eff * 2/7 for spheres
            limit = min(limit, 0.1 * contact_duration(self.kt, self.eta_t, m_eff * 2.0 / 7.0))
            if self.eta_t > 0:
                limit = min(limit, 0.2 * m_eff * 2.0 / 7.0 / self.eta_t)
        if self.rolling is not None:
            # the rolling spring turns the spheres against each other: effective mass <= 0.4 m_eff
            limit = min(limit, 0.1 * contact_duration(self.kr, self.eta_r, 0.4 * m_eff))
            if self.eta_r > 0:
                limit = min(limit, 0.2 * 0.4 * m_eff / self.eta_r)
        return min(limit, twisting_time_step(self, particles))

    def overlaps(self, particles, i, j, force, energy):
        """(static, stored), arrays over the index pairs (i, j): the overlap F/k that carries
        ``force`` and the overlap sqrt(2 U/k) that stores ``energy`` in the spring."""
        return force / self.stiffness, np.sqrt(2.0 * energy / self.stiffness)

    def stiffer(self, particles, i, j, force, energy, overlap):
        """(parameter, value): the smallest stiffness that keeps both overlaps of :meth:`overlaps`
        at most ``overlap`` (arrays), for all the pairs given."""
        return "stiffness", float(np.max(np.maximum(force / overlap, 2.0 * energy / overlap**2)))


def check_tangential(law, friction, rolling):
    """(friction, rolling) of a contact law, checked; rolling with a zero coefficient is None."""
    if friction is not None and not isinstance(friction, Friction):
        raise TypeError(f"{law} friction must be a demkit.Friction or None, got {friction!r}")
    if rolling is not None and not isinstance(rolling, RollingResistance):
        raise TypeError(f"{law} rolling must be a demkit.RollingResistance or None, got {rolling!r}")
    if rolling is not None and friction is None:
        raise ValueError(f"{law} rolling resistance needs friction (a sphere rolls only on a contact that "
                         f"grips): pass friction=demkit.Friction(...) too")
    if rolling is not None and rolling.coefficient == 0.0:
        rolling = None
    return friction, rolling


def check_twisting(law, friction, twisting):
    """The twisting resistance of a contact law, checked; None when it can exert no torque (a zero
    lever, or Marshall's lever (2/3) mu a with mu = 0)."""
    if twisting is None:
        return None
    if not isinstance(twisting, TwistingResistance):
        raise TypeError(f"{law} twisting must be a demkit.TwistingResistance or None, got {twisting!r}")
    if friction is None:
        raise ValueError(f"{law} twisting resistance needs friction (a contact resists twisting only where it "
                         f"grips, and Marshall's coefficients come from the friction law): pass "
                         f"friction=demkit.Friction(...) too")
    lever = twisting.lever if twisting.lever is not None else friction.coefficient
    return None if lever == 0.0 else twisting


def add_twisting(law, force_function, energy_function):
    """Give a contact law with friction its twisting spring (history, parameter values, functions), or
    the twisting parameters of one without: 0 (lever 0: none)."""
    law.k_tw = law.eta_tw = law.lever_tw = 0.0
    if law.twisting is not None:
        law.history_size += TWIST_HISTORY
        law.force_function = force_function
        law.energy_function = energy_function
        law.k_tw, law.eta_tw, law.lever_tw = law.twisting.fixed


def twisting_repr(law):
    """", twisting=..." for a law's repr when it has twisting resistance (else nothing: the repr of
    a law without it is what it was before twisting existed)."""
    return f", twisting={law.twisting!r}" if getattr(law, "twisting", None) is not None else ""


def twisting_time_step(law, particles):
    """A tenth of the period of a given twist spring on the two least inertial spheres, and 0.2
    I*/eta_tw for a given twist dashpot (math.inf otherwise: Marshall's k_t a^2/2 turns the spheres
    slower than the tangential spring moves them, by a factor of order sqrt(delta/R))."""
    if getattr(law, "twisting", None) is None:
        return math.inf
    inertia = np.sort(particles.inertia)
    i_eff = float(inertia[0]) if len(inertia) == 1 else float(inertia[0] * inertia[1] / (inertia[0] + inertia[1]))
    limit = math.inf
    if law.k_tw > 0.0:
        limit = 0.1 * contact_duration(law.k_tw, max(law.eta_tw, 0.0), i_eff)
    if law.eta_tw > 0.0:
        limit = min(limit, 0.2 * i_eff / law.eta_tw)
    return limit
