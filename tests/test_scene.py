"""Scene composition: only what is asked for, plug-ins, diagnostics without side effects."""
import numpy as np
import pytest
from conftest import two_magnets
from plugin_interactions import ContactCounter, Poison

import demkit as dk


def contact_only(n=3):
    pos = np.array([[0.0, 0, 0], [2.5, 0, 0], [5.0, 0, 0]])[:n]
    p = dk.Particles(position=pos, velocity=[[0.1, 0, 0], [0, 0, 0], [-0.1, 0, 0]][:n], radius=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(stiffness=10.0, damping=0.1)])


def test_scene_without_dipoles_has_no_dipole_fields_or_code():
    scene = contact_only()
    p = scene.particles
    assert p.dipole is None and p.angular_velocity is None
    assert scene.history_values == 0
    assert "dipole_force" not in scene.fused_source() and "force_1" not in scene.fused_source()
    traj = dk.Simulation(scene, dk.VelocityVerlet(0.01)).run(duration=1.0, record_every=0.5)
    assert traj.dipole is None and traj.angular_velocity is None
    assert p.dipole is None and p.angular_velocity is None


def test_dipole_scene_allocates_spin():
    scene = two_magnets()
    assert scene.particles.angular_velocity.shape == (2, 3)
    assert "dipole_force" in scene.fused_source()
    assert "cache=True" in scene.fused_source()  # library interactions are compiled once, then cached


def test_energy_keys_and_total():
    e = two_magnets().energy()
    assert set(e) >= {"kinetic", "rotational", "magnetic", "contact", "total", "dissipated"}
    assert e["total"] == pytest.approx(e["kinetic"] + e["rotational"] + e["magnetic"] + e["contact"])
    assert e["kinetic"] == pytest.approx(5.78e-3**2)  # two unit masses at v = 5.78e-3


def test_forces_have_no_side_effects():
    scene = contact_only()
    before = {k: v.copy() for k, v in vars(scene.particles).items() if isinstance(v, np.ndarray)}
    f1, _ = scene.forces()
    f2, _ = scene.forces()
    np.testing.assert_array_equal(f1, f2)
    for k, v in before.items():
        np.testing.assert_array_equal(getattr(scene.particles, k), v)
    assert scene.dissipated == 0.0


def test_angular_momentum_orbital_plus_spin():
    scene = two_magnets()
    p = scene.particles
    p.angular_velocity[:] = [[0, 0, 0.01], [0, 0, 0.02]]
    expected = np.cross(p.position, p.velocity).sum(axis=0) + p.inertia[0] * np.array([0, 0, 0.03])
    np.testing.assert_allclose(scene.angular_momentum(), expected, rtol=1e-14)


def test_plugin_with_per_contact_history():
    p = dk.Particles(position=[[0.0, 0, 0], [2.05, 0, 0], [10.0, 0, 0]],
                     velocity=[[0.05, 0, 0], [-0.05, 0, 0], [0, 0, 0]], radius=1.0)
    counter = ContactCounter()
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=1.0), counter])
    pairs, values = scene.history(counter)
    assert values.shape == (3, 1) and pairs.tolist() == [[0, 1], [0, 2], [1, 2]]
    scene.forces()
    assert not scene.history(counter)[1].any()  # evaluating forces commits no history
    steps_touching = 0
    sim = dk.Simulation(scene, dk.EulerCromer(0.01))
    for _ in range(400):
        before = np.linalg.norm(p.position[1] - p.position[0]) < 2.0
        sim.run(duration=0.01)
        steps_touching += before
    # EC evaluates forces at the start of each step: history counts those steps for pair (0, 1)
    values = scene.history(counter)[1]
    assert values[0, 0] == steps_touching > 0
    assert values[1:, 0].sum() == 0  # pairs (0, 2) and (1, 2) never touched
    assert "counter" in scene.energy()
    with pytest.raises(ValueError, match="keeps no per-contact history"):  # (an IndexError once)
        scene.history(scene.interactions[0])


def test_non_finite_state_stops_with_step_time_and_particle():
    p = dk.Particles(position=[[0.0, 0, 0], [10.0, 0, 0]], velocity=[[0.5, 0, 0], [-0.5, 0, 0]], radius=1.0)
    scene = dk.Scene(p, [Poison(distance=5.0)])
    sim = dk.Simulation(scene, dk.EulerCromer(0.1))
    with pytest.raises(dk.SimulationError, match="non-finite") as info:
        sim.run(duration=20.0, record_every=0.5)
    err = info.value
    # the separation closes at ~1 per unit time: it crosses 5 at t ~ 5, NaN shows one step later
    assert 4.5 < err.time < 5.6
    assert err.step == round(err.time / 0.1)
    assert err.particle in (0, 1)
    assert f"step {err.step}" in str(err)
    traj = err.trajectory
    assert traj is sim.trajectory and len(traj) >= 9
    assert np.isfinite(traj.position).all() and traj.time[-1] < err.time


def test_run_continues_time_and_record_every_validation():
    scene = contact_only(2)
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.01))
    sim.run(duration=0.5)
    traj = sim.run(duration=0.5, record_every=0.1)
    assert traj.time[0] == pytest.approx(0.5) and traj.time[-1] == pytest.approx(1.0)
    with pytest.raises(ValueError, match="record_every"):
        sim.run(duration=1.0, record_every=0.001)
    with pytest.raises(ValueError, match="duration"):
        sim.run(duration=-1.0)


def test_pair_energies_sum_to_the_energy_kinds():
    rng = np.random.default_rng(3)
    pos = np.array([[0.0, 0, 0], [1.9, 0.1, 0], [0.3, 1.95, 0.2], [6, 6, 6]])
    p = dk.Particles(position=pos, radius=1.0, dipole=rng.normal(size=(4, 3)))
    scene = dk.Scene(p, [dk.Dipole(0.5, cutoff=5.0), dk.KelvinVoigt(3.0)])
    pairs, per_pair = scene.pair_energies()
    assert per_pair.shape == (6, 2) and pairs.shape == (6, 2)
    e = scene.energy()
    assert per_pair[:, 0].sum() == pytest.approx(e["magnetic"], rel=1e-14)
    assert per_pair[:, 1].sum() == pytest.approx(e["contact"], rel=1e-14)
    far = [k for k, (i, j) in enumerate(pairs) if 3 in (i, j)]
    assert not per_pair[far].any()  # beyond the dipole cutoff and out of contact
    assert (per_pair[:, 1] > 0).sum() == 2  # pairs (0,1) and (0,2) overlap


def test_functions_without_source_are_refused_with_a_clear_error():
    """demkit writes a plug-in's functions into generated code: one made with exec has no source file."""
    ns = {"dk": dk}
    exec(compile("import numba\n@numba.njit\ndef push(i, j, dx, dy, dz, r2, k):\n    return k * dx, k * dy, k * dz\n"
                 "class Push(dk.PairInteraction):\n    energy_kind = 'push'\n    parameters = ('k',)\n"
                 "    force_function = push\n    energy_function = push\n    def __init__(self):\n        self.k = 1.0\n",
                 "<typed>", "exec"), ns)
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=0.5, mass=1.0)
    with pytest.raises(ValueError, match="Push: the source of push cannot be read.*define them in a .py file"):
        dk.Scene(p, [ns["Push"]()])
