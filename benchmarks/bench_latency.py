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
  CPU time is what does not depend on the load), for the examples' scenes; a second start with the
  caches warm; and a scene that differs only in parameter values, particle count or thread count
  (which must compile nothing).

Usage: python benchmarks/bench_latency.py [threads] [compile] [--quick]
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
    "dipoles8000": """
        def make():
            sys.path.insert(0, {here!r})
            from reference_scene import load_reference_scene, particles_and_box
            p, box = particles_and_box(load_reference_scene(8000, {tmp!r}))
            inters = [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)]
            return dk.Scene(p, inters, box=box, skin=0.3), dk.VelocityVerlet(1e-3)
    """,
    "magnetic_cluster": """
        def make():
            loaded = dk.load_scene({root!r} + "/examples/magnetic_cluster/cluster.toml")
            return loaded.scene, loaded.integrator
    """,
    "two_magnets": """
        def make():
            return dk.two_magnets.TwoMagnets(b_over_R=4.0).scene(), dk.EulerCromer(0.01)
    """,
}

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
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
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
import numpy as np
import demkit as dk
{scene}
scene, integrator = make()
sim = dk.Simulation(scene, integrator)
sim.run(duration=integrator.dt, progress=False)  # the first step
print("RESULT", json.dumps({{"cpu_s": time.process_time() - t0, "wall_s": time.perf_counter() - w0}}))
"""


def _empty_caches(cache):
    shutil.rmtree(cache, ignore_errors=True)
    for folder in (ROOT / "demkit").rglob("__pycache__"):  # numba's cache of demkit's own modules
        for f in folder.iterdir():
            if f.suffix in (".nbi", ".nbc"):
                f.unlink()


def part_compile(quick, scenes):
    tmp = tempfile.mkdtemp(prefix="demkit-latency-")
    cache = Path(tmp) / "kernels"
    env = dict(os.environ, DEMKIT_CACHE_DIR=str(cache), DEMKIT_QUIET="1")
    rows = []
    try:
        for name in scenes:
            code = COMPILE_CHILD.format(scene=_scene_source(name, tmp))
            _empty_caches(cache)
            cold = _child(code, env)
            warm = _child(code, env)
            row = {"scene": name, "cold_cpu_s": cold["cpu_s"], "cold_wall_s": cold["wall_s"],
                   "warm_cpu_s": warm["cpu_s"], "warm_wall_s": warm["wall_s"]}
            print(json.dumps(row), flush=True)
            rows.append(row)
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
        scenes = ["two_magnets", "magnetic_cluster"] if quick else ["two_magnets", "magnetic_cluster", "gas4000",
                                                                    "pour3000"]
        results["compile"] = {"machine": machine, "rows": part_compile(quick, scenes)}
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=1, default=float) + "\n")
    print(f"written {RESULTS}")


if __name__ == "__main__":
    main(sys.argv[1:])
