"""Kelvin-Voigt contact: restitution against the analytic solution, energy bookkeeping."""
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import demkit as dk
from conftest import energy_gradient
from demkit.interactions.contact import restitution


def head_on(damping, no_tension=False, v=0.1, stiffness=1.0):
    p = dk.Particles(position=[[-1.001, 0, 0], [1.001, 0, 0]], velocity=[[v, 0, 0], [-v, 0, 0]],
                     radius=1.0, mass=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(stiffness, damping, no_tension=no_tension)])


def no_tension_restitution(k, c, m_eff):
    """Analytic e when the contact ends as soon as k delta + c delta_dot = 0 (before delta = 0).

    delta(t) = v0/w exp(-g t) sin(w t), g = c/(2 m_eff), w = sqrt(k/m_eff - g^2); after the force
    vanishes the spheres fly apart at the rate reached then.
    """
    g = c / (2 * m_eff)
    w = math.sqrt(k / m_eff - g * g)
    delta = lambda t: math.exp(-g * t) * math.sin(w * t) / w  # noqa: E731  (v0 = 1)
    rate = lambda t: math.exp(-g * t) * (math.cos(w * t) - g / w * math.sin(w * t))  # noqa: E731
    t_end = brentq(lambda t: k * delta(t) + c * rate(t), 1e-9, math.pi / w)
    return -rate(t_end)


def measured_restitution(scene, dt=1e-3):
    v0 = scene.particles.velocity[1, 0] - scene.particles.velocity[0, 0]
    dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=8.0)
    r = scene.particles.position[1, 0] - scene.particles.position[0, 0]
    assert r > 2.0, "the spheres must have separated"
    return -(scene.particles.velocity[1, 0] - scene.particles.velocity[0, 0]) / v0


@pytest.mark.parametrize("zeta", [0.05, 0.2, 0.5])
def test_restitution_matches_analytic(zeta):
    m_eff, k = 0.5, 1.0
    c = 2 * zeta * math.sqrt(k * m_eff)
    e = measured_restitution(head_on(c))
    # the dashpot force jumps at first touch, so the time-stepped contact is first order in dt:
    # at dt = 1e-3 (contact ~2200 steps) the error is ~1e-4; 5e-4 leaves margin
    assert e == pytest.approx(restitution(k, c, m_eff), abs=5e-4)
    assert e == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2)), abs=5e-4)


@pytest.mark.parametrize("zeta", [0.05, 0.2, 0.5])
def test_restitution_without_tension_matches_analytic(zeta):
    m_eff, k = 0.5, 1.0
    c = 2 * zeta * math.sqrt(k * m_eff)
    e = measured_restitution(head_on(c, no_tension=True))
    expected = no_tension_restitution(k, c, m_eff)
    assert e == pytest.approx(expected, abs=5e-4)
    # forbidding tension always gives a livelier bounce than letting the dashpot pull
    assert expected > restitution(k, c, m_eff)


def test_restitution_independent_of_speed():
    c = 0.3
    # dt = 2.5e-4: the first-order error from where the touch falls inside a step is ~5e-5
    assert measured_restitution(head_on(c, v=0.05), dt=2.5e-4) == pytest.approx(
        measured_restitution(head_on(c, v=0.2), dt=2.5e-4), abs=2e-4)


@pytest.mark.parametrize("no_tension", [False, True])
def test_energy_plus_dissipated_work_is_conserved(no_tension):
    errors = []
    for dt in (1e-3, 2.5e-4):
        scene = head_on(0.3, no_tension=no_tension)
        e0 = scene.energy()["total"]
        traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=8.0, record_every=0.01)
        balance = traj.energy["total"] + traj.energy["dissipated"]
        errors.append(np.abs(balance - e0).max() / e0)
        assert traj.energy["dissipated"][-1] > 0.3 * e0  # a real share of the energy was dissipated
    # The dashpot force jumps at the touch, so the balance closes to O(dt): measured 6e-4 at
    # dt = 1e-3 (about half a step of dashpot power), and it must shrink with dt like dt.
    assert errors[0] < 1e-3
    assert errors[1] < errors[0] / 3


def test_elastic_force_is_minus_energy_gradient():
    p = dk.Particles(position=[[0, 0, 0], [1.5, 0.3, -0.2]], radius=[0.9, 0.8], mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=7.0)])
    force, _ = scene.forces()
    np.testing.assert_allclose(force[1], -energy_gradient(scene, "contact", 1, h=1e-6), rtol=1e-7)


def test_largest_safe_time_step_is_a_tenth_of_the_contact():
    scene = head_on(0.1)
    m_eff = 0.5
    zeta = 0.1 / (2 * math.sqrt(m_eff))
    duration = math.pi / (math.sqrt(1 / m_eff) * math.sqrt(1 - zeta**2))
    assert scene.max_time_step() == pytest.approx(duration / 10, rel=1e-12)
