"""kill -9 at random moments: a run writing a VTK series and checkpoints is killed 20 times (while
stepping, writing a frame or a checkpoint, resuming: wherever the signal lands), and after every
kill the series is readable and the checkpoint loads; resumed each time, the run ends in exactly
the state of an uninterrupted run (bit for bit) and its series holds every frame once."""
import os
import random
import signal
import time

import numpy as np

import demkit as dk
from demkit import checkpoint as ckpt_module
from restart_scenes import gas

N, DT, UNTIL, FRAME_EVERY = 120, 2e-3, 36.0, 0.4  # the 20 kills reach about step 5400 of 18000

def _child_run(tmp_path, ready, until=UNTIL):
    """The run, as a user's script would do it: resume when there is a checkpoint, else start."""
    scene = gas(n=N)
    checkpoint = dk.Checkpoint(tmp_path / "run.ckpt", every=2.0, seconds=0.05)
    resuming = checkpoint.exists()
    writer = dk.VTKWriter(tmp_path / "series", every=FRAME_EVERY, trails=False, resume=resuming)
    sim = dk.Simulation(scene, dk.VelocityVerlet(DT), writers=[writer], checkpoint=checkpoint)
    if resuming:
        sim.resume()
    os.write(ready, b"r")
    sim.run(until=until)
    sim.close()
    np.save(tmp_path / "final.npy", scene.particles.position)


def _fork(tmp_path, until=UNTIL):
    """A child process running the script (forked: this process has compiled the kernels already,
    so the child starts at once); returns its pid once it is about to run."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        code = 0
        try:
            os.close(read)
            _child_run(tmp_path, write, until)
        except BaseException:  # noqa: BLE001 (report anything, never return into pytest)
            import traceback
            traceback.print_exc()
            code = 1
        os._exit(code)
    os.close(write)
    assert os.read(read, 1) == b"r", "the child failed before running"
    os.close(read)
    return pid


def _check_after_kill(tmp_path):
    pvd = tmp_path / "series" / "particles.pvd"
    if pvd.exists():
        series = dk.read_series(pvd)  # every listed frame readable
        assert np.all(np.diff(series.time) > 0)
        assert np.allclose(np.diff(series.time), FRAME_EVERY)
    if (tmp_path / "run.ckpt").exists():
        meta, _ = ckpt_module.load(tmp_path / "run.ckpt")
        return meta["step"]
    return 0


def test_sigkill_at_random_moments_loses_nothing_and_resumes_exactly(tmp_path):
    scene = gas(n=N)  # the truth: the same run, never interrupted (and the kernels compiled here)
    dk.Simulation(scene, dk.VelocityVerlet(DT)).run(until=UNTIL)
    rng = random.Random(2026)
    steps = []
    for _ in range(20):
        pid = _fork(tmp_path)
        time.sleep(rng.uniform(0.0, 0.2))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        steps.append(_check_after_kill(tmp_path))
    assert steps[-1] > steps[0], f"the run made progress across kills: {steps}"
    assert steps[-1] < round(UNTIL / DT), "the kills landed before the end"
    pid = _fork(tmp_path)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert np.array_equal(np.load(tmp_path / "final.npy"), scene.particles.position)
    series = dk.read_series(tmp_path / "series" / "particles.pvd")
    assert np.allclose(series.time, np.arange(len(series.time)) * FRAME_EVERY)
    assert series.time[-1] == UNTIL
    assert np.allclose(series.position[-1], scene.particles.position[np.argsort(scene.particles.ids)])
    assert not list((tmp_path / "series").glob("*.tmp"))


def test_a_checkpoint_between_two_frames_adds_no_frame_to_the_resumed_series(tmp_path, monkeypatch):
    """One-step chunks (as on a loaded machine) put the time-based checkpoints between frames: a run
    resumed from one continues the series on its grid, with no frame at the checkpoint's time."""
    from demkit import simulation
    monkeypatch.setattr(simulation, "CHUNK_SECONDS", 1e-9)
    monkeypatch.setattr(simulation, "CHUNK_OVERHEAD_RATIO", 0.0)
    until = 20 * FRAME_EVERY  # 4000 one-step chunks: the four kills reach about step 1500
    scene = gas(n=N)
    dk.Simulation(scene, dk.VelocityVerlet(DT)).run(until=until)  # the truth
    rng = random.Random(7)
    resumed_from = []
    for _ in range(4):
        pid = _fork(tmp_path, until)
        time.sleep(rng.uniform(0.1, 0.3))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        resumed_from.append(_check_after_kill(tmp_path))
    assert any(step % round(FRAME_EVERY / DT) for step in resumed_from), resumed_from  # some between frames
    pid = _fork(tmp_path, until)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert np.array_equal(np.load(tmp_path / "final.npy"), scene.particles.position)
    series = dk.read_series(tmp_path / "series" / "particles.pvd")
    assert np.allclose(series.time, np.arange(21) * FRAME_EVERY), series.time


def test_a_child_killed_while_it_holds_numbas_thread_lock_stops_no_one():
    """numba takes a lock shared with forked processes whenever a run asks for or sets its thread
    count (every chunk). A child killed while holding it made its parent and every later sibling wait
    forever (found: this file's kills hung a test worker). Each forked child now takes a lock of its
    own (demkit.engine.threads): the lock a child holds when it dies is its own."""
    import numba
    import numba.np.ufunc.parallel as parallel

    def short_run():
        dk.Simulation(gas(n=N), dk.VelocityVerlet(DT)).run(duration=5 * DT, progress=False)

    short_run()  # compiled here, inherited by the children
    assert numba.get_num_threads() >= 1 and parallel._backend_init_process_lock is not None
    pid = os.fork()
    if pid == 0:  # the child: dies holding whatever lock numba uses in it
        try:
            numba.get_num_threads()
            parallel._backend_init_process_lock.acquire()
            os.kill(os.getpid(), signal.SIGKILL)
        finally:
            os._exit(1)
    _, status = os.waitpid(pid, 0)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL
    lock = parallel._backend_init_process_lock  # the parent's: free (a wait of 10 s, not forever)
    assert lock.acquire(timeout=10.0), "the killed child left numba's lock taken"
    lock.release()
    pid = os.fork()
    if pid == 0:  # a later sibling runs
        code = 1
        try:
            short_run()
            code = 0
        except BaseException:  # noqa: BLE001 (report anything, never return into pytest)
            import traceback
            traceback.print_exc()
        finally:
            os._exit(code)
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        time.sleep(0.05)
    else:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        raise AssertionError("a sibling forked after the kill hung")
    assert os.waitstatus_to_exitcode(status) == 0
