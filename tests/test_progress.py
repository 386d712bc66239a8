"""Progress bars (tqdm) for runs and animations, the compile notice, and `demkit render`."""
import io
import os
import signal
import subprocess
import sys
import textwrap
import threading
import uuid
from types import SimpleNamespace

import numba
import numpy as np
import pytest
from conftest import demkit_in_process, headless_env, two_magnets
from tqdm import tqdm

import demkit as dk
from demkit import progress as prog
from demkit.engine import notice


@pytest.fixture
def warm():
    """A simulation of the paper's collision whose kernels are compiled (no compile notice later)."""
    sim = dk.Simulation(two_magnets(), dk.EulerCromer(dt=0.01))
    sim.run(1.0, progress=False)
    return sim


def final_line(err):
    """The bar as last drawn: tqdm redraws in place with carriage returns."""
    return err.replace("\r", "\n").strip().splitlines()[-1]


def test_a_forced_bar_reaches_the_total_with_the_simulated_time_and_closes(warm, capsys):
    capsys.readouterr()
    warm.run(2000.0, record_every=10.0, progress=True)
    err = capsys.readouterr().err
    last = final_line(err)
    assert "100%" in last and "200k/200k" in last and "t = 2001/2001" in last and "step/s" in last
    assert err.endswith("\n") and not tqdm._instances  # closed, left on screen
    warm.run(until=3001.0, progress=True)  # continuing: simulated time counts from where it is
    assert "t = 3001/3001" in final_line(capsys.readouterr().err)


def test_no_bar_without_a_terminal_or_when_switched_off(warm, capsys, monkeypatch):
    capsys.readouterr()
    warm.run(3000.0, progress=None)  # stderr is captured: not a terminal
    warm.run(3000.0, progress=False)
    assert capsys.readouterr().err == ""
    monkeypatch.setattr(prog, "_is_terminal", lambda stream: True)
    monkeypatch.setenv("DEMKIT_QUIET", "1")
    warm.run(3000.0)
    assert capsys.readouterr().err == ""
    with pytest.raises(TypeError, match="progress must be None"):
        warm.run(10.0, progress="yes")


class FakeClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


@pytest.mark.parametrize("seconds_per_unit, shown", [(0.1, True), (0.002, False)])
def test_automatic_bars_only_for_long_work_on_a_terminal(monkeypatch, capsys, seconds_per_unit, shown):
    clock = FakeClock()
    monkeypatch.setattr(prog.time, "perf_counter", clock)
    monkeypatch.setattr(prog, "_is_terminal", lambda stream: True)
    monkeypatch.delenv("DEMKIT_QUIET", raising=False)
    with prog.Progress(100, None, desc="work") as bar:
        for done in range(0, 101, 10):
            bar.update(done)
            clock.now += 10 * seconds_per_unit
    err = capsys.readouterr().err
    # 100 units at 0.1 s: 10 s in all, shown from the first update after 0.5 s; at 2 ms: 0.2 s, never
    assert ("100/100" in final_line(err)) if shown else err == ""


def test_the_bar_is_closed_when_a_run_stops_with_an_error(capsys):
    p = dk.Particles([[0.0, 0, 0], [3.0, 0, 0]], velocity=[[2.0, 0, 0], [-2.0, 0, 0]], radius=1.0)
    sim = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(0.5)]), dk.EulerCromer(1e-3))  # tunnels at t ~ 0.5
    with pytest.raises(dk.SimulationError, match="overlap by more than"):
        sim.run(5.0, progress=True)
    err = capsys.readouterr().err
    assert not tqdm._instances and err.endswith("\n")
    assert "100%" not in final_line(err)  # stopped where the run stopped


def test_the_bar_is_closed_on_ctrl_c_and_the_run_is_kept(warm, capsys):
    capsys.readouterr()
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt, match="interrupted at step"):
            warm.run(1e9, progress=True)  # ~10^11 steps: ends only by the interrupt
    finally:
        timer.cancel()
    assert not tqdm._instances and capsys.readouterr().err.endswith("\n")
    assert warm.trajectory.time[-1] == pytest.approx(warm.time)


PAIR = '''
import numba
import demkit as dk

@numba.njit
def soft_force(i, j, dx, dy, dz, r2, strength):
    s = -strength / (r2 * r2)
    return s * dx, s * dy, s * dz

@numba.njit
def soft_energy(i, j, dx, dy, dz, r2, strength):
    return strength / (2.0 * r2)

class Soft(dk.PairInteraction):
    parameters = ("strength",)
    force_function = soft_force
    energy_function = soft_energy
    energy_kind = "soft"

    def __init__(self, strength):
        self.strength = strength
'''


def test_compiling_is_announced_before_and_timed_after_and_a_warm_scene_is_silent(monkeypatch, capsys, tmp_path,
                                                                                   request):
    monkeypatch.setattr(notice, "NOTICE_AFTER", 0.0)
    monkeypatch.delenv("DEMKIT_QUIET", raising=False)
    # importable plug-ins (tier 1 calls them through the scene's adapters, a second or two to compile),
    # new to the cache in every run of the suite (a random token in the force function's source)
    monkeypatch.syspath_prepend(str(tmp_path))

    def new_plugin(name):
        (tmp_path / f"{name}.py").write_text(PAIR.replace("    s = -strength", f"    # {uuid.uuid4()} {name}\n    s = -strength"))
        request.addfinalizer(lambda: sys.modules.pop(name, None))
        return vars(__import__(name))

    p = dk.Particles(position=[[0, 0, 0], [3.0, 0.1, 0]], radius=1.0)
    # tier 1's own code for such a scene compiled first (once per install, a notice of its own)
    dk.Simulation(dk.Scene(p.copy(), [dk.KelvinVoigt(1.0)], tier=1), dk.VelocityVerlet(0.01)).run(0.02, progress=False)
    dk.Scene(p.copy(), [dk.KelvinVoigt(1.0)], tier=1).energy()
    capsys.readouterr()
    quiet = dk.Scene(p, [new_plugin("progress_test_quiet_plugin")["Soft"](strength=1.0)])
    ns = new_plugin("progress_test_plugin")
    scene = dk.Scene(p, [ns["Soft"](strength=1.0)])
    assert capsys.readouterr().err == ""  # building a scene compiles nothing of its own
    assert quiet.energy()["soft"] == pytest.approx(1.0 / (2 * 9.01))  # compiled outside a notice: silent
    assert capsys.readouterr().err == ""
    dk.Simulation(scene, dk.VelocityVerlet(0.01)).run(duration=0.02, progress=False)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2, err  # one notice for the scene's run, then its time
    assert err[0].startswith("demkit: compiling kernels for this scene (first run only,")
    assert "the adapters of your own functions" in err[0]  # tier 1's own code is compiled: nothing else
    assert err[1].startswith("demkit: kernels compiled in ") and err[1].endswith(" s (cached for the next runs)")
    again = dk.Scene(dk.Particles(position=[[0, 0, 0], [3.0, 0.1, 0]], radius=1.0), [ns["Soft"](strength=2.0)])
    dk.Simulation(again, dk.VelocityVerlet(0.01)).run(duration=0.02, progress=False)
    assert capsys.readouterr().err == ""  # the same kernels again: nothing compiles, nothing is said
    # a compile of demkit's code inside the scope is announced, unless DEMKIT_QUIET is set (a small
    # function of a kernel module stands for a scene's kernels: a second plug-in's would cost 10 s)
    for quiet, said in (("", 2), ("1", 0)):
        monkeypatch.setenv("DEMKIT_QUIET", quiet)
        module = {"__name__": "demkit_kernel_quiet_test"}
        exec("def plus_one(x):\n    return x + 1\n", module)
        with notice.compile_notice("a moment"):
            numba.njit(module["plus_one"])(1)
        assert len(capsys.readouterr().err.splitlines()) == said


def test_the_compile_notice_expects_what_the_scene_needs(monkeypatch):
    """Small scenes and scenes with neighbour lists expect different compile times, and the cell
    lists' code (compiled once per install) is added only while numba's cache lacks it."""
    small, lists = SimpleNamespace(growing=False), SimpleNamespace(growing=True)
    dk.Scene(dk.Particles(position=[[0.5, 0.5, 0.5], [2.0, 0.5, 0.5]], radius=0.5),
             [dk.KelvinVoigt(1.0)], box=dk.Box([4.0, 4.0, 4.0], periodic=True))  # builds lists: cached now
    assert notice.cell_lists_cached()
    lo, hi = notice.ESTIMATES["small"]
    assert notice.compile_estimate(small, "run") == f"about {lo}-{hi} s on an idle machine"
    lo, hi = notice.ESTIMATES["lists"]
    assert notice.compile_estimate(lists, "run") == f"about {lo}-{hi} s on an idle machine"
    monkeypatch.setattr(notice, "cell_lists_cached", lambda: False)
    extra = notice.ESTIMATES["cell_lists"]
    assert notice.compile_estimate(lists, "run") == (f"about {lo + extra}-{hi + extra} s on an idle machine; the "
                                                   f"cell lists' code compiles once per install")
    lo, hi = notice.ESTIMATES["lists_scene"]
    assert notice.compile_estimate(lists, "scene").startswith(f"about {lo + extra}-{hi + extra} s")
    assert notice.compile_estimate(small, "run") == notice.compile_estimate(small, "scene")  # no lists to build


def test_the_one_time_compile_notice_expects_more_for_a_first_scene_with_lists():
    """Tier 1's generic kernels on a new install: a scene in open space compiles the few pieces it needs
    (about 10 s), the first scene with neighbour lists the list builder and the full pieces too."""
    small = SimpleNamespace(growing=False, interactions=[], effects=[])
    lists = SimpleNamespace(growing=True, interactions=[], effects=[])
    lo, hi = notice.ESTIMATES["generic"]
    assert notice.compile_estimate(small, "run", tier=1).endswith(f"about {lo}-{hi} s on an idle machine")
    lo_lists, hi_lists = notice.ESTIMATES["generic_lists"]
    assert notice.compile_estimate(lists, "run", tier=1).endswith(f"about {lo_lists}-{hi_lists} s on an idle machine")
    assert lo_lists > lo and hi_lists > hi


def test_small_scenes_find_close_pairs_like_the_cell_list(rng):
    box = dk.Box([10.0, 10.0, 10.0], periodic=[True, True, False])
    for n, b in ((40, box), (40, None), (3, None)):
        p = dk.Particles(position=rng.uniform(0.5, 9.5, (n, 3)), radius=0.1)
        scene = dk.Scene(p, [dk.KelvinVoigt(1.0)], box=b)
        small = {tuple(sorted(pair)) for pair in scene.close_pairs(3.0).tolist()}
        d = p.position[:, None] - p.position[None]
        if b is not None:
            d = b.minimum_image(d)
        r = np.linalg.norm(d, axis=2)
        truth = {(i, j) for i in range(n) for j in range(i + 1, n) if r[i, j] < 3.0}
        assert small == truth and (len(truth) > 0 or n == 3)


def render_child(*args, timeout=300):
    env = headless_env()
    return subprocess.run([sys.executable, "-m", "demkit", "render", *map(str, args)], capture_output=True,
                          text=True, env=env, timeout=timeout)


@pytest.fixture(scope="module")
def series(tmp_path_factory):
    folder = tmp_path_factory.mktemp("render")
    writer = dk.VTKWriter(folder / "series", every=25.0)
    sim = dk.Simulation(two_magnets(x0=25.0), dk.EulerCromer(dt=0.01), writers=[writer])
    sim.run(400.0, progress=False)
    sim.close()
    return writer.pvd


def test_demkit_render_writes_an_animation_and_a_picture(series, tmp_path):
    from PIL import Image, ImageSequence

    done = render_child(series, "-o", tmp_path / "run.gif", "--max-frames", "5", "--size", "160x120", "--fps", "5")
    if done.returncode == 1 and "render" in done.stderr:
        pytest.skip(f"no off-screen rendering here: {done.stderr.strip()}")
    assert done.returncode == 0, done.stderr
    with Image.open(tmp_path / "run.gif") as gif:
        assert sum(1 for _ in ImageSequence.Iterator(gif)) == 5 and gif.size == (160, 120)
    done = render_child(series, "-o", tmp_path / "last.png", "--time", "100", "--size", "200x150")
    assert done.returncode == 0, done.stderr
    with Image.open(tmp_path / "last.png") as png:
        assert png.size == (200, 150)


def test_animate_shows_a_bar_over_the_frames_when_asked(series, tmp_path):
    code = textwrap.dedent(f"""
        import demkit as dk
        dk.viz.animate({str(series)!r}, {str(tmp_path / 'bar.gif')!r}, max_frames=4, window_size=(120, 90),
                       progress=True)
    """)
    env = headless_env()
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    if done.returncode != 0 and "RenderingUnavailable" in done.stderr:
        pytest.skip("no off-screen rendering here")
    assert done.returncode == 0, done.stderr
    last = final_line(done.stderr)
    assert last.startswith("rendering frames") and "4/4" in last


@pytest.mark.parametrize("args, message", [
    (["-o", "run.avi"], "the suffix chooses what is written"),
    (["-o", "run.gif", "--time", "3"], "--time chooses the frame of a picture"),
    (["-o", "run.gif", "--size", "big"], "--size must be WIDTHxHEIGHT"),
])
def test_demkit_render_refuses_bad_options_in_one_line(series, tmp_path, args, message):
    # refused before anything is drawn: the command runs in this process (a child costs ~1 s)
    args = [str(tmp_path / a) if a.startswith("run.") else a for a in args]
    done = demkit_in_process("render", str(series), *args, cwd=tmp_path)
    assert done.returncode == 2 and message in done.stderr and "Traceback" not in done.stderr
    assert not list(tmp_path.iterdir())  # nothing written
    if "--size" in args:
        done = demkit_in_process("render", str(tmp_path / "missing.pvd"), "-o", str(tmp_path / "x.gif"), cwd=tmp_path)
        assert done.returncode == 2 and "does not exist" in done.stderr


# ---- accuracy studies: one bar over the runs ---------------------------------------------------
def collision():
    """Two spheres that meet head-on at t ~ 0.25 and part again (a small, fast study)."""
    p = dk.Particles([[0.0, 0, 0], [2.2, 0.3, 0]], velocity=[[0.4, 0, 0], [-0.4, 0, 0]], radius=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(50.0, 0.5)])


def study(progress):
    return dk.accuracy.work_precision(collision(), 1.0, methods=[dk.EulerCromer, dk.VelocityVerlet],
                                      dts=[0.02, 0.01], progress=progress, repeats=1)


def same_rows(a, b):
    """Every entry of the two reports' rows equal (NaN equal to NaN), wall and CPU times aside."""
    assert len(a.rows) == len(b.rows)
    for x, y in zip(a.rows, b.rows):
        assert x.keys() == y.keys()
        for key in x:
            if key not in ("seconds", "cpu_seconds", "timing_spread"):
                assert np.array_equal(x[key], y[key], equal_nan=not isinstance(x[key], str)), key


@pytest.fixture
def terminal_and_eager(monkeypatch):
    """stderr taken for a terminal, and automatic bars shown for any work: a run that drew its own
    bar would show it here. The study's kernels are compiled first (no compile notice later)."""
    monkeypatch.setenv("DEMKIT_QUIET", "1")
    study(False)
    monkeypatch.delenv("DEMKIT_QUIET")
    monkeypatch.setattr(prog, "_is_terminal", lambda stream: True)
    monkeypatch.setattr(prog, "AUTO_SECONDS", 0.0)
    monkeypatch.setattr(prog, "AUTO_AFTER", 0.0)
    monkeypatch.setattr(dk.simulation, "CHUNK_SECONDS", 1e-9)  # runs of one-step chunks: many updates
    monkeypatch.setattr(dk.simulation, "CHUNK_OVERHEAD_RATIO", 0.0)


def test_an_accuracy_study_shows_one_bar_over_its_runs_and_the_same_results(capsys, terminal_and_eager):
    quiet = study(False)
    assert capsys.readouterr().err == ""
    shown = study(True)
    err = capsys.readouterr().err
    last = final_line(err)
    # 2 methods x 2 dts and the adaptive reference: 5 runs, the current one in the postfix
    assert last.startswith("accuracy study: 100%") and "5/5" in last and "done" in last
    for stage in ("EulerCromer dt = 0.02", "VelocityVerlet dt = 0.01", "reference: adaptive DOP853"):
        assert stage in err
    assert "demkit run" not in err and not tqdm._instances  # the runs drew no bars; the study's is closed
    fourth = [line for line in err.replace("\r", "\n").splitlines() if "VelocityVerlet dt = 0.01]" in line]
    assert fourth and all(" 3/5 " in line for line in fourth)  # shown with the runs done before it
    same_rows(quiet, shown)
    assert quiet.reference["evaluations"] == shown.reference["evaluations"]
    assert study(None).rows[0]["position_error"] == quiet.rows[0]["position_error"]  # automatic: a bar
    assert "accuracy study" in capsys.readouterr().err


def test_no_study_bar_when_quiet_or_switched_off(capsys, monkeypatch, terminal_and_eager):
    study(False)
    assert capsys.readouterr().err == ""
    monkeypatch.setenv("DEMKIT_QUIET", "1")
    study(None)
    assert capsys.readouterr().err == ""
    with pytest.raises(TypeError, match="progress must be None"):
        dk.accuracy.work_precision(collision(), 1.0, dts=[0.01], progress=1)


def test_demkit_accuracy_shows_the_bar_unless_told_not_to(capsys, terminal_and_eager, tmp_path):
    from demkit.cli import main

    scene = tmp_path / "pair.py"
    scene.write_text(textwrap.dedent("""
        import demkit as dk
        p = dk.Particles([[0.0, 0, 0], [2.2, 0.3, 0]], velocity=[[0.4, 0, 0], [-0.4, 0, 0]], radius=1.0)
        scene = dk.Scene(p, [dk.KelvinVoigt(50.0, 0.5)])
        duration = 1.0
    """))
    common = [str(scene), "--dts", "0.02,0.01", "--methods", "VelocityVerlet", "--plot", str(tmp_path / "wp.png"),
              "--repeats", "2"]
    assert main(["accuracy", *common]) == 0
    captured = capsys.readouterr()
    assert "3/3" in final_line(captured.err) and "VelocityVerlet" in captured.out
    assert "the least wall time of 2 runs each" in captured.out  # --repeats
    assert main(["accuracy", *common, "--no-progress"]) == 0
    assert capsys.readouterr().err == ""


# ---- demkit render interrupted -------------------------------------------------------------------
@pytest.fixture(scope="module")
def long_series(tmp_path_factory):
    """400 frames: long enough to interrupt a render in the middle."""
    folder = tmp_path_factory.mktemp("long")
    writer = dk.VTKWriter(folder / "series", every=1.0, trails=False)
    sim = dk.Simulation(two_magnets(x0=25.0), dk.EulerCromer(dt=0.01), writers=[writer])
    sim.run(400.0, progress=False)
    sim.close()
    return writer.pvd


def test_ctrl_c_stops_a_render_with_one_line_and_no_partial_animation(long_series, tmp_path):
    out, partial = tmp_path / "run.mp4", tmp_path / "run.partial.mp4"
    out.write_bytes(b"an older animation")
    env = headless_env()
    child = subprocess.Popen([sys.executable, "-m", "demkit", "render", str(long_series), "-o", str(out),
                              "--max-frames", "400", "--size", "96x64"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, env=env,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # as in a terminal
    try:
        for _ in range(1200):  # the partial file appears with the first frame
            if partial.exists() or child.poll() is not None:
                break
            threading.Event().wait(0.05)
        if child.poll() is None:
            child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=60)
    finally:
        child.kill()
    if child.returncode == 1 and "render" in err:
        pytest.skip(f"no off-screen rendering here: {err.strip()}")
    assert child.returncode == 130, err
    line = err.strip().splitlines()[-1]
    assert line.startswith("demkit render: rendering interrupted after ") and "of 400 frames" in line
    assert "was not written (the partial file was removed)" in line and "Traceback" not in err
    assert not partial.exists() and out.read_bytes() == b"an older animation"  # left as it was


@pytest.mark.parametrize("suffix", [".gif", ".mp4"])
def test_an_animation_gets_its_name_only_when_complete(tmp_path, suffix):
    from demkit.viz.movie import MovieWriter

    frame = np.zeros((32, 48, 3), np.uint8)
    frame[:, :24] = (200, 30, 30)
    movie = MovieWriter(tmp_path / f"a{suffix}", fps=10)
    for _ in range(3):
        movie.add(frame)
    movie.abort()
    assert list(tmp_path.iterdir()) == []  # nothing on disk, not even a partial file
    movie = MovieWriter(tmp_path / f"b{suffix}", fps=10)
    for _ in range(3):
        movie.add(frame)
    assert movie.close() == tmp_path / f"b{suffix}"
    assert [p.name for p in tmp_path.iterdir()] == [f"b{suffix}"] and (tmp_path / f"b{suffix}").stat().st_size > 0


# ---- terminals of 0 columns: plain lines ------------------------------------------------------------
class NarrowTerminal(io.StringIO):
    """A terminal-like stderr without a file descriptor: its width is the environment's COLUMNS."""

    def isatty(self):
        return True


def test_a_terminal_of_0_columns_gets_plain_progress_lines(monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(prog.time, "perf_counter", clock)
    monkeypatch.setattr(sys, "stderr", NarrowTerminal())
    monkeypatch.setenv("COLUMNS", "0")
    monkeypatch.delenv("DEMKIT_QUIET", raising=False)
    with prog.Progress(100, None, desc="work", unit="run") as bar:  # automatic: judged after 0.5 s
        for done in range(0, 101, 5):
            bar.update(done, note="second half" if done >= 50 else "first half")
            clock.now += 0.5  # 10 s in all: a bar is wanted
    # tqdm's text on whole lines: the first update, a new stage, then one at most every 5 s
    # (PLAIN_SECONDS) and the end (already shown by the last update: not twice)
    assert sys.stderr.getvalue().splitlines() == [
        "work:   5% 5/100 [00:00<?, ?run/s, first half]",
        "work:  50% 50/100 [00:04<00:04, 11.11run/s, second half]",
        "work: 100% 100/100 [00:09<00:00, 10.53run/s, second half]"]
    monkeypatch.setattr(sys, "stderr", NarrowTerminal())
    with prog.Progress(3, True, desc="forced") as bar:  # forced: the same
        for done in range(4):
            bar.update(done)
    assert sys.stderr.getvalue().splitlines() == ["forced:   0% 0/3 [00:00<?, ?it/s]",
                                                  "forced: 100% 3/3 [00:00<?, ?it/s]"]
    # a terminal of 80 columns: tqdm's bar as before
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setattr(sys, "stderr", NarrowTerminal())
    with prog.Progress(3, True, desc="wide") as bar:
        for done in range(4):
            bar.update(done)
    assert "\r" in sys.stderr.getvalue() and "|##########| 3/3" in sys.stderr.getvalue()


def test_a_real_terminal_of_0_columns_shows_progress(tmp_path):
    """A pseudo-terminal whose size is 0 x 0 (tqdm draws nothing on it): a forced bar is plain lines."""
    pty, fcntl, termios, struct = (pytest.importorskip(m) for m in ("pty", "fcntl", "termios", "struct"))
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 0, 0, 0, 0))
    code = ("import demkit.progress as p\n"
            "with p.Progress(4, True, desc='narrow', unit='job') as bar:\n"
            "    for k in range(5): bar.update(k, note=f'job {k}')\n")
    env = {k: v for k, v in os.environ.items() if k not in ("COLUMNS", "LINES")}
    try:
        done = subprocess.run([sys.executable, "-c", code], stderr=slave, stdout=subprocess.PIPE, env=env,
                              timeout=60)
        os.close(slave)
        out = b""
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the other end is closed and everything read
                break
            if not chunk:
                break
            out += chunk
    finally:
        os.close(master)
    assert done.returncode == 0
    lines = out.decode().replace("\r\n", "\n").splitlines()
    assert lines[-1].startswith("narrow: 100% 4/4") and lines[-1].endswith("job 4]")
    assert [line.split("[")[0].split()[-1] for line in lines] == ["0/4", "1/4", "2/4", "3/4", "4/4"]


def test_sweeps_count_on_a_shared_bar(tmp_path, capsys):
    import sweep_tasks

    capsys.readouterr()
    with prog.Progress(5, True, desc="study", unit="point") as bar:
        dk.sweep(sweep_tasks.square, {"x": [1.0, 2.0]}, results=tmp_path / "a.csv", workers=1, progress=bar)
        assert bar.done == 2 and bar.bar is not None  # left open for the next sweep
        dk.sweep(sweep_tasks.square, {"x": [1.0, 3.0, 4.0]}, results=tmp_path / "a.csv", workers=1, progress=bar)
    # x = 1 was in the table already: counted at once, not run again
    assert bar.done == 5 and "5/5" in final_line(capsys.readouterr().err)
