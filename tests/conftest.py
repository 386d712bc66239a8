"""Shared builders for the tests."""
import numpy as np
import pytest

import demkit as dk

R_PAPER = 6.94
V_PAPER = 5.78e-3


def two_magnets(b_over_r=4.0, v=V_PAPER, x0=150.0, model=dk.Dipole, damping=0.1, radius=R_PAPER):
    """The seed paper's collision in its units: unit dipoles along the initial line of centres."""
    b = b_over_r * radius
    pos = np.array([[-x0, -b / 2, 0.0], [x0, b / 2, 0.0]])
    n = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    p = dk.Particles(position=pos, velocity=[[v, 0, 0], [-v, 0, 0]], radius=radius, mass=1.0,
                     dipole=[n, n])
    return dk.Scene(p, [model(prefactor=1 / 3), dk.KelvinVoigt(stiffness=1.0, damping=damping)])


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def energy_gradient(scene, kind, i, h):
    """Central-difference gradient of scene.energy()[kind] with respect to the position of particle i."""
    x = scene.particles.position
    grad = np.zeros(3)
    for a in range(3):
        x[i, a] += h
        up = scene.energy()[kind]
        x[i, a] -= 2 * h
        down = scene.energy()[kind]
        x[i, a] += h
        grad[a] = (up - down) / (2 * h)
    return grad
