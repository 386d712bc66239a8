"""Integrators: convergence order on a smooth problem, exact free rotation, chunk independence."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import demkit as dk


def smooth_scene():
    """Three magnets released at rest with skewed moments: they attract, turn and spin, never touch."""
    pos = np.array([[0.0, 0.0, 0.0], [3.0, 0.4, 0.0], [0.5, 3.2, 0.7]])
    dip = np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.5], [0.6, -0.2, 1.0]])
    p = dk.Particles(position=pos, radius=0.5, mass=[1.0, 1.3, 0.8], dipole=dip)
    return dk.Scene(p, [dk.Dipole(prefactor=1.0)])


def reference(duration):
    """Independent truth: scipy's DOP853 on x, v, w and dm/dt = w x m, forces from Scene.forces()."""
    scene = smooth_scene()
    p = scene.particles
    n = len(p)

    def rhs(_, y):
        x, v, w, m = y.reshape(4, n, 3)
        p.position[:], p.velocity[:], p.angular_velocity[:], p.dipole[:] = x, v, w, m
        f, tau = scene.forces()
        return np.concatenate([v, f / p.mass[:, None], tau / p.inertia[:, None], np.cross(w, m)]).ravel()

    y0 = np.concatenate([p.position, p.velocity, p.angular_velocity, p.dipole]).ravel()
    sol = solve_ivp(rhs, (0, duration), y0, method="DOP853", rtol=1e-12, atol=1e-13)
    return sol.y[:, -1].reshape(4, n, 3)


@pytest.fixture(scope="module")
def truth():
    return reference(4.0)


@pytest.mark.parametrize("integrator, order", [(dk.EulerCromer, 1), (dk.VelocityVerlet, 2)])
def test_convergence_order(truth, integrator, order):
    dts = np.array([0.04, 0.02, 0.01, 0.005])
    errors = []
    for dt in dts:
        scene = smooth_scene()
        dk.Simulation(scene, integrator(dt)).run(duration=4.0)
        p = scene.particles
        assert np.linalg.norm(p.position[0] - p.position[1]) > 1.0  # never touched
        errors.append(np.abs(p.position - truth[0]).max())
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    # a clean power law: slope within 0.15 of the nominal order
    assert slope == pytest.approx(order, abs=0.15), f"errors {errors}"


def test_dipole_norm_preserved_and_free_rotation_exact():
    omega = np.array([[0.3, -0.2, 0.9], [0.0, 0.0, 2.0]])
    m0 = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 1.0]])
    p = dk.Particles(position=[[0, 0, 0], [50, 0, 0]], radius=1.0, dipole=m0, angular_velocity=omega)
    # power-law dipoles exert no torque: the spins stay constant and the dipoles precess freely
    scene = dk.Scene(p, [dk.PowerLawDipole(prefactor=1e-12)])
    dt, steps = 0.01, 20000
    dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=dt * steps)
    for i in range(2):
        w = omega[i]
        axis, angle = w / np.linalg.norm(w), np.linalg.norm(w) * dt * steps
        exact = (m0[i] * np.cos(angle) + np.cross(axis, m0[i]) * np.sin(angle)
                 + axis * (axis @ m0[i]) * (1 - np.cos(angle)))
        # 20000 exact rotations: round-off only (angle ~ 400 rad, so ~1e-16 * 2e4 growth)
        np.testing.assert_allclose(p.dipole[i], exact, atol=1e-11)
        assert np.linalg.norm(p.dipole[i]) == pytest.approx(np.linalg.norm(m0[i]), rel=1e-13)


@pytest.mark.parametrize("integrator", [dk.EulerCromer, dk.VelocityVerlet])
def test_recording_does_not_change_the_trajectory(integrator):
    a, b = smooth_scene(), smooth_scene()
    dk.Simulation(a, integrator(0.01)).run(duration=2.0)
    traj = dk.Simulation(b, integrator(0.01)).run(duration=2.0, record_every=0.03)
    np.testing.assert_array_equal(a.particles.position, b.particles.position)
    np.testing.assert_array_equal(traj.position[-1], b.particles.position)
    assert traj.time[-1] == pytest.approx(2.0)
    # frames every 3 steps plus the final state (200 steps is not a multiple of 3)
    assert len(traj) == 200 // 3 + 2


def test_integrator_rejects_bad_time_step():
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="time step"):
            dk.EulerCromer(bad)
