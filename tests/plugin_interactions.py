"""User-style plug-in interactions used by the tests (importable, so their kernels are cached)."""
import math

from numba import njit

import demkit as dk
from demkit.interactions.contact import kelvin_voigt_energy, kelvin_voigt_force
from demkit.interactions.fields import gravity_energy, gravity_force


@njit
def contact_counter_force(i, j, dx, dy, dz, r2, radius, history, p, offset, commit, growth):
    """No force; counts the steps a pair spends touching in its per-contact history."""
    reach = radius[i] + radius[j]
    if commit and r2 < reach * reach:
        history[p, offset] += growth
    return 0.0, 0.0, 0.0


@njit
def contact_counter_energy(i, j, dx, dy, dz, r2, radius, history, p, offset, commit, growth):
    return 0.0


class ContactCounter(dk.PairInteraction):
    reads = ("radius",)
    history_size = 1
    energy_kind = "counter"
    parameters = ("growth",)
    force_function = contact_counter_force
    energy_function = contact_counter_energy

    def __init__(self):
        self.growth = 1.0


@njit
def poison_force(i, j, dx, dy, dz, r2, limit):
    """A force that turns NaN once the pair is closer than sqrt(limit): a stand-in for a blow-up."""
    s = math.sqrt(r2 - limit) * 0.0 - 1e-3
    return s * dx, s * dy, s * dz


@njit
def poison_energy(i, j, dx, dy, dz, r2, limit):
    return 0.0


class Poison(dk.PairInteraction):
    energy_kind = "poison"
    parameters = ("limit",)
    force_function = poison_force
    energy_function = poison_energy

    def __init__(self, distance):
        self.limit = distance ** 2


@njit
def touch_counter_force(i, j, dx, dy, dz, r2, radius, history, p, offset, commit, unit):
    """No force; history = steps the pair has been touching without a break (0 when apart)."""
    reach = radius[i] + radius[j]
    if commit:
        history[p, offset] = history[p, offset] + unit if r2 < reach * reach else 0.0
    return 0.0, 0.0, 0.0


@njit
def touch_counter_energy(i, j, dx, dy, dz, r2, radius, history, p, offset, commit, unit):
    return 0.0


class TouchCounter(dk.PairInteraction):
    reads = ("radius",)
    history_size = 1
    energy_kind = "counter"
    parameters = ("unit",)
    force_function = touch_counter_force
    energy_function = touch_counter_energy

    def __init__(self, cutoff=None):
        self.unit = 1.0
        self.cutoff_distance = cutoff


@njit
def pull_small_force(i, x, y, z, radius, mass, size, gx, gy, gz):
    """Gravity on the spheres smaller than ``size`` only."""
    if radius[i] < size:
        return mass[i] * gx, mass[i] * gy, mass[i] * gz
    return 0.0, 0.0, 0.0


@njit
def pull_small_energy(i, x, y, z, radius, mass, size, gx, gy, gz):
    if radius[i] < size:
        return -mass[i] * (gx * x + gy * y + gz * z)
    return 0.0


class PullSmall(dk.SphereInteraction):
    """A user-style single-sphere plug-in: gravity that acts only on spheres below a size."""
    reads = ("radius", "mass")
    energy_kind = "gravity"
    parameters = ("size", "gx", "gy", "gz")
    force_function = pull_small_force
    energy_function = pull_small_energy

    def __init__(self, size, g):
        self.size = size
        self.gx, self.gy, self.gz = g


@njit
def own_kelvin_voigt_force(i, j, dx, dy, dz, r2, velocity, radius, stiffness, damping, no_tension):
    """The shipped spring-dashpot called from a function of your own (so: not in the generic catalogue)."""
    return kelvin_voigt_force(i, j, dx, dy, dz, r2, velocity, radius, stiffness, damping, no_tension)


@njit
def own_kelvin_voigt_energy(i, j, dx, dy, dz, r2, velocity, radius, stiffness, damping, no_tension):
    return kelvin_voigt_energy(i, j, dx, dy, dz, r2, velocity, radius, stiffness, damping, no_tension)


class OwnKelvinVoigt(dk.KelvinVoigt):
    """dk.KelvinVoigt (frictionless) through functions of your own."""
    force_function = own_kelvin_voigt_force
    energy_function = own_kelvin_voigt_energy


@njit
def own_gravity_force(i, x, y, z, mass, gx, gy, gz):
    return gravity_force(i, x, y, z, mass, gx, gy, gz)


@njit
def own_gravity_energy(i, x, y, z, mass, gx, gy, gz):
    return gravity_energy(i, x, y, z, mass, gx, gy, gz)


class OwnGravity(dk.Gravity):
    """dk.Gravity through functions of your own."""
    force_function = own_gravity_force
    energy_function = own_gravity_energy
