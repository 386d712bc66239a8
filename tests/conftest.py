"""Shared builders for the tests."""
import functools
import os

import numpy as np
import pytest

import demkit as dk

# runs of the suite stay on tier 1 (the generic module, compiled once for the whole suite), in this
# process and in the child processes the tests start (examples, the command line, kills): a long
# test would otherwise compile its scene's own code in the background (tens of CPU s beside the
# other worker). tests/test_tiers.py switches on purpose, and asks for tier 2 where it compares the
# tiers; scenes with functions of your own run on tier 2 (DEMKIT_TIER=1 is a default, not a demand).
os.environ["DEMKIT_TIER"] = "1"
#: demkit.engine.tiers' shipped thresholds, which the suite replaces by "never" (the `shipped_tiers` fixture puts them back)
SHIPPED_THRESHOLDS = {name: getattr(dk.engine.tiers, name) for name in ("WORTH_COMPILING", "WORTH_COMPILING_OPEN",
                                                                  "WORTH_LOADING")}
for _name in SHIPPED_THRESHOLDS:
    setattr(dk.engine.tiers, _name, float("inf"))

#: the tests that open the second half of the collection. With -n 2 (--dist worksteal) each worker starts
#: on its half of the collection; both opening on tier 1 left one waiting ~35 s for the other's compile of
#: the same generic pieces (a function is compiled once by the processes sharing a cache). These compile
#: scenes' own code (tier 2) first, beside the first worker's tier 1: the paper's fused modules and the plain
#: family, then the small scene's fused module (27 CPU s), by when the first worker has the full family's
#: pair loops the small scene's tier-1 run needs (opening on it, it waited ~20 s for them).
SECOND_HALF_OPENS = ("tests/test_analysis.py::test_final_spin_on_a_real_run",
                     "tests/test_analysis.py::test_outcome_on_clear_cases[setup3-stick]",
                     "tests/test_tiers.py::test_small_scene_with_multiple_time_steps_same_bits")


def pytest_collection_modifyitems(config, items):
    """SECOND_HALF_OPENS moved to the front of the collection's second half (every worker collects the
    same order); a run of a few files keeps its order."""
    moved = [item for name in SECOND_HALF_OPENS for item in items if item.nodeid == name]
    if len(moved) < len(SECOND_HALF_OPENS):
        return
    rest = [item for item in items if item not in moved]
    half = len(items) // 2
    items[:] = rest[:half] + moved + rest[half:]


R_PAPER = 6.94
V_PAPER = 5.78e-3


def two_magnets(b_over_r=4.0, v=V_PAPER, x0=150.0, model=dk.Dipole, damping=0.1, radius=R_PAPER):
    """The seed paper's collision in its units: unit dipoles along the initial line of centres."""
    b = b_over_r * radius
    pos = np.array([[-x0, -b / 2, 0.0], [x0, b / 2, 0.0]])
    n = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
    p = dk.Particles(position=pos, velocity=[[v, 0, 0], [-v, 0, 0]], radius=radius, mass=1.0,
                     dipole=[n, n])
    return dk.Scene(p, [model(prefactor=1 / 3), dk.KelvinVoigt(stiffness=1.0, damping=damping)])


@functools.cache
def _headless_probe():
    """Probe off-screen rendering without a display once in this process (demkit.viz.backend), and
    return what the probe sets in the environment; {} when nothing renders here."""
    from demkit.viz import backend
    saved, chosen = dict(os.environ), backend._chosen
    for key in ("DISPLAY", "WAYLAND_DISPLAY", backend.WINDOW_VARIABLE, backend.PROBED_VARIABLE):
        os.environ.pop(key, None)
    backend._chosen = None
    try:
        backend.ensure_rendering()
        return {k: os.environ[k] for k in (backend.WINDOW_VARIABLE, backend.PROBED_VARIABLE) if k in os.environ}
    except backend.RenderingUnavailable:
        return {}
    finally:
        os.environ.clear()
        os.environ.update(saved)
        backend._chosen = chosen


def headless_env(probed=True):
    """This process's environment without a display, for a child process that renders; with
    ``probed``, with the result of one probe of this test process (demkit.viz.backend: the child
    trusts it instead of probing again, 2-3 s a child)."""
    from demkit.viz import backend
    drop = ("DISPLAY", "WAYLAND_DISPLAY", backend.WINDOW_VARIABLE, backend.PROBED_VARIABLE)
    env = {k: v for k, v in os.environ.items() if k not in drop}
    return {**env, **_headless_probe()} if probed else env


def run_example_quick(script, out, timeout=600):
    """Run ``main(["--quick", "--output", out])`` of the example ``script`` in a child process
    without DISPLAY (it renders: a broken OpenGL stack could crash the interpreter); returns the
    finished process and what main returned (its JSON after "RESULT" on stdout)."""
    import json
    import os
    import subprocess
    import sys
    code = (f"import json, runpy\nmain = runpy.run_path({str(script)!r})['main']\n"
            f"print('RESULT' + json.dumps(main(['--quick', '--output', {str(out)!r}])))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=headless_env(),
                          timeout=timeout)
    assert done.returncode == 0, done.stdout + done.stderr
    return done, json.loads(next(line for line in done.stdout.splitlines() if line.startswith("RESULT"))[6:])


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def energy_gradient(scene, kind, i, h):
    """Central-difference gradient of scene.energy()[kind] with respect to the position of particle i."""
    x = scene.particles.position
    grad = np.zeros(3)
    for a in range(3):
        x[i, a] += h
        up = scene.energy()[kind]
        x[i, a] -= 2 * h
        down = scene.energy()[kind]
        x[i, a] += h
        grad[a] = (up - down) / (2 * h)
    return grad


# ---- opt-in: which test compiles what (DEMKIT_COMPILE_LOG=path.jsonl), to keep the suite short
if __import__("os").environ.get("DEMKIT_COMPILE_LOG"):
    import json
    import os
    import threading
    import time

    from numba.core import event

    class _CompileLog(event.Listener):
        """Top-level numba compilations (seconds, function, module) per test."""

        def __init__(self):
            self.depth, self.start, self.test, self.rows = 0, None, None, []

        def on_start(self, ev):
            self.depth += 1
            if self.depth == 1:
                self.start = time.perf_counter(), time.process_time()

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0 and self.start is not None:
                f = ev.data["dispatcher"].py_func
                self.rows.append({"test": self.test, "function": f.__name__, "module": f.__module__,
                                  "cpu": time.process_time() - self.start[1], "began": self.start[0],
                                  "wall": time.perf_counter() - self.start[0],
                                  "thread": threading.current_thread().name, "pid": os.getpid()})
                self.start = None

    _LOG = _CompileLog()
    event.register("numba:compile", _LOG)

    def _children_cpu():
        import resource
        usage = resource.getrusage(resource.RUSAGE_CHILDREN)
        return usage.ru_utime + usage.ru_stime

    @pytest.fixture(autouse=True)
    def _log_compiles(request):
        _LOG.test = request.node.nodeid
        began, cpu, children = time.perf_counter(), time.process_time(), _children_cpu()
        yield
        # and the test itself (its wall and CPU seconds, its child processes' CPU seconds, from when):
        # a timeline of each worker
        _LOG.rows.append({"test": _LOG.test, "function": None, "began": began, "wall": time.perf_counter() - began,
                          "cpu": time.process_time() - cpu, "children": _children_cpu() - children,
                          "pid": os.getpid()})
        with open(os.environ["DEMKIT_COMPILE_LOG"], "a") as fh:
            for row in _LOG.rows:
                fh.write(json.dumps(row) + "\n")
        _LOG.rows.clear()


@pytest.fixture
def shipped_tiers(monkeypatch):
    """Scenes choose their tier as outside the suite (no DEMKIT_TIER, demkit.engine.tiers' shipped thresholds),
    in a process that has run no combination yet."""
    monkeypatch.delenv("DEMKIT_TIER", raising=False)
    for name, seconds in SHIPPED_THRESHOLDS.items():
        monkeypatch.setattr(dk.engine.tiers, name, seconds)
    monkeypatch.setattr(dk.engine.tiers, "_SPENT", {})
    monkeypatch.setattr(dk.engine.tiers, "_READY", set())


@pytest.fixture
def paper_on_tier_2(monkeypatch):
    """For tests that run many steps of the paper's two spheres: their scenes on tier 2 (the fused
    module, about 4x faster than tier 1 for two spheres, compiled once for the suite and then loaded
    from the cache; the same bits, tests/test_tiers.py)."""
    monkeypatch.setenv("DEMKIT_TIER", "2")


def demkit_in_process(*args, cwd):
    """``python -m demkit *args`` run in this process, as ``subprocess.run`` reports it (exit code,
    stdout, stderr): a child spends ~2 CPU-s importing demkit and loading numba's caches. What only a
    process shows (Ctrl-C, signals, the entry point itself) is tested with real children."""
    import contextlib
    import io
    import os
    import subprocess

    from demkit.cli import main
    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(list(args))
            except SystemExit as stop:  # argparse's refusals (2), sys.exit(...)
                code = stop.code
                if isinstance(code, str):
                    print(code, file=err)
                    code = 1
    finally:
        os.chdir(here)
    return subprocess.CompletedProcess(["demkit", *args], code or 0, out.getvalue(), err.getvalue())


def same_bits_on_two_threads_and_one(make_scene, duration):
    """``make_scene()`` built, its forces (a serial scene) and a run on threads (``parallel=True``) on
    two of numba's threads and on one: the same bits each (positions, spins and, where the scene
    has them, moments: induced ones change), and the runs give numba's setting back. The scene is
    rebuilt from its spheres, interactions and effects (fields, walls)."""
    import numba
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("numba has one thread here")
    before = numba.get_num_threads()
    runs, forces = [], []
    try:
        for threads in (2, 1):
            numba.set_num_threads(threads)
            scene = make_scene()
            parts = list(scene.interactions) + list(scene.effects)
            serial = dk.Scene(scene.particles, parts, box=scene.box, parallel=False)
            forces.append(np.concatenate([a.ravel() for a in serial.forces()]))  # on `threads` threads
            scene = dk.Scene(scene.particles, parts, box=scene.box, parallel=True)
            sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
            traj = sim.run(duration=duration, record_every=duration / 2, progress=False)
            assert sim.statistics["threads"] == threads
            assert numba.get_num_threads() == threads  # given back, whatever the run's chunks set
            moments = [] if traj.dipole is None else [traj.dipole.ravel()]
            runs.append(np.concatenate([traj.position.ravel(), traj.angular_velocity.ravel(), *moments]))
    finally:
        numba.set_num_threads(before)
    assert forces[0].tobytes() == forces[1].tobytes()
    assert runs[0].tobytes() == runs[1].tobytes()
