"""Magnetic dipole-dipole interaction between uniformly magnetised spheres.

For moments m_i, m_j and separation r = x_j - x_i (unit vector n = r/|r|), with A the prefactor
(mu0/4pi = 1e-7 in SI; 1/3 with unit moments gives the paper's units where 3 mu0 m1 m2/4pi = 1):

    U     = A [m_i.m_j - 3 (m_i.n)(m_j.n)] / r^3
    F_j   = -dU/dr_j = 3A/r^4 [(m_i.m_j) n + (m_i.n) m_j + (m_j.n) m_i - 5 (m_i.n)(m_j.n) n],  F_i = -F_j
    tau_i = m_i x B_j(x_i) = A/r^3 [3 (m_j.n)(m_i x n) - m_i x m_j]      (and i <-> j)

Head-to-tail moments (m_i = m_j = n) attract: F_j = -6 A /r^4 n. The point-dipole form is exact
for uniformly magnetised spheres (Edwards et al., Am. J. Phys. 85, 130 (2017)).
"""
from __future__ import annotations

import math

from numba import njit

from ..motion import KERNEL_OPTIONS

from .base import PairInteraction, positive


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


class Dipole(PairInteraction):
    """Full dipole-dipole force and torque (see module docstring).

    prefactor : A = mu0/4pi (1e-7 T m/A in SI); 1/3 with unit moments gives the seed paper's units.
    cutoff : centre distance beyond which the pair is ignored (None: never). A cutoff without a
        shift makes the energy jump when pairs cross it.
    """

    reads = ("dipole",)
    torque = True
    energy_kind = "magnetic"
    parameters = ("prefactor",)
    force_function = dipole_force
    energy_function = dipole_energy

    def __init__(self, prefactor=1e-7, cutoff=None):
        self.prefactor = positive("Dipole prefactor", prefactor)
        self.cutoff_distance = None if cutoff is None else positive("Dipole cutoff", cutoff)


class PowerLawDipole(Dipole):
    """The seed paper's central approximation of the dipole force (no torque).

    F_j = -6 A |m_i||m_j| / r^4 n and U = -2 A |m_i||m_j| / r^3: the head-to-tail force, applied
    whatever the orientation. It conserves angular momentum trivially but gives the wrong spin-up.
    """

    torque = False
    force_function = power_law_force
    energy_function = power_law_energy
