"""Truncated and corrupted output files read back: a damaged trajectory file is set aside (never
overwritten) with a line saying why, and the resumed run goes on; a damaged checkpoint is refused in
one line (exit 2) and leaves every file as it was."""
import pytest

import demkit as dk
from demkit.cli import main

from .conftest import arrays, injected, scene_file

pytestmark = pytest.mark.reliability


def truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[:len(data) // 2])


def corrupt(path):
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 64] = bytes(64)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("damage", [truncate, corrupt])
def test_a_damaged_trajectory_file_is_set_aside_and_the_run_resumes(tmp_path, capsys, damage):
    path = scene_file(tmp_path)
    dk.load_scene(path, overrides={"run.duration": 0.1}).run(progress=False)
    out = tmp_path / "out"
    damage(out / "traj.npz")
    damaged = (out / "traj.npz").read_bytes()
    injected(f"{damage.__name__} a trajectory file")
    dk.load_scene(path).run(progress=False)
    err = capsys.readouterr().err
    assert "frames before t = 0.1 (the resume) are not kept: it cannot be read" in err, err
    assert f"the file is kept as {out / 'traj.set-aside.npz'}" in err, err
    assert (out / "traj.set-aside.npz").read_bytes() == damaged
    assert arrays(out / "traj.npz")["time"][[0, -1]].tolist() == [0.1, 0.5]


@pytest.mark.parametrize("damage", [truncate, corrupt])
def test_a_damaged_checkpoint_is_refused_in_one_line_and_nothing_is_changed(tmp_path, capsys, damage):
    path = scene_file(tmp_path)
    dk.load_scene(path, overrides={"run.duration": 0.1}).run(progress=False)
    out = tmp_path / "out"
    damage(out / "run.ckpt")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    injected(f"{damage.__name__} a checkpoint")
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit:
        main(["run", str(path), "--no-progress"])
    stdout, err = capsys.readouterr()
    assert exit.value.code == 2 and len(err.strip().splitlines()) == 1, err
    assert "run.ckpt" in err and ("truncated or corrupted" in err or "not a readable" in err), err
    assert "resuming from" not in stdout
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
