"""Off-screen pictures and animations. Everything that renders runs in a child process (a broken
OpenGL stack can crash the interpreter), without DISPLAY, so no X server is involved."""
import ctypes.util
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from conftest import two_magnets
from PIL import Image, ImageSequence

import demkit as dk


def run_child(code, extra_env=None, timeout=300):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY",
                                                           "VTK_DEFAULT_OPENGL_WINDOW")}
    env.update(extra_env or {})
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          env=env, timeout=timeout)


def not_blank(image, background=(255, 255, 255)):
    """Fraction of pixels that differ from the background."""
    rgb = np.asarray(image.convert("RGB"), dtype=int)
    return float(np.mean(np.abs(rgb - np.array(background)).sum(axis=2) > 30))


def has_colour(image, rgb, tolerance=60):
    pixels = np.asarray(image.convert("RGB"), dtype=int)
    return bool((np.abs(pixels - np.array(rgb)).sum(axis=2) < tolerance).any())


RENDER_ALL = """
    import json, sys
    import demkit as dk
    from demkit.viz.__main__ import main as cli
    import numpy as np
    out = sys.argv[1] if len(sys.argv) > 1 else {out!r}
    series = {series!r}
    info = dk.viz.rendering_info()
    dk.viz.snapshot(series, out + "/last.png", window_size=(400, 300))
    dk.viz.snapshot(series + "/particles_000003.vtu", out + "/frame.png", window_size=(400, 300), view="iso")
    dk.viz.animate(series, out + "/run.gif", max_frames=12, window_size=(320, 240), fps=10)
    dk.viz.animate(dk.read_series(series), out + "/run.mp4", max_frames=12, window_size=(320, 240))
    assert cli(["snapshot", series, out + "/cli.png", "--time", "150"]) == 0
    print("INFO" + json.dumps(info))
"""


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Write a short collision series, then render it in a child process; returns the folder."""
    folder = tmp_path_factory.mktemp("viz")
    writer = dk.VTKWriter(folder / "series", every=25.0)
    sim = dk.Simulation(two_magnets(x0=25.0), dk.EulerCromer(dt=0.01), writers=[writer])
    sim.run(400.0)
    sim.close()
    done = run_child(RENDER_ALL.format(out=str(folder), series=str(folder / "series")))
    assert done.returncode == 0, done.stdout + done.stderr
    info = json.loads(next(l for l in done.stdout.splitlines() if l.startswith("INFO"))[4:])
    return folder, info


def test_headless_backend_needs_no_x_server(rendered):
    _, info = rendered
    assert info["window"] in ("vtkEGLRenderWindow", "vtkOSOpenGLRenderWindow")


def test_snapshot_is_not_blank(rendered):
    folder, _ = rendered
    for name in ("last.png", "frame.png", "cli.png"):
        image = Image.open(folder / name)
        assert image.size == ((400, 300) if name != "cli.png" else (1024, 768))
        assert 0.01 < not_blank(image) < 0.9
    last = Image.open(folder / "last.png")
    assert has_colour(last, (31, 119, 180), 90) and has_colour(last, (214, 39, 40), 90)  # both spheres


def test_gif_has_changing_frames(rendered):
    folder, _ = rendered
    frames = [f.convert("RGB") for f in ImageSequence.Iterator(Image.open(folder / "run.gif"))]
    assert len(frames) >= 10
    assert all(not_blank(f) > 0.005 for f in frames)
    assert not np.array_equal(np.asarray(frames[0]), np.asarray(frames[-1]))


def test_mp4_decodes_to_frames(rendered):
    imageio_ffmpeg = pytest.importorskip("imageio_ffmpeg")
    folder, _ = rendered
    reader = imageio_ffmpeg.read_frames(str(folder / "run.mp4"))
    meta = next(reader)
    frames = [np.frombuffer(f, np.uint8).reshape(meta["size"][1], meta["size"][0], 3) for f in reader]
    assert len(frames) == 12 and meta["size"] == (320, 240)
    assert not_blank(Image.fromarray(frames[-1])) > 0.005


CRASHING_PROBE = """
    import demkit.viz as viz
    from demkit.viz import backend
    backend.PROBE_CODE = "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)"
    try:
        viz.snapshot({series!r}, {png!r})
    except viz.RenderingUnavailable as err:
        print("CLEAR:", err)
"""


def test_crashing_gl_stack_gives_a_clear_error(rendered, tmp_path):
    folder, _ = rendered
    done = run_child(CRASHING_PROBE.format(series=str(folder / "series"), png=str(tmp_path / "x.png")))
    assert done.returncode == 0, done.stderr
    assert "CLEAR:" in done.stdout and "SIGSEGV" in done.stdout and "libegl1" in done.stdout
    assert not (tmp_path / "x.png").exists()


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is not None,
                    reason="OSMesa is installed here, so forcing it does not break rendering")
def test_missing_osmesa_gives_a_clear_error(rendered, tmp_path):
    folder, _ = rendered
    done = run_child(CRASHING_PROBE.replace("backend.PROBE_CODE", "# ").format(
        series=str(folder / "series"), png=str(tmp_path / "x.png")),
        extra_env={"VTK_DEFAULT_OPENGL_WINDOW": "vtkOSOpenGLRenderWindow"})
    assert done.returncode == 0, done.stderr
    assert "CLEAR:" in done.stdout and "vtkOSOpenGLRenderWindow" in done.stdout


def test_bad_arguments_fail_before_rendering(tmp_path):
    traj = dk.Simulation(two_magnets(x0=30.0), dk.EulerCromer(dt=0.01)).run(20.0, record_every=10.0)
    with pytest.raises(ValueError, match=".gif or .mp4"):
        dk.viz.animate(traj, tmp_path / "run.avi")
    with pytest.raises(ValueError, match="no frame has a time"):
        dk.viz.animate(traj, tmp_path / "run.gif", time_range=(100.0, 200.0))
    with pytest.raises(ValueError, match="out of range"):
        dk.viz.snapshot(traj, tmp_path / "x.png", frame=5)
    with pytest.raises(ValueError, match="view"):
        dk.viz.snapshot(traj, tmp_path / "x.png", view="top")
    with pytest.raises(TypeError, match="cannot draw"):
        dk.viz.snapshot(42, tmp_path / "x.png")
    with pytest.raises(ValueError, match="no .pvd"):
        dk.viz.snapshot(tmp_path, tmp_path / "x.png")


def test_two_magnet_example_writes_a_series_and_an_animation(tmp_path):
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "two_magnets" / "watch.py"
    done = run_child(f"import runpy, sys; sys.argv = ['watch.py', '--out', {str(tmp_path)!r}, '--frames', '8']; "
                     f"runpy.run_path({str(script)!r}, run_name='__main__')")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "first contact" in done.stdout
    series = dk.read_series(tmp_path / "vtk")
    assert len(series) == 451 and series.dipole is not None
    assert (tmp_path / "vtk" / "particles_trails.vtp").exists()
    frames = list(ImageSequence.Iterator(Image.open(tmp_path / "collision.gif")))
    assert len(frames) == 8 and all(not_blank(f) > 0.005 for f in frames)
