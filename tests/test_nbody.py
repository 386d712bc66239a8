"""The N-body engine: neighbour lists against brute force, forces against an all-pairs minimum-image
sum, history through rebuilds and permutations, conservation in a periodic box, threads."""
import math

import numba
import numpy as np
import pytest
from numba import njit
from plugin_interactions import TouchCounter
from reference_forces import dipole_forces, kelvin_voigt_forces, pairs_within

import demkit as dk
from demkit.engine import neighbours
from demkit.engine.state import SORTS, new_pair_list


def gas(n=300, phi=0.2, periodic=True, seed=1, uneven=False, dipoles=True, speed=1.0, moment=1.0):
    """Random non-overlapping spheres at volume fraction phi with thermal velocities."""
    rng = np.random.default_rng(seed)
    radius = rng.uniform(0.35, 0.65, n) if uneven else 0.5
    box = dk.build.box_for(n, radius, phi, periodic=periodic)
    x = dk.build.random_packing(n, radius, box, seed=rng)
    v = speed * dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=rng)
    mu = moment * dk.build.random_directions(n, seed=rng) if dipoles else None
    return dk.Particles(position=x, velocity=v, radius=radius, mass=1.0, dipole=mu), box


BOXES = {"open": False, "periodic": True, "mixed": (True, False, True)}


@pytest.mark.parametrize("kind", list(BOXES))
def test_lists_hold_exactly_the_pairs_within_each_cutoff_after_motion(kind):
    p, box = gas(n=300, periodic=BOXES[kind], uneven=True, seed=2)
    contact, dipole = dk.KelvinVoigt(stiffness=1000.0), dk.Dipole(prefactor=1.0, cutoff=3.0)
    # dipole first, as in the other Dipole + KelvinVoigt scenes here: the order of the interactions
    # is part of the generated kernels, and this order shares them (the lists do not depend on it)
    scene = dk.Scene(p, [dipole, contact], box=box if kind != "open" else None, skin=0.1)
    assert [g.kind for g in scene.plan.groups] == ["list", "list"]
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
    sim.run(duration=3.0)
    assert sim.statistics["neighbour_list_builds"] >= 10  # the lists were rebuilt many times
    x = p.position if kind == "open" else p.position + p.image * box.size
    frame = None if kind == "open" else box
    for inter, cutoff in ((contact, 2 * p.radius.max()), (dipole, 3.0)):
        listed = {tuple(sorted(pair)) for pair in scene.candidate_pairs(inter).tolist()}
        truth = pairs_within(x, cutoff, frame)
        assert truth <= listed
        near = pairs_within(x, cutoff + scene.skin, frame)  # each moved < skin/2 since the build
        assert listed <= pairs_within(x, cutoff + 2 * scene.skin, frame) and len(near & listed) == len(listed & near)
        i, j = np.array(sorted(listed)).T
        d = scene.separations(np.stack([i, j], 1))
        assert {pair for pair, r in zip(sorted(listed), np.linalg.norm(d, axis=1)) if r < cutoff} == truth


@pytest.mark.parametrize("kind", ["open", "periodic"])
def test_forces_torques_energies_equal_the_all_pairs_minimum_image_sum(kind):
    p, box = gas(n=400, periodic=kind == "periodic", uneven=True, seed=3)
    p.position += 0.02 * np.random.default_rng(4).normal(size=p.position.shape)  # some overlaps
    frame = box if kind == "periodic" else None
    scene = dk.Scene(p, [dk.Dipole(prefactor=0.7, cutoff=3.5), dk.KelvinVoigt(stiffness=500.0, damping=2.0)],
                     box=frame)
    force, torque = scene.forces()
    fd, td, ud = dipole_forces(p.position, p.dipole, 0.7, cutoff=3.5, box=frame)
    fc, uc = kelvin_voigt_forces(p.position, p.velocity, p.radius, 500.0, 2.0, box=frame)
    assert uc > 0  # contacts present
    # round-off only: the sums run in another order (relative to the largest force, 1e-12)
    np.testing.assert_allclose(force, fd + fc, rtol=0, atol=1e-12 * np.abs(fd + fc).max())
    np.testing.assert_allclose(torque, td, rtol=0, atol=1e-12 * np.abs(td).max())
    e = scene.energy()
    assert e["magnetic"] == pytest.approx(ud, rel=1e-12)
    assert e["contact"] == pytest.approx(uc, rel=1e-12)


def counts_by_ids(scene, counter):
    pairs, values = scene.history(counter)
    ids = scene.particles.ids
    return {tuple(sorted((ids[i], ids[j]))): v for (i, j), v in zip(pairs.tolist(), values[:, 0]) if v}


def test_history_follows_its_pair_through_rebuilds_and_a_permutation():
    p, box = gas(n=150, phi=0.3, periodic=True, dipoles=False, seed=5, speed=1.5)
    runs = {}
    for name, order in (("listed", np.arange(150)), ("permuted", np.random.default_rng(6).permutation(150))):
        q = dk.Particles(position=p.position[order], velocity=p.velocity[order], radius=p.radius[order],
                         ids=p.ids[order])
        counter = TouchCounter(cutoff=1.0)
        scene = dk.Scene(q, [dk.KelvinVoigt(stiffness=1000.0), counter], box=box, skin=0.05)
        sim = dk.Simulation(scene, dk.EulerCromer(dt=1e-3))
        sim.run(duration=1.5)
        runs[name] = (counts_by_ids(scene, counter), sim.statistics["neighbour_list_builds"])
    counts, builds = runs["listed"]
    assert builds > 20 and len(counts) > 10
    assert max(counts.values()) > 50  # contacts that lasted through several rebuilds
    assert runs["permuted"][0] == counts


def test_re_sorting_by_cell_is_invisible_and_keeps_history():
    p, box = gas(n=400, phi=0.3, periodic=True, seed=14, speed=1.5)
    finals, counts = [], []
    for every in (0, 3):  # never, or at the first rebuild 3 steps after the last re-sort
        counter = TouchCounter(cutoff=1.0)
        scene = dk.Scene(p.copy(), [dk.Dipole(1.0, cutoff=3.0), dk.KelvinVoigt(1000.0), counter], box=box,
                         sort_every=every)
        sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
        traj = sim.run(duration=0.5, record_every=0.1)
        if every:
            assert scene.counters[SORTS] > 10 and not np.array_equal(scene.arrays["tag"], np.arange(400))
        finals.append((traj, scene.forces()[0], scene.particles.position.copy()))
        counts.append(counts_by_ids(scene, counter))
    (t0, f0, x0), (t1, f1, x1) = finals
    # the same run up to round-off (sums in another order): positions and forces in the user's order
    np.testing.assert_allclose(x1, x0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(t1.position, t0.position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(f1, f0, rtol=0, atol=1e-7 * np.abs(f0).max())
    assert counts[1] == counts[0] and len(counts[0]) > 10


def test_history_survives_rebuilds_exactly_as_an_all_pairs_history():
    """Open space: the same counter without a cutoff keeps its history for all pairs (no lists)."""
    p, _ = gas(n=100, phi=0.2, periodic=False, dipoles=False, seed=7, speed=1.5)
    runs = []
    for cutoff in (1.0, None):
        counter = TouchCounter(cutoff=cutoff)
        scene = dk.Scene(p.copy(), [dk.KelvinVoigt(stiffness=1000.0), counter], skin=0.05)
        assert ("list" if cutoff else "all") in [g.kind for g in scene.plan.groups]
        runs.append((dk.Simulation(scene, dk.EulerCromer(dt=1e-3)), scene, counter))
    compared = 0
    for _ in range(20):  # compare at many moments: contacts in an expanding gas come and go
        counts = []
        for sim, scene, counter in runs:
            sim.run(duration=0.1)
            counts.append(counts_by_ids(scene, counter))
        assert counts[0] == counts[1]
        compared += len(counts[0])
    assert compared > 20 and runs[0][0].statistics["neighbour_list_builds"] > 0


def test_a_pair_that_leaves_the_list_loses_its_history_and_re_enters_at_zero():
    x = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
    tag = np.arange(3)
    box, periodic = np.zeros(3), np.zeros(3, dtype=bool)
    pl = new_pair_list(1.5, 3, 2, 1)
    # the serial fill as the generic list upkeep gives it (a bool would compile the builder again: 5 CPU s)
    fill = neighbours.filler(numba.typeof(pl), numba.typeof(box), numba.typeof(periodic))
    neighbours.rebuild(pl, x, tag, tag, box, periodic, np.zeros(0), fill)
    assert neighbours.pairs_of(pl, tag).tolist() == [[0, 1]]
    pl.history[0] = [3.0, -1.0]
    x[1, 0] = 0.5  # moves, still listed: history kept
    neighbours.rebuild(pl, x, tag, tag, box, periodic, np.zeros(0), fill)
    assert pl.history[0].tolist() == [3.0, -1.0]
    x[1, 0] = 4.0  # now 1.0 from particle 2 and 4.0 from particle 0: the pair (0, 1) left
    neighbours.rebuild(pl, x, tag, tag, box, periodic, np.zeros(0), fill)
    assert neighbours.pairs_of(pl, tag).tolist() == [[1, 2]] and not pl.history[0].any()
    x[1, 0] = 1.0  # back: the pair (0, 1) re-enters with zero history
    neighbours.rebuild(pl, x, tag, tag, box, periodic, np.zeros(0), fill)
    assert neighbours.pairs_of(pl, tag).tolist() == [[0, 1]] and not pl.history[0].any()


@njit
def smooth_contact_force(i, j, dx, dy, dz, r2, radius, stiffness):
    """F = k delta^2 along d (repulsive), U = k delta^3 / 3: smooth at the touch, unlike k delta."""
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0, 0.0, 0.0
    r = math.sqrt(r2)
    s = stiffness * (reach - r) ** 2 / r
    return s * dx, s * dy, s * dz


@njit
def smooth_contact_energy(i, j, dx, dy, dz, r2, radius, stiffness):
    reach = radius[i] + radius[j]
    if r2 >= reach * reach:
        return 0.0
    return stiffness * (reach - math.sqrt(r2)) ** 3 / 3.0


class SmoothContact(dk.PairInteraction):
    reads = ("radius",)
    energy_kind = "contact"
    parameters = ("stiffness",)
    force_function = smooth_contact_force
    energy_function = smooth_contact_energy

    def __init__(self, stiffness):
        self.stiffness = stiffness

    def cutoff(self, particles):
        return 2.0 * float(particles.radius.max())


def energy_error(dt, duration=1.0):
    """Energy error of a periodic dipolar gas with the switched (energy-conserving) cutoff and a
    contact smooth at the touch (a linear spring's kink makes every contact onset a first-order event)."""
    p, box = gas(n=250, phi=0.25, periodic=True, seed=8)
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0, switch_width=0.5), SmoothContact(2e4)], box=box)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=dt))
    traj = sim.run(duration=duration, record_every=0.05)
    total = traj.energy["total"]
    return np.abs(total - total[0]).max(), traj, scene


def test_periodic_box_conserves_momentum_and_energy_to_second_order():
    coarse, traj, scene = energy_error(2e-3)
    fine, _, _ = energy_error(1e-3)
    momentum = traj.linear_momentum()
    assert np.abs(momentum - momentum[0]).max() < 1e-11  # round-off over 500 steps
    kinetic = traj.energy["kinetic"][0]
    assert coarse < 1e-3 * kinetic  # bounded and small
    assert 3.4 < coarse / fine < 4.6  # second order: halving dt divides the error by ~4
    assert traj.image is not None and np.abs(traj.image).max() >= 1  # spheres crossed the box
    assert (traj.position >= 0).all() and (traj.position < scene.box.size).all()


def test_unwrapped_paths_are_continuous_across_periodic_boundaries():
    p, box = gas(n=200, periodic=True, dipoles=False, seed=9, speed=4.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=1e4)], box=box)  # stiff enough for these speeds
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3)).run(duration=2.0, record_every=0.01)
    jumps = np.abs(np.diff(traj.unwrapped(), axis=0)).max()
    assert np.abs(traj.image).max() >= 1 and jumps < 0.2  # speeds ~ 4-15: < 0.15 per frame
    assert np.abs(np.diff(traj.position, axis=0)).max() > 0.9 * box.size.min()  # wrapped ones jump


def thread_scene(p, box, parallel):
    """Dipoles cut at 3 and contacts with friction history, re-sorted every 40 steps: the kernels of
    restart_scenes.gas, so that the thread tests here and test_checkpoint's share one serial and one
    thread module (a thread module of its own cost ~40 CPU s to compile on a cold cache)."""
    inters = [dk.Dipole(prefactor=1.0, cutoff=3.0), dk.KelvinVoigt(2000.0, 3.0, friction=dk.Friction(0.4))]
    return dk.Scene(p.copy(), inters, box=box, parallel=parallel, sort_every=40)


def test_thread_count_changes_nothing_and_threads_agree_with_the_serial_loop():
    p, box = gas(n=300, periodic=True, seed=10)
    serial = thread_scene(p, box, parallel=False)
    threaded = thread_scene(p, box, parallel=True)
    # one serial module for any size and thread setting (nothing recompiles), loops on threads in
    # the thread module only
    assert serial.fused_source() == threaded.fused_source() and "prange(" not in serial.fused_source()
    assert "prange(" in threaded.fused_source(threads=True)
    f0, t0 = serial.forces()
    f1, t1 = threaded.forces()
    np.testing.assert_allclose(f1, f0, rtol=0, atol=1e-12 * np.abs(f0).max())
    np.testing.assert_allclose(t1, t0, rtol=0, atol=1e-12 * np.abs(t0).max())
    finals = []
    before = numba.get_num_threads()
    try:
        for threads in (1, numba.config.NUMBA_NUM_THREADS):
            numba.set_num_threads(threads)
            scene = thread_scene(p, box, parallel=True)
            dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3)).run(duration=0.3)
            finals.append(scene.particles.position.copy())
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(finals[0], finals[1])  # bit-identical whatever the thread count


def test_chunk_buffers_are_zero_after_every_force_evaluation_so_the_next_needs_no_clearing():
    """The chunked pair loops add chunks 1.. into buffers that must be zero on entry: sum_chunks
    zeroes them as it sums (no separate clearing pass). Stale buffers would add a chunk's forces
    twice in the next evaluation."""
    p, box = gas(n=300, periodic=True, seed=10)
    scene = thread_scene(p, box, parallel=True)
    assert scene.arrays["thread_force"].shape[0] >= 1  # at least two chunks
    f0, t0 = scene.forces()
    assert np.abs(f0).max() > 0 and np.abs(t0).max() > 0
    for kernels in (scene.kernels, scene.thread_kernels):  # the serial and the thread module
        n = len(f0)  # (forces_of is called from compiled code only: compute_forces runs the same loops)
        kernels.compute_forces(scene.state, np.zeros((n, 3)), np.zeros((n, 3)), False, True)
        assert not scene.arrays["thread_force"].any() and not scene.arrays["thread_torque"].any()
        f1, t1 = scene.forces()
        np.testing.assert_array_equal(f1, f0)
        np.testing.assert_array_equal(t1, t0)


def test_small_open_scenes_have_no_lists_no_threads_no_periodic_code():
    p = dk.Particles(position=[[0.0, 0, 0], [3.0, 0, 0]], radius=1.0, dipole=[[0, 0, 1.0], [0, 0, 1.0]])
    scene = dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(1.0)])
    src = scene.fused_source()
    assert [g.kind for g in scene.plan.groups] == ["all"]
    assert "maintain_lists" not in src and "prange(" not in src.split("def group_0_energies")[0]
    assert "lx = box" not in src and "image" not in scene.arrays or scene.arrays["image"].size == 0
    assert scene.particles.image is None and scene.history_values == 0
    open_big, _ = gas(n=100, periodic=False, dipoles=False)
    scene = dk.Scene(open_big, [dk.KelvinVoigt(100.0)])
    assert "lx = box" not in scene.fused_source() and scene.particles.image is None


def test_statistics_report_rebuilds_pairs_and_rates():
    p, box = gas(n=200, periodic=True, seed=11)
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0), dk.KelvinVoigt(stiffness=1000.0)], box=box)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
    sim.run(duration=0.5)
    st = sim.statistics
    assert st["steps"] == 500 and st["particle_steps_per_second"] > 0 and st["neighbour_list_builds"] >= 1
    cutoffs = sorted(entry["cutoff"] for entry in st["lists"])
    assert cutoffs == [1.0, 3.0] and all(entry["pairs"] <= entry["capacity"] for entry in st["lists"])


def test_a_sphere_crossing_more_than_the_skin_in_one_step_stops_the_run():
    p, box = gas(n=100, periodic=True, dipoles=False, seed=12)
    p.velocity[17] = [400.0, 0.0, 0.0]  # 0.4 per step at dt = 1e-3, skin 0.3
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=100.0)], box=box)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
    with pytest.raises(dk.SimulationError, match="moved more than the neighbour-list skin") as info:
        sim.run(duration=1.0, record_every=0.1)
    assert info.value.particle == 17 and info.value.step <= 2
    assert f"step {info.value.step}" in str(info.value)


def test_bad_boxes_skins_and_cutoffs_are_refused_before_stepping():
    p, box = gas(n=100, periodic=True, seed=13)
    with pytest.raises(ValueError, match="Box size"):
        dk.Box(size=(1.0, -2.0, 3.0))
    with pytest.raises(ValueError, match="Box size"):
        dk.Box(size=(1.0, math.nan, 3.0))
    with pytest.raises(ValueError, match="periodic"):
        dk.Box(size=5.0, periodic="yes")
    with pytest.raises(ValueError, match="not longer than twice the reach"):
        dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=0.6 * box.size[0])], box=box)
    with pytest.raises(ValueError, match="no cutoff"):
        dk.Scene(p, [dk.Dipole(prefactor=1.0)], box=box)
    with pytest.raises(ValueError, match="shorter than the contact reach"):
        dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=0.8)], box=box)
    for skin in (0.0, -0.1, math.inf):
        with pytest.raises(ValueError, match="skin"):
            dk.Scene(p, [dk.KelvinVoigt(10.0)], box=box, skin=skin)
    closed = dk.Box(box.size, periodic=False)
    q = p.copy()
    q.position[5] = [-1.0, 2.0, 2.0]
    with pytest.raises(ValueError, match="outside the box"):
        dk.Scene(q, [dk.KelvinVoigt(10.0)], box=closed)


@pytest.mark.parametrize("n", [2, 1200])  # shared arrays (no lists), and re-sorted copies
def test_replacing_a_particle_array_between_runs_takes_effect(n):
    p, box = gas(n=n, periodic=False, dipoles=False, seed=15) if n > 2 else (
        dk.Particles(position=[[0.0, 0, 0], [3.0, 0, 0]], radius=1.0), None)
    scene = dk.Scene(p, [dk.KelvinVoigt(10.0)])
    v = np.zeros((n, 3))
    v[0] = [1.0, 0.0, 0.0]
    x0 = p.position[0].copy()
    scene.particles.velocity = v  # a new array, not an in-place edit
    dk.Simulation(scene, dk.VelocityVerlet(0.001)).run(duration=0.05)
    assert scene.particles.position[0, 0] == pytest.approx(x0[0] + 0.05, abs=1e-3)
    scene.particles.velocity = np.zeros((n + 1, 3))
    with pytest.raises(ValueError, match="shape"):
        scene.forces()


def test_threads_chosen_chunk_by_chunk_give_the_bits_of_threads_and_of_one_thread(monkeypatch):
    """The serial and the thread module run the same fixed chunks: a run that switches between them
    at every compiled chunk (forced here) ends bit for bit where a run on threads and a run on one
    thread end; statistics say how many threads ran and why."""
    import demkit.scene as scene_module
    import demkit.simulation as simulation_module
    import demkit.engine.threads as threads
    p, box = gas(n=300, periodic=True, seed=10)
    before = numba.get_num_threads()

    def final(parallel, nthreads):
        numba.set_num_threads(nthreads)
        scene = thread_scene(p, box, parallel=parallel)
        sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
        sim.run(duration=0.3)
        return scene.particles.position.copy(), sim

    try:
        on_threads, sim = final(True, numba.config.NUMBA_NUM_THREADS)
        assert sim.statistics["threads_reason"] == "parallel=True"
        one_thread, sim = final(True, 1)
        assert sim.statistics["threads"] == 1 and "set_num_threads(1)" in sim.statistics["threads_reason"]
        monkeypatch.setattr(scene_module, "PARALLEL_MIN", 100)  # parallel=None: threads measured
        monkeypatch.setattr(scene_module, "THREADS_FROM_SECONDS", 0.0)
        monkeypatch.setattr(simulation_module, "CHUNK_SECONDS", 1e-4)  # many chunks
        monkeypatch.setattr(simulation_module, "CHUNK_OVERHEAD_RATIO", 0.0)
        monkeypatch.setattr(threads.ThreadChoice, "_worth", lambda self: 0.0)  # load the thread module at once
        monkeypatch.setattr(threads, "RECHECK_SECONDS", 0.0)  # every chunk a probe: switch all the time
        monkeypatch.setattr(threads, "MARGIN", math.inf)  # threads never kept
        switching, sim = final(None, numba.config.NUMBA_NUM_THREADS)
        sim._threads._compiling.join()
        sim.run(duration=0.1)  # now with the thread module ready
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(one_thread, on_threads)
    assert sim.statistics["threads"] == 1 and "measured" in sim.statistics["threads_reason"]
    assert set(sim.statistics["steps_per_second_by_threads"]) == {1, numba.config.NUMBA_NUM_THREADS}
    ref_sim = dk.Simulation(thread_scene(p, box, parallel=True), dk.VelocityVerlet(dt=1e-3))
    numba.set_num_threads(1)
    try:
        ref_sim.run(duration=0.4)
    finally:
        numba.set_num_threads(before)
    np.testing.assert_array_equal(sim.scene.particles.position, ref_sim.scene.particles.position)


def test_a_new_simulation_starts_on_the_choice_measured_for_its_kind_of_scene(monkeypatch):
    """Threads measured faster for a kind of scene (the same loops, spheres and threads): a new
    Simulation of a new scene of that kind starts on threads at once, the rates carried over, and
    still checks them again (here every chunk, and threads always lose: it goes back to one thread).
    A scene with another number of spheres starts from scratch."""
    import demkit.scene as scene_module
    import demkit.engine.threads as threads
    p, box = gas(n=300, periodic=True, seed=10)
    monkeypatch.setattr(scene_module, "PARALLEL_MIN", 100)
    monkeypatch.setattr(scene_module, "THREADS_FROM_SECONDS", 0.0)
    monkeypatch.setattr(threads.ThreadChoice, "_worth", lambda self: 0.0)
    monkeypatch.setattr(threads, "_CHOSEN", {})
    monkeypatch.setattr(dk.simulation, "CHUNK_SECONDS", 1e-4)  # many chunks
    monkeypatch.setattr(dk.simulation, "CHUNK_OVERHEAD_RATIO", 0.0)
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs two numba threads")
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        monkeypatch.setattr(threads, "MARGIN", 0.0)  # threads always win
        monkeypatch.setattr(threads, "RECHECK_SECONDS", 0.0)
        first = dk.Simulation(thread_scene(p, box, parallel=None), dk.VelocityVerlet(dt=1e-3))
        assert first._threads.threads == 1  # nothing known yet
        first.run(duration=0.05)
        first._threads._compiling.join()
        first.run(duration=0.05)  # the probe: threads chosen
        assert first.statistics["threads"] > 1
        monkeypatch.setattr(threads, "RECHECK_SECONDS", 60.0)
        again = dk.Simulation(thread_scene(p, box, parallel=None), dk.VelocityVerlet(dt=1e-3))
        assert again._threads.threads > 1 and "earlier run" in again._threads.reason
        assert again._threads.rates == threads._CHOSEN[first._threads._key][1]  # as last decided
        monkeypatch.setattr(threads, "RECHECK_SECONDS", 0.0)
        monkeypatch.setattr(threads, "MARGIN", math.inf)  # now threads always lose their check
        again = dk.Simulation(thread_scene(p, box, parallel=None), dk.VelocityVerlet(dt=1e-3))
        again.run(duration=0.1)
        assert again.statistics["threads"] == 1 and "measured" in again.statistics["threads_reason"]
        q, qbox = gas(n=301, periodic=True, seed=10)
        other = dk.Simulation(thread_scene(q, qbox, parallel=None), dk.VelocityVerlet(dt=1e-3))
        assert other._threads.threads == 1 and other._threads.thread_loop is None
    finally:
        numba.set_num_threads(before)


def test_threads_outlast_a_slow_chunk_but_not_a_collapse_or_a_slow_spell():
    """On threads, an ordinary chunk is compared with a one-thread rate measured seconds before;
    chunks differ by the list rebuilds they hold, so threads are left at once only below LEAVE of
    that rate (a busy core making them far slower), or once SPELL_CHUNKS chunks on threads ran no
    faster than one thread on average (a busy core beside a long step: ~0.9x); a probe must win by MARGIN."""
    from demkit.engine import threads

    def on_threads():
        choice = threads.ThreadChoice.__new__(threads.ThreadChoice)  # the decision alone, no scene
        choice.fixed, choice.max_threads, choice.threads, choice.probing = None, 2, 2, False
        choice.rates, choice.reason = {1: 140.0, 2: 180.0}, "2 threads measured 1.29x as fast as one"
        choice.recheck, choice.next_check, choice._spell = threads.RECHECK_SECONDS, 0.0, [0, 0.0, 0]
        choice._key = None  # remembered for no kind of scene
        return choice

    choice = on_threads()
    for rate in (120.0, 190.0, 185.0, 125.0, 180.0):  # one slow chunk now and then: noise, stay
        choice.measured(33, 33 / rate)
        assert choice.threads == 2 and "1.29x" in choice.reason
    choice.measured(33, 33 / 70.0)  # 0.5x: the other core is busy, leave at once
    assert choice.threads == 1 and "0.50x" in choice.reason
    choice = on_threads()
    for k in range(threads.SPELL_CHUNKS):  # each chunk 0.9x: none below LEAVE, their mean no faster
        assert choice.threads == 2
        choice.measured(33, 33 / 126.0)
    assert choice.threads == 1 and "0.90x" in choice.reason
    choice.threads, choice.probing = 2, True  # a probe on threads must win by MARGIN
    choice.measured(8, 8 / 143.0)
    assert choice.threads == 1
    choice.threads, choice.probing = 2, True
    choice.measured(8, 8 / 150.0)
    assert choice.threads == 2 and "1.07x" in choice.reason


def test_only_scenes_with_enough_work_per_step_are_cut_into_chunks_for_threads():
    """parallel=None: chunks (and threads) only where a force evaluation is estimated at 0.5 ms or
    more; the estimate follows the pairs (a longer dipole cutoff, more pairs, more time). Contact-only
    gases at volume fraction 0.2: 8000 spheres (0.2-0.3 ms a step, 1.1-1.5x as fast on two threads)
    qualify, 4000 (0.13 ms, 0.66x) do not."""
    from demkit.engine.threads import THREADS_FROM_SECONDS
    assert THREADS_FROM_SECONDS == 0.5e-3
    p, box = gas(n=2000, periodic=True, seed=3, dipoles=True)
    contacts = dk.Scene(p.copy(), [dk.KelvinVoigt(stiffness=1000.0, damping=1.0)], box=box)
    dipoles = dk.Scene(p.copy(), [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(1000.0, 1.0)], box=box)
    assert contacts.force_seconds < 0.5e-3 < dipoles.force_seconds
    for n, eligible in ((4000, False), (8000, True)):
        q, qbox = gas(n=n, periodic=True, seed=4, dipoles=False)
        assert dk.Scene(q, [dk.KelvinVoigt(stiffness=1000.0, damping=1.0)], box=qbox).parallel == eligible
    assert contacts.chunks == 1 and not contacts.parallel
    assert dipoles.chunks == numba.config.NUMBA_NUM_THREADS and dipoles.parallel == (dipoles.chunks > 1)
    pairs = dipoles.force_seconds - contacts.force_seconds  # the dipole list's pairs, about 1/2 rho 4/3 pi (4 + skin)^3
    rho = 2000 / box.volume
    assert pairs / (2000 * 0.5 * rho * 4 / 3 * math.pi * (4.0 + dipoles.skin) ** 3 * 1.2e-8) == pytest.approx(1, rel=0.05)
    from demkit.engine.threads import ThreadChoice
    assert "estimated" in ThreadChoice(contacts, "velocity_verlet").describe()


def test_chunks_last_twenty_times_the_copying_and_checking_between_them():
    """A compiled chunk lasts CHUNK_SECONDS, or 20x what the last return to Python spent copying the
    arrays back and checking them when that is longer (a million spheres: ~0.1 s a return), and
    grows at most 4x from one chunk to the next."""
    p = dk.Particles(position=[[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]], radius=0.5, mass=1.0)
    sim = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(stiffness=1000.0, damping=1.0)]), dk.VelocityVerlet(dt=1e-3))
    assert sim._next_chunk(1000, 1.0, 1000) == int(1000 * dk.simulation.CHUNK_SECONDS)  # 1000 steps a second
    sim._rate = None
    assert sim._next_chunk(1000, 1.0, 1000, between=0.1) == 2000  # 2 s of steps, not 0.2 s
    sim._rate = None
    assert sim._next_chunk(100, 0.1, 100, between=0.1) == 400  # at most 4x the last chunk


def test_a_tier_switch_that_brings_a_thread_module_before_any_probe_gets_it_probed():
    """Tier 2 handed in with its thread module while the run had not probed threads yet (no check
    scheduled): the next chunk probes them; before, it compared the clock with None and stopped the run
    (the N = 8000 reference scene on two cores, TypeError)."""
    from demkit.engine import threads

    class Module:
        velocity_verlet_steps = "serial loop"

    class Threaded:
        velocity_verlet_steps = "thread loop"

    choice = threads.ThreadChoice.__new__(threads.ThreadChoice)  # the decision alone, no scene
    choice.fixed, choice.max_threads, choice.threads, choice.probing = None, 2, 1, False
    choice.name, choice.scene, choice.thread_loop, choice._compiling = "velocity_verlet_steps", None, None, None
    choice.rates, choice.recheck, choice.next_check = {1: 500.0, 2: None}, threads.RECHECK_SECONDS, None
    choice._warm, choice._after_probe, choice._spell, choice._key = True, False, [0, 0.0, 0], None
    choice.use_modules(Module(), Threaded())
    loop, steps = choice.loop(100, 10_000)
    assert loop == "thread loop" and choice.probing and steps < 100  # a short probe on threads
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


def test_a_tier_2_scene_with_its_thread_pieces_cached_loads_them_at_once(monkeypatch):
    """With neighbour lists, tier 2 is the scene's own pieces: a new run looks for their thread module
    in numba's cache (not for a fused module, which such a scene never compiles) and loads it when half a
    second of run is left, as it does a cached fused module. Until 1 Dec 2026 it always waited for
    WORTH_COMPILING (5 s) of run: the N = 8000 reference scene's 5-s runs stayed on one thread (17 M
    particle-steps/s against 27 M on two)."""
    import demkit.engine.generic_modules as generic_modules
    import demkit.engine.modules as modules
    import demkit.engine.threads as threads
    import demkit.scene as scene_module
    p, box = gas(n=300, periodic=True, seed=12)
    monkeypatch.setattr(scene_module, "PARALLEL_MIN", 100)
    monkeypatch.setattr(scene_module, "THREADS_FROM_SECONDS", 0.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0)], box=box, tier=2, parallel=None)
    assert scene._pieces_tier_2()
    pieces = modules.pieces_source(scene.plan, scene.program_columns, threads=True)[1]
    asked = []

    def cached(module, function, answer):
        asked.append((module, function))
        return answer

    monkeypatch.setattr(generic_modules, "is_cached", lambda threads, function: True)
    for answer, worth in ((True, 0.5), (False, threads.WORTH_COMPILING)):
        asked.clear()
        monkeypatch.setattr(modules, "cached_function", lambda m, f, answer=answer: cached(m, f, answer))
        choice = threads.ThreadChoice(scene, "velocity_verlet")
        assert choice._worth() == worth
        assert (pieces, "piece_pairs_forces") in asked


def test_the_fill_given_to_the_list_builder_has_the_types_the_builder_passes_it():
    """The list upkeep gives the builder its fill as a first-class function (neighbours.filler), typed by
    neighbours.fill_signature: those must be the types start_build's arrays have (else every rebuild would
    fail to compile), and the lists built through it, serial and on threads, are scipy's pairs."""
    rng = np.random.default_rng(5)
    n, side = 400, 9.0
    position = rng.uniform(0.0, side, (n, 3))
    box, periodic, le = np.full(3, side), np.array([True, True, False]), np.zeros(0)
    tag = np.arange(n, dtype=np.int64)
    arguments = tuple(numba.typeof(a) for a in (new_pair_list(1.2, n, 0, 2), position, tag, box, periodic, le))
    neighbours.start_build.compile(arguments)
    work = neighbours.start_build.overloads[arguments].signature.return_type.types
    expected = (*work[:3], arguments[3], arguments[4], numba.types.float64, *work[3:9])
    pl_fields = dict(arguments[0].field_dict)
    expected += (pl_fields["start"], pl_fields["end"], pl_fields["partner"], *work[9:], arguments[5])
    assert neighbours.fill_signature(arguments[0], arguments[3], arguments[4]) == expected
    lists = []
    for threads in (False, True):
        pl = new_pair_list(1.2, n, 0, 2)
        neighbours.rebuild(pl, position, tag, tag, box, periodic, le, neighbours.filler(
            arguments[0], arguments[3], arguments[4], threads))
        lists.append({(min(i, j), max(i, j)) for i, j in neighbours.pairs_of(pl, tag).tolist()})
    assert lists[0] == lists[1] == pairs_within(position, 1.2, dk.Box((side,) * 3, periodic=(True, True, False)))
