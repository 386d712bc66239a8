"""The seed paper's non-dimensionalisation (Bartz & Shaw), from SI inputs and back.

Scales: time t_c = sqrt(m/k), length x_c = (3 mu0 mu^2 / (4 pi k))^(1/5), mass m, so that in
dimensionless units m = 1, k = 1 and the dipole prefactor 3 mu0 mu1 mu2/(4 pi) = 1 (use
``Dipole(prefactor=1/3)`` with unit moments). Derived scales: velocity x_c/t_c, force k x_c,
energy k x_c^2, angular velocity 1/t_c, damping (force per velocity) m/t_c.

For the paper's 5 mm NdFeB spheres (m = 4 g, Young's modulus 39.5 GPa, M = 8.8e5 A/m)
``PaperUnits.from_si(...)`` gives t_c = 3.59e-6 s, x_c = 7.29e-4 m, R/x_c = 6.86. The paper quotes
x_c = 7.2e-4 m and R~ = 6.94 = 5 mm / 7.2e-4 m: it divided by the rounded x_c. To convert with the
paper's own rounded scales, build them directly:
``PaperUnits(mass=4e-3, length=7.2e-4, time=3.6e-6, radius=5e-3)`` (R~ = 6.94, 5.78e-3 <-> 1.156 m/s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

MU0 = 4e-7 * math.pi  # vacuum permeability, T m / A (pre-2019 exact value; 2019 SI differs by 1e-10)

_DIMENSIONS = {  # quantity -> (mass, length, time) exponents
    "time": (0, 0, 1), "length": (0, 1, 0), "mass": (1, 0, 0), "velocity": (0, 1, -1),
    "angular_velocity": (0, 0, -1), "frequency": (0, 0, -1), "acceleration": (0, 1, -2),
    "force": (1, 1, -2), "energy": (1, 2, -2), "stiffness": (1, 0, -2), "damping": (1, 0, -1),
    "angular_momentum": (1, 2, -1), "torque": (1, 2, -2),
}


def stiffness_from_young(young_modulus, radius):
    """The paper's contact stiffness k = Y A / L with A = pi R^2 and L = 2R, i.e. k = pi Y R / 2 (N/m)."""
    return math.pi * _positive("young_modulus", young_modulus) * _positive("radius", radius) / 2.0


def dipole_from_magnetisation(magnetisation, radius):
    """Dipole moment of a uniformly magnetised sphere, mu = M (4/3) pi R^3 (A m^2)."""
    return _positive("magnetisation", magnetisation) * 4.0 / 3.0 * math.pi * _positive("radius", radius) ** 3


def induced_dipole(susceptibility, radius, field, mu0=MU0):
    """Dipole moment a field B (T) induces in a lone linear sphere of susceptibility chi,
    mu = 4 pi R^3 chi/(chi + 3) B / mu0 (A m^2; Clausius-Mossotti: M = 3 chi/(chi + 3) B / mu0)."""
    chi = _positive("susceptibility", susceptibility)
    return 4.0 * math.pi * _positive("radius", radius) ** 3 * chi / (chi + 3.0) * _positive("field", field) / mu0


def _positive(name, value):
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value}")
    return value


@dataclass(frozen=True)
class PaperUnits:
    """Characteristic scales of the paper's dimensionless units (all SI)."""

    mass: float       # kg
    length: float     # x_c, m
    time: float       # t_c, s
    radius: float     # sphere radius, m

    @classmethod
    def from_si(cls, mass, radius, stiffness=None, dipole_moment=None, magnetisation=None,
                young_modulus=None, mu0=MU0):
        """Scales from SI inputs: mass (kg), radius (m), stiffness (N/m) or young_modulus (Pa),
        and dipole_moment (A m^2) or magnetisation (A/m)."""
        mass, radius = _positive("mass", mass), _positive("radius", radius)
        if (stiffness is None) == (young_modulus is None):
            raise ValueError("give exactly one of stiffness (N/m) or young_modulus (Pa)")
        k = _positive("stiffness", stiffness) if stiffness is not None else stiffness_from_young(young_modulus, radius)
        if (dipole_moment is None) == (magnetisation is None):
            raise ValueError("give exactly one of dipole_moment (A m^2) or magnetisation (A/m)")
        mu = (_positive("dipole_moment", dipole_moment) if dipole_moment is not None
              else dipole_from_magnetisation(magnetisation, radius))
        length = (3.0 * mu0 * mu * mu / (4.0 * math.pi * k)) ** 0.2
        return cls(mass=mass, length=length, time=math.sqrt(mass / k), radius=radius)

    @property
    def dimensionless_radius(self):
        """R~ = R / x_c."""
        return self.radius / self.length

    def scale(self, quantity):
        """SI value of one dimensionless unit of ``quantity`` (e.g. 'velocity' -> x_c/t_c in m/s)."""
        if quantity not in _DIMENSIONS:
            raise ValueError(f"unknown quantity {quantity!r}; known: {sorted(_DIMENSIONS)}")
        a, b, c = _DIMENSIONS[quantity]
        return self.mass ** a * self.length ** b * self.time ** c

    def to_si(self, value, quantity):
        """Dimensionless value -> SI."""
        return value * self.scale(quantity)

    def from_si_value(self, value, quantity):
        """SI value -> dimensionless."""
        return value / self.scale(quantity)


def paper_magnets():
    """Scales for the paper's 5 mm NdFeB spheres: m = 4 g, R = 5 mm, Y = 39.5 GPa, M = 8.8e5 A/m."""
    return PaperUnits.from_si(mass=4e-3, radius=5e-3, young_modulus=39.5e9, magnetisation=8.8e5)
