"""Integrators: convergence order on a smooth problem, exact free rotation, chunk independence,
long-run energy behaviour, angular momentum."""
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


@pytest.mark.parametrize("integrator, order", [(dk.EulerCromer, 1), (dk.VelocityVerlet, 2), (dk.ForestRuth, 4),
                                               (dk.RK4, 4)])
def test_convergence_order(truth, integrator, order):
    # fourth-order methods on longer steps, so that their smallest error (~1e-10) stays far above
    # the reference's (DOP853 at rtol 1e-12)
    dts = np.array([0.04, 0.02, 0.01, 0.005]) * (4 if order == 4 else 1)
    errors, dipole_errors = [], []
    for dt in dts:
        scene = smooth_scene()
        dk.Simulation(scene, integrator(dt)).run(duration=4.0)
        p = scene.particles
        assert np.linalg.norm(p.position[0] - p.position[1]) > 1.0  # never touched
        errors.append(np.abs(p.position - truth[0]).max())
        dipole_errors.append(np.abs(p.dipole - truth[3]).max())
        # every method turns the dipoles by exact rotations: norms stay 1 to round-off
        np.testing.assert_allclose(np.linalg.norm(p.dipole, axis=1), np.linalg.norm(truth[3], axis=1), rtol=1e-12)
    assert integrator.order == order
    for errs in (errors, dipole_errors):
        slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
        # a clean power law: slope within 0.15 of the nominal order (0.3 for fourth order, whose
        # coarsest step is not yet in the asymptotic range: measured slopes 4.1-4.3)
        assert slope == pytest.approx(order, abs=0.3 if order == 4 else 0.15), f"errors {errs}"


def field_pendulums():
    """Two heavy magnets side by side in a field along z: their moments nod about z like coupled
    rotational pendulums (the field's torque m x B, the dipoles' torques), a bounded oscillation."""
    pos = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    dip = np.array([[0.5, 0.0, 1.0], [0.0, -0.4, 1.0]])
    omega = np.array([[0.0, 0.3, 0.5], [0.2, 0.0, -0.4]])
    # mass 1e6 keeps the spheres almost in place; inertia 4e-7 m R^2 = 0.1 lets them turn
    p = dk.Particles(position=pos, radius=0.5, mass=1e6, inertia_factor=4e-7, dipole=dip, angular_velocity=omega)
    return dk.Scene(p, [dk.Dipole(prefactor=1.0), dk.UniformField((0.0, 0.0, 1.0))])


@pytest.mark.parametrize("integrator, dt", [(dk.VelocityVerlet, 0.02), (dk.ForestRuth, 0.05), (dk.RK4, 0.05)])
def test_a_million_steps_symplectic_energy_stays_bounded_rk4_drifts(integrator, dt):
    sim = dk.Simulation(field_pendulums(), integrator(dt))
    steps = 1_000_000
    energy = sim.run(dt * steps, record_every=dt * steps / 100).energy["total"]
    error = np.abs(energy - energy[0])
    first, second = error[:51].max(), error[51:].max()
    if integrator.symplectic:
        # bounded: the second half of the run reaches the same largest error as the first
        # (measured ratios 1.015 VV, 1.007 FR with fused multiply-adds; 1.106 VV in IEEE arithmetic:
        # the largest of 50 samples of an oscillating error); a drift would double it
        assert second < 1.25 * first
        assert first < (2e-3 if integrator is dk.VelocityVerlet else 1e-4)  # measured 1.6e-4, 1.0e-5
    else:
        # RK4 loses energy steadily: the error grows about linearly (measured 0.025 -> 0.047),
        # and ends at its largest, below the start
        assert second > 1.6 * first
        assert energy[-1] - energy[0] == pytest.approx(-second, rel=0.05)


@pytest.mark.parametrize("integrator", [dk.EulerCromer, dk.VelocityVerlet, dk.ForestRuth, dk.RK4])
def test_angular_momentum_is_conserved_to_round_off_by_symplectic_methods(integrator):
    scene = smooth_scene()  # dipoles only: no wall, no field, so L about any point is conserved
    scene.particles.angular_velocity = np.array([[0.2, 0.0, 0.1], [0.0, -0.3, 0.0], [0.1, 0.1, 0.4]])
    traj = dk.Simulation(scene, integrator(0.02)).run(duration=4.0, record_every=0.2)
    drift = np.abs(traj.angular_momentum - traj.angular_momentum[0]).max()
    scale = np.abs(traj.angular_momentum[0]).max()
    if integrator.symplectic:
        # each kick's torques and r x F cancel for forces from a rotation-invariant energy, drifts
        # and exact rotations keep L: round-off (measured ~1e-16 of L)
        assert drift < 1e-13 * scale
    else:
        assert 1e-13 * scale < drift < 1e-6 * scale  # RK4: small, but not round-off


@pytest.mark.parametrize("integrator", [dk.ForestRuth, dk.RK4])
def test_methods_without_contact_history_refuse_friction_scenes(integrator):
    p = dk.Particles(position=[[0, 0, 0], [1.05, 0, 0]], radius=0.5)
    scene = dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0, friction=dk.Friction(0.5))])
    with pytest.raises(ValueError, match=f"{integrator.__name__} cannot integrate per-contact history.*VelocityVerlet"):
        dk.Simulation(scene, integrator(1e-3))
    dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0)]), integrator(1e-3)).run(0.01)  # without friction: fine


@pytest.mark.parametrize("integrator", [dk.ForestRuth, dk.RK4])
def test_forces_after_a_run_belong_to_the_state_reached(integrator):
    scene = smooth_scene()
    dk.Simulation(scene, integrator(0.05)).run(duration=1.0)
    force, torque = scene.forces()
    np.testing.assert_array_equal(scene.force, force)  # what writers and diagnostics read
    np.testing.assert_array_equal(scene.torque, torque)
    assert integrator.evaluations_per_step == (3 if integrator is dk.ForestRuth else 4)


def test_simulations_taking_turns_on_one_scene_each_get_their_working_arrays():
    # an RK4 and a multiple-time-stepping simulation of the same scene, run in turns, give what
    # one run of each after the other gives (their working arrays are reserved at every run)
    a, b = smooth_scene(), smooth_scene()
    rk4, mts = dk.Simulation(a, dk.RK4(0.05)), dk.Simulation(a, dk.MultipleTimeStep(0.05, inner=2))
    rk4.run(0.5)
    mts.run(0.5)
    assert a.arrays["stage"].shape == (4, 3, 3)  # slow and fast forces and torques
    rk4.run(0.5)
    assert a.arrays["stage"].shape == (9, 3, 3)  # RK4's own, not the 4 left by the other run
    for integrator in (dk.RK4(0.05), dk.MultipleTimeStep(0.05, inner=2), dk.RK4(0.05)):
        dk.Simulation(b, integrator).run(0.5)
    np.testing.assert_array_equal(a.particles.position, b.particles.position)
    np.testing.assert_array_equal(a.particles.dipole, b.particles.dipole)


def test_only_rk4_scenes_hold_stage_arrays():
    scene = smooth_scene()
    dk.Simulation(scene, dk.RK4(0.05)).run(0.1)
    assert scene.arrays["stage"].shape == (9, 3, 3)
    dk.Simulation(scene, dk.VelocityVerlet(0.05)).run(0.1)  # an unused effect costs nothing
    assert scene.arrays["stage"].size == 0


def test_dipole_norm_preserved_and_free_rotation_exact():
    omega = np.array([[0.3, -0.2, 0.9], [0.0, 0.0, 2.0]])
    m0 = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 1.0]])
    p = dk.Particles(position=[[0, 0, 0], [50, 0, 0]], radius=1.0, dipole=m0, angular_velocity=omega)
    # dipoles 50 radii apart at prefactor 1e-300: forces and torques ~1e-306, far below the round-off
    # of any velocity or spin (~1e-16), so the spins stay constant bit for bit and the dipoles precess
    # freely. (The Dipole-only scene's kernels are the ones smooth_scene compiles for the tests above;
    # a PowerLawDipole, torque-free by construction, compiled a module of its own for this test.)
    scene = dk.Scene(p, [dk.Dipole(prefactor=1e-300)])
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


@pytest.mark.parametrize("integrator", [dk.EulerCromer, dk.VelocityVerlet, dk.ForestRuth, dk.RK4])
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


# ---- multiple time stepping ------------------------------------------------------------------

def magnetic_pair_with_friction():
    """Two magnets meeting off-centre: contacts with friction history (fast), dipoles (slow)."""
    p = dk.Particles(position=[[0.0, 0.0, 0.0], [1.6, 0.5, 0.0]], velocity=[[0.0, 0.0, 0.0], [-0.6, 0.0, 0.0]],
                     radius=0.5, dipole=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    contact = dk.KelvinVoigt(2000.0, 2.0, friction=dk.Friction(0.4))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0 / 3.0), contact])


def test_multiple_time_stepping_with_one_inner_step_is_velocity_verlet():
    for make in (smooth_scene, magnetic_pair_with_friction):
        a, b = make(), make()
        ta = dk.Simulation(a, dk.VelocityVerlet(0.002)).run(3.0)
        tb = dk.Simulation(b, dk.MultipleTimeStep(0.002, inner=1)).run(3.0)
        # the same steps; only the order of adding slow and fast kicks differs (round-off, which the
        # 1.5 time units of contact in the second scene amplify: measured 0 and ~1e-15)
        np.testing.assert_allclose(tb.position[-1], ta.position[-1], rtol=0, atol=1e-11)
        assert tb.energy["dissipated"][-1] == pytest.approx(ta.energy["dissipated"][-1], rel=1e-9)


def test_multiple_time_stepping_is_second_order_and_inner_steps_pay_off():
    # the field's torque (fast) drives the pendulums, the dipoles (slow) couple them
    ref = dk.Simulation(field_pendulums(), dk.RK4(0.002)).run(20.0)
    errors = {}
    for inner in (1, 4):
        for dt in (0.04, 0.02, 0.01):
            traj = dk.Simulation(field_pendulums(), dk.MultipleTimeStep(dt, inner=inner)).run(20.0)
            errors[inner, dt] = np.abs(traj.dipole[-1] - ref.dipole[-1]).max()
    for inner in (1, 4):
        ratios = [errors[inner, 0.04] / errors[inner, 0.02], errors[inner, 0.02] / errors[inner, 0.01]]
        assert ratios == pytest.approx([4.0, 4.0], rel=0.05)  # second order: measured 4.01-4.02
    # four inner steps for the fast field: 14x smaller error at the same outer step (measured 14.4)
    assert errors[4, 0.02] < errors[1, 0.02] / 10


def test_multiple_time_stepping_follows_velocity_verlet_through_contacts_with_friction():
    h = 5e-4
    ref_scene = magnetic_pair_with_friction()
    ref = dk.Simulation(ref_scene, dk.VelocityVerlet(h)).run(4.0, record_every=0.5)
    scene = magnetic_pair_with_friction()
    traj = dk.Simulation(scene, dk.MultipleTimeStep(8 * h, inner=8)).run(4.0, record_every=0.5)
    # contacts and friction on the same inner step as the reference: the pair bounces and turns
    # alike through four contacts; only the dipoles' slower sampling differs (measured 2.5e-4 in
    # position, while velocity Verlet at h/4 differs from velocity Verlet at h by 3e-2)
    distance = np.linalg.norm(traj.position[:, 0] - traj.position[:, 1], axis=1)
    assert distance.min() < 1.06 and distance[-1] > 1.1
    np.testing.assert_allclose(traj.position, ref.position, atol=1e-3)
    # total + dissipated misses by about velocity Verlet's error at the inner step (the dashpot's
    # jumps at contact onset; measured -1.43e-4 and -1.36e-4: the dipoles' slower sampling adds 5 %;
    # 7.91e-3 and 7.92e-3 when friction's work was booked as dt x power)
    budget, ref_budget = (t.energy["total"] + t.energy["dissipated"] for t in (traj, ref))
    assert budget[-1] - budget[0] == pytest.approx(ref_budget[-1] - ref_budget[0], rel=0.1)
    assert traj.energy["dissipated"][-1] == pytest.approx(ref.energy["dissipated"][-1], rel=0.01)


def test_multiple_time_stepping_refusals_and_its_inner_time_step_guard():
    for bad in (0, -2, 1.5, "4", True):
        with pytest.raises(ValueError, match="inner must be a whole number"):
            dk.MultipleTimeStep(0.01, inner=bad)
    scene = magnetic_pair_with_friction()
    limit = scene.max_time_step()
    dk.Simulation(scene, dk.MultipleTimeStep(10 * limit, inner=20))  # its contacts see limit / 2
    with pytest.raises(ValueError, match="inner time step dt/inner = .* too large"):
        dk.Simulation(scene, dk.MultipleTimeStep(10 * limit, inner=5))
    slow_friction = dk.KelvinVoigt(1000.0, 1.0, friction=dk.Friction(0.5))
    slow_friction.slow = True
    p = dk.Particles(position=[[0, 0, 0], [1.05, 0, 0]], radius=0.5)
    with pytest.raises(ValueError, match="slow interaction that keeps history"):
        dk.Simulation(dk.Scene(p, [slow_friction]), dk.MultipleTimeStep(1e-3))
    assert dk.MultipleTimeStep(0.01, inner=6).evaluations_per_step == 7


def test_multiple_time_stepping_keeps_its_slow_forces_through_re_sorting():
    from test_nbody import gas

    p, box = gas(n=300, phi=0.3, periodic=True, seed=5, speed=2.0)
    finals = []
    for every in (0, 3):  # never re-sort, or at the first list rebuild 3 steps after the last one
        scene = dk.Scene(p.copy(), [dk.Dipole(1.0, cutoff=3.0), dk.KelvinVoigt(1000.0, 1.0)], box=box,
                         sort_every=every, parallel=False)
        traj = dk.Simulation(scene, dk.MultipleTimeStep(4e-3, inner=4)).run(0.4, record_every=0.1)
        finals.append(traj.unwrapped())
        if every:
            assert scene.counters[2] > 3  # re-sorted (SORTS) many times
    # the same run up to round-off: the slow forces held between steps moved with their spheres
    np.testing.assert_allclose(finals[1], finals[0], rtol=0, atol=1e-9)
