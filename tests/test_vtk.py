"""VTK output: what VTKWriter writes reads back (meshio, pyvista, ParaView) at the right times."""
import os
import re
import shutil
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest
from conftest import two_magnets

import demkit as dk
from demkit.io import read_pvd, read_series, write_polylines, write_series

DT = 0.01


def three_spheres(dipole=True, contact=True):
    """Three touching spheres with non-sequential ids (frames are matched by id, not order)."""
    pos = [[0.0, 0.0, 0.0], [2.1, 0.3, 0.0], [1.0, 1.9, 0.4]]
    p = dk.Particles(pos, velocity=[[0.01, 0, 0], [-0.02, 0.01, 0], [0, -0.01, 0.005]], radius=1.1,
                     mass=[1.0, 2.0, 1.5], dipole=np.eye(3) if dipole else None, ids=[7, 3, 11])
    inter = ([dk.Dipole(prefactor=1 / 3)] if dipole else []) + ([dk.KelvinVoigt(1.0, 0.1)] if contact else [])
    return dk.Scene(p, inter)


def run_with_writer(tmp_path, scene, duration=2.0, every=0.5, **options):
    writer = dk.VTKWriter(tmp_path / "out", every=every, **options)
    sim = dk.Simulation(scene, dk.EulerCromer(dt=DT), writers=[writer])
    traj = sim.run(duration, record_every=every)
    return sim, writer, traj


def test_frames_read_back_with_meshio_at_the_recorded_times(tmp_path):
    sim, writer, traj = run_with_writer(tmp_path, three_spheres())
    sim.close()
    entries = read_pvd(writer.pvd)
    assert [t for t, _ in entries] == pytest.approx(traj.time, abs=1e-12)
    assert writer.fields == ("velocity", "angular_velocity", "dipole", "force", "torque")
    for k, (_, path) in enumerate(entries):
        mesh = meshio.read(path)
        np.testing.assert_array_equal(mesh.points, traj.position[k])
        data = mesh.point_data
        assert set(data) == {"id", "radius", "mass", "velocity", "angular_velocity", "dipole", "force", "torque"}
        np.testing.assert_array_equal(data["id"], [7, 3, 11])
        np.testing.assert_array_equal(data["mass"], [1.0, 2.0, 1.5])
        np.testing.assert_array_equal(data["velocity"], traj.velocity[k])
        np.testing.assert_array_equal(data["angular_velocity"], traj.angular_velocity[k])
        np.testing.assert_array_equal(data["dipole"], traj.dipole[k])
        assert mesh.cells[0].type == "vertex" and len(mesh.cells[0]) == 3
    force, torque = sim.scene.forces()  # the last frame is the final state
    np.testing.assert_array_equal(data["force"], force)
    np.testing.assert_array_equal(data["torque"], torque)
    assert np.abs(force).max() > 0


def test_pyvista_reads_the_series_and_the_trails(tmp_path):
    pv = pytest.importorskip("pyvista")
    sim, writer, traj = run_with_writer(tmp_path, three_spheres())
    sim.close()
    reader = pv.get_reader(str(writer.pvd))
    np.testing.assert_allclose(reader.time_values, traj.time, atol=1e-12)
    for k in (0, len(traj) - 1):
        reader.set_active_time_value(traj.time[k])
        grid = reader.read()[0]
        np.testing.assert_array_equal(grid.points, traj.position[k])
        np.testing.assert_array_equal(grid.point_data["dipole"], traj.dipole[k])
    trails = pv.read(writer.series.trails)
    assert trails.n_lines == 3 and trails.n_points == 3 * len(traj)
    order = np.argsort(traj.ids)  # lines are in id order: 3, 7, 11
    paths = np.asarray(trails.points).reshape(3, len(traj), 3)
    np.testing.assert_array_equal(paths, traj.position[:, order].transpose(1, 0, 2))
    np.testing.assert_array_equal(trails.point_data["time"].reshape(3, -1)[1], traj.time)
    np.testing.assert_array_equal(trails.cell_data["id"], [3, 7, 11])


def test_only_fields_the_scene_has(tmp_path):
    scene = three_spheres(dipole=False)  # Kelvin-Voigt only: no dipole, no torque, no spin
    sim, writer, _ = run_with_writer(tmp_path, scene)
    assert writer.fields == ("velocity", "force")
    _, data = dk.io.read_frame(writer.series.folder / "particles_000000.vtu")
    assert set(data) == {"id", "radius", "mass", "velocity", "force"}
    with pytest.raises(ValueError, match="no dipole"):
        run_with_writer(tmp_path / "b", three_spheres(dipole=False), fields=["dipole"])


def test_field_selection_and_single_precision(tmp_path):
    sim, writer, traj = run_with_writer(tmp_path, three_spheres(), fields=["dipole"], dtype="float32")
    pos, data = dk.io.read_frame(writer.series.folder / "particles_000002.vtu")
    assert set(data) == {"id", "radius", "mass", "dipole"} and pos.dtype == np.float32
    np.testing.assert_allclose(pos, traj.position[2], rtol=1e-6)


@pytest.mark.parametrize("compress", [True, "lzma"])
def test_compressed_frames_read_back_identically(tmp_path, compress):
    sim, writer, traj = run_with_writer(tmp_path, three_spheres(), compress=compress)
    sim.close()
    path = writer.series.folder / "particles_000003.vtu"
    assert ET.parse(path).getroot().get("compressor") in ("vtkZLibDataCompressor", "vtkLZMADataCompressor")
    np.testing.assert_array_equal(meshio.read(path).points, traj.position[3])
    series = read_series(writer.pvd)
    np.testing.assert_array_equal(series.velocity[:, [1, 0, 2]], traj.velocity)  # id order 3, 7, 11
    pv = pytest.importorskip("pyvista")
    trails = pv.read(writer.series.trails)
    assert trails.n_lines == 3


def test_series_is_valid_after_every_frame_and_trails_can_be_rebuilt(tmp_path):
    writer = dk.VTKWriter(tmp_path / "out", every=1.0)
    scene = three_spheres()
    writer.begin(scene.particles, has_force=True, has_torque=True)
    force, torque = scene.forces()
    for k in range(3):
        writer.write_state(float(k), scene.particles, force, torque)
        assert [t for t, _ in read_pvd(writer.pvd)] == list(range(k + 1))
    # "interrupted": never closed, so no trails yet; rebuild them from the frames
    assert not writer.series.trails.exists()
    out = write_polylines(writer.series.folder, tmp_path / "rebuilt.vtp")
    pv = pytest.importorskip("pyvista")
    assert pv.read(out).n_points == 9


def test_context_manager_writes_trails(tmp_path):
    scene = three_spheres()
    with dk.VTKWriter(tmp_path / "out", every=0.5) as writer:
        sim = dk.Simulation(scene, dk.EulerCromer(dt=DT), writers=[writer])
        sim.run(1.0)
    assert writer.series.trails.exists() and writer.frames_written == 3
    with pytest.raises(ValueError, match="used already"):
        dk.Simulation(scene, dk.EulerCromer(dt=DT), writers=[writer]).run(1.0)


def test_trajectory_to_series_round_trip(tmp_path):
    traj = dk.Simulation(two_magnets(x0=30.0), dk.EulerCromer(dt=DT)).run(200.0, record_every=50.0)
    pvd = write_series(traj, tmp_path / "series", compress=True)
    back = read_series(pvd.parent)
    np.testing.assert_array_equal(back.time, traj.time)
    np.testing.assert_array_equal(back.position, traj.position)
    np.testing.assert_array_equal(back.dipole, traj.dipole)
    assert back.force is None and len(back) == 5
    assert (pvd.parent / "particles_trails.vtp").exists()


@pytest.mark.parametrize("every", [0, -1.0, float("nan"), float("inf"), "soon", None])
def test_bad_interval(tmp_path, every):
    with pytest.raises(ValueError, match="every"):
        dk.VTKWriter(tmp_path / "out", every=every)


def test_bad_folders_and_options(tmp_path):
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ValueError, match="not a folder"):
        dk.VTKWriter(tmp_path / "afile", every=1.0)
    with pytest.raises(ValueError, match="cannot write"):
        dk.VTKWriter(tmp_path / "afile" / "sub", every=1.0)
    with pytest.raises(ValueError, match="compress"):
        dk.VTKWriter(tmp_path / "c", every=1.0, compress="gzip")
    with pytest.raises(ValueError, match="unknown field"):
        dk.VTKWriter(tmp_path / "d", every=1.0, fields=["spin"])
    with pytest.raises(ValueError, match="dtype"):
        dk.VTKWriter(tmp_path / "e", every=1.0, dtype="float16")


def test_the_series_ends_with_the_state_the_run_ends_in(tmp_path):
    """A run that ends between two frames (1.0 with a frame every 0.3): its end state is the last
    frame, as it is the trajectory's; a run that continues writes on the interval's grid (counted from
    step 0) and its own end."""
    sim, writer, traj = run_with_writer(tmp_path, three_spheres(), duration=1.0, every=0.3)
    entries = read_pvd(writer.pvd)
    assert [t for t, _ in entries] == pytest.approx([0.0, 0.3, 0.6, 0.9, 1.0], abs=1e-12)
    assert [t for t, _ in entries] == pytest.approx(traj.time, abs=1e-12)
    np.testing.assert_array_equal(meshio.read(entries[-1][1]).points, traj.position[-1])
    sim.run(0.25)  # to t = 1.25: a frame at 1.2 and the end
    sim.run(0.05)  # to t = 1.3: not a frame of the grid, the end
    sim.run(0.2)   # to t = 1.5, on the grid: written once
    sim.close()
    times = [t for t, _ in read_pvd(writer.pvd)]
    assert times == pytest.approx([0.0, 0.3, 0.6, 0.9, 1.0, 1.2, 1.25, 1.3, 1.5], abs=1e-12)


def test_existing_data_is_never_silently_replaced(tmp_path):
    sim, writer, _ = run_with_writer(tmp_path, three_spheres(), duration=2.0)  # 5 frames
    sim.close()
    folder = writer.series.folder
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="not empty.*overwrite=True"):
        dk.VTKWriter(folder, every=1.0)
    assert len(read_pvd(folder / "particles.pvd")) == 5
    # overwrite=True replaces the series (no stale frames from the longer run) and keeps other files
    sim, writer, _ = run_with_writer(tmp_path, three_spheres(), duration=1.0, overwrite=True)
    sim.close()
    assert len(read_pvd(writer.pvd)) == 3
    assert sorted(p.name for p in folder.glob("particles_*.vtu")) == [f"particles_00000{k}.vtu" for k in range(3)]
    assert (folder / "notes.txt").read_text() == "mine"


def test_paraview_script_path_cli():
    out = subprocess.run([sys.executable, "-m", "demkit.io", "--paraview-script"], capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out.endswith("paraview_setup.py") and dk.io.paraview_script().exists()


PVPYTHON_CHECK = textwrap.dedent("""
    import sys
    from paraview.simple import PVDReader
    reader = PVDReader(FileName=sys.argv[1])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues)
    reader.UpdatePipeline(times[-1])
    info = reader.GetDataInformation()
    print("RESULT", len(times), times[-1], info.GetNumberOfPoints(), ",".join(sorted(reader.PointData.keys())))
""")


@pytest.mark.skipif(shutil.which("pvpython") is None,
                    reason="ParaView's pvpython is not installed (Debian package 'paraview')")
def test_paraview_opens_the_series(tmp_path):
    sim, writer, traj = run_with_writer(tmp_path, three_spheres(), compress=True)
    sim.close()
    script = tmp_path / "check.py"
    script.write_text(PVPYTHON_CHECK)
    done = subprocess.run(["pvpython", str(script), str(writer.pvd)], capture_output=True, text=True, timeout=120)
    line = next((l for l in done.stdout.splitlines() if l.startswith("RESULT")), None)
    assert line, done.stdout + done.stderr
    _, steps, last, points, arrays = line.split()
    assert int(steps) == len(traj) and float(last) == pytest.approx(traj.time[-1])
    assert int(points) == 3
    assert arrays.split(",") == sorted(["id", "radius", "mass", "velocity", "angular_velocity", "dipole",
                                        "force", "torque"])
    # the shipped set-up script builds its pipeline and writes a state file (no rendering needed)
    state = tmp_path / "view.pvsm"
    done = subprocess.run(["pvpython", str(dk.io.paraview_script()), str(writer.pvd), "--state", str(state)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "spheres, dipoles" in done.stdout and state.exists()


PVPYTHON_BOX = textwrap.dedent("""
    import sys
    from paraview.simple import PVDReader
    reader = PVDReader(FileName=sys.argv[1])
    reader.UpdatePipelineInformation()
    for t in reader.TimestepValues:
        reader.UpdatePipeline(t)
        print("BOX", t, *reader.GetDataInformation().GetBounds())
""")


@pytest.mark.skipif(shutil.which("pvpython") is None,
                    reason="ParaView's pvpython is not installed (Debian package 'paraview')")
def test_paraview_draws_a_deforming_box_frame_by_frame(tmp_path):
    """A box compressed along x and drawn out along y: ParaView reads the outline series (each frame's box,
    demkit.io.box_outline) at every time step, and the set-up script draws it instead of the fixed outline."""
    rng = np.random.default_rng(1)
    box = dk.Box(8.0, periodic=True, deform=dk.Deform(x=-0.2, y=0.1))
    p = dk.Particles(position=dk.build.random_packing(30, 0.5, dk.Box(8.0, periodic=True), seed=rng),
                     velocity=rng.normal(size=(30, 3)), radius=0.5, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1e3, 2.0)], box=box)
    writer = dk.VTKWriter(tmp_path / "out", every=0.5)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[writer])
    sim.run(2.0, progress=False)
    sim.close()
    script = tmp_path / "check.py"
    script.write_text(PVPYTHON_BOX)
    done = subprocess.run(["pvpython", str(script), str(tmp_path / "out" / "particles_box.pvd")], capture_output=True,
                          text=True, timeout=120)
    rows = [list(map(float, line.split()[1:])) for line in done.stdout.splitlines() if line.startswith("BOX")]
    assert len(rows) == 5, done.stdout + done.stderr
    for t, *bounds in rows:
        size = box.size_at(t)
        assert np.allclose(bounds, [0, size[0], 0, size[1], 0, size[2]], rtol=1e-12, atol=1e-12)
    assert rows[-1][2] == pytest.approx(8.0 * 0.6) and rows[-1][4] == pytest.approx(8.0 * 1.2)
    state = tmp_path / "view.pvsm"
    done = subprocess.run(["pvpython", str(dk.io.paraview_script()), str(writer.pvd), "--state", str(state)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "box outline at every frame (the box deforms: from 4.8 x 8 x 8 to 8 x 9.6 x 8 at most)" in done.stdout
    assert "particles_box.pvd" in state.read_text()


def test_trails_are_written_at_exit_when_the_writer_is_never_closed(tmp_path):
    code = textwrap.dedent(f"""
        import demkit as dk
        p = dk.Particles([[0, 0, 0], [3, 0, 0]], velocity=[[0.1, 0, 0], [0, 0, 0]], radius=1.0)
        scene = dk.Scene(p, [dk.KelvinVoigt(1.0, 0.1)])
        sim = dk.Simulation(scene, dk.EulerCromer(dt=0.01), writers=[dk.VTKWriter({str(tmp_path / 'out')!r}, every=1.0)])
        sim.run(3.0)
    """)
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    assert (tmp_path / "out" / "particles_trails.vtp").exists()
    assert len(read_pvd(tmp_path / "out" / "particles.pvd")) == 4


def test_documented_writer_example_runs(tmp_path, monkeypatch):
    import re
    from pathlib import Path

    doc = Path(__file__).resolve().parents[1] / "docs" / "visualisation.md"
    first = re.findall(r"```python\n(.*?)```", doc.read_text(), flags=re.S)[0]
    monkeypatch.chdir(tmp_path)
    namespace = {}
    exec(compile(first, str(doc), "exec"), namespace)
    assert namespace["writer"].frames_written == 21
    assert len(read_pvd(tmp_path / "out" / "particles.pvd")) == 21
    assert (tmp_path / "out" / "particles_trails.vtp").exists()


# ---- periodic boxes: image counts, the box, unwrapped trails ------------------------------------

def crossing_trajectory(frames=12):
    """Sphere 0 runs along +x through the periodic x side (L = 10) at t = 4; sphere 1 sits still."""
    box = dk.Box([10.0, 8.0, 6.0], periodic=[True, True, False])
    t = np.arange(frames) * 1.0
    unwrapped = np.zeros((frames, 2, 3))
    unwrapped[:, 0] = np.c_[8.0 + 0.5 * t, np.full(frames, 4.0), np.full(frames, 3.0)]
    unwrapped[:, 1] = [2.0, 2.0, 2.0]
    position, image = box.wrap(unwrapped)
    velocity = np.zeros_like(position)
    velocity[:, 0, 0] = 0.5
    traj = dk.Trajectory(t, position, velocity, None, None, {}, None, np.full(2, 0.4), np.ones(2),
                         np.full(2, 0.064), np.array([5, 9]), image=image, box=box)
    return traj, unwrapped


def slowing_trajectory(n=20, frames=3):
    """n spheres in a row (more than paraview_setup's ID_COLOURS_UP_TO: coloured by speed), their
    speeds spread over 0.077 .. 2.9 in the first frame and 0.005 .. 0.5 in the last."""
    t = np.arange(frames) * 1.0
    position = np.zeros((frames, n, 3))
    position[:, :, 0] = 2.5 * np.arange(n)
    speed = np.linspace(np.linspace(0.077, 2.9, n), np.linspace(0.005, 0.5, n), frames)
    velocity = np.zeros_like(position)
    velocity[:, :, 1] = speed
    return dk.Trajectory(t, position, velocity, None, None, {}, None, np.full(n, 1.0), np.ones(n), np.full(n, 0.4),
                         np.arange(n))


@pytest.mark.skipif(shutil.which("pvpython") is None or shutil.which("xvfb-run") is None,
                    reason="needs ParaView's pvpython and xvfb-run (Debian packages 'paraview', 'xvfb')")
def test_paraview_screenshot_colours_span_the_speeds_of_the_frame_drawn(tmp_path):
    # the picture is of the last frame (speeds 0.005 .. 0.5); its colours were those of the first
    # frame's range (0.077 .. 2.9): every sphere blue. Now the fastest are red (cool-to-warm map).
    pvd = write_series(slowing_trajectory(), tmp_path / "series")
    png = tmp_path / "shot.png"
    for _ in range(3):  # xvfb-run -a can race another test's X server for a display number
        done = subprocess.run(["xvfb-run", "-a", "pvpython", str(dk.io.paraview_script()), str(pvd), "--state",
                               str(tmp_path / "view.pvsm"), "--screenshot", str(png)],
                              capture_output=True, text=True, timeout=120)
        if "bad X server connection" not in done.stderr:
            break
    assert done.returncode == 0, done.stdout + done.stderr
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB"), dtype=int)[:480]  # above the colour bar
    red = (rgb[..., 0] > 150) & (rgb[..., 2] < 90)
    blue = (rgb[..., 2] > 150) & (rgb[..., 0] < 110)
    assert red.sum() > 500 and blue.sum() > 500, (red.sum(), blue.sum())


def test_series_carries_the_box_and_image_counts_and_trails_do_not_jump(tmp_path):
    traj, unwrapped = crossing_trajectory()
    assert traj.image[:, 0, 0].tolist() == [0] * 4 + [1] * 8  # it does cross
    pvd = write_series(traj, tmp_path / "series")
    back = read_series(pvd)
    assert back.box == traj.box
    np.testing.assert_array_equal(back.image, traj.image)
    np.testing.assert_array_equal(back.position, traj.position)
    np.testing.assert_allclose(back.unwrapped(), unwrapped)
    _, data = dk.io.read_frame(tmp_path / "series" / "particles_000005.vtu")
    assert data["image"].dtype.kind == "i" and data["image"].shape == (2, 3)
    pv = pytest.importorskip("pyvista")
    trails = pv.read(tmp_path / "series" / "particles_trails.vtp")
    path = np.asarray(trails.points).reshape(2, len(traj), 3)[0]
    assert np.abs(np.diff(path, axis=0)).max() == pytest.approx(0.5)  # steps of 0.5, no jump of 10
    np.testing.assert_allclose(path, unwrapped[:, 0])
    np.testing.assert_array_equal(trails.field_data["box_size"], [10.0, 8.0, 6.0])
    np.testing.assert_array_equal(trails.field_data["box_periodic"], [1, 1, 0])
    # a series without a box reads back without one
    plain = read_series(write_series(three_spheres_trajectory(), tmp_path / "plain"))
    assert plain.box is None and plain.image is None


def three_spheres_trajectory():
    return dk.Simulation(three_spheres(), dk.EulerCromer(dt=DT)).run(0.2, record_every=0.1)


class StandIn:
    """What VTKWriter reads from a Simulation: time and scene (particles, interactions, box)."""

    def __init__(self, particles, box):
        self.time = 0.0
        self.scene = type("Scene", (), {"particles": particles, "interactions": (), "box": box})()


def test_writer_stores_the_scene_box_and_image_counts(tmp_path):
    traj, unwrapped = crossing_trajectory(frames=6)
    p = dk.Particles(traj.position[0], velocity=traj.velocity[0], radius=0.4, ids=traj.ids,
                     image=traj.image[0])
    sim = StandIn(p, traj.box)
    writer = dk.VTKWriter(tmp_path / "out", every=1.0)
    writer.open(sim)
    for k in range(len(traj)):
        sim.time, p.position[:], p.image[:] = traj.time[k], traj.position[k], traj.image[k]
        writer.write(sim)
    writer.close()
    back = read_series(writer.pvd)
    assert back.box == traj.box and writer.fields == ("velocity",)
    np.testing.assert_array_equal(back.image, traj.image)
    pv = pytest.importorskip("pyvista")
    path = np.asarray(pv.read(writer.series.trails).points).reshape(2, len(traj), 3)[0]
    np.testing.assert_allclose(path, unwrapped[:, 0])
    with pytest.raises(ValueError, match="malformed Box"):
        text = writer.pvd.read_text().replace('periodic="1 1 0"', 'periodic="1 1"')
        (tmp_path / "bad.pvd").write_text(text)
        dk.io.pvd.read_box(tmp_path / "bad.pvd")


FAKE_PARAVIEW = textwrap.dedent("""
    # paraview.simple as far as paraview_setup.py uses it: a series of 3 frames, 12 spheres with dipoles
    from unittest.mock import MagicMock

    def PVDReader(**options):
        reader = MagicMock()
        reader.TimestepValues = [0.0, 5.0, 10.0]
        reader.PointData.keys.return_value = ["id", "radius", "velocity", "dipole"]
        reader.PointData.__getitem__.return_value.GetRange.return_value = (0.5, 0.5)
        reader.GetDataInformation.return_value.GetNumberOfPoints.return_value = 12
        reader.GetDataInformation.return_value.GetBounds.return_value = (0.0, 1.0, 0.0, 2.0, 0.0, 3.0)
        return reader

    def CreateView(kind):
        view = MagicMock()
        view.CameraViewAngle = 30.0
        return view

    def SaveState(path):
        open(path, "w").write("<ParaView/>")

    def SaveScreenshot(path, view, **options):
        open(path, "wb").write(b"picture")

    def __getattr__(name):  # every other function of paraview.simple
        return MagicMock()
""")


def test_paraview_script_says_what_it_does_as_it_goes(tmp_path):
    """The set-up script prints a line a step, with the time, instead of working for minutes in silence
    (run here against a stand-in for paraview.simple: pvpython is rarely installed)."""
    fake = tmp_path / "fake" / "paraview"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("")
    (fake / "simple.py").write_text(FAKE_PARAVIEW)
    pvd = tmp_path / "particles.pvd"
    pvd.write_text('<VTKFile type="Collection"><Collection/><Box size="1 2 3" periodic="0 0 1"/></VTKFile>')
    done = subprocess.run([sys.executable, str(dk.io.paraview_script()), str(pvd), "--screenshot",
                           str(tmp_path / "shot.png")], capture_output=True, text=True, timeout=60,
                          env=dict(os.environ, PYTHONPATH=str(tmp_path / "fake")))
    assert done.returncode == 0, done.stderr
    steps = [line for line in done.stdout.splitlines() if line.startswith("[")]
    assert all(re.match(r"\[ *\d+\.\d s\] ", line) for line in steps)
    said = [line.split("] ", 1)[1] for line in steps]
    expected = ["loading ParaView", f"opening {pvd}", "reading the series' frame list",
                "3 frames (t = 0 to 10), 12 spheres; fields: id, radius, velocity, dipole", "sphere glyphs",
                "colouring by speed: the range follows the frame shown", "dipole arrows",
                "growing trails", "box outline 1 x 2 x 3", "camera: framing the box", "writing the state file",
                "rendering the last frame (t = 10)", "done"]
    assert len(said) == len(expected) and all(s.startswith(e) for s, e in zip(said, expected)), said
    assert (tmp_path / "particles.pvsm").exists() and (tmp_path / "shot.png").exists()
    # the colour range over the whole run, on request: it reads every frame first, and says so
    done = subprocess.run([sys.executable, str(dk.io.paraview_script()), str(pvd), "--colour-range", "run"],
                          capture_output=True, text=True, timeout=60,
                          env=dict(os.environ, PYTHONPATH=str(tmp_path / "fake")))
    assert done.returncode == 0, done.stderr
    assert "colouring by speed: its range over the whole run reads all 3 frames" in done.stdout


@pytest.mark.skipif(shutil.which("pvpython") is None or shutil.which("xvfb-run") is None,
                    reason="needs ParaView's pvpython and xvfb-run (Debian packages 'paraview', 'xvfb')")
def test_paraview_script_state_has_a_view_framing_the_box_and_the_screenshot_exits_cleanly(tmp_path):
    traj, _ = crossing_trajectory()
    pvd = write_series(traj, tmp_path / "series")
    state, png = tmp_path / "view.pvsm", tmp_path / "shot.png"
    for _ in range(3):  # xvfb-run -a can race another test's X server for a display number; not ours to test
        done = subprocess.run(["xvfb-run", "-a", "pvpython", str(dk.io.paraview_script()), str(pvd), "--state",
                               str(state), "--screenshot", str(png)], capture_output=True, text=True, timeout=120)
        if "bad X server connection" not in done.stderr:
            break
    assert done.returncode == 0, done.stdout + done.stderr  # was 1 (GLXBadContext at exit)
    assert "box" in done.stdout
    from PIL import Image

    pixels = np.asarray(Image.open(png).convert("RGB"), dtype=int)
    assert pixels.shape == (768, 1024, 3) and len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20
    root = ET.parse(state).getroot()
    view = next(p for p in root.iter("Proxy") if p.get("type") == "RenderView")
    layout = next(p for p in root.iter("Proxy") if p.get("type") == "ViewLayout")
    assert [i.get("view") for i in layout.iter("Item")] == [view.get("id")]  # the GUI shows the view

    def prop(name):
        element = next(e for e in view.iter("Property") if e.get("name") == name)
        return [float(x.get("value")) for x in element.iter("Element")]

    assert prop("CameraFocalPoint") == pytest.approx([5.0, 4.0, 3.0])  # the box centre
    assert np.linalg.norm(np.subtract(prop("CameraPosition"), [5.0, 4.0, 3.0])) > 7.0
    sources = {i.get("name") for c in root.iter("ProxyCollection") if c.get("name") == "sources"
               for i in c.iter("Item")}
    assert {"spheres", "box", "growing trails", "trails"} <= sources
