"""Off-screen pictures and animations. Everything that renders runs in a child process (a broken
OpenGL stack can crash the interpreter), without DISPLAY, so no X server is involved."""
import ctypes.util
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from conftest import headless_env, two_magnets
from PIL import Image, ImageSequence

import demkit as dk


def run_child(code, extra_env=None, timeout=300, probed=True):
    """Run ``code`` in a child Python without a display (``probed``: trusting this process's probe)."""
    env = headless_env(probed)
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
    done = run_child(CRASHING_PROBE.format(series=str(folder / "series"), png=str(tmp_path / "x.png")), probed=False)
    assert done.returncode == 0, done.stderr
    assert "CLEAR:" in done.stdout and "SIGSEGV" in done.stdout and "libegl1" in done.stdout
    assert not (tmp_path / "x.png").exists()


@pytest.mark.skipif(ctypes.util.find_library("OSMesa") is not None,
                    reason="OSMesa is installed here, so forcing it does not break rendering")
def test_missing_osmesa_gives_a_clear_error(rendered, tmp_path):
    folder, _ = rendered
    done = run_child(CRASHING_PROBE.replace("backend.PROBE_CODE", "# ").format(
        series=str(folder / "series"), png=str(tmp_path / "x.png")),
        extra_env={"VTK_DEFAULT_OPENGL_WINDOW": "vtkOSOpenGLRenderWindow"}, probed=False)
    assert done.returncode == 0, done.stderr
    assert "CLEAR:" in done.stdout and "vtkOSOpenGLRenderWindow" in done.stdout


def test_bad_arguments_fail_before_rendering(tmp_path):
    traj = dk.Simulation(two_magnets(x0=30.0), dk.EulerCromer(dt=0.01)).run(20.0, record_every=10.0)
    with pytest.raises(ValueError, match=".gif or .mp4"):
        dk.viz.animate(traj, tmp_path / "run.avi")
    with pytest.raises(ValueError, match="no frame has a time"):
        dk.viz.animate(traj, tmp_path / "run.gif", time_range=(100.0, 200.0))
    with pytest.raises(ValueError, match="out of range"):
        dk.viz.snapshot(traj, tmp_path / "x.png", frame_index=5)
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


# ---- many spheres: framing, colouring, subsets, periodic boxes --------------------------------

def touching_ball(n, radius=1.0):
    """The n sites of an fcc packing of touching spheres nearest to the origin."""
    a = 2 * radius * np.sqrt(2)
    g = np.arange(-5, 6)
    cells = np.array(np.meshgrid(g, g, g, indexing="ij")).reshape(3, -1).T
    sites = (cells[:, None, :] + np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])) * a
    sites = sites.reshape(-1, 3)
    return sites[np.argsort(np.linalg.norm(sites, axis=1), kind="stable")[:n]]


def trajectory(position, velocity=None, box=None, image=None, dipole=None, radius=1.0):
    """A Trajectory built by hand from positions (T,N,3)."""
    t, n = position.shape[:2]
    velocity = np.zeros_like(position) if velocity is None else velocity
    return dk.Trajectory(np.arange(t) * 1.0, position, velocity, None, dipole, {}, None, np.full(n, radius),
                         np.ones(n), np.full(n, 0.4 * radius**2), np.arange(n), image=image, box=box)


def exploded(n=200, fragments=5, far=225.0):
    """A cluster of n - fragments touching spheres and fragments flown ``far`` away (2 frames),
    each sphere with its own speed."""
    rng = np.random.default_rng(3)
    direction = rng.normal(size=(fragments, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    pos = np.vstack([touching_ball(n - fragments), far * direction])
    speed = np.r_[np.linspace(0.0, 0.01, n - fragments), np.full(fragments, 0.02)]
    velocity = np.vstack([np.zeros((n - fragments, 3)), direction]) * speed[:, None]
    velocity[: n - fragments, 0] = speed[: n - fragments]
    m = rng.normal(size=(n, 3))
    return trajectory(np.stack([pos, pos]), np.stack([velocity, velocity]),
                      dipole=np.stack([m, m]) / np.linalg.norm(m, axis=1)[None, :, None])


def straddling(L=30.0, frames=3):
    """A 13-sphere cluster around the corner x = y = 0 of a periodic box, plus a sphere that crosses
    the x side between frames 1 and 2, plus lone spheres."""
    box = dk.Box([L, L, L], periodic=True)
    ball = touching_ball(13) + [0.3, 0.2, L / 2]
    others = np.array([[L - 0.5, 20.0, 5.0], [10.0, 10.0, 10.0], [20.0, 5.0, 25.0]])
    unwrapped = np.repeat(np.vstack([ball, others])[None], frames, axis=0)
    unwrapped[:, 13, 0] += 0.4 * np.arange(frames)
    position, image = box.wrap(unwrapped)
    return trajectory(position, box=box, image=image)


def plan(source, shown=(-1,), **style):
    from demkit.viz.plan import Plan, Style

    frames = source
    shown = np.arange(len(frames.time))[list(shown)]
    return Plan(frames, Style(**style), shown)


def brute_force(position, radius, box, extra=0.0, scale=1.0):
    d = position[None, :, :] - position[:, None, :]
    if box is not None:
        d = box.minimum_image(d)
    close = np.linalg.norm(d, axis=2) < (radius[:, None] + radius[None, :]) * scale + extra
    np.fill_diagonal(close, False)
    return close


def test_clusters_and_contacts_agree_with_brute_force_in_open_and_periodic_space(rng):
    from scipy.sparse.csgraph import connected_components

    box = dk.Box([12.0, 12.0, 12.0], periodic=[True, True, False])
    position = rng.uniform(0, 12, (300, 3))
    radius = rng.uniform(0.4, 0.6, 300)
    for b in (None, box):
        touching = brute_force(position, radius, b, scale=1.01)
        np.testing.assert_array_equal(dk.viz.contacts(position, radius, b), touching.sum(axis=1))
        linked = brute_force(position, radius, b, extra=0.1 * radius.mean())
        count, label = connected_components(linked, directed=False)
        got = dk.viz.clusters(position, radius, b)
        assert got.max() + 1 == count
        for c in range(count):  # the same groups, ranked by size
            assert len(np.unique(got[label == c])) == 1
        sizes = np.bincount(got)
        assert np.all(np.diff(sizes) <= 0)
    # across the periodic x side: touching, so one cluster
    pair = np.array([[0.2, 6.0, 6.0], [11.9, 6.0, 6.0]])
    assert dk.viz.contacts(pair, 0.25, box).tolist() == [1, 1]
    assert dk.viz.clusters(pair, 0.25, box).tolist() == [0, 0]
    assert dk.viz.clusters(pair, 0.25, None).tolist() == [0, 1]


def test_default_framing_follows_the_cluster_the_box_or_everything():
    far = plan(exploded())
    assert far.framing.kind == "cluster" and far.colouring.name == "speed"
    assert np.ptp(far.framing.bounds.reshape(3, 2), axis=1).max() < 20  # not 450
    assert plan(exploded(), frame="all").framing.kind == "all"
    assert plan(straddling()).framing.kind == "box"
    assert plan(straddling()).framing.outline.tolist() == [0, 30, 0, 30, 0, 30]
    two = trajectory(np.array([[[0.0, 0, 0], [50.0, 0, 0]]]))
    assert plan(two).framing.kind == "all" and plan(two).colouring.name == "id"
    assert plan(two, subset=[1]).framing.bounds.tolist() == [49, 51, -1, 1, -1, 1]


def test_a_pile_at_the_bottom_of_a_tall_box_fills_the_picture_with_the_box_outlined():
    # 4 x 4 x 2 unit spheres on the floor of a 8 x 8 x 80 box: framing the box drew them as a strip
    # a fortieth of its height; 'auto' frames the spheres and still outlines the box
    g = np.arange(4) * 2.0 + 1.0
    pile = np.stack(np.meshgrid(g, g, [1.0, 3.0], indexing="ij"), -1).reshape(-1, 3)
    box = dk.Box([8.0, 8.0, 80.0], periodic=[True, True, False])
    p = plan(trajectory(pile[None], box=box))
    assert p.framing.kind == "all"
    assert p.framing.bounds.tolist() == [0, 8, 0, 8, 0, 4]  # the pile (centres 1 .. 7), padded by a radius
    assert p.framing.outline.tolist() == [0, 8, 0, 8, 0, 80]
    assert not p.isolate  # the outline is drawn
    gas = np.random.default_rng(2).uniform(0, 80, (40, 3)) * [0.1, 0.1, 1.0]
    assert plan(trajectory(gas[None], box=box)).framing.kind == "box"  # spheres filling it: the box


def test_a_cluster_across_a_periodic_side_is_drawn_in_one_piece():
    source = straddling()
    p = plan(source, frame="cluster")
    members = p.framing.members
    assert members.sum() == 13
    drawn = p.framing.place(source.position[-1])[members]
    assert np.ptp(drawn, axis=0).max() < 8  # wrapped, it spans the box (about 30)
    assert np.ptp(source.position[-1][members], axis=0).max() > 25
    box = p.framing.outline.reshape(3, 2)
    assert np.all(drawn >= box[:, 0]) and np.all(drawn < box[:, 1])  # the outline moved with it


def test_colour_fields():
    source = exploded()
    speed = plan(source, frame="all").colouring
    assert speed.title == "speed" and speed.bar and speed.clim == pytest.approx((0.0, 0.02))
    assert plan(source).colouring.clim == pytest.approx((0.0, 0.01))  # the range of the spheres framed
    contacts = plan(source, color_by="contacts").colouring
    assert contacts.values(1).max() == 12 and contacts.values(1)[-5:].tolist() == [0] * 5
    assert contacts.clim[1] % (contacts.n_labels - 1) == 0  # whole numbers at the labels
    dipole = plan(source, color_by="dipole").colouring
    np.testing.assert_allclose(dipole.values(0), source.dipole[0][:, 2])
    assert dipole.clim == (-1.0, 1.0)
    cluster = plan(source, color_by="cluster", frame="all").colouring
    assert cluster.values(0)[:195].max() == 0 and sorted(cluster.values(0)[195:]) == [1, 2, 3, 4, 5]
    assert cluster.bar and len(cluster.annotations) == 6
    values = np.arange(200.0)
    assert plan(source, color_by=values).colouring.values(1)[7] == 7
    assert plan(source, color_by=np.stack([values, 2 * values])).colouring.values(1)[7] == 14
    assert plan(source, color_by="velocity").colouring.title == "velocity (magnitude)"
    assert plan(source, color_by=values).colouring.title == "value"
    assert plan(source, color_by=values, color_label="angle (deg)").colouring.title == "angle (deg)"
    colours = speed.rgb(np.array([0.0, 0.02, np.nan]))
    assert colours[0].tolist() == [68, 1, 84] and colours[1].tolist() == [253, 231, 36]
    assert colours[2].tolist() == [128, 128, 128]


def test_bad_drawing_arguments_are_clear_value_errors(tmp_path):
    source, png = exploded(), tmp_path / "x.png"
    cases = [(dict(color_by="temperature"), "cannot colour by 'temperature'.*contacts.*speed.*dipole"),
             (dict(color_by=np.ones(7)), r"shape \(N,\)"),
             (dict(subset=[3, 200]), "out of range for 200 spheres"),
             (dict(subset=np.ones(5, bool)), "one entry per sphere"),
             (dict(subset=[]), "selects no sphere"),
             (dict(subset="largest"), "subset must be"),
             (dict(bounds=(0, 1, 0, 1)), "6 finite numbers"),
             (dict(bounds=(0, 1, 2, 1, 0, 1)), "min < max"),
             (dict(zoom=0), "zoom must be a positive"),
             (dict(color_label=3), "color_label must be a string"),
             (dict(zoom="near"), "zoom must be a positive"),
             (dict(frame="box"), "needs a source with a box"),
             (dict(frame="middle"), "frame must be one of"),
             (dict(frame=3), "frame_index=3"),
             (dict(cmap="rainbowish"), "unknown colour map"),
             (dict(clim=(1, 0)), "low < high")]
    for options, message in cases:
        with pytest.raises(ValueError, match=message):
            dk.viz.snapshot(source, png, **options)
    with pytest.raises(ValueError, match="subset"):
        dk.viz.animate(source, tmp_path / "x.gif", subset=lambda frames, k: [999])
    assert not png.exists()


RENDER_MANY = """
    import sys
    import numpy as np
    import demkit as dk
    from demkit.viz.plan import Plan, Style
    from demkit.viz.render import FrameDrawer, load
    out = {out!r}
    size = dict(window_size=(400, 300))
    dk.viz.snapshot(out + "/exploded", out + "/cluster.png", frame="cluster", **size)
    dk.viz.snapshot(out + "/exploded", out + "/all.png", frame="all", **size)
    dk.viz.snapshot(out + "/exploded", out + "/speed.png", color_by="speed", arrows=False, **size)
    blue = (np.arange(200) % 10 == 0) & (np.arange(200) < 195)  # the cluster's spheres in palette colour 0
    dk.viz.snapshot(out + "/exploded", out + "/subset.png", color_by="id", subset=blue, arrows=False, **size)
    dk.viz.snapshot(out + "/exploded", out + "/ids.png", color_by="id", arrows=False, **size)
    dk.viz.snapshot(out + "/exploded", out + "/zoom.png", frame="cluster", zoom=3, **size)
    frames = load(out + "/straddling")
    dk.viz.snapshot(frames, out + "/box.png", view="xy", trail=5, **size)
    drawer = FrameDrawer(Plan(frames, Style(trail=5.0, view="xy"), np.array([2])))
    trails = drawer._trails(2, np.arange(16))
    drawer.close()
    lines = np.asarray(trails.lines).reshape(-1, 3)[:, 1:]
    step = np.linalg.norm(np.diff(np.asarray(trails.points)[lines], axis=1)[:, 0], axis=1)
    print("TRAILS", len(lines), step.max())
    dk.viz.snapshot(out + "/walled", out + "/walls.png", view="xz", arrows=False, color_by="id", **size)
    walled = dk.Scene(dk.Particles(position=[[0.0, 0.0, 0.5], [1.0, 0.0, 0.5]], radius=0.5, mass=1.0),
                      [dk.KelvinVoigt(1e3, 5.0), dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 1.1), (0, 0, -1))])
    traj = dk.Simulation(walled, dk.VelocityVerlet(1e-3)).run(0.1, record_every=0.1, progress=False)
    dk.viz.snapshot(traj, out + "/walls_trajectory.png", view="xz", arrows=False, color_by="id", **size)
"""


@pytest.fixture(scope="module")
def many(tmp_path_factory):
    """Series of the test scenes written to disk, drawn in a child process; returns the folder."""
    folder = tmp_path_factory.mktemp("many")
    dk.write_series(exploded(), folder / "exploded", trails=False)
    dk.write_series(straddling(), folder / "straddling", trails=False)
    walled = dk.Scene(dk.Particles(position=[[0.0, 0.0, 0.5], [1.0, 0.0, 0.5]], radius=0.5, mass=1.0),
                      [dk.KelvinVoigt(1e3, 5.0), dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 1.1), (0, 0, -1))])
    dk.Simulation(walled, dk.VelocityVerlet(1e-3), writers=[dk.VTKWriter(folder / "walled", every=0.1)]).run(0.1)
    done = run_child(RENDER_MANY.format(out=str(folder)))
    assert done.returncode == 0, done.stdout + done.stderr
    return folder, done.stdout


def test_framing_on_the_cluster_fills_the_picture(many):
    folder, _ = many
    cluster, everything = (not_blank(Image.open(folder / f)) for f in ("cluster.png", "all.png"))
    assert cluster > 0.3 and everything < 0.02  # a dot when 5 fragments are 225 away
    assert not_blank(Image.open(folder / "zoom.png")) > 0.9


def test_colour_by_speed_has_a_colour_bar_and_many_colours(many):
    folder, _ = many
    pixels = np.asarray(Image.open(folder / "speed.png").convert("RGB"), dtype=int)
    bar, spheres = pixels[:, 320:], pixels[:, :320]  # the bar is in the right sixth
    assert has_colour(Image.fromarray(bar.astype(np.uint8)), (253, 231, 37), 40)  # viridis top
    assert has_colour(Image.fromarray(bar.astype(np.uint8)), (68, 1, 84), 40)     # and bottom
    drawn = spheres[np.abs(spheres - 255).sum(axis=2) > 30]
    hues = {tuple(c) for c in (drawn // 32)}
    assert len(hues) > 15


def test_subset_draws_only_those_spheres(many):
    folder, _ = many
    every, subset = Image.open(folder / "ids.png"), Image.open(folder / "subset.png")
    # coloured by id, the whole cluster shows palette colours 0, 1, 2, ...; the subset (every tenth
    # sphere of the cluster: ids 0, 10, 20, ...) only colour 0, blue
    others = ((214, 39, 40), (44, 160, 44), (255, 127, 14), (188, 189, 34))
    assert all(has_colour(every, c, 60) for c in others)
    assert not any(has_colour(subset, c, 60) for c in others)
    assert has_colour(subset, (31, 119, 180), 60)
    assert not_blank(subset) > 0.1  # framed on the subset, not on the fragments 225 away


def test_periodic_box_outline_and_trails_without_jumps(many):
    folder, out = many
    line = next(l for l in out.splitlines() if l.startswith("TRAILS"))
    _, count, longest = line.split()
    assert int(count) == 16 * 2 - 1  # the step across the side is left out
    assert float(longest) == pytest.approx(0.4)
    pixels = np.asarray(Image.open(folder / "box.png").convert("RGB"), dtype=int)
    grey = (np.abs(pixels - pixels[..., :1]).sum(axis=2) < 10) & (pixels[..., 0] < 200) & (pixels[..., 0] > 60)
    rows, cols = np.nonzero(grey)
    assert np.ptp(rows) > 250 and np.ptp(cols) > 250  # the outline spans the picture


def test_the_walls_of_a_series_are_drawn_with_their_rims(many):
    """Two spheres on a floor under a lid, seen along y: the two walls' rims are dark grey lines across the
    picture below and above the spheres (demkit.io.walls, demkit.viz.render)."""
    folder, _ = many
    pixels = np.asarray(Image.open(folder / "walls.png").convert("RGB"), dtype=int)
    rim = (np.abs(pixels - np.array([80, 80, 80])).sum(axis=2) < 40).mean(axis=1)  # fraction of each row
    rows = np.flatnonzero(rim > 0.5)
    spheres = np.flatnonzero((np.abs(pixels - pixels[..., :1]).sum(axis=2) > 60).any(axis=1))  # coloured rows
    assert len(rows) and rows.min() < spheres.min() and rows.max() > spheres.max()
    # the run's Trajectory draws the same walls where their motion has them (the same picture)
    again = np.asarray(Image.open(folder / "walls_trajectory.png").convert("RGB"), dtype=int)
    assert np.mean(np.abs(again - pixels).sum(axis=2) > 30) < 0.002


def test_rings_and_chains_are_told_apart():
    from demkit.clustering import clusters, contacts, rings_and_chains

    ring = [[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0, 2 * np.pi, 7)[:-1]]  # side 1: touching
    chain = [[10.0 + k, 0.0, 0.0] for k in range(4)]
    triangle_with_tail = [[20.0, 0.0, 0.0], [21.0, 0.0, 0.0], [20.5, np.sqrt(0.75), 0.0], [22.0, 0.0, 0.0]]
    x = np.array(ring + chain + triangle_with_tail + [[30.0, 0.0, 0.0]])
    labels, counts = clusters(x, 0.5), contacts(x, 0.5)
    rings, chains = rings_and_chains(labels, counts)
    assert rings == [6] and chains == [4]  # the triangle with a tail is neither, a lone sphere neither


RENDER_VISIBILITY = """
    import json
    import numpy as np
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy
    import demkit as dk
    from demkit.viz.plan import Plan, Style
    from demkit.viz.render import BAR_SPACE, TITLE_OVERHANG, FrameDrawer

    def gas_with_a_cluster(L=24.0, n=500, seed=5):
        # a random walk of 40 touching unit spheres in the middle of a periodic box, 460 lone
        # spheres all around it (none touching: gaps of at least 0.6)
        rng = np.random.default_rng(seed)
        pos = [np.full(3, L / 2)]
        while len(pos) < 40:
            step = rng.normal(size=3)
            x = pos[-1] + 2.0 * step / np.linalg.norm(step)
            if np.min(np.linalg.norm(np.array(pos[:-1] + [x + 10 * L]) - x, axis=1)) > 2.2 and \\
                    np.all(np.abs(x - L / 2) < 6):
                pos.append(x)
        placed, k = np.zeros((n, 3)), len(pos)
        placed[:k] = pos
        while k < n:  # candidates drawn as one at a time, tried in batches against those placed
            batch = rng.uniform(0, L, (256, 3))
            d = placed[:k, None, :] - batch[None]
            d -= L * np.round(d / L)
            free = np.sqrt((d * d).sum(axis=2)).min(axis=0) > 2.6
            start = k
            for x in batch[free]:
                d = placed[start:k] - x  # and against those placed from this batch
                d -= L * np.round(d / L)
                if k < n and (k == start or np.sqrt((d * d).sum(axis=1)).min() > 2.6):
                    placed[k] = x
                    k += 1
        pos = placed[None]
        return dk.Trajectory(np.zeros(1), pos, np.zeros_like(pos), None, None, {{}}, None, np.ones(n), np.ones(n),
                             np.full(n, 0.4), np.arange(n), box=dk.Box([L] * 3, periodic=True))

    def seen(drawer, area):
        # the spheres with at least one pixel in the rendered image within ``area`` (x0, y0, x1, y1),
        # by actor, from VTK's hardware selection (what the picture shows, occlusion included)
        selector = vtk.vtkHardwareSelector()
        selector.SetRenderer(drawer.plotter.renderer)
        selector.SetArea(*area)
        selector.SetFieldAssociation(vtk.vtkDataObject.FIELD_ASSOCIATION_CELLS)
        result = selector.Select()
        out = {{"spheres": set(), "faded": set()}}
        for i in range(result.GetNumberOfNodes()):
            node = result.GetNode(i)
            prop = node.GetProperties().Get(vtk.vtkSelectionNode.PROP())
            for name, index in drawer.drawn.items():
                if name in drawer._actors and prop is drawer._actors[name][1]:
                    cells = vtk_to_numpy(node.GetSelectionList())
                    out[name] |= set(index[np.unique(cells // drawer.sphere.n_cells)].tolist())
        return out

    source = gas_with_a_cluster()
    w, h = 640, 480
    report = {{}}
    for isolate in (True, False):
        plan = Plan(source, Style(frame="cluster", color_by="cluster", window_size=(w, h)), np.array([0]))
        report["isolated"] = plan.isolate
        plan.isolate = isolate
        drawer = FrameDrawer(plan)
        drawer.draw(0)
        members = set(np.flatnonzero(plan.framing.members).tolist())
        visible = seen(drawer, (0, 0, w - 1, h - 1))["spheres"] & members
        bar_left = int((1 - BAR_SPACE - TITLE_OVERHANG) * w)
        in_bar = seen(drawer, (bar_left, 0, w - 1, h - 1))
        in_label = seen(drawer, (0, int(0.93 * h), int(0.15 * w), h - 1))
        report[str(isolate)] = dict(members=len(members), visible=len(visible) / len(members),
                                    bar=sum(map(len, in_bar.values())), label=sum(map(len, in_label.values())))
        drawer.close()
    print("VISIBLE" + json.dumps(report))
"""


def test_a_cluster_framed_in_3d_is_seen_whole_and_nothing_covers_the_bar_or_the_label():
    # the 3-D gas: framing the largest cluster put the camera inside the gas, where lone
    # spheres in front hid it and crossed the colour bar. Counted in the rendered image by VTK's
    # hardware selection (a sphere counts as seen with one pixel showing).
    done = run_child(RENDER_VISIBILITY.format())
    assert done.returncode == 0, done.stdout + done.stderr
    report = json.loads(next(l for l in done.stdout.splitlines() if l.startswith("VISIBLE"))[7:])
    isolated, drawn_as_before = report["True"], report["False"]
    assert report["isolated"] and isolated["members"] == 40
    assert isolated["visible"] >= 0.9  # 39 of 40 measured: one member behind others of the cluster
    assert isolated["bar"] == 0 and isolated["label"] == 0
    # drawn as before (every sphere solid) the same picture hid much of it (0.6 measured) and the
    # bar and label had spheres behind them: the measure tells the two apart
    assert drawn_as_before["visible"] < 0.8 and drawn_as_before["bar"] > 0


def test_the_time_label_is_rounded_to_what_tells_frames_apart():
    from demkit.viz.render import time_label
    times = np.arange(31) * 0.01 - 2e-6  # frames of a step that does not divide their spacing
    assert time_label(times, 30) == "t = 0.300" and time_label(times, 0) == "t = 0.000"
    assert time_label(np.arange(5) * 0.025, 3) == "t = 0.075"
    assert time_label(np.array([0.0, 250.0, 500.0]), 1) == "t = 250"
    assert time_label(np.array([1.2345678]), 0) == "t = 1.23457"  # one frame: six digits


def test_default_trails_leave_a_gas_readable():
    from demkit.viz.plan import TRAIL_RADII, default_trail

    # 50 spheres of radius 0.5 at speed 2 for 100 time units: trails as long as 3 radii take (0.75),
    # not a quarter of the run (25, 50 diameters); two spheres keep a quarter of the run
    t = np.arange(101.0)
    position = np.zeros((101, 50, 3))
    position[:, :, 0] = 2.0 * t[:, None]
    velocity = np.zeros_like(position)
    velocity[..., 0] = 2.0
    gas = trajectory(position, velocity, radius=0.5)
    assert default_trail(gas, np.arange(101)) == pytest.approx(TRAIL_RADII * 0.5 / 2.0)
    no_velocity = trajectory(position, radius=0.5)
    no_velocity.velocity = None
    assert default_trail(no_velocity, np.arange(101)) == pytest.approx(0.75)  # from the steps
    pair = trajectory(position[:, :2], velocity[:, :2], radius=0.5)
    assert default_trail(pair, np.arange(101)) == pytest.approx(25.0)
    assert default_trail(gas, np.array([40])) == pytest.approx(0.75)  # a snapshot: frames 0..40


def test_a_child_trusts_its_parents_probe_only_for_the_same_window(monkeypatch):
    """The probe's result is handed to child processes (a sweep's workers, the tests' scripts) through
    DEMKIT_RENDERING_PROBED; a child trusts it only when it would try the same window first."""
    from demkit.viz import backend
    monkeypatch.setattr(backend, "_chosen", None)
    for variable in ("DISPLAY", "WAYLAND_DISPLAY", backend.WINDOW_VARIABLE):
        monkeypatch.delenv(variable, raising=False)
    monkeypatch.setenv(backend.PROBED_VARIABLE, "vtkEGLRenderWindow|llvmpipe (LLVM 15.0.6)|vtkEGLRenderWindow")
    assert backend._inherited() == {"window": "vtkEGLRenderWindow", "renderer": "llvmpipe (LLVM 15.0.6)",
                                     "variable": "vtkEGLRenderWindow"}
    assert __import__("os").environ[backend.WINDOW_VARIABLE] == "vtkEGLRenderWindow"
    monkeypatch.setenv(backend.WINDOW_VARIABLE, "vtkOSOpenGLRenderWindow")  # the user asks for another
    assert backend._inherited() is None
    monkeypatch.delenv(backend.WINDOW_VARIABLE)
    monkeypatch.setenv(backend.PROBED_VARIABLE, "vtkXOpenGLRenderWindow|some GPU|")  # the parent's display
    assert backend._inherited() is None  # this process has none
    monkeypatch.setenv(backend.PROBED_VARIABLE, "garbage")
    assert backend._inherited() is None
    monkeypatch.setenv(backend.PROBED_VARIABLE, "vtkEGLRenderWindow|llvmpipe|vtkEGLRenderWindow")
    called = []
    monkeypatch.setattr(backend, "probe", lambda window: called.append(window) or (False, "not here"))
    assert backend.ensure_rendering()["window"] == "vtkEGLRenderWindow" and called == []
