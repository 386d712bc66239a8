"""Guards while stepping: a run that can no longer be trusted stops with a SimulationError naming
the step, time, particle(s) and cause, and keeps the frames recorded so far."""
import numpy as np
import pytest

import demkit as dk


def test_a_sphere_falling_through_a_soft_wall_stops_before_it_passes():
    # a ball dropped from height 20 hits the floor at v = sqrt(2 g h) = 6.3; a wall of k = 10 would
    # need an overlap of v sqrt(m/k) = 2 radii to stop it: the run must stop at half a radius
    p = dk.Particles([[0.0, 0.0, 21.0]], radius=1.0, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(10.0), dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -1.0))])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    sim.run(1.0, record_every=0.5)  # a run that goes well, then one that stops
    first = sim.step
    with pytest.raises(dk.SimulationError, match="overlaps Wall.*more than 0.5 of its radius") as err:
        sim.run(9.0, record_every=0.5)
    assert sim.statistics["steps"] == sim.step - first > 0  # the stopped run's figures, not the first run's
    z = p.position[0, 2]
    assert 0.45 < 1.0 - z < 0.6  # stopped as the overlap passed half the radius, not later
    fall = np.sqrt(2 * 20.0)  # time to fall to the wall
    assert fall < err.value.time < fall + 1.0
    assert err.value.particle == 0 and err.value.step == sim.step
    traj = err.value.trajectory
    assert len(traj) == int((err.value.time - 1.0) / 0.5) + 1 and np.isfinite(traj.position).all()  # this run's frames


def test_two_spheres_tunnelling_through_a_soft_contact_stop_with_both_ids():
    p = dk.Particles([[0.0, 0, 0], [3.0, 0, 0]], velocity=[[2.0, 0, 0], [-2.0, 0, 0]], radius=1.0, ids=[7, 9])
    scene = dk.Scene(p, [dk.KelvinVoigt(0.5)])  # overlap needed: 2 sqrt(0.5/0.5) = 2 radii
    sim = dk.Simulation(scene, dk.EulerCromer(1e-3))
    with pytest.raises(dk.SimulationError, match=r"particles id (7 and 9|9 and 7) overlap by more than 0.5"):
        sim.run(5.0)
    gap = np.linalg.norm(p.position[1] - p.position[0])
    assert 0.45 < 2.0 - gap < 0.6  # overlap just past half a radius


def test_energy_growth_guard_stops_a_run_gaining_energy():
    # velocity Verlet far beyond its stability limit on a stiff contact gains energy at every bounce
    # (the dt guard is bypassed by shrinking the law's claimed contact time: the kind of scene the
    # guard exists for is one whose instability no check before stepping foresaw)
    p = dk.Particles([[0.0, 0, 0], [2.5, 0, 0]], velocity=[[0.5, 0, 0], [-0.5, 0, 0]], radius=1.0)
    law = dk.KelvinVoigt(1e3)
    law.max_time_step = lambda particles, *a, **k: np.inf
    scene = dk.Scene(p, [law])
    sim = dk.Simulation(scene, dk.EulerCromer(0.06), max_energy_growth=0.05)
    with pytest.raises(dk.SimulationError, match="energy grew by"):
        sim.run(200.0, record_every=1.0)
    assert sim.statistics["steps"] == sim.step > 0 and sim.statistics["seconds"] > 0
    energy = sim.trajectory.energy["total"] + sim.trajectory.energy["dissipated"]
    assert np.isfinite(energy).all()


@pytest.mark.parametrize("threads, n", [(False, 37), (True, 37), (False, 3)])
def test_the_finiteness_check_agrees_with_numpy_for_any_value_anywhere(threads, n):
    """The check every step ends with (serial and on threads) against np.isfinite: NaN of either
    sign and +-inf in each array at each place, among values of both signs, and huge finite values
    (a sum of the values themselves would overflow: an earlier check called 1e308 + 1e308 non-finite)."""
    from demkit.engine.motion import state_is_finite, state_is_finite_threads
    check = state_is_finite_threads if threads else state_is_finite
    rng = np.random.default_rng(5)
    arrays = [rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-300, 300, size=(n, 3)) for _ in range(3)]
    arrays[0][n - 1] = 1e308  # few spheres: the rows are summed one by one, many: flat views
    arrays[1][n - 2] = -1e308
    assert check(*arrays) and check(arrays[0], arrays[1], np.zeros((0, 3)))
    for bad in (np.nan, -np.nan, np.inf, -np.inf):
        for a in arrays:
            for k in range(a.size):
                old = a.flat[k]
                a.flat[k] = bad
                assert not check(*arrays), (bad, k)
                a.flat[k] = old
    assert check(*arrays) == all(np.isfinite(a).all() for a in arrays)
