"""Speed on a real machine: threads beside a busy core, and compilation before the first step.
Writes benchmarks/results/latency.json (parts merged into what is there).

Parts (all by default; name some to run only those):

* ``threads``: steps per second of wall time with demkit's default settings against the same run
  on one thread (``NUMBA_NUM_THREADS=1``), on an idle machine and with one core kept busy by a
  CPU-burning child process started beside the run; scenes: a periodic contact-only gas of 4000
  spheres (velocity Verlet), a 3000-sphere frictional Hertz pour under gravity into a walled box,
  the N = 8000 dipole reference scene (where two threads gain), and the examples' scenes. Each
  measurement is a fresh process with warm kernel caches (compilation excluded) timing one run of
  about 6 s, as a user runs (the threads' probes included); default and one-thread processes
  alternate three times and the median of each is kept (this machine's speed drifts by 20 % and
  more between minutes; a ratio of the best runs would be decided by one outlier).
* ``compile``: time to the first step with empty kernel caches (numba's cache of demkit's own
  modules emptied too), counted as CPU seconds of the process (compilation is single-threaded:
  CPU time is what does not depend on the load): the paper's scene (Euler-Cromer and RK4), the
  600-sphere magnetic gas with Hertz contacts and friction, the magnetic_cluster example, and
  `demkit accuracy` on a 3-sphere scene file (the whole study, CPU s of the command); the same with
  demkit's own modules cached (a new scene on a machine that ran demkit before) and fully warm; and
  a scene differing only in parameter values and particle count (which must compile nothing).

* ``tiers`` (only when named): the two tiers of compiled code (docs/engine.md). ``fresh_install``:
  every cache empty, CPU s to the first step of the paper's scene (the main job's). ``new_combination``:
  demkit's install-wide code cached (the generic module warmed by *other* scenes of the same kind:
  a three-sphere Kelvin-Voigt scene for the small scenes, a periodic contact-only gas for scenes
  with lists, then every piece of tier 1 compiled for that kind of state), the scene's own fused
  module never compiled: CPU s from ``import demkit`` to the
  first step in a fresh process. ``tier2_first_step`` (the scenes with lists, and the paper's fused module): then the same scene
  started on tier 2 (``DEMKIT_TIER=2``) in a fresh process, CPU s to its first step: what tier 2 of a
  new combination costs (its own pieces; the time loops are tier 1's). ``install_wide``: CPU s compiling every function of the generic
  modules (serial and threads, both families of pieces) as the integrators and diagnostics use them, then the
  long-range sums (Ewald, P3M, each over a slab too; FMM), the solve of induced moments, sorting by cell, a
  sheared box, contact events over lists, a cone and the contact diagnostics (``tier_1_cpu_s``: the first part
  alone, what this figure was until 1 Dec 2026): the whole child process's CPU s from its start, the median of
  three (``cpu_s_runs``); ``compile_cpu_s``: the part inside numba's compiles (the rest: imports, running the
  scenes' few steps, P3M's tuning). ``speed``: steps per
  second of the same run on tier 1 and tier 2 (warm, medians of alternating rounds).

* ``long_range`` (only when named): the same two measurements for long-range dipole sums: the
  compile part for the N = 1000 reference scene with Ewald(1e-4) and the N = 8000 one with
  P3M(1e-4) (frictionless Hooke contacts), the threads part for the latter.

Usage: python benchmarks/bench_latency.py [threads] [compile] [tiers] [long_range] [--quick] [--against=<git revision>]

``--against=REV`` runs the compile part of revision REV's code alternating with this one's (before
and after, side by side on the same machine), written under ``compile_against_REV``.
"""
from __future__ import annotations

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RESULTS = HERE / "results" / "latency.json"
# Users' Python writes bytecode: an installed demkit has its .pyc files, and the kernel modules demkit
# generates get theirs on first import. With PYTHONDONTWRITEBYTECODE set (some shells and containers
# set it), every child would compile ~65 modules' source again: 0.3-0.4 CPU s counted as start-up.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)


def reference_scene(n, dipole):
    """Source of make() for benchmarks/reference_scene.py's N = n scene with Dipole(1, <dipole>) and
    frictionless Hooke contacts ({here}, {tmp} filled in later by _scene_source)."""
    return f"""
        def make():
            import sys
            sys.path.insert(0, {{here!r}})
            from reference_scene import load_reference_scene, particles_and_box
            p, box = particles_and_box(load_reference_scene({n}, {{tmp!r}}))
            inters = [dk.Dipole(prefactor=1.0, {dipole}), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)]
            return dk.Scene(p, inters, box=box, skin=0.3), dk.VelocityVerlet(1e-3)
    """


# the scenes, as Python source run in a child process; each defines make() -> (scene, integrator)
SCENES = {
    "gas4000": """
        def make():
            n, R = 4000, 0.5
            box = dk.build.box_for(n, R, 0.2)
            pos = dk.build.random_packing(n, R, box, seed=1)
            v = np.random.default_rng(2).normal(size=(n, 3))
            p = dk.Particles(position=pos, velocity=v, radius=R, mass=1.0)
            return dk.Scene(p, [dk.KelvinVoigt(stiffness=1000.0, damping=1.5)], box=box), dk.VelocityVerlet(1e-3)
    """,
    "pour3000": """
        def make():
            # 3000 spheres of radius 0.5 on a loose lattice, falling 20-40 diameters onto the floor
            # of a 20 x 20 walled box: Hertz contacts with Coulomb friction, gravity 1
            R, side, g = 0.5, 20.0, 1.0
            k = np.arange(3000)
            x = 0.75 + 1.25 * (k % 15)
            y = 0.75 + 1.25 * ((k // 15) % 15)
            z = 20.0 + 1.25 * (k // 225)
            rng = np.random.default_rng(3)
            pos = np.stack([x, y, z], axis=1) + rng.uniform(-0.1, 0.1, (3000, 3))
            p = dk.Particles(position=pos, radius=R, mass=1.0)
            law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5))
            walls = [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 0), (1, 0, 0)), dk.Wall((0, 0, 0), (0, 1, 0)),
                     dk.Wall((side, side, 0), (-1, 0, 0)), dk.Wall((side, side, 0), (0, -1, 0))]
            scene = dk.Scene(p, [law, dk.Gravity((0, 0, -g)), *walls], skin=0.4)
            return scene, dk.VelocityVerlet(1e-3)
    """,
    "dipoles8000": reference_scene(8000, "cutoff=4.0"),
    "magnetic_cluster": """
        def make():
            loaded = dk.load_scene({root!r} + "/examples/magnetic_cluster/cluster.toml")
            return loaded.scene, loaded.integrator
    """,
    "two_magnets": """
        def make():
            return dk.two_magnets.TwoMagnets(b_over_R=4.0).scene(), dk.EulerCromer(0.01)
    """,
    "two_magnets_rk4": """
        def make():
            return dk.two_magnets.TwoMagnets(b_over_R=4.0).scene(), dk.RK4(0.01)
    """,
    "gas600": """
        def make(n=600, cutoff=4.0, young=2e4, mu=0.5):
            # the issue's 600-sphere magnetic gas: dipoles cut at 4 diameters, Hertz with friction, periodic
            R = 0.5
            box = dk.build.box_for(n, R, 0.2)
            pos = dk.build.random_packing(n, R, box, seed=1)
            rng = np.random.default_rng(2)
            d = rng.normal(size=(n, 3))
            p = dk.Particles(position=pos, velocity=rng.normal(size=(n, 3)), radius=R, mass=1.0,
                             dipole=d / np.linalg.norm(d, axis=1)[:, None])
            law = dk.Hertz(young=young, poisson=0.3, restitution=0.5, friction=dk.Friction(mu))
            return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=cutoff), law], box=box), dk.VelocityVerlet(1e-3)
    """,
    "ewald1000": reference_scene(1000, "long_range=dk.Ewald(1e-4)"),
    "p3m8000": reference_scene(8000, "long_range=dk.P3M(1e-4)"),
}
# the same scenes with other parameter values and particle counts: must compile nothing once the
# scene above ran
VARIANTS = {
    "two_magnets": """
        def make():
            return dk.two_magnets.TwoMagnets(b_over_R=2.5, speed=3e-3).scene(), dk.EulerCromer(0.02)
    """,
    "gas600": SCENES["gas600"].replace("def make(n=600, cutoff=4.0, young=2e4, mu=0.5):",
                                       "def make(n=450, cutoff=3.0, young=5e4, mu=0.3):"),
}
# `demkit accuracy` on a 3-sphere scene file, the command's default methods and time steps
ACCURACY_FILE = """
[particles]
position = [[0.0, 0.0, 0.0], [3.0, 0.4, 0.0], [-2.5, 1.5, 0.3]]
velocity = [[0.05, 0.0, 0.0], [-0.05, 0.0, 0.0], [0.0, -0.04, 0.0]]
dipole = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
radius = 0.5
[interactions.dipole]
prefactor = 0.01
[interactions.kelvin_voigt]
stiffness = 1000.0
damping = 2.0
[integrator]
dt = 0.005
[run]
duration = 20.0
"""

THREAD_CHILD = """
import json, sys, time
import numpy as np
import demkit as dk
{scene}
scene, integrator = make()
if {warm}:  # fill the kernel caches: the serial module, and the thread module where there is one
    dk.Simulation(scene, integrator).run(duration=20 * integrator.dt, progress=False)
    if scene.parallel:
        threaded = dk.Scene(scene.particles, list(scene.interactions + scene.effects), box=scene.box,
                            skin=scene.skin, parallel=True)
        dk.Simulation(threaded, integrator).run(duration=20 * integrator.dt, progress=False)
    print("RESULT {{}}")
    sys.exit(0)
sim = dk.Simulation(scene, integrator)
sim.run(duration=20 * integrator.dt, progress=False)  # load the kernels, first list builds
t = time.perf_counter()
steps = 0
while time.perf_counter() - t < 0.5:  # calibrate
    sim.run(duration=20 * integrator.dt, progress=False); steps += 20
rate = steps / (time.perf_counter() - t)
best = None
for _ in range({repeats}):  # one long run each, as a user runs (the threads' probes included)
    n = max(20, int(rate * {seconds}))
    t = time.perf_counter()
    sim.run(duration=n * integrator.dt, progress=False)
    r = n / (time.perf_counter() - t)
    best = r if best is None else max(best, r)
print("RESULT", json.dumps({{"steps_per_s": best, "threads": sim.statistics["threads"],
                            "reason": sim.statistics["threads_reason"]}}))
"""


def _scene_source(name, tmp):
    return textwrap.dedent(SCENES[name]).format(here=str(HERE), tmp=tmp, root=str(ROOT))


def _child(code, env):
    # run in the temporary folder: `python -c` puts the working directory first on sys.path, and from
    # the project's root it would import this tree's demkit whatever PYTHONPATH says
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         cwd=tempfile.gettempdir())
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1]
    return json.loads(line[len("RESULT "):])


class Burner:
    """A child process keeping one core busy (a plain Python loop)."""

    def __enter__(self):
        self.proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        time.sleep(0.3)
        return self

    def __exit__(self, *exc):
        self.proc.kill()
        self.proc.wait()


def part_threads(quick, repeats, seconds, scenes, rounds=3):
    tmp = tempfile.mkdtemp(prefix="demkit-latency-")
    rows = []
    try:
        for name in scenes:
            code = THREAD_CHILD.format(scene=_scene_source(name, tmp), repeats=repeats, seconds=seconds, warm=False)
            warm = THREAD_CHILD.format(scene=_scene_source(name, tmp), repeats=repeats, seconds=seconds, warm=True)
            _child(warm, dict(os.environ))  # warm the caches (both thread counts compile once)
            _child(warm, dict(os.environ, NUMBA_NUM_THREADS="1"))
            for load in ("idle", "busy"):
                row = {"scene": name, "load": load, "default_runs": [], "one_thread_runs": []}
                for r in range(rounds):  # interleaved, in turns first: this machine's speed drifts by 20 %
                    order = (("default", {}), ("one_thread", {"NUMBA_NUM_THREADS": "1"}))
                    for label, env in order if r % 2 == 0 else order[::-1]:
                        env = dict(os.environ, **env)
                        if load == "busy":
                            with Burner():
                                res = _child(code, env)
                        else:
                            res = _child(code, env)
                        row[f"{label}_runs"].append(res["steps_per_s"])
                        if label == "default":
                            row["threads_chosen"], row["reason"] = res["threads"], res["reason"]
                # medians: one run's outliers (+-25 % on this machine) would decide a ratio of bests
                row["default"] = statistics.median(row["default_runs"])
                row["one_thread"] = statistics.median(row["one_thread_runs"])
                row["ratio_default_to_one_thread"] = row["default"] / row["one_thread"]
                print(json.dumps(row), flush=True)
                rows.append(row)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return rows


COMPILE_CHILD = """
import json, time
t0 = time.process_time(); w0 = time.perf_counter()
from numba.core import event
compiled = []
class Count(event.Listener):
    def on_start(self, ev):
        pass
    def on_end(self, ev):
        if (ev.data["dispatcher"].py_func.__module__ or "").startswith(("demkit_kernel", "demkit_generic")):
            compiled.append(ev.data["dispatcher"].py_func.__name__)
event.register("numba:compile", Count())
import numpy as np
import demkit as dk
{scene}
scene, integrator = make()
sim = dk.Simulation(scene, integrator)
sim.run(duration=integrator.dt, progress=False)  # the first step
print("RESULT", json.dumps({{"cpu_s": time.process_time() - t0, "wall_s": time.perf_counter() - w0,
                            "kernel_functions_compiled": len(compiled)}}))
"""

ACCURACY_CHILD = """
import json, resource, subprocess, sys, time
w0 = time.perf_counter()
done = subprocess.run([sys.executable, "-m", "demkit", "accuracy", {path!r}, "--no-progress", "--plot", {plot!r}],
                      capture_output=True, text=True)
if done.returncode:
    raise SystemExit(done.stderr)
use = resource.getrusage(resource.RUSAGE_CHILDREN)
print("RESULT", json.dumps({{"cpu_s": use.ru_utime + use.ru_stime, "wall_s": time.perf_counter() - w0}}))
"""


def _empty_caches(cache, tree=ROOT):
    shutil.rmtree(cache, ignore_errors=True)
    for folder in (Path(tree) / "demkit").rglob("__pycache__"):  # numba's cache of demkit's own modules
        for f in folder.iterdir():
            if f.suffix in (".nbi", ".nbc"):
                f.unlink()


def _export(rev, tmp):
    """The demkit package of git revision ``rev`` in a folder of its own (for side-by-side runs)."""
    folder = Path(tmp) / f"demkit-{rev}"
    folder.mkdir()
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "demkit"], capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return folder


def part_compile(quick, scenes, against=None, rounds=2):
    """Time to the first step, CPU s: ``cold`` (every cache empty), ``new_scene`` (demkit's own
    modules cached, the scene's kernels not: a new scene on a machine that ran demkit before) and
    ``warm``; and for the scenes of VARIANTS, the same scene with other values and particle count
    after it (kernel functions compiled: must be 0). With ``against`` (a git revision) the same runs
    of that revision's code alternate with this one's, ``rounds`` times; medians are kept."""
    tmp = tempfile.mkdtemp(prefix="demkit-latency-")
    cache = Path(tmp) / "kernels"
    trees = [("this", ROOT)] + ([(against, _export(against, tmp))] if against else [])
    runs = {}
    try:
        accuracy_file = Path(tmp) / "three.toml"
        accuracy_file.write_text(ACCURACY_FILE)
        for r in range(rounds if against else 1):
            for label, tree in trees if r % 2 == 0 else trees[::-1]:
                env = dict(os.environ, DEMKIT_CACHE_DIR=str(cache), DEMKIT_QUIET="1", PYTHONPATH=str(tree))
                for name in scenes:
                    if name == "accuracy3":
                        code = ACCURACY_CHILD.format(path=str(accuracy_file), plot=str(Path(tmp) / "a.png"))
                    else:
                        code = COMPILE_CHILD.format(scene=_scene_source(name, tmp))
                    _empty_caches(cache, tree)
                    out = {"cold": _child(code, env)}
                    if name != "accuracy3":
                        shutil.rmtree(cache, ignore_errors=True)
                        out["new_scene"] = _child(code, env)
                        out["warm"] = _child(code, env)
                    if name in VARIANTS:
                        variant = COMPILE_CHILD.format(scene=textwrap.dedent(VARIANTS[name]))
                        out["variant"] = _child(variant, env)
                    for mode, res in out.items():
                        runs.setdefault((label, name, mode), []).append(res)
                    print(json.dumps({"round": r, "code": label, "scene": name,
                                      **{m: round(v["cpu_s"], 2) for m, v in out.items()}}), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    rows = []
    for (label, name, mode), results in runs.items():
        row = {"code": label, "scene": name, "mode": mode, "cpu_s": statistics.median(r["cpu_s"] for r in results),
               "cpu_s_runs": [round(r["cpu_s"], 2) for r in results]}
        if mode == "variant":
            row["kernel_functions_compiled"] = max(r["kernel_functions_compiled"] for r in results)
        rows.append(row)
    return rows


# scenes that warm the generic modules (install-wide code) without compiling a target scene's fused module
WARM_GENERIC = {
    "small": """
        def make():
            p = dk.Particles(position=[[0, 0, 0], [15, 0, 0], [0, 15, 0]], velocity=[[0.01, 0, 0], [0, 0, 0], [0, 0, 0]],
                             radius=5.0, mass=1.0)
            return dk.Scene(p, [dk.KelvinVoigt(1.0, 0.1)], tier=1), {integrator}
    """,
    "lists": """
        def make():
            n, R = 300, 0.5
            box = dk.build.box_for(n, R, 0.2)
            p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=3), radius=R, mass=1.0)
            return dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0)], box=box, tier=1), {integrator}
    """,
}
#: after a warm-up scene: every piece of tier 1, of every family, for its kind of state (the install-wide
#: code; a scene compiles only the pieces it calls, demkit.engine.generic.needs_of)
WARM_PIECES = """
import numba
from demkit.engine import catalogue, generic, generic_modules
for family in catalogue.FAMILIES:
    generic_modules.build_generic(False, generic.CALLS, None, family).calls_for(numba.typeof(scene.state))
"""
WARM_GENERIC["lists_sums"] = """
        def make():
            # a P3M sum with Kelvin-Voigt contacts, no field: its code (a long-range sum is install-wide
            # code, compiled once per install) without the measured combination
            n, R = 125, 0.5
            box = dk.build.box_for(n, R, 0.1)
            p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=4), radius=R, mass=1.0,
                             dipole=np.tile([0.0, 0.0, 1.0], (n, 1)))
            return dk.Scene(p, [dk.Dipole(0.1, long_range=dk.P3M(1e-3)), dk.KelvinVoigt(1000.0, 1.0)], box=box,
                            tier=1), {integrator}
    """
WARM_GENERIC["small_sums"] = """
        def make():
            # magnetisable spheres with Hertz contacts (the measured scene has Kelvin-Voigt, a field, gravity)
            p = dk.Particles(position=[[0, 0, 0], [1.5, 0, 0], [0, 1.5, 0]], radius=0.5, mass=1.0, susceptibility=1.0)
            return dk.Scene(p, [dk.Dipole(0.5), dk.Hertz(young=2e4, poisson=0.3, restitution=0.5),
                                dk.UniformField((0, 0.2, 0))], tier=1), \
                {integrator}
    """
PLUGIN = """
        def make():
            # the guide's SoftRepulsion (docs/guide.md), defined in an importable module: functions of your own
            import pathlib, sys
            folder = pathlib.Path({tmp!r})
            (folder / "latency_plugin.py").write_text(
                "import math\\nfrom numba import njit\\nimport demkit as dk\\n\\n"
                "@njit\\ndef soft_force(i, j, dx, dy, dz, r2, radius, strength):\\n"
                "    reach = radius[i] + radius[j]\\n    if r2 >= reach * reach:\\n        return 0.0, 0.0, 0.0\\n"
                "    r = math.sqrt(r2)\\n    s = strength * (reach - r) ** 2 / r\\n    return s * dx, s * dy, s * dz\\n\\n"
                "@njit\\ndef soft_energy(i, j, dx, dy, dz, r2, radius, strength):\\n"
                "    reach = radius[i] + radius[j]\\n    r = math.sqrt(r2)\\n"
                "    return strength * (reach - r) ** 3 / 3 if r < reach else 0.0\\n\\n"
                "class SoftRepulsion(dk.PairInteraction):\\n    reads = ('radius',)\\n    energy_kind = 'contact'\\n"
                "    parameters = ('strength',)\\n    force_function = soft_force\\n    energy_function = soft_energy\\n"
                "    def __init__(self, strength):\\n        self.strength = strength\\n"
                "    def cutoff(self, particles):\\n        return 2.0 * float(particles.radius.max())\\n")
            sys.path.insert(0, str(folder))
            from latency_plugin import SoftRepulsion
            {body}
    """
SCENES["plugin"] = PLUGIN.replace("{body}", """p = dk.Particles(position=[[0, 0, 0], [1.05, 0, 0], [0, 1.05, 0]], radius=0.5, mass=1.0,
                             dipole=[[0, 0, 1.0], [0, 0, 1.0], [0, 0, 1.0]])
            return dk.Scene(p, [dk.Dipole(0.01), SoftRepulsion(100.0), dk.Gravity((0, 0, -1.0))]), \\
                dk.VelocityVerlet(1e-3)""")
SCENES["plugin_lists"] = PLUGIN.replace("{body}", """n, R = 600, 0.5
            box = dk.build.box_for(n, R, 0.3)
            p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=3), radius=R, mass=1.0,
                             velocity=np.random.default_rng(4).normal(size=(n, 3)),
                             dipole=dk.build.random_directions(n, seed=4))
            return dk.Scene(p, [dk.Dipole(0.5, cutoff=3.0), SoftRepulsion(2000.0)], box=box), \\
                dk.VelocityVerlet(1e-3)""")
TIER_SCENES = {  # name: (scene source, kind of state, integrator)
    "two_magnets": ("two_magnets", "small", "dk.EulerCromer(0.01)"),
    "gas600": ("gas600", "lists", "dk.VelocityVerlet(1e-3)"),
    "pour_twisting": ("pour_twisting", "lists", "dk.VelocityVerlet(1e-3)"),
    "p3m": ("p3m", "lists_sums", "dk.VelocityVerlet(1e-3)"),
    "magnetisable": ("magnetisable", "small_sums", "dk.VelocityVerlet(1e-3)"),
    "plugin": ("plugin", "small", "dk.VelocityVerlet(1e-3)"),  # functions of your own (demkit.engine.own_laws)
    "plugin_lists": ("plugin_lists", "lists", "dk.VelocityVerlet(1e-3)"),
}
SCENES["p3m"] = """
        def make():
            # 216 dipoles summed by P3M in a periodic box, Hertz contacts, a field
            n, R = 216, 0.5
            box = dk.build.box_for(n, R, 0.1)
            rng = np.random.default_rng(5)
            d = rng.normal(size=(n, 3))
            p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=2), radius=R, mass=1.0,
                             dipole=d / np.linalg.norm(d, axis=1)[:, None])
            return dk.Scene(p, [dk.Dipole(0.1, long_range=dk.P3M(1e-4)), dk.Hertz(young=2e4, poisson=0.3, restitution=0.5),
                                dk.UniformField((0, 0, 0.2))], box=box), dk.VelocityVerlet(1e-3)
    """
SCENES["magnetisable"] = """
        def make():
            # a chain of five magnetisable spheres in a uniform field, Kelvin-Voigt contacts, gravity
            p = dk.Particles(position=[[0, 0, 1.05 * k] for k in range(5)], radius=0.5, mass=1.0, susceptibility=3.0)
            return dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(1000.0, 1.0), dk.UniformField((0, 0, 0.5)),
                                dk.Gravity((0, 0, -1.0))]), dk.VelocityVerlet(1e-3)
    """
SCENES["pour_twisting"] = """
        def make():
            # a walled pour: Hertz with friction, rolling and twisting resistance, gravity and a field
            R, side = 0.5, 8.0
            k = np.arange(400)
            pos = np.stack([0.75 + 1.25 * (k % 6), 0.75 + 1.25 * ((k // 6) % 6), 1.0 + 1.25 * (k // 36)], axis=1)
            rng = np.random.default_rng(3)
            d = rng.normal(size=(400, 3))
            p = dk.Particles(position=pos + rng.uniform(-0.1, 0.1, (400, 3)), radius=R, mass=1.0, dipole=0.1 * d)
            law = dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5),
                           rolling=dk.RollingResistance(0.05), twisting=dk.TwistingResistance())
            walls = [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 0), (1, 0, 0)), dk.Wall((0, 0, 0), (0, 1, 0)),
                     dk.Wall((side, side, 0), (-1, 0, 0)), dk.Wall((side, side, 0), (0, -1, 0))]
            return dk.Scene(p, [law, dk.Gravity((0, 0, -1.0)), dk.UniformField((0, 0, 0.1)), *walls], skin=0.4), \
                dk.VelocityVerlet(1e-3)
    """

SPEED_CHILD = """
import json, time
import numpy as np
import demkit as dk
{scene}
scene, integrator = make()
scene = dk.Scene(scene.particles, list(scene.interactions + scene.effects), box=scene.box, tier={tier})
sim = dk.Simulation(scene, integrator)
sim.run(duration=20 * integrator.dt, progress=False)
steps = 20
while True:  # about {seconds} s of stepping
    t = time.perf_counter(); sim.run(duration=steps * integrator.dt, progress=False); took = time.perf_counter() - t
    if took > {seconds}:
        break
    steps = int(steps * min(10.0, 1.5 * {seconds} / max(took, 1e-3)))
print("RESULT", json.dumps({{"steps_per_s": steps / took, "tier": sim.statistics["tier"]}}))
"""

INSTALL_CHILD = """
import json, time
t0 = time.process_time()
from numba.core import event
compiling = [0.0, 0]  # CPU s inside numba's outermost compiles (the rest: imports, the scenes' runs, P3M's tuning)
class Compiles(event.Listener):
    def on_start(self, ev):
        compiling[1] += 1
        if compiling[1] == 1:
            compiling[0] -= time.process_time()
    def on_end(self, ev):
        compiling[1] -= 1
        if compiling[1] == 0:
            compiling[0] += time.process_time()
event.register("numba:compile", Compiles())
import numpy as np
import demkit as dk
from demkit.integrators import TEMPLATES
p = dk.Particles(position=[[0, 0, 0], [1.5, 0, 0], [0, 1.5, 0]], radius=0.5, mass=1.0, dipole=np.eye(3))
small = dk.Scene(p, [dk.Dipole(0.01), dk.KelvinVoigt(1000.0, 1.0)], tier=1)
n, R = 300, 0.5
box = dk.build.box_for(n, R, 0.2)
q = dk.Particles(position=dk.build.random_packing(n, R, box, seed=3), radius=R, mass=1.0, dipole=np.tile([1.0, 0, 0], (n, 1)))
big = dk.Scene(q, [dk.Dipole(0.01, cutoff=3.0), dk.KelvinVoigt(1000.0, 1.0)], box=box, tier=1, parallel=True)
# the same with friction, rolling and twisting resistance, walls and gravity: the full family of pieces
full = [dk.KelvinVoigt(1000.0, 1.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.1), twisting=dk.TwistingResistance()),
        dk.Wall((0, 0, -5.0), (0, 0, 1)), dk.Gravity((0, 0, -1.0))]
small_full = dk.Scene(p, [dk.Dipole(0.01), *full], tier=1)
big_full = dk.Scene(q, [dk.Dipole(0.01, cutoff=3.0), *full], box=dk.Box(box.size, periodic=[True, True, False]),
                    tier=1, parallel=True)
record = None
for scene in (small, big, small_full, big_full):
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    sim.run(duration=1e-3, progress=False)  # record_frame and the lists
    scene.energy(); scene.forces(); scene.pair_energies(); scene.pair_forces()
    lists = scene in (big, big_full)
    loops = [scene.kernels.velocity_verlet_steps] + ([scene.thread_kernels.velocity_verlet_steps] if lists else [])
    signature = next(loop.signatures[0] for loop in loops if loop.signatures)  # the loop that ran
    for threads in ((False, True) if lists else (False,)):
        module = scene.thread_kernels if threads else scene.kernels
        for name in TEMPLATES:
            getattr(module, name + "_steps").compile(signature)
tier_1 = time.process_time() - t0
# the long-range sums (Ewald, P3M, each also over a slab; FMM) and the solve of induced moments, with
# and without lists: demkit's own functions and the generic module's, compiled once per install too
m = 125
mbox = dk.build.box_for(m, R, 0.1)
mpos = dk.build.random_packing(m, R, mbox, seed=4)
g = np.arange(4) + 0.5
layer = np.column_stack([np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2), np.full(16, 0.5)])
sums = []
for lr in (dk.Ewald(1e-4), dk.P3M(1e-4)):
    sums.append(dk.Scene(dk.Particles(position=mpos, radius=R, mass=1.0, dipole=np.tile([0.0, 0, 1], (m, 1))),
                         [dk.Dipole(0.1, long_range=lr), dk.KelvinVoigt(1000.0, 1.0)], box=mbox, tier=1, parallel=True))
    sums.append(dk.Scene(dk.Particles(position=mpos, radius=R, mass=1.0, susceptibility=1.0),
                         [dk.Dipole(0.1, long_range=lr), dk.KelvinVoigt(1000.0, 1.0), dk.UniformField((0, 0, 0.2))],
                         box=mbox, tier=1, parallel=True))
for lr in (dk.Ewald(1e-6), dk.P3M(1e-4)):
    sums.append(dk.Scene(dk.Particles(layer, radius=0.2, mass=1.0, dipole=np.tile([0.6, 0.0, 0.8], (16, 1))),
                         [dk.Dipole(1.0, long_range=lr)], box=dk.Box([4.0, 4.0, 1.0], periodic=[True, True, False]),
                         tier=1))
sums.append(dk.Scene(dk.Particles(position=[[0, 0, 1.05 * k] for k in range(5)], radius=0.5, mass=1.0,
                                  susceptibility=3.0),
                     [dk.Dipole(1.0), dk.KelvinVoigt(1000.0, 1.0), dk.UniformField((0, 0, 0.5))], tier=1))
sums.append(dk.Scene(dk.Particles(position=mpos, radius=R, mass=1.0, susceptibility=1.0),
                     [dk.Dipole(0.1, cutoff=3.0), dk.KelvinVoigt(1000.0, 1.0), dk.UniformField((0, 0, 0.2))],
                     box=mbox, tier=1))
try:  # (fmm3dpy: the [fmm] extra)
    sums.append(dk.Scene(dk.Particles(position=[[0, 0, 0], [1.5, 0, 0], [0, 1.5, 0], [1.5, 1.5, 0]], radius=0.5,
                                      mass=1.0, dipole=np.eye(4, 3) + 0.1),
                         [dk.Dipole(0.01, long_range=dk.FMM(1e-6, exact_below=0)), dk.KelvinVoigt(1000.0, 1.0)], tier=1))
except ImportError:
    pass
for scene in sums:
    for integrator in (dk.VelocityVerlet(1e-4), dk.MultipleTimeStep(1e-4, inner=2)):
        dk.Simulation(scene, integrator).run(duration=2e-4, progress=False)
    scene.energy(); scene.forces()
# and what other scenes compile once: sorting by cell, a sheared box, contact events over lists, a cone,
# the contact diagnostics (the laws called from Python)
others = [dk.Scene(dk.Particles(position=q.position, radius=R, mass=1.0), [dk.KelvinVoigt(1000.0, 1.0)], box=box,
                   tier=1, sort_every=1),
          dk.Scene(dk.Particles(position=q.position, radius=R, mass=1.0, dipole=q.dipole), full[:1],
                   box=dk.Box(box.size, periodic=True, shear=dk.Shear(0.1, "x", "y")), tier=1),
          dk.Scene(dk.Particles(position=[[0, 0, 2.0], [0.55, 0, 3.0]], radius=0.5, mass=1.0), [full[0], dk.Gravity((0, 0, -1.0)),
                   dk.Cone((0, 0, 0), (0, 0, 1), 0.6, upper=5.0, angular_velocity=0.5)], tier=1)]
for scene in others:
    dk.Simulation(scene, dk.VelocityVerlet(1e-3)).run(duration=3e-3, progress=False)
dk.Simulation(others[0], dk.VelocityVerlet(1e-3, resolve_contacts=True)).run(duration=2e-3, progress=False)
for scene in (small_full, big_full, others[2]):
    scene.contacts()
print("RESULT", json.dumps({{"cpu_s": time.process_time() - t0, "tier_1_cpu_s": tier_1, "compile_cpu_s": compiling[0]}}))
"""


def part_tiers(quick, rounds=3):
    """The tiers' figures (see the module docstring)."""
    tmp = tempfile.mkdtemp(prefix="demkit-latency-")
    cache = Path(tmp) / "kernels"
    env = dict(os.environ, DEMKIT_CACHE_DIR=str(cache), DEMKIT_QUIET="1")
    rows = []
    try:
        fresh = []
        for _ in range(1 if quick else rounds):  # the spread is wide (15-20 CPU s): the median of three
            _empty_caches(cache)
            fresh.append(_child(COMPILE_CHILD.format(scene=_scene_source("two_magnets", tmp)), env))
        rows.append({"what": "fresh_install", "scene": "two_magnets",
                     "cpu_s": statistics.median(r["cpu_s"] for r in fresh),
                     "cpu_s_runs": [round(r["cpu_s"], 2) for r in fresh],
                     "kernel_functions_compiled": fresh[0]["kernel_functions_compiled"]})
        print(json.dumps(rows[-1]), flush=True)
        for name, (source, kind, integrator) in TIER_SCENES.items():
            warm = COMPILE_CHILD.format(scene=textwrap.dedent(WARM_GENERIC[kind].format(integrator=integrator)))
            _child(warm + WARM_PIECES, env)  # the install-wide code of this kind of scene, from another scene
            first = _child(COMPILE_CHILD.format(scene=_scene_source(source, tmp)), env)
            runs = [first]
            if not first["kernel_functions_compiled"] and not quick:
                # nothing compiled: the same measurement again is as new (this machine's speed drifts
                # by 0.2-0.3 CPU s between minutes): the median of three
                runs += [_child(COMPILE_CHILD.format(scene=_scene_source(source, tmp)), env) for _ in range(rounds - 1)]
                first = dict(first, cpu_s=statistics.median(r["cpu_s"] for r in runs),
                             cpu_s_runs=[round(r["cpu_s"], 2) for r in runs])
            rows.append({"what": "new_combination", "scene": name, **first})
            print(json.dumps(rows[-1]), flush=True)
            if kind == "lists" or name == "two_magnets":  # tier 2 of the same new combination: its own
                # pieces (with lists), or its fused module (the paper's open scene: its time loop; frames are tier 1's)
                second = _child(COMPILE_CHILD.format(scene=_scene_source(source, tmp)), dict(env, DEMKIT_TIER="2"))
                rows.append({"what": "tier2_first_step", "scene": name, **second})
                print(json.dumps(rows[-1]), flush=True)
        if not quick:  # several minutes each; the machine drifts by 5-10 % between minutes: the median of three
            runs = []
            for _ in range(rounds):
                _empty_caches(cache)
                runs.append(_child(INSTALL_CHILD.format(), env))
            middle = sorted(runs, key=lambda r: r["cpu_s"])[len(runs) // 2]
            rows.append({"what": "install_wide", **middle, "cpu_s_runs": [round(r["cpu_s"], 1) for r in runs],
                         "compile_cpu_s_runs": [round(r["compile_cpu_s"], 1) for r in runs]})
            print(json.dumps(rows[-1]), flush=True)
        for name in ("two_magnets", "gas600", "plugin_lists"):
            row = {"what": "speed", "scene": name, "tier1_runs": [], "tier2_runs": []}
            for r in range(1 if quick else rounds):
                for tier in ((1, 2) if r % 2 == 0 else (2, 1)):
                    res = _child(SPEED_CHILD.format(scene=_scene_source(name, tmp), tier=tier,
                                                    seconds=2.0 if quick else 4.0), env)
                    row[f"tier{tier}_runs"].append(res["steps_per_s"])
            row["tier1"] = statistics.median(row["tier1_runs"])
            row["tier2"] = statistics.median(row["tier2_runs"])
            row["ratio_tier1_to_tier2"] = row["tier1"] / row["tier2"]
            rows.append(row)
            print(json.dumps(row), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return rows


def main(argv):
    quick = "--quick" in argv
    parts = [a for a in argv if not a.startswith("--")] or ["threads", "compile"]
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    machine = {"cores": os.cpu_count(), "date": time.strftime("%Y-%m-%d %H:%M")}
    if "threads" in parts:
        scenes = ["gas4000", "pour3000"] if quick else ["gas4000", "pour3000", "dipoles8000", "magnetic_cluster",
                                                        "two_magnets"]
        results["threads"] = {"machine": machine, "rows": part_threads(quick, 1, 3.0 if quick else 6.0, scenes,
                                                                       rounds=1 if quick else 3)}
    if "compile" in parts:
        against = next((a.split("=", 1)[1] for a in argv if a.startswith("--against=")), None)
        scenes = ["two_magnets", "gas600"] if quick else ["two_magnets", "two_magnets_rk4", "gas600",
                                                          "magnetic_cluster", "accuracy3"]
        key = f"compile_against_{against}" if against else "compile"  # a comparison keeps its own table
        results[key] = {"machine": machine, "against": against, "quick": quick,
                        "rows": part_compile(quick, scenes, against=against)}
    if "tiers" in parts:
        results["tiers"] = {"machine": machine, "quick": quick, "rows": part_tiers(quick)}
    if "long_range" in parts:  # the dipole sums of every range: compilation, and threads beside a busy core
        results["long_range"] = {
            "machine": machine,
            "compile": part_compile(quick, ["ewald1000"] if quick else ["ewald1000", "p3m8000"]),
            "threads": part_threads(quick, 1, 3.0 if quick else 6.0, ["p3m8000"], rounds=1 if quick else 3)}
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=1, default=float) + "\n")
    print(f"written {RESULTS}")


if __name__ == "__main__":
    main(sys.argv[1:])
