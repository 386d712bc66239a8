"""Ctrl-C and kill -9 while a sphere sits across a periodic face (unfolded in the kernels' state and
the checkpoint, folded in the trajectory file): the resumed trajectory file equals an
uninterrupted run's, frame for frame, bit for bit."""
import os
import signal

import numpy as np
import pytest

import demkit as dk
from demkit import checkpoint as ckpt

from .conftest import L, arrays, assert_same_npz, injected, scene_file

pytestmark = pytest.mark.reliability


def outside(path):
    """Is a sphere outside [0, L) in the checkpoint's state (the forced condition)?"""
    _, saved = ckpt.load(path)
    x = saved["state.position"]
    return bool(((x < 0) | (x >= L)).any())


def test_ctrl_c_while_a_sphere_is_across_a_face_resumes_into_the_whole_run(tmp_path, monkeypatch, straight):
    path = scene_file(tmp_path)
    save = dk.Checkpoint.save

    def ctrl_c_at_step_70(checkpoint, sim):  # t = 0.07: off the record grid, sphere 0 at x ~ 6.02
        out = save(checkpoint, sim)
        if sim.step == 70:
            signal.raise_signal(signal.SIGINT)
        return out
    monkeypatch.setattr(dk.Checkpoint, "save", ctrl_c_at_step_70)
    with pytest.raises(KeyboardInterrupt):
        dk.load_scene(path).run(progress=False)
    injected("SIGINT, sphere across a periodic face")
    monkeypatch.setattr(dk.Checkpoint, "save", save)
    assert outside(tmp_path / "out" / "run.ckpt")
    kept = arrays(tmp_path / "out" / "traj.npz")
    assert kept["time"][-1] == pytest.approx(0.07) and (kept["position"] < L).all()
    dk.load_scene(path).run(progress=False)
    assert_same_npz(tmp_path / "out" / "traj.npz", straight)


def _killed_child(path, kill):
    """Run the scene file in a forked child that kills itself with SIGKILL where ``kill`` says
    (it patches the child's demkit); returns once the child is dead."""
    pid = os.fork()
    if pid == 0:
        try:
            kill()
            dk.load_scene(path).run(progress=False)
        finally:
            os._exit(3)  # not killed: the parent's assertion says so
    _, status = os.waitpid(pid, 0)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL, status


def _die():
    os.kill(os.getpid(), signal.SIGKILL)


def kill_before_checkpoint(step):
    """kill -9 after the trajectory file of ``step`` is written, before its checkpoint is."""
    def patch():
        save = ckpt.save

        def dying(sim, path, extra=None):
            if sim.step == step:
                _die()
            return save(sim, path, extra)
        ckpt.save = dying
    return patch


def kill_while_writing_the_trajectory(step):
    """kill -9 in the middle of writing the trajectory file at ``step`` (its temporary file half written)."""
    def patch():
        from demkit.scenefile import running as scenefile  # (save_trajectory calls its _savez)
        savez = scenefile._savez

        def dying(trajectory, tmp):
            if round(trajectory.time[-1] / 0.001) == step:
                with open(tmp, "wb") as fh:
                    fh.write(b"PK\x03\x04 half a zip")
                _die()
            return savez(trajectory, tmp)
        scenefile._savez = dying
    return patch


def kill_while_stepping(step):
    """kill -9 between two chunks of steps, after ``step``'s frames, before its checkpoint."""
    def patch():
        from demkit import guards
        check = guards.while_stepping

        def dying(scene, integrator):
            if scene.stepped_by is not None and scene.stepped_by.step >= step:
                _die()
            return check(scene, integrator)
        guards.while_stepping = dying
    return patch


def test_kill_9_at_chosen_moments_across_a_face_loses_no_frame(tmp_path, straight):
    """Killed three times (between the trajectory file and the checkpoint, half-way through writing
    the file, while stepping), resumed each time: after every kill the file holds every frame up to
    the checkpoint, and the final file is the uninterrupted run's."""
    path = scene_file(tmp_path)
    out = tmp_path / "out"
    for kill, step in ((kill_before_checkpoint, 70), (kill_while_writing_the_trajectory, 90),
                       (kill_while_stepping, 130)):
        _killed_child(path, kill(step))
        injected(f"SIGKILL {kill.__name__}")
        if kill is kill_while_writing_the_trajectory:
            assert len(list(out.glob("traj.*.partial.npz"))) == 1  # its half-written temporary file
        meta, _ = ckpt.load(out / "run.ckpt")
        assert meta["step"] < step
        assert outside(out / "run.ckpt"), "the kill should land while a sphere is across the face"
        kept = arrays(out / "traj.npz")
        steps = np.rint(kept["time"] / 0.001).astype(int)
        on_grid = steps[(steps % 30 == 0) & (steps <= meta["step"])]
        assert np.array_equal(on_grid, np.arange(0, meta["step"] + 1, 30)), steps  # nothing written is lost
    dk.load_scene(path).run(progress=False)
    assert_same_npz(out / "traj.npz", straight)
    assert not list(out.glob("*.partial*"))  # removed by the run that owns the file


def test_a_file_that_ends_before_the_checkpoint_says_so(tmp_path, capsys):
    """A trajectory file older than the checkpoint: the message says where it ends (not that a write
    did not happen) and the resumed file holds the times it says."""
    path = scene_file(tmp_path)
    dk.load_scene(path, overrides={"run.duration": 0.06}).run(progress=False)
    old = arrays(tmp_path / "out" / "traj.npz")
    dk.load_scene(path, overrides={"run.duration": 0.12, "outputs.trajectory": "elsewhere.npz"}).run(progress=False)
    dk.load_scene(path).run(progress=False)
    err = capsys.readouterr().err
    assert "it ends at t = 0.06, before the checkpoint's t = 0.12" in err, err
    assert "ended without writing it" not in err
    assert np.array_equal(old["time"], [0.0, 0.03, 0.06])


def test_a_checkpoint_without_a_digest_is_matched_in_the_files_convention(tmp_path, monkeypatch, straight):
    """A checkpoint that names no digest of the frames (written by dk.Checkpoint alone): the file's
    last frame is compared with the checkpoint's state folded as frames are, so a sphere across the
    face (x > L in the checkpoint, x - L in the file) still matches and every frame is kept."""
    import json

    import numpy as np
    path = scene_file(tmp_path)
    dk.load_scene(path, overrides={"run.duration": 0.07}).run(progress=False)
    target = tmp_path / "out" / "run.ckpt"
    assert outside(target)
    with np.load(target) as z:
        saved = {name: z[name] for name in z.files}
    meta = json.loads(saved["meta"].tobytes().decode())
    del meta["trajectory"]
    saved["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    with open(target, "wb") as fh:
        np.savez(fh, **saved)
    injected("checkpoint without a digest, sphere across a periodic face")
    dk.load_scene(path).run(progress=False)
    assert_same_npz(tmp_path / "out" / "traj.npz", straight)
