"""Outputs that cannot be written: found before the first step (one line naming the path and the
problem, exit 2 through `demkit run`), and a run whose output then cannot be written (a full disk)
saves it elsewhere and says where. Read-only folders are simulated by failing the file system calls
(tests run as root, for whom permission bits stop nothing)."""
import errno

import numpy as np
import pytest

import demkit as dk
from demkit import outputs
from demkit.cli import main

from .conftest import CROSSING, arrays, assert_same_npz, failing_writes, injected, scene_file

pytestmark = pytest.mark.reliability

NO_CHECKPOINT = CROSSING.split("[outputs.checkpoint]")[0]


@pytest.fixture
def no_stepping(monkeypatch):
    """Fail the test if a run starts."""
    def refuse(*args, **kwargs):
        raise AssertionError("the run started")
    monkeypatch.setattr(dk.Simulation, "run", refuse)


@pytest.mark.parametrize("sets, named", [
    (['outputs.trajectory="ro/traj.npz"'], "trajectory"),
    (['outputs.checkpoint.path="ro/run.ckpt"'], "checkpoint"),
    (['outputs.vtk.folder="ro/vtk"', "outputs.vtk.every=0.1"], "output folder"),
])
def test_an_output_in_a_read_only_folder_is_refused_before_the_first_step(tmp_path, monkeypatch, capsys, no_stepping,
                                                                         sets, named):
    path = scene_file(tmp_path)
    (tmp_path / "ro").mkdir()
    failing_writes(monkeypatch, tmp_path / "ro", errno.EROFS)
    injected(f"read-only folder ({named})")
    with pytest.raises(SystemExit) as exit:
        main(["run", str(path)] + [f"--set={item}" for item in sets])
    err = capsys.readouterr().err
    assert exit.value.code == 2 and len(err.strip().splitlines()) == 1, err
    assert named in err and str(tmp_path / "ro") in err and "Read-only file system" in err, err


def test_an_output_under_a_file_is_refused_before_the_first_step(tmp_path, capsys, no_stepping):
    path = scene_file(tmp_path)
    injected("output path under a file")
    with pytest.raises(SystemExit) as exit:
        main(["run", str(path), "--set", 'outputs.trajectory="/dev/null/traj.npz"'])
    err = capsys.readouterr().err
    assert exit.value.code == 2 and "cannot write the trajectory /dev/null/traj.npz: /dev/null is a file" in err, err


def test_pictures_and_animations_are_checked_before_rendering(tmp_path, monkeypatch):
    traj = dk.Simulation(dk.load_scene(scene_file(tmp_path)).scene, dk.VelocityVerlet(0.001)).run(0.002)
    monkeypatch.setattr(dk.viz, "ensure_rendering", lambda: pytest.fail("rendering started"))
    (tmp_path / "ro").mkdir()
    failing_writes(monkeypatch, tmp_path / "ro", errno.EROFS)
    for draw, name, what in ((dk.viz.snapshot, "x.png", "picture"), (dk.viz.animate, "x.gif", "animation")):
        injected(f"read-only folder ({what})")
        with pytest.raises(ValueError, match=f"cannot write the {what} .*ro/{name}: Read-only file system"):
            draw(traj, tmp_path / "ro" / name)


@pytest.mark.parametrize("name, what", [("x.png", "picture"), ("x.mp4", "animation")])
def test_demkit_render_to_a_read_only_folder_is_one_line_before_rendering(tmp_path, monkeypatch, capsys, name, what):
    source = scene_file(tmp_path)  # never read: the output is checked first
    monkeypatch.setattr(dk.viz, "ensure_rendering", lambda: pytest.fail("rendering started"))
    (tmp_path / "ro").mkdir()
    failing_writes(monkeypatch, tmp_path / "ro", errno.EROFS)
    injected(f"read-only folder (demkit render {what})")
    with pytest.raises(SystemExit) as exit:
        main(["render", str(source), "-o", str(tmp_path / "ro" / name)])
    err = capsys.readouterr().err
    assert exit.value.code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"demkit render: error: cannot write the {what} {tmp_path / 'ro' / name}: Read-only file "
                          f"system"), err


def _full_disk_from_the_first_step(monkeypatch, folder):
    """The disk under ``folder`` fills up once stepping starts (after the checks before it)."""
    run = dk.Simulation.run

    def filling(sim, *args, **kwargs):
        failing_writes(monkeypatch, folder)
        return run(sim, *args, **kwargs)
    monkeypatch.setattr(dk.Simulation, "run", filling)


def test_a_full_disk_at_the_end_saves_the_trajectory_elsewhere_and_says_where(tmp_path, monkeypatch, capsys, straight):
    path = scene_file(tmp_path / "run", NO_CHECKPOINT)
    rescue = tmp_path / "rescue"
    rescue.mkdir()
    monkeypatch.setattr(outputs, "rescue_folders", lambda: [tmp_path / "full-too", rescue])
    _full_disk_from_the_first_step(monkeypatch, tmp_path / "run")
    injected("full disk at the end of a run")
    assert main(["run", str(path), "--no-progress"]) == 0
    out, err = capsys.readouterr()
    saved = list(rescue.glob("demkit-rescued-traj-*.npz"))
    assert len(saved) == 1 and f"saved it instead in {saved[0]}" in err and "No space left on device" in err, err
    assert f"wrote trajectory: {saved[0]}" in out, out
    assert_same_npz(saved[0], straight)
    assert not (tmp_path / "run" / "out" / "traj.npz").exists()
    assert not list((tmp_path / "run" / "out").glob("*partial*"))


def test_a_full_disk_while_resuming_keeps_the_earlier_file_whole(tmp_path, monkeypatch, capsys, straight):
    """Checkpoints and the trajectory cannot be written after a resume: each save warns, the file of
    the earlier run is left byte for byte, and the whole run is saved elsewhere."""
    path = scene_file(tmp_path / "run")
    dk.load_scene(path, overrides={"run.duration": 0.1}).run(progress=False)
    before = {p.name: p.read_bytes() for p in (tmp_path / "run" / "out").iterdir()}
    monkeypatch.setattr(outputs, "rescue_folders", lambda: [tmp_path])
    _full_disk_from_the_first_step(monkeypatch, tmp_path / "run")
    injected("full disk at every checkpoint after a resume")
    with pytest.warns(dk.simulation.CheckpointWarning, match="No space left on device"):
        dk.load_scene(path).run(progress=False)
    assert {p.name: p.read_bytes() for p in (tmp_path / "run" / "out").iterdir()} == before
    saved = list(tmp_path.glob("demkit-rescued-traj-*.npz"))
    assert len(saved) == 1, capsys.readouterr().err
    assert_same_npz(saved[0], straight)


def test_nowhere_to_write_is_one_line_naming_every_place_tried(tmp_path, monkeypatch, capsys):
    path = scene_file(tmp_path / "run", NO_CHECKPOINT)
    monkeypatch.setattr(outputs, "rescue_folders", lambda: [tmp_path / "run"])
    _full_disk_from_the_first_step(monkeypatch, tmp_path / "run")
    injected("full disk everywhere")
    assert main(["run", str(path), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("demkit run: error: could not write the trajectory anywhere: tried ") and \
        err[-1].count("No space left on device") == 2, err


def test_a_full_disk_under_the_vtk_series_mid_run_keeps_the_checkpoint_and_frames(tmp_path, monkeypatch, capsys,
                                                                                   straight):
    """A VTK frame that cannot be written stops the run in one line (exit 1); the checkpoint and the
    trajectory file written before it are kept, and the same command finishes the run."""
    path = scene_file(tmp_path)
    command = ["run", str(path), "--no-progress", '--set=outputs.vtk.folder="out/vtk"', "--set=outputs.vtk.every=0.05"]
    write = dk.io.VTKWriter.write

    def full_at_step_250(writer, sim):
        if sim.step >= 250:
            raise OSError(errno.ENOSPC, "No space left on device", str(writer.series.folder))
        return write(writer, sim)
    monkeypatch.setattr(dk.io.VTKWriter, "write", full_at_step_250)
    injected("full disk under the VTK series mid-run")
    assert main(command) == 1
    err = "".join(line for line in capsys.readouterr().err.splitlines(keepends=True)
                  if not line.startswith("demkit: "))  # a compile notice on a cold cache is not the message
    assert err.count("\n") == 1 and err.startswith("demkit run: error: [Errno 28] No space left on device"), err
    assert err.rstrip().endswith(f"kept: trajectory {tmp_path / 'out' / 'traj.npz'}, VTK series "
                                 f"{tmp_path / 'out' / 'vtk' / 'particles.pvd'}, checkpoint "
                                 f"{tmp_path / 'out' / 'run.ckpt'}; run the same command to resume"), err
    monkeypatch.setattr(dk.io.VTKWriter, "write", write)
    kept = arrays(tmp_path / "out" / "traj.npz")
    assert kept["time"][-1] == pytest.approx(0.24)  # the frames up to the last checkpoint (t = 0.24)
    assert main(command) == 0
    assert_same_npz(tmp_path / "out" / "traj.npz", straight)
    series = dk.read_series(tmp_path / "out" / "vtk" / "particles.pvd").time
    assert np.allclose(series, np.arange(11) * 0.05), series  # the uninterrupted run's frames, no more
