"""Checkpoints and exact restart: a run stopped and resumed any number of times gives bit for bit
what the uninterrupted run gives (the truth here is the uninterrupted run itself: equality, not a
tolerance), for every integrator, with friction history, periodic images, re-sorting, walls, and
1 or 2 threads; bad checkpoint files are refused before anything changes."""
import os
import signal
import threading
import time
import zipfile

import numba
import numpy as np
import pytest

import demkit as dk
from demkit import checkpoint as ckpt_module
from restart_scenes import assert_identical, gas, state_of

DT = 2e-3

INTEGRATORS = [
    pytest.param(lambda: dk.VelocityVerlet(DT), True, id="VelocityVerlet+friction"),
    pytest.param(lambda: dk.EulerCromer(DT), True, id="EulerCromer+friction"),
    pytest.param(lambda: dk.MultipleTimeStep(2 * DT, inner=2), True, id="MultipleTimeStep+friction"),
    pytest.param(lambda: dk.ForestRuth(DT), False, id="ForestRuth"),
    pytest.param(lambda: dk.RK4(DT), False, id="RK4"),
    pytest.param(lambda: dk.VelocityVerlet(DT, resolve_contacts=True), False, id="VelocityVerlet-resolved"),
]


def uninterrupted(make_integrator, friction, until, **scene_options):
    scene = gas(friction=friction, **scene_options)
    sim = dk.Simulation(scene, make_integrator())
    traj = sim.run(until=until, record_every=until / 4)
    return state_of(scene), traj


def in_pieces(make_integrator, friction, ends, path, **scene_options):
    """A run from 0 to ends[-1], stopped at every end and resumed in a new scene and simulation."""
    last = None
    for k, end in enumerate(ends):
        scene = gas(friction=friction, **scene_options)
        sim = dk.Simulation(scene, make_integrator(), checkpoint=dk.Checkpoint(path))
        if k:
            sim.resume()
            assert sim.time == pytest.approx(ends[k - 1], abs=1e-12)
        last = sim.run(until=end, record_every=ends[-1] / 4) if k == len(ends) - 1 else sim.run(until=end)
    return state_of(scene), last


@pytest.mark.parametrize("make_integrator, friction", INTEGRATORS)
def test_stopped_and_resumed_runs_are_bit_identical_to_an_uninterrupted_one(tmp_path, make_integrator, friction):
    until = 0.4
    truth, traj = uninterrupted(make_integrator, friction, until)
    state, last = in_pieces(make_integrator, friction, [0.064, 0.132, 0.312, until], tmp_path / "run.ckpt")
    assert truth["image"].any(), "spheres crossed the box faces"
    if friction:
        assert any(np.any(v[1]) for k, v in truth.items() if k.startswith("history")), "contacts kept history"
    assert_identical(state, truth)
    # the frames the resumed run recorded are the uninterrupted run's frames at those times
    assert last.time[-1] == traj.time[-1]
    assert np.array_equal(last.position[-1], traj.position[-1])
    assert np.array_equal(last.energy["total"][-1], traj.energy["total"][-1])



@pytest.mark.parametrize("make_sum", [lambda: dk.Ewald(1e-4), lambda: dk.P3M(1e-3)], ids=["Ewald", "P3M"])
def test_runs_with_a_long_range_sum_restart_bit_identical(tmp_path, make_sum):
    """The frictional gas with its dipoles summed over every image (Ewald, P3M; the real-space cutoff
    the gas's 3.0), stopped and resumed twice: the bits of the uninterrupted run. The sum's tuning is
    made when each scene is built, from the same starting spheres; the re-sorting every 40 steps
    puts the spheres in another internal order, which a resumed run must take up where it stopped."""
    make = lambda: dk.VelocityVerlet(DT)  # noqa: E731
    until = 0.2
    truth, traj = uninterrupted(make, True, until, long_range=make_sum())
    state, last = in_pieces(make, True, [0.064, 0.132, until], tmp_path / "long.ckpt", long_range=make_sum())
    assert truth["image"].any(), "spheres crossed the box faces"
    assert any(np.any(v[1]) for k, v in truth.items() if k.startswith("history")), "contacts kept history"
    assert_identical(state, truth)
    assert np.array_equal(last.energy["magnetic"][-1], traj.energy["magnetic"][-1])
    # the sum changed the run: the cut-off dipoles' run is another
    cut, _ = uninterrupted(make, True, until)
    assert not np.array_equal(cut["position"], truth["position"])

def test_restart_is_exact_with_walls_gravity_and_sphere_history(tmp_path):
    make = lambda: dk.VelocityVerlet(DT)  # noqa: E731
    truth, _ = uninterrupted(make, True, 0.3, walls=True)
    state, _ = in_pieces(make, True, [0.1, 0.3], tmp_path / "walls.ckpt", walls=True)
    assert_identical(state, truth)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs numba with at least 2 threads")
def test_two_threads_are_deterministic_equal_to_one_thread_and_restart_exactly(tmp_path):
    make = lambda: dk.VelocityVerlet(DT)  # noqa: E731
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(2)
        first, _ = uninterrupted(make, True, 0.2, parallel=True)
        second, _ = uninterrupted(make, True, 0.2, parallel=True)
        pieces, _ = in_pieces(make, True, [0.07, 0.2], tmp_path / "threads.ckpt", parallel=True)
        numba.set_num_threads(1)
        single, _ = uninterrupted(make, True, 0.2, parallel=True)
    finally:
        numba.set_num_threads(before)
    assert_identical(second, first)  # run to run
    assert_identical(pieces, first)  # restart
    assert_identical(single, first)  # fixed chunks: the thread count does not change the result


def test_continuing_runs_of_one_simulation_equal_one_long_run():
    scene = gas()
    sim = dk.Simulation(scene, dk.VelocityVerlet(DT))
    for end in (0.05, 0.1, 0.2):
        sim.run(until=end)
    truth, _ = uninterrupted(lambda: dk.VelocityVerlet(DT), True, 0.2)
    assert_identical(state_of(scene), truth)


def test_checkpoint_file_is_plain_npz_without_pickles_and_saved_at_the_interval(tmp_path):
    path = tmp_path / "c.ckpt"
    scene = gas()
    checkpoint = dk.Checkpoint(path, every=0.02)
    dk.Simulation(scene, dk.VelocityVerlet(DT), checkpoint=checkpoint).run(until=0.1)
    assert checkpoint.saves == 1 + 5  # at the start (before any output) and every 0.02, the last at the end
    with np.load(path, allow_pickle=False) as data:
        assert all(data[name].dtype != object for name in data.files)
    assert not list(tmp_path.glob("*.tmp"))
    meta, _ = ckpt_module.load(path)
    assert meta["step"] == 50 and meta["time"] == pytest.approx(0.1)


# ---- bad checkpoints: a clear error, nothing changed ------------------------------------------------
def _saved(tmp_path, **options):
    path = tmp_path / "good.ckpt"
    scene = gas(**options)
    dk.Simulation(scene, dk.VelocityVerlet(DT), checkpoint=dk.Checkpoint(path)).run(until=0.02)
    return path


def _refused(path, scene, match, integrator=None):
    sim = dk.Simulation(scene, integrator or dk.VelocityVerlet(DT))
    before = scene.digest(), scene.particles.position.copy()
    size = path.stat().st_size if path.exists() else None
    content = path.read_bytes() if path.exists() else None
    with pytest.raises(ValueError, match=match):
        sim.resume(path)
    assert scene.digest() == before[0] and np.array_equal(scene.particles.position, before[1])
    assert sim.step == 0
    if content is not None:
        assert path.stat().st_size == size and path.read_bytes() == content


def test_a_checkpoint_of_another_scene_integrator_or_version_is_refused(tmp_path, monkeypatch):
    path = _saved(tmp_path)
    other = gas()
    other_radius = gas(n=121)
    _refused(path, other_radius, "121 particles|another scene")
    p = other.particles
    changed = dk.Scene(dk.Particles(p.position, p.velocity, radius=0.5, mass=2.0, dipole=p.dipole,
                                    angular_velocity=p.angular_velocity),
                       list(other.interactions), box=other.box, sort_every=40)
    _refused(path, changed, "another scene")
    _refused(path, gas(), "same integrator", integrator=dk.VelocityVerlet(2 * DT))
    monkeypatch.setattr(dk.version, "__version__", "9.9.9")  # (what checkpoints record)
    _refused(path, gas(), "demkit 9.9.9")


def test_truncated_corrupted_pickled_and_missing_checkpoints_are_refused(tmp_path):
    path = _saved(tmp_path)
    data = path.read_bytes()
    truncated = tmp_path / "truncated.ckpt"
    truncated.write_bytes(data[: len(data) // 2])
    _refused(truncated, gas(), "truncated or corrupted")
    corrupted = tmp_path / "corrupted.ckpt"
    flipped = bytearray(data)
    middle = len(flipped) // 2
    flipped[middle: middle + 64] = bytes(255 - b for b in flipped[middle: middle + 64])
    corrupted.write_bytes(bytes(flipped))
    _refused(corrupted, gas(), "truncated or corrupted|not a readable")
    pickled = tmp_path / "pickled.ckpt"
    with np.load(path) as good:
        arrays = {name: good[name] for name in good.files}
    arrays["payload"] = np.array([{"os": "system"}], dtype=object)
    with open(pickled, "wb") as fh:
        np.savez(fh, **arrays)
    _refused(pickled, gas(), "pickled objects")
    _refused(tmp_path / "absent.ckpt", gas(), "no checkpoint file")
    zipped = tmp_path / "foreign.ckpt"
    with zipfile.ZipFile(zipped, "w") as z:
        z.writestr("readme.txt", "not numpy")
    _refused(zipped, gas(), "not a demkit checkpoint|not a readable|truncated or corrupted")


def test_checkpoint_arguments_are_checked(tmp_path):
    for bad in (0, -1.0, float("nan"), "10", True):
        with pytest.raises((TypeError, ValueError), match="every"):
            dk.Checkpoint(tmp_path / "x.ckpt", every=bad)
    with pytest.raises(ValueError, match="does not exist"):
        dk.Checkpoint(tmp_path / "missing" / "x.ckpt")
    with pytest.raises(TypeError, match="Checkpoint"):
        dk.Simulation(gas(), dk.VelocityVerlet(DT), checkpoint=str(tmp_path / "x.ckpt"))
    with pytest.raises(ValueError, match="needs a path"):
        dk.Simulation(gas(), dk.VelocityVerlet(DT)).resume()


# ---- Ctrl-C -----------------------------------------------------------------------------------------
def _two_spheres():
    p = dk.Particles([[0.0, 0, 0], [3.0, 0, 0]], velocity=[[0, 0.1, 0], [0, -0.1, 0]], radius=0.5,
                     dipole=[[1.0, 0, 0], [1.0, 0, 0]])
    return dk.Scene(p, [dk.Dipole(prefactor=0.05), dk.KelvinVoigt(5000.0, 1.0)])


def _interrupt_after(seconds):
    timer = threading.Timer(seconds, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    return timer


def test_ctrl_c_ends_a_run_cleanly_keeping_frames_state_and_a_checkpoint(tmp_path):
    scene = _two_spheres()
    path = tmp_path / "sigint.ckpt"
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4), checkpoint=dk.Checkpoint(path))
    sim.run(1e-3)  # compile first
    until = 1e-3 + 1e-4 * 6e8  # far more than the second this test waits
    timer = _interrupt_after(0.5)
    began = time.perf_counter()
    with pytest.raises(KeyboardInterrupt, match="interrupted at step"):
        sim.run(until - sim.time, record_every=1.0)
    waited = time.perf_counter() - began
    timer.join()
    assert waited < 0.5 + 1.0  # honoured within a chunk (~0.2 s), not at the end of the run
    traj = sim.trajectory
    assert sim.time > 1e-3 and traj.time[-1] == sim.time and len(traj) >= 2
    assert sim.statistics["steps"] == sim.step - 10 and sim.statistics["threads"] == 1  # the interrupted run's
    assert np.array_equal(traj.position[-1], scene.particles.position)
    assert np.all(np.diff(traj.time) > 0)
    meta, _ = ckpt_module.load(path)
    assert meta["step"] == sim.step
    kept = tmp_path / "at-interrupt.ckpt"
    kept.write_bytes(path.read_bytes())
    # the interrupted run goes on, in this simulation and from the checkpoint in a new scene, exactly
    stop = sim.step + 20000
    sim.run(until=stop * 1e-4)
    scene2 = _two_spheres()
    sim2 = dk.Simulation(scene2, dk.VelocityVerlet(1e-4)).resume(kept)
    sim2.run(until=stop * 1e-4)
    assert np.array_equal(scene2.particles.position, scene.particles.position)
    assert np.array_equal(scene2.particles.angular_velocity, scene.particles.angular_velocity)


def test_ctrl_c_while_the_end_frame_is_written_finishes_the_run_then_stops_it(tmp_path):
    """A Ctrl-C after the run's last chunk, while its writers write the end frame (compiled calls:
    the frame's forces), is caught like one during the chunks: the end's work is done (the frame
    written, the trajectory kept, the checkpoint saved) and the run then stops with a
    KeyboardInterrupt that says so. (Found in CI: a Ctrl-C that landed there was raised inside numba's
    call machinery and came out of `demkit run` as a TypeError; it was outside the catcher.)"""
    import signal

    class InterruptingWriter:
        every = 1e-3  # not a divisor of the run below: the end frame is written after the last chunk

        def __init__(self):
            self.forces = []

        def open(self, simulation):
            pass

        def close(self):
            pass

        def write(self, simulation):
            if simulation.step == 25:  # the end frame
                os.kill(os.getpid(), signal.SIGINT)
            self.forces.append(simulation.scene.forces()[0].copy())  # a compiled call after the signal

    path = tmp_path / "end.ckpt"
    writer = InterruptingWriter()
    sim = dk.Simulation(_two_spheres(), dk.VelocityVerlet(1e-4), writers=[writer], checkpoint=dk.Checkpoint(path))
    with pytest.raises(KeyboardInterrupt, match="interrupted at its end"):
        sim.run(2.5e-3, record_every=1e-3)
    assert sim.step == 25 and len(writer.forces) == 4 and np.isfinite(writer.forces[-1]).all()  # steps 0, 10, 20, 25
    assert np.allclose(sim.trajectory.time, [0.0, 1e-3, 2e-3, 2.5e-3])
    meta, _ = ckpt_module.load(path)
    assert meta["step"] == 25


def test_a_kill_before_the_end_frame_leaves_a_checkpoint_from_which_the_rerun_writes_it(tmp_path, monkeypatch):
    """A run ending between two frames writes an end frame after its last chunk. A checkpoint due at
    that last step is saved after the end frame, so a kill in between leaves an earlier checkpoint:
    the rerun of the same command redoes the last steps and writes the end frame (before, it found
    a checkpoint at the end time, refused run(until=end) and the end frame was never written)."""
    from demkit.io import read_pvd
    path, out = tmp_path / "c.ckpt", tmp_path / "out"

    def simulation():
        checkpoint = dk.Checkpoint(path, every=1e-4)  # due at every step, the run's last one included
        writer = dk.VTKWriter(out, every=4e-4, resume=checkpoint.exists())
        return dk.Simulation(_two_spheres(), dk.VelocityVerlet(1e-4), writers=[writer], checkpoint=checkpoint)

    def killed(*args):
        raise RuntimeError("killed")

    sim = simulation()
    monkeypatch.setattr(sim, "_write_end", killed)
    with pytest.raises(RuntimeError, match="killed"):
        sim.run(until=10e-4)  # frames at steps 0, 4, 8, then the end frame at step 10
    assert ckpt_module.load(path)[0]["step"] < 10
    again = simulation()
    again.resume()
    again.run(until=10e-4)
    again.close()
    times = [t for t, _ in read_pvd(out / "particles.pvd")] if (out / "particles.pvd").exists() else None
    assert times == pytest.approx([0.0, 4e-4, 8e-4, 10e-4])
    assert ckpt_module.load(path)[0]["step"] == 10


def test_run_arguments_are_checked():
    sim = dk.Simulation(_two_spheres(), dk.VelocityVerlet(1e-4))
    for bad in ("10", True, None):
        with pytest.raises((TypeError, ValueError), match="number|duration"):
            sim.run(bad)
    with pytest.raises(ValueError, match="not both"):
        sim.run(1.0, until=2.0)
    with pytest.raises(ValueError, match="not after"):
        sim.run(until=0.0)
    with pytest.raises(ValueError, match="GiB"):
        sim.run(1e-4 * 2e11, record_every=1e-4)  # 2e11 frames: terabytes, refused before anything
    with pytest.raises(TypeError, match="instance"):
        dk.Simulation(_two_spheres(), dk.VelocityVerlet)
    assert "Simulation(" in repr(sim) and "VelocityVerlet" in repr(sim)


def test_a_full_disk_warns_keeps_the_previous_checkpoint_and_the_run_goes_on(tmp_path, monkeypatch):
    path = tmp_path / "disk.ckpt"
    scene = _two_spheres()
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4), checkpoint=dk.Checkpoint(path, every=1e-3))
    sim.run(2e-3)
    before = path.read_bytes()

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(ckpt_module.np, "savez", full)
    with pytest.warns(dk.CheckpointWarning, match="No space left"):
        sim.run(5e-3)
    assert sim.step == 70 and path.read_bytes() == before
    assert not list(tmp_path.glob("*.tmp"))


def test_a_run_announces_a_large_output_before_it_starts(tmp_path, monkeypatch):
    import demkit.recording as simulation  # (where the run counts what it will write)
    monkeypatch.setattr(simulation, "LARGE_OUTPUT_FILES", 10)
    writer = dk.VTKWriter(tmp_path / "out", every=1e-4, trails=False)
    sim = dk.Simulation(_two_spheres(), dk.VelocityVerlet(1e-4), writers=[writer])
    with pytest.warns(dk.LargeOutputWarning, match="about 2[0-9] files"):
        sim.run(2e-3)


def test_the_checkpoint_script_run_again_after_it_finished_runs_nothing_and_changes_nothing(tmp_path, capfd):
    """docs/restart.md's pattern (resume when a checkpoint exists, then run(until=T)) run a second
    time after it finished: no ValueError, no step, no file touched; the one frame is the end state."""
    path, out = tmp_path / "run.ckpt", tmp_path / "out"

    def script():
        checkpoint = dk.Checkpoint(path, every=2e-3)
        writer = dk.VTKWriter(out, every=1e-3, resume=checkpoint.exists())
        sim = dk.Simulation(_two_spheres(), dk.VelocityVerlet(1e-4), writers=[writer], checkpoint=checkpoint)
        if checkpoint.exists():
            sim.resume()
        traj = sim.run(until=5e-3, record_every=1e-3)
        sim.close()
        return sim, traj

    _, first = script()
    files = {f.name: f.read_bytes() for f in sorted(out.iterdir())}
    saved = path.read_bytes()
    capfd.readouterr()
    sim, again = script()
    assert "already reached" in capfd.readouterr().err
    assert sim.step == 50 and sim.statistics["steps"] == 0
    assert len(again) == 1 and again.time[0] == pytest.approx(5e-3)
    assert np.array_equal(again.position[0], first.position[-1])
    assert np.array_equal(again.energy["total"], first.energy["total"][-1:])
    assert {f.name: f.read_bytes() for f in sorted(out.iterdir())} == files and path.read_bytes() == saved
    with pytest.raises(ValueError, match="not after"):  # before the end: still refused
        sim.run(until=4e-3)


def test_the_notes_of_a_resumed_run_cover_the_whole_run(tmp_path):
    """The end-of-run figures (largest overlap, energy drift) of a run stopped and resumed in a new
    simulation are those of the uninterrupted run: the checkpoint keeps the figures of the frames before
    it. (Every recorded frame is read here: at most one frame per 1000 steps, the notes' sampling
    limit, the resume on a frame of the record)."""
    dt, until, middle = 1e-3, 8.0, 4.0
    figures, trajectories = [], []
    for ends in ([until], [middle, until]):
        path = tmp_path / f"notes{len(ends)}.ckpt"
        for k, end in enumerate(ends):
            sim = dk.Simulation(gas(friction=True), dk.VelocityVerlet(dt), checkpoint=dk.Checkpoint(path),
                                notes=False)
            if k:
                sim.resume()
            last = sim.run(until=end, record_every=2.0)
        figures.append({key: sim.statistics[key] for key in ("overlap_largest", "overlap_typical", "energy_drift")})
        trajectories.append(last)
    whole, resumed = figures
    assert whole["overlap_largest"] > 0.01 and whole["energy_drift"] > 0
    assert resumed["overlap_largest"] == whole["overlap_largest"] and resumed["energy_drift"] == whole["energy_drift"]
    # the typical overlap averages the frames' means (the frame at the resume is read twice)
    assert resumed["overlap_typical"] == pytest.approx(whole["overlap_typical"], rel=0.2)
    # the part after the resume alone (what the notes covered before) drifts otherwise
    drifts = []
    for trajectory in trajectories:
        total = trajectory.energy["total"]
        drifts.append(np.max(np.abs(total - total[0])))
    assert abs(drifts[1] / drifts[0] - 1.0) > 0.01
