"""Uniform body forces and fields: gravity and a uniform magnetic field.

Gravity g:          F_i = m_i g,   U_i = -m_i g.x_i  (x: the wrapped position in periodic boxes, so
                    gravity along a periodic axis makes that energy jump at the boundary; fixed
                    spheres are held and count zero).
Uniform field B:    tau_i = m_i x B,   U_i = -m_i.B,   no force (a uniform field does not pull).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS

from .base import SAFE_PHASE, inverse_inertia
from .sphere import SphereInteraction, vector


@njit(**KERNEL_OPTIONS)
def gravity_force(i, x, y, z, mass, gx, gy, gz):
    m = mass[i] if mass[i] < math.inf else 0.0  # a fixed sphere (infinite mass) is held
    return m * gx, m * gy, m * gz


@njit(**KERNEL_OPTIONS)
def gravity_energy(i, x, y, z, mass, gx, gy, gz):
    m = mass[i] if mass[i] < math.inf else 0.0
    return -m * (gx * x + gy * y + gz * z)


class Gravity(SphereInteraction):
    """Uniform gravitational acceleration ``acceleration`` (3-vector, length/time^2)."""

    reads = ("mass",)
    energy_kind = "gravity"
    parameters = ("gx", "gy", "gz")
    repeat_hint = "give one Gravity with the summed acceleration, Gravity(g1 + g2)"
    force_function = gravity_force
    energy_function = gravity_energy

    def __init__(self, acceleration):
        self.acceleration = vector("Gravity acceleration", acceleration)
        self.gx, self.gy, self.gz = (float(c) for c in self.acceleration)

    def __repr__(self):
        return f"Gravity({self.acceleration.tolist()})"


@njit(**KERNEL_OPTIONS)
def field_torque(i, x, y, z, dipole, bx, by, bz):
    mx = dipole[i, 0]
    my = dipole[i, 1]
    mz = dipole[i, 2]
    return 0.0, 0.0, 0.0, my * bz - mz * by, mz * bx - mx * bz, mx * by - my * bx


@njit(**KERNEL_OPTIONS)
def field_energy(i, x, y, z, dipole, bx, by, bz):
    return -(dipole[i, 0] * bx + dipole[i, 1] * by + dipole[i, 2] * bz)


class UniformField(SphereInteraction):
    """A uniform magnetic field B (3-vector, in the units where energy = moment x field)."""

    reads = ("dipole",)
    torque = True
    energy_kind = "field"
    parameters = ("bx", "by", "bz")
    repeat_hint = "give one UniformField with the summed field, UniformField(B1 + B2)"
    force_function = field_torque
    energy_function = field_energy

    def __init__(self, field):
        self.field = vector("UniformField field", field)
        self.bx, self.by, self.bz = (float(c) for c in self.field)

    def max_time_step(self, particles):
        """A moment swings about B like a pendulum, at omega^2 = |m| |B| / I at most: the step keeps
        omega dt <= SAFE_PHASE (:mod:`demkit.interactions.base`) for the fastest sphere."""
        _, inv_inertia = inverse_inertia(particles)
        rate2 = np.linalg.norm(particles.dipole, axis=1) * float(np.linalg.norm(self.field)) * inv_inertia
        fastest = float(np.max(rate2)) if len(rate2) else 0.0
        return SAFE_PHASE / math.sqrt(fastest) if fastest > 0.0 else math.inf

    def __repr__(self):
        return f"UniformField({self.field.tolist()})"
