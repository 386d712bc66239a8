"""VTK series that grow in place, survive SIGKILL, are continued by a resumed run, and say how
much they will write."""
import os
import random
import select
import signal
import time
import traceback
from pathlib import Path

import numpy as np
import pytest

import demkit as dk
from demkit.io import read_pvd, read_series
from demkit.io.pvd import GrowingPvd, read_entries, write_pvd

# ---- the .pvd grows in place ---------------------------------------------------------------------

def test_growing_pvd_is_byte_identical_to_a_full_rewrite_and_falls_back_to_one(tmp_path):
    box = dk.Box([10.0, 8.0, 6.0], periodic=[True, False, True])
    grown = GrowingPvd(tmp_path / "a.pvd", box)
    entries = [(0.1 * k, f"a_{k:06d}.vtu") for k in range(40)]
    for t, name in entries:
        grown.append(t, name)
        size = (tmp_path / "a.pvd").stat().st_size
    write_pvd(tmp_path / "b.pvd", entries, box)
    assert (tmp_path / "a.pvd").read_bytes() == (tmp_path / "b.pvd").read_bytes()
    assert read_entries(tmp_path / "a.pvd") == (entries, box)
    inode = (tmp_path / "a.pvd").stat().st_ino
    grown.append(4.0, "a_000040.vtu")  # in place: same file, grown by one line
    assert (tmp_path / "a.pvd").stat().st_ino == inode and (tmp_path / "a.pvd").stat().st_size > size
    # a file changed behind its back, or a new box, is written whole instead of patched
    (tmp_path / "a.pvd").write_text((tmp_path / "a.pvd").read_text() + "\n\n")
    grown.append(4.1, "a_000041.vtu")
    grown.box = None
    grown.append(4.2, "a_000042.vtu")
    entries += [(4.0, "a_000040.vtu"), (4.1, "a_000041.vtu"), (4.2, "a_000042.vtu")]
    write_pvd(tmp_path / "b.pvd", entries)
    assert (tmp_path / "a.pvd").read_bytes() == (tmp_path / "b.pvd").read_bytes()


def test_a_frame_that_fails_to_write_is_not_listed(tmp_path):
    writer = dk.VTKWriter(tmp_path / "out", every=1.0, trails=False)
    p = dk.Particles([[0.0, 0, 0], [3.0, 0, 0]], radius=1.0)
    writer.begin(p)
    writer.write_state(0.0, p)

    def broken(path):
        Path(path).write_text("<VTKFile half a fr")
        raise OSError("disk full")

    with pytest.raises(OSError):
        writer.series.add_frame(1.0, broken)
    assert [t for t, _ in read_pvd(writer.pvd)] == [0.0] and len(read_series(writer.pvd)) == 1
    assert not (tmp_path / "out" / "particles_000001.vtu").exists()  # only its .tmp


def test_a_torn_pvd_is_salvaged_when_resuming(tmp_path):
    text = ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
            '  <Collection>\n    <DataSet timestep="0.0" group="" part="0" file="p_000000.vtu"/>\n'
            '    <DataSet timestep="0.5" group="" part="0" file="p_0000')
    (tmp_path / "p.pvd").write_text(text)
    with pytest.raises(ValueError, match="cannot read"):
        read_entries(tmp_path / "p.pvd")
    with pytest.warns(UserWarning, match="1 complete entries"):
        assert read_entries(tmp_path / "p.pvd", salvage=True) == ([(0.0, "p_000000.vtu")], None)


# ---- SIGKILL at random moments ---------------------------------------------------------------------

X0, V = np.array([[0.0, 0, 0], [3.0, 0, 0]]), np.array([[0.25, 0, 0], [-0.5, 0.125, 0]])


def write_until_killed(folder, resume_at, ready):
    """Child process: write frame k at t = 0.5 k (state X0 + V t) without end; with ``resume_at``
    >= 0, first continue the series as a run resumed from a checkpoint at that time. Writes a
    byte to the pipe ``ready`` once writing is under way."""
    p = dk.Particles(X0, velocity=V, radius=1.0, ids=[4, 2])
    writer = dk.VTKWriter(folder, every=0.5, trails=False, resume=resume_at >= 0)
    if resume_at >= 0:
        k = round(resume_at / 0.5)
        p.position[:] = X0 + V * (0.5 * k)
        k += not writer.continue_series(0.5 * k, p)
    else:
        writer.begin(p)
        writer.write_state(0.0, p)
        k = 1
    os.write(ready, b"r")
    while True:
        p.position[:] = X0 + V * (0.5 * k)
        writer.write_state(0.5 * k, p)
        k += 1


def start_child(folder, resume_at):
    """Fork a child process running :func:`write_until_killed`; returns its pid once it writes."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child never returns into the test
        try:
            os.close(read)
            write_until_killed(folder, resume_at, write)
        except BaseException:
            traceback.print_exc()
        finally:
            os._exit(1)
    os.close(write)
    try:
        ready, _, _ = select.select([read], [], [], 60.0)
        started = bool(ready) and os.read(read, 1) == b"r"
    finally:
        os.close(read)
    if not started:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        raise AssertionError("the child process did not start writing")
    return pid


def check_series(folder, pv):
    """The series in ``folder`` reads back whole: frame k at t = 0.5 k holding the state at that time."""
    series = read_series(folder)
    n = len(series)
    np.testing.assert_array_equal(series.time, 0.5 * np.arange(n))  # monotone, nothing missing
    # ids 4, 2: read back in id order
    np.testing.assert_array_equal(series.position, X0[[1, 0]] + V[[1, 0]] * series.time[:, None, None])
    reader = pv.get_reader(str(Path(folder) / "particles.pvd"))
    np.testing.assert_array_equal(reader.time_values, series.time)
    reader.set_active_time_value(reader.time_values[-1])
    np.testing.assert_array_equal(reader.read()[0].points, series.position[-1][[1, 0]])
    return n


def test_series_survives_sigkill_at_random_moments_and_is_continued_after_it(tmp_path):
    pv = pytest.importorskip("pyvista")
    rng = random.Random(12)
    folder = tmp_path / "out"
    counts, resumed_from = [], -1.0
    for trial in range(10):
        pid = start_child(folder, resumed_from)
        time.sleep(rng.uniform(0.0, 0.05))
        os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
        assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL  # killed while writing
        n = check_series(folder, pv)
        assert n > (resumed_from / 0.5 if counts else 0)  # nothing lost of what was kept
        counts.append(n)
        # the next run resumes from a "checkpoint" a few frames before the last one written
        resumed_from = 0.5 * max(0, n - 1 - rng.randrange(4))
    assert counts[-1] > 10
    # resuming in this process removes what the last kill left (temporary or unlisted frames)
    writer = dk.VTKWriter(folder, every=0.5, trails=True, resume=True)
    p = dk.Particles(np.zeros((2, 3)), velocity=np.zeros((2, 3)), radius=1.0, ids=[4, 2])
    assert writer.continue_series(0.5 * (counts[-1] - 1), p) is False
    listed = {path.name for _, path in read_pvd(writer.pvd)}
    assert {path.name for path in folder.iterdir()} == listed | {"particles.pvd"}
    writer.close()  # trails rebuilt from every frame on disk
    assert pv.read(folder / "particles_trails.vtp").n_points == 2 * counts[-1]


# ---- resume ------------------------------------------------------------------------------------

class StandIn:
    """What VTKWriter reads from a Simulation: time and a scene with forces."""

    def __init__(self, particles, box=None):
        self.time = 0.0
        interactions = (dk.KelvinVoigt(1.0, 0.1),)
        forces = lambda: (0.01 * particles.position, np.zeros((len(particles), 3)))  # noqa: E731
        self.scene = type("Scene", (), {"particles": particles, "interactions": interactions, "box": box,
                                        "forces": staticmethod(forces)})()


def moving_spheres():
    box = dk.Box([10.0, 10.0, 10.0], periodic=[True, True, True])
    p = dk.Particles([[1.0, 1.0, 1.0], [5.0, 5.0, 5.0], [8.0, 2.0, 3.0]], velocity=np.zeros((3, 3)),
                     radius=0.5, ids=[9, 1, 5], dipole=np.eye(3), image=np.zeros((3, 3), dtype=np.int64))
    return StandIn(p, box)


def set_state(sim, t):
    """A deterministic state at time t: sphere 0 crosses the periodic x side at t = 4."""
    p = sim.scene.particles
    unwrapped = np.array([[7.0 + 0.75 * t, 1.0, 1.0], [5.0, 5.0 - 0.2 * t, 5.0], [8.0, 2.0, 3.0 + 0.1 * t]])
    p.position[:], p.image[:] = sim.scene.box.wrap(unwrapped)
    p.velocity[:] = [[0.75, 0, 0], [0, -0.2, 0], [0, 0, 0.1]]
    sim.time = t


def write_run(folder, times, resume_at=None):
    """Write frames at ``times``; with ``resume_at``: a writer made with resume=True takes the
    folder over at that time first (as a run resumed from a checkpoint)."""
    sim = moving_spheres()
    writer = dk.VTKWriter(folder, every=1.0, resume=resume_at is not None)
    if resume_at is None:
        set_state(sim, times[0])
        writer.open(sim)
        write_now = True
    else:
        set_state(sim, resume_at)
        write_now = writer.resume(sim)
    if write_now:
        writer.write(sim)
    for t in times:
        if t > sim.time:
            set_state(sim, t)
            writer.write(sim)
    writer.close()
    return writer, write_now


def folder_bytes(folder):
    return {p.name: p.read_bytes() for p in sorted(Path(folder).iterdir())}


def test_resumed_series_equals_an_uninterrupted_one(tmp_path):
    times = [float(t) for t in range(10)]
    write_run(tmp_path / "whole", times)
    writer, _ = write_run(tmp_path / "resumed", times)
    assert writer.frames_written == 10
    # "resume from a checkpoint at t = 5": frames 6..9 are deleted, then written again
    (tmp_path / "resumed" / "particles_000010.vtu").write_bytes(b"unlisted frame of a killed run")
    (tmp_path / "resumed" / "particles_000011.vtu.tmp").write_bytes(b"half a frame")
    (tmp_path / "resumed" / "notes.txt").write_text("mine")
    resumed, write_now = write_run(tmp_path / "resumed", times, resume_at=5.0)
    assert write_now is False  # the series has the frame at t = 5 already
    assert resumed.frames_written == 10
    whole, again = folder_bytes(tmp_path / "whole"), folder_bytes(tmp_path / "resumed")
    assert again.pop("notes.txt") == b"mine"  # other files are left alone
    assert again.keys() == whole.keys()
    assert again == whole  # frames, .pvd (with the box) and trails (rebuilt from frames 0..5), byte for byte
    series = read_series(tmp_path / "resumed")
    assert series.box == dk.Box([10.0] * 3, periodic=[True] * 3) and series.image[-1, 2, 0] == 1


def test_resume_between_frames_writes_the_current_state(tmp_path):
    write_run(tmp_path / "out", [0.0, 1.0, 2.0, 3.0])
    writer, write_now = write_run(tmp_path / "out", [2.5, 3.5], resume_at=2.5)
    assert write_now is True
    assert [t for t, _ in read_pvd(writer.pvd)] == [0.0, 1.0, 2.0, 2.5, 3.5]
    assert sorted(p.name for p in (tmp_path / "out").glob("*.vtu")) == [f"particles_00000{k}.vtu" for k in range(5)]
    # a time within the relative tolerance of a frame counts as that frame
    writer = dk.VTKWriter(tmp_path / "out", every=1.0, resume=True)
    sim = moving_spheres()
    set_state(sim, 2.5 * (1 + 1e-13))
    assert writer.resume(sim) is False and writer.frames_written == 4


def test_resume_refusals_are_clear_and_change_nothing(tmp_path):
    sim = moving_spheres()
    set_state(sim, 1.0)
    with pytest.raises(ValueError, match="no series 'particles' to resume"):
        dk.VTKWriter(tmp_path / "empty", every=1.0, resume=True).resume(sim)
    with pytest.raises(ValueError, match="no series"):
        dk.VTKWriter(tmp_path / "empty2", every=1.0).resume(sim)  # a plain writer has nothing to resume
    fresh = dk.VTKWriter(tmp_path / "fresh", every=1.0, resume=True)  # nothing to resume: a new run starts
    fresh.open(sim)
    fresh.write(sim)
    assert fresh.frames_written == 1
    write_run(tmp_path / "out", [0.0, 1.0, 2.0])
    before = folder_bytes(tmp_path / "out")
    with pytest.raises(ValueError, match="not empty.*resume=True"):
        dk.VTKWriter(tmp_path / "out", every=1.0)  # a plain new writer is still refused
    with pytest.raises(ValueError, match="holds series 'particles' already.*resume"):
        dk.VTKWriter(tmp_path / "out", every=1.0, resume=True).open(sim)  # a new run does not overwrite it
    with pytest.raises(ValueError, match="pass one of them"):
        dk.VTKWriter(tmp_path / "out", every=1.0, resume=True, overwrite=True)
    with pytest.raises(ValueError, match="fields.*to continue it"):
        dk.VTKWriter(tmp_path / "out", every=1.0, resume=True, fields=["velocity"]).resume(sim)
    (tmp_path / "out" / "particles_000001.vtu").unlink()
    broken = folder_bytes(tmp_path / "out")
    with pytest.raises(ValueError, match="missing frame file.*particles_000001.vtu"):
        dk.VTKWriter(tmp_path / "out", every=1.0, resume=True).resume(sim)
    assert folder_bytes(tmp_path / "out") == broken
    del before["particles_000001.vtu"]
    assert broken == before


def test_resume_continues_the_contact_series(tmp_path):
    from test_vtk import three_spheres

    def run(folder, resume_at=None):
        """Frames every 0.25 up to t = 1: a fresh Simulation replays the run up to ``resume_at``
        without writing (as if restored from a checkpoint), then its writer resumes the series."""
        sim = dk.Simulation(three_spheres(), dk.EulerCromer(dt=0.01))
        writer = dk.VTKWriter(folder, every=0.25, contacts=True, resume=resume_at is not None)
        if resume_at is None:
            writer.open(sim)
            writer.write(sim)
        else:
            while sim.time < resume_at - 1e-9:
                sim.run(0.25)
            assert writer.resume(sim) is False
        while sim.time < 1.0 - 1e-9:
            sim.run(0.25)
            writer.write(sim)
        writer.close()
        return writer

    run(tmp_path / "whole")
    run(tmp_path / "resumed")
    writer = run(tmp_path / "resumed", resume_at=0.5)
    assert len(read_pvd(writer.contact_series.pvd)) == 5
    whole, again = folder_bytes(tmp_path / "whole"), folder_bytes(tmp_path / "resumed")
    assert again.keys() == whole.keys() and "particles_contacts_000004.vtp" in again
    assert again == whole


# ---- planned output ------------------------------------------------------------------------------

def files_and_bytes(folder):
    files = [p for p in Path(folder).iterdir() if p.is_file()]
    return len(files), sum(p.stat().st_size for p in files)


@pytest.mark.parametrize("n, frames, dtype, image, trails", [
    (2, 30, "float64", False, True), (500, 6, "float64", True, True), (2000, 4, "float32", False, False)])
def test_planned_output_estimates_what_is_written(tmp_path, n, frames, dtype, image, trails):
    rng = np.random.default_rng(n)
    p = dk.Particles(rng.uniform(0, 100, (n, 3)), velocity=rng.normal(size=(n, 3)), radius=1.0,
                     dipole=rng.normal(size=(n, 3)), angular_velocity=rng.normal(size=(n, 3)),
                     image=rng.integers(-3, 3, (n, 3)) if image else None)
    writer = dk.VTKWriter(tmp_path / "out", every=1.0, dtype=dtype, trails=trails)
    before_open = writer.planned_output(frames, p)  # guesses force and torque: the particles spin
    writer.begin(p, has_force=True, has_torque=True)
    files, size = writer.planned_output(frames, p)
    assert before_open == (files, size)
    force = rng.normal(size=(n, 3))
    for k in range(frames):
        writer.write_state(float(k), p, force, force)
    writer.close()
    real_files, real_size = files_and_bytes(tmp_path / "out")
    assert files == real_files
    assert 1 / 1.2 < size / real_size < 1.2, (size, real_size)
    assert writer.planned_output(frames, p)[0] == frames  # more frames: the .pvd and trails exist already


def test_planned_output_counts_contact_frames(tmp_path):
    from test_vtk import three_spheres

    scene = three_spheres()
    per_sphere = len(scene.contacts()) / len(scene.particles)
    assert per_sphere > 0
    sim = dk.Simulation(scene, dk.EulerCromer(dt=0.01))
    writer = dk.VTKWriter(tmp_path / "out", every=0.1, contacts=True)
    writer.open(sim)
    files, size = writer.planned_output(8, scene.particles, contacts_per_particle=per_sphere)
    for _ in range(8):
        writer.write(sim)
        sim.run(0.1)
    writer.close()
    real_files, real_size = files_and_bytes(tmp_path / "out")
    assert files == real_files == 8 + 1 + 1 + 8 + 1
    assert 1 / 1.5 < size / real_size < 1.5, (size, real_size)
    with pytest.raises(ValueError, match="frames"):
        writer.planned_output(-1, scene.particles)
