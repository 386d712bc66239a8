"""Hertz normal contact with a restitution-calibrated dashpot, optionally with Mindlin friction.

For overlap delta = R_i + R_j - r > 0 between spheres of one material (Young's modulus E, Poisson
ratio nu), with R* = R_i R_j/(R_i + R_j), m* = (1/m_i + 1/m_j)^-1, contact radius a = sqrt(R* delta),

    E* = E / (2 (1 - nu^2)),  G* = G / (2 (2 - nu)),  G = E / (2 (1 + nu))
    F_e = 4/3 E* a delta = 4/3 E* sqrt(R*) delta^(3/2),      U = 2/5 F_e delta
    F_n = max(0, F_e + eta_n d(delta)/dt),  eta_n = gamma sqrt(m* S_n),  S_n = dF_e/d(delta) = 2 E* a

(a rigid plane has E* = E/(1 - nu^2), G* = G/(2 - nu), R* = R, m* = m). The damping is that of
Tsuji, Tanaka & Ishida (Powder Technol. 71, 239 (1992)), eta ~ delta^(1/4): the dimensionless
equation of a collision, x'' = -x^(3/2) - gamma sqrt(3/2) x^(1/4) x' with the force clamped at
zero (no attraction at the end of the contact), depends on gamma alone, so the restitution
coefficient is the same for every pair, size, mass and impact speed. demkit finds gamma for the
restitution asked for from its own solution of that equation (scipy, relative tolerance 1e-11,
fitted to that accuracy once: :mod:`demkit.interactions.hertz_restitution`), not a published
fitted formula: the restitution that comes out is the one that goes in.

With :class:`Friction` and no friction stiffness the tangential spring is Mindlin's no-slip
stiffness k_t = 8 G* a; the tangential dashpot has the normal damping ratio,
eta_t = eta_n sqrt(k_t / S_n), unless given.

The analytic elastic impact at approach speed v (Chung & Ooi 2011, tests 1-3):
delta_max = (15 m* v^2 / (16 E* sqrt(R*)))^(2/5), contact time t_c = 2.94328 delta_max / v.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS

from .base import PairInteraction, number, positive
from .contact import (NO_SHIFT, TWIST_PARAMETERS, add_twisting, check_tangential, check_twisting, contact_duration,
                      twisting_repr, twisting_time_step)
from .friction import HISTORY, pair_friction, release, springs_energy
from .hertz_restitution import damping_for_restitution
from .rolling import STIFFNESS_FACTOR
from .twisting import twist_energy, twist_release, twisting_on_i

#: t_c = HERTZ_TIME * delta_max / v for an elastic Hertz impact (2 (2/5) B(2/5, 1/2))
HERTZ_TIME = 2.9432812



def hertz_impact(young_eff, radius_eff, mass_eff, speed):
    """(maximum overlap, maximum force, contact time) of an elastic Hertz impact."""
    delta = (15.0 * mass_eff * speed ** 2 / (16.0 * young_eff * math.sqrt(radius_eff))) ** 0.4
    force = 4.0 / 3.0 * young_eff * math.sqrt(radius_eff) * delta ** 1.5
    return delta, force, HERTZ_TIME * delta / speed


@njit(**KERNEL_OPTIONS)
def hertz_normal(overlap, rate, radius_eff, mass_eff, young_eff, gamma):
    """(F_n, elastic part, S_n, eta_n) of the damped Hertz law."""
    a = math.sqrt(radius_eff * overlap)
    elastic = 4.0 / 3.0 * young_eff * a * overlap
    stiffness = 2.0 * young_eff * a
    eta = gamma * math.sqrt(mass_eff * stiffness)
    fn = elastic + (eta * rate if rate != 0.0 else 0.0)  # two fixed spheres: infinite eta, zero rate
    if fn < 0.0:
        fn = 0.0
    return fn, elastic, stiffness, eta


@njit(**KERNEL_OPTIONS)
def hertz_force(i, j, dx, dy, dz, r2, velocity, radius, mass, young_eff, shear_eff, gamma, vshift=NO_SHIFT):
    """Force on j and dissipated power of a damped Hertz contact."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0, 0.0, 0.0, 0.0
    r = math.sqrt(r2)
    nx = dx / r
    ny = dy / r
    nz = dz / r
    rate = -((velocity[j, 0] - velocity[i, 0] - vshift[0]) * nx + (velocity[j, 1] - velocity[i, 1] - vshift[1]) * ny
             + (velocity[j, 2] - velocity[i, 2] - vshift[2]) * nz)
    radius_eff = radius[i] * radius[j] / reach
    mass_eff = 1.0 / (1.0 / mass[i] + 1.0 / mass[j])
    fn, elastic, _, _ = hertz_normal(reach - r, rate, radius_eff, mass_eff, young_eff, gamma)
    return fn * nx, fn * ny, fn * nz, (fn - elastic) * rate


@njit(**KERNEL_OPTIONS)
def hertz_energy(i, j, dx, dy, dz, r2, velocity, radius, mass, young_eff, shear_eff, gamma):
    """Elastic energy 8/15 E* sqrt(R*) delta^(5/2)."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    overlap = reach - math.sqrt(r2)
    radius_eff = radius[i] * radius[j] / reach
    return 8.0 / 15.0 * young_eff * math.sqrt(radius_eff) * overlap ** 2.5


@njit(**KERNEL_OPTIONS)
def hertz_friction_force(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                         young_eff, shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, mu_r, kr_fixed,
                         eta_r_fixed, k_tw, eta_tw, lever_tw, dt, vshift=NO_SHIFT):
    """Force on j, torques on i and j and dissipated power of a Hertz contact with friction
    (Mindlin spring when kt_fixed is 0; normal damping ratio when eta_t_fixed < 0) and rolling
    resistance when mu_r > 0 (k_r = 2.25 mu_r^2 S_n when kr_fixed is 0, damping ratio likewise); the
    twisting parameters (0) are not read."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        lost = release(history, p, offset, 2 if mu_r > 0.0 else 1, dt) if commit else 0.0
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, lost
    r = math.sqrt(r2)
    nx = dx / r
    ny = dy / r
    nz = dz / r
    overlap = reach - r
    vx = velocity[j, 0] - velocity[i, 0] - vshift[0]
    vy = velocity[j, 1] - velocity[i, 1] - vshift[1]
    vz = velocity[j, 2] - velocity[i, 2] - vshift[2]
    rate = -(vx * nx + vy * ny + vz * nz)
    radius_eff = radius[i] * radius[j] / reach
    mass_eff = 1.0 / (1.0 / mass[i] + 1.0 / mass[j])
    fn, elastic, stiffness, eta = hertz_normal(overlap, rate, radius_eff, mass_eff, young_eff, gamma)
    kt, eta_t, kr, eta_r = tangential_springs(kt_fixed, eta_t_fixed, mu_r, kr_fixed, eta_r_fixed, shear_eff,
                                              radius_eff, overlap, stiffness, eta)
    ftx, fty, ftz, tix, tiy, tiz, tjx, tjy, tjz, lost = pair_friction(
        nx, ny, nz, vx, vy, vz, angular_velocity, i, j, radius, overlap, style, fn, mu, kt, eta_t, mu_r, kr, eta_r,
        history, p, offset, commit, dt)
    return fn * nx + ftx, fn * ny + fty, fn * nz + ftz, tix, tiy, tiz, tjx, tjy, tjz, (fn - elastic) * rate + lost


@njit(**KERNEL_OPTIONS)
def hertz_friction_energy(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                          young_eff, shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, mu_r, kr_fixed,
                          eta_r_fixed, k_tw, eta_tw, lever_tw, dt):
    """Elastic energy of the Hertz contact, of its tangential spring and of its rolling spring."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    overlap = reach - math.sqrt(r2)
    radius_eff = radius[i] * radius[j] / reach
    return 8.0 / 15.0 * young_eff * math.sqrt(radius_eff) * overlap ** 2.5 + springs_energy(history, p, offset, mu_r)


@njit(**KERNEL_OPTIONS)
def hertz_twisting_force(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                         young_eff, shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, mu_r, kr_fixed, eta_r_fixed,
                         k_tw, eta_tw, lever_tw, dt, vshift=NO_SHIFT):
    """:func:`hertz_friction_force` plus twisting resistance (:mod:`.twisting`: Marshall's k_t a^2/2,
    eta_t a^2/2, (2/3) mu a with the contact's own k_t and eta_t where the given value is -1), none when
    lever_tw is 0 (then :func:`hertz_friction_force`'s bits: tier 1 runs both as this law)."""
    fx, fy, fz, tix, tiy, tiz, tjx, tjy, tjz, power = hertz_friction_force(
        i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, mass, history, p, offset, commit, young_eff,
        shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, mu_r, kr_fixed, eta_r_fixed, k_tw, eta_tw, lever_tw, dt,
        vshift)
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
    radius_eff = radius[i] * radius[j] / reach
    fn, _, stiffness, eta = hertz_normal(reach - r, rate, radius_eff, 1.0 / (1.0 / mass[i] + 1.0 / mass[j]),
                                         young_eff, gamma)
    kt, eta_t, _, _ = tangential_springs(kt_fixed, eta_t_fixed, 0.0, 0.0, 0.0, shear_eff, radius_eff, reach - r,
                                         stiffness, eta)
    w = angular_velocity
    mx, my, mz, lost = twisting_on_i(nx, ny, nz, w[i, 0] - w[j, 0], w[i, 1] - w[j, 1], w[i, 2] - w[j, 2], fn,
                                     math.sqrt(radius_eff * (reach - r)), mu, kt, eta_t, k_tw, eta_tw, lever_tw,
                                     1.0 if style >= 2.0 else 0.0, history, p, o, commit, dt)
    return fx, fy, fz, tix + mx, tiy + my, tiz + mz, tjx - mx, tjy - my, tjz - mz, power + lost


@njit(**KERNEL_OPTIONS)
def hertz_twisting_energy(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, mass, history, p, offset, commit,
                          young_eff, shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, mu_r, kr_fixed, eta_r_fixed,
                          k_tw, eta_tw, lever_tw, dt):
    """Elastic energy of the Hertz contact and of its springs, the twist spring's included (none when
    lever_tw is 0)."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    energy = hertz_friction_energy(i, j, dx, dy, dz, r2, velocity, angular_velocity, radius, mass, history, p, offset,
                                   commit, young_eff, shear_eff, gamma, mu, kt_fixed, eta_t_fixed, style, mu_r,
                                   kr_fixed, eta_r_fixed, k_tw, eta_tw, lever_tw, dt)
    if lever_tw == 0.0:
        return energy
    return energy + twist_energy(history, p, offset + (2 * HISTORY if mu_r > 0.0 else HISTORY))


@njit(**KERNEL_OPTIONS)
def tangential_springs(kt_fixed, eta_t_fixed, mu_r, kr_fixed, eta_r_fixed, shear_eff, radius_eff, overlap, stiffness,
                       eta):
    """(k_t, eta_t, k_r, eta_r) of a Hertz contact with contact stiffness S_n and normal damping eta_n:
    Mindlin's k_t = 8 G* sqrt(R* delta) unless fixed, the normal damping ratio unless fixed, and the
    rolling spring 2.25 mu_r^2 S_n (none when mu_r is 0)."""
    kt = kt_fixed if kt_fixed > 0.0 else 8.0 * shear_eff * math.sqrt(radius_eff * overlap)
    eta_t = eta_t_fixed if eta_t_fixed >= 0.0 else eta * math.sqrt(kt / stiffness)
    if mu_r == 0.0:
        return kt, eta_t, 0.0, 0.0
    kr = kr_fixed if kr_fixed > 0.0 else STIFFNESS_FACTOR * mu_r * mu_r * stiffness
    return kt, eta_t, kr, (eta_r_fixed if eta_r_fixed >= 0.0 else eta * math.sqrt(kr / stiffness))



class Hertz(PairInteraction):
    """Hertz normal contact between spheres of one material, damped to a given restitution.

    young : Young's modulus E > 0 (pressure units of the scene).
    poisson : Poisson ratio nu in (-1, 0.5).
    restitution : normal restitution coefficient e in (0, 1] (1: elastic).
    friction : a :class:`Friction` (Mindlin spring unless a stiffness is given) or None.
    rolling : a :class:`RollingResistance` (needs friction; default stiffness 2.25 mu_r^2 S_n) or None.
    twisting : a :class:`TwistingResistance` (needs friction; Marshall's defaults from the Mindlin
        spring, k_tw = 4 G* a^3) or None.
    """

    reads = ("velocity", "radius", "mass")
    dissipative = True
    energy_kind = "contact"
    contact_reach = True
    parameters = ("young_eff", "shear_eff", "gamma")
    repeat_hint = "one contact law acts on every touching pair: keep one, with its friction and rolling"
    force_function = hertz_force
    energy_function = hertz_energy

    def __init__(self, young, poisson, restitution=1.0, friction=None, rolling=None, twisting=None):
        self.young = positive("Hertz young (Young's modulus)", young)
        poisson = number("Hertz poisson (Poisson ratio)", poisson)
        if not (-1.0 < poisson < 0.5):
            raise ValueError(f"Hertz poisson (Poisson ratio) must lie in (-1, 0.5), got {poisson}")
        self.poisson = poisson
        restitution = number("Hertz restitution", restitution)
        if not (0.0 < restitution <= 1.0):
            raise ValueError(f"Hertz restitution must lie in (0, 1], got {restitution}")
        self.restitution = restitution
        shear = self.young / (2.0 * (1.0 + poisson))
        self.young_eff = self.young / (2.0 * (1.0 - poisson ** 2))
        self.shear_eff = shear / (2.0 * (2.0 - poisson))
        self.gamma = damping_for_restitution(restitution)
        self.friction, self.rolling = check_tangential("Hertz", friction, rolling)
        self.twisting = check_twisting("Hertz", friction, twisting)
        if friction is not None:
            self.reads = ("velocity", "angular_velocity", "radius", "mass")
            self.torque = True
            self.history_size = HISTORY * (2 if self.rolling is not None else 1)
            self.parameters = self.parameters + ("mu", "kt_fixed", "eta_t_fixed", "style", "mu_r", "kr_fixed",
                                                 "eta_r_fixed") + TWIST_PARAMETERS + ("dt",)
            self.force_function = hertz_friction_force
            self.energy_function = hertz_friction_energy
            self.mu = friction.coefficient
            self.kt_fixed = friction.stiffness if friction.stiffness is not None else 0.0
            self.eta_t_fixed = friction.damping if friction.damping is not None else -1.0
            self.style = friction.style
            rolling = self.rolling
            self.mu_r = rolling.coefficient if rolling is not None else 0.0
            self.kr_fixed = rolling.stiffness if rolling is not None and rolling.stiffness is not None else 0.0
            self.eta_r_fixed = rolling.damping if rolling is not None and rolling.damping is not None else -1.0
            self.dt = 0.0
            add_twisting(self, hertz_twisting_force, hertz_twisting_energy)

    def _pair(self, particles, i, j):
        """sqrt(R*) E* (arrays over the index pairs): F = 4/3 c delta^(3/2), U = 8/15 c delta^(5/2)."""
        r = particles.radius
        return np.sqrt(r[i] * r[j] / (r[i] + r[j])) * self.young_eff

    def overlaps(self, particles, i, j, force, energy):
        """(static, stored), arrays over the index pairs (i, j): the overlap whose elastic force
        4/3 E* sqrt(R*) delta^(3/2) is ``force`` and the one whose energy 8/15 E* sqrt(R*)
        delta^(5/2) is ``energy``."""
        c = self._pair(particles, i, j)
        return (force / (4.0 / 3.0 * c)) ** (2.0 / 3.0), (energy / (8.0 / 15.0 * c)) ** 0.4

    def stiffer(self, particles, i, j, force, energy, overlap):
        """(parameter, value): the smallest Young's modulus that keeps both overlaps of
        :meth:`overlaps` at most ``overlap`` (arrays), for all the pairs given."""
        root = self._pair(particles, i, j) / self.young_eff
        needed = np.maximum(force / (4.0 / 3.0 * root * overlap**1.5), energy / (8.0 / 15.0 * root * overlap**2.5))
        return "young", float(np.max(needed)) * 2.0 * (1.0 - self.poisson**2)

    def __repr__(self):
        return (f"Hertz(young={self.young!r}, poisson={self.poisson!r}, restitution={self.restitution!r}, "
                f"friction={self.friction!r}, rolling={self.rolling!r}{twisting_repr(self)})")

    def cutoff(self, particles):
        return 2.0 * float(np.max(particles.radius))

    def max_time_step(self, particles, speed=None):
        """A tenth of the elastic contact time of the two smallest spheres at approach speed
        ``speed`` (default: twice the fastest speed present; no limit while everything is at rest)."""
        if speed is None:
            v = particles.velocity
            speed = 2.0 * float(np.max(np.linalg.norm(v, axis=1))) if len(v) else 0.0
        order = np.argsort(particles.radius)
        a, b = order[0], order[min(1, len(order) - 1)]
        r = particles.radius
        m = particles.mass
        radius_eff = r[a] * r[b] / (r[a] + r[b])
        mass_eff = 1.0 / (1.0 / m[a] + 1.0 / m[b]) if a != b else 0.5 * m[a]
        limit = 0.1 * hertz_impact(self.young_eff, radius_eff, mass_eff, speed)[2] if speed > 0.0 else math.inf
        if self.friction is not None and self.kr_fixed > 0.0:  # a given rolling stiffness (see KelvinVoigt)
            limit = min(limit, 0.1 * contact_duration(self.kr_fixed, 0.0, 0.4 * mass_eff))
        return min(limit, twisting_time_step(self, particles))
