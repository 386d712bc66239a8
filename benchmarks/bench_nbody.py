"""N-body engine benchmarks, side by side with LAMMPS in one run. Writes benchmarks/results/nbody.json.

Parts (all by default; name some to run only those):

* ``speed``: the N = 8000 reference scene (benchmarks/reference_scene.py: periodic, phi = 0.2,
  dipoles of 2, kT = 1), velocity Verlet dt = 0.001, skin 0.3, 1000 timed steps after a warm-up
  (5000 without dipoles), the deck's four models: ``nofric`` (Dipole(prefactor=1, cutoff=4) +
  KelvinVoigt(1000, 1.5)), ``full`` (the same with Friction(0.5, 2/7 k_n, 0.75, slip_radius="full"),
  LAMMPS' linear_history), ``nodip_nofric`` (KelvinVoigt only, spheres without dipoles or spins)
  and ``nodip`` (KelvinVoigt with that friction, spinning spheres); demkit on 1 and 2 threads,
  LAMMPS (benchmarks/lammps/in.reference, same data file) on 1 and 2 MPI ranks. This machine's
  speed drifts by 20-50 % between minutes, so the two codes alternate: ROUNDS rounds, each a demkit
  process (best of 3 runs in it) and a LAMMPS run (best of 2), the order swapped every round; a
  round's ratio compares runs made within the same minute, and the figure kept is the median of the
  rounds' ratios (all rounds' rates are in the row). Every timed demkit run starts from the data
  file, as LAMMPS' run does: the gas cools, and runs that went on from an earlier one rebuilt their
  lists every 161 steps instead of 61 and ran up to 35 % faster (the figures before 2026-11-26
  evening took the best of three consecutive runs).
* ``memory``: bytes per sphere of the engine for contacts + dipoles + per-contact history (a
  3-value history on the contact list, as friction keeps), counted array by array (recording excluded).
* ``scaling``: contact-only cost per particle-step and peak memory for N = 1e3 ... 1e6 (one
  process each), with a plot benchmarks/results/nbody_scaling.png.
* ``allpairs``: the exact all-pairs dipole sum (no cutoff) of an open cluster: pair evaluations per
  second on 2 threads.
* ``unused``: what the N-body machinery costs a scene that does not use it: the seed paper's
  two-sphere scene (open space, no lists, no threads) against its figure before the N-body engine.

Usage: python benchmarks/bench_nbody.py [speed] [memory] [scaling] [allpairs] [unused] [plot] [--quick]
       [--models=nofric,full,nodip_nofric,nodip] (part speed: only these models; the others' rows are kept)
       [--tier=2|1] (part speed: demkit's scenes on the fused modules, tier 2, rows ``speed``; or on the
       generic tier 1, rows ``speed_tier1``: docs/engine.md)
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results" / "nbody.json"
DECK = HERE / "lammps" / "in.reference"
N_REFERENCE = 8000
STEPS = 1000
#: the deck's models (part speed)
MODELS = ("nofric", "full", "nodip_nofric", "nodip")
#: alternating demkit / LAMMPS rounds per model and core count (part speed)
ROUNDS = 3

# one demkit measurement in a fresh process (threads and peak memory are per process)
CHILD = textwrap.dedent("""
    import json, resource, sys, time
    sys.path.insert(0, {here!r})
    import numba, numpy as np, demkit as dk
    from reference_scene import load_reference_scene, particles_and_box
    numba.set_num_threads({threads})
    scene_data = load_reference_scene({n}, {folder!r})
    model = {model!r}  # the deck's models: full, nofric, nodip, nodip_nofric

    def fresh(parallel=None):
        # the data file's state: every timed run covers the deck's steps 0 .. nsteps, as LAMMPS' does
        # (a gas that went on from an earlier run has cooled and rebuilds its lists less often)
        data = {{k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v for k, v in scene_data.items()}}
        p, box = particles_and_box(data)
        if model.startswith("nodip"):
            p = dk.Particles(position=p.position, velocity=p.velocity, radius=p.radius, mass=p.mass,
                             angular_velocity=p.angular_velocity if model == "nodip" else None)
        extra = {{}}
        if model in ("full", "nodip"):  # LAMMPS' linear_history kt = 2/7 kn, damping 0.5 of the normal's
            extra["friction"] = dk.Friction(0.5, stiffness=2.0 / 7.0 * 1000.0, damping=0.75, slip_radius="full")
        inters = [dk.KelvinVoigt(stiffness=1000.0, damping=1.5, **extra)]
        if not model.startswith("nodip"):
            inters.insert(0, dk.Dipole(prefactor=1.0, cutoff=4.0))
        scene = dk.Scene(p, inters, box=box, skin=0.3, parallel=parallel, tier={tier})
        return dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))

    fresh().run(duration=0.02)  # compile or load the kernels (kept for the process)
    if {threads} > 1:  # and the thread module: timed runs are of a warm cache (a run shorter than
        fresh(True).run(duration=0.02)  # threads.WORTH_COMPILING never compiles it itself)
    best = None
    for _ in range({repeats}):
        sim = fresh()
        sim.run(duration={steps} * 1e-3)
        st = sim.statistics
        if best is None or st["particle_steps_per_second"] > best["particle_steps_per_second"]:
            best = st
    best["peak_rss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print("RESULT", json.dumps(best, default=float))
""")


def demkit_run(model, threads, n=N_REFERENCE, steps=STEPS, repeats=3, folder=None, tier=None):
    code = CHILD.format(here=str(HERE), threads=threads, n=n, folder=folder, model=model, steps=steps,
                        repeats=repeats, tier=tier)
    env = dict(os.environ, NUMBA_NUM_THREADS=str(max(2, threads)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    if out.returncode != 0:  # say why: the child's own error, not only its exit status
        raise RuntimeError(f"demkit's {model} run on {threads} thread(s) failed:\n{out.stderr[-3000:]}")
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1]
    return json.loads(line[len("RESULT "):])


def lammps_rate(model, ranks, data, steps=STEPS, repeats=3):
    from lammps_run import lammps_available, run_deck
    if not lammps_available(ranks):
        return None
    rates = [run_deck(DECK, {"data": str(data), "model": model, "nsteps": steps}, ranks=ranks)["atom_steps_per_s"]
             for _ in range(repeats)]
    return max(rates)


def part_speed(folder, quick, models=MODELS, tier=2):
    import statistics

    from reference_scene import write_reference_scene
    _, _, data = write_reference_scene(N_REFERENCE, folder)
    rows = []
    rounds = 1 if quick else ROUNDS
    for model in models:
        for cores in (1, 2):
            steps = 300 if quick else (STEPS if not model.startswith("nodip") else 5 * STEPS)
            ours, theirs, ratios, builds, lists = [], [], [], [], None
            for r in range(rounds):  # the codes alternate, the order swapped each round (module docstring)
                pair = {}
                for code in ("demkit", "lammps") if r % 2 == 0 else ("lammps", "demkit"):
                    if code == "demkit":
                        res = demkit_run(model, cores, steps=steps, folder=folder, repeats=1 if quick else 3,
                                         tier=tier)
                        pair["demkit"] = res["particle_steps_per_second"]
                        builds.append(res["steps_per_build"])
                        lists = res["lists"]
                    else:
                        pair["lammps"] = lammps_rate(model, cores, data, steps=steps, repeats=1 if quick else 2)
                ours.append(pair["demkit"])
                theirs.append(pair["lammps"])
                if pair["lammps"] is not None:
                    ratios.append(pair["demkit"] / pair["lammps"])
            rows.append({"model": model, "cores": cores, "tier": tier,
                         "demkit_particle_steps_per_s": statistics.median(ours),
                         "lammps_atom_steps_per_s": statistics.median(theirs) if ratios else None,
                         "ratio": statistics.median(ratios) if ratios else None,
                         "ratio_rounds": ratios, "demkit_rounds": ours, "lammps_rounds": theirs,
                         "steps_per_list_build": statistics.median(builds), "lists": lists})
            print(json.dumps(rows[-1], default=float), flush=True)
    return rows


def part_memory(folder):
    """Engine bytes per sphere, array by array (the state, the lists at their capacity, the user's
    arrays when the kernels keep their own sorted copies)."""
    import numpy as np

    import demkit as dk
    from reference_scene import load_reference_scene, particles_and_box
    sys.path.insert(0, str(HERE.parent / "tests"))
    from plugin_interactions import TouchCounter

    p, box = particles_and_box(load_reference_scene(N_REFERENCE, folder))

    class History3(TouchCounter):
        history_size = 3  # as much as a tangential spring keeps

    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(1000.0, 1.5), History3(cutoff=1.0)],
                     box=box, skin=0.3)
    dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3)).run(duration=0.2)
    counted = {}
    for name, value in scene.arrays.items():
        if isinstance(value, np.ndarray):
            counted[f"state.{name}"] = value.nbytes
    for g, pl in enumerate(scene.state.lists):
        for name in ("start", "end", "partner", "history", "bounds"):
            counted[f"list{g}.{name}"] = getattr(pl, name).nbytes
    if scene.plan.sorted:
        for name in dk.scene.PARTICLE_FIELDS + ("ids",):
            value = getattr(scene.particles, name)
            if value is not None:
                counted[f"user.{name}"] = value.nbytes
    n = len(p)
    return {"bytes_per_sphere": sum(counted.values()) / n,
            "by_array_per_sphere": {k: v / n for k, v in sorted(counted.items(), key=lambda kv: -kv[1])},
            "lists": scene.neighbour_lists()}


SCALING_CHILD = textwrap.dedent("""
    import json, resource, sys, time
    import numba, numpy as np, demkit as dk
    numba.set_num_threads({threads})

    def rss():  # resident memory now (bytes)
        return int(open("/proc/self/statm").read().split()[1]) * resource.getpagesize()

    n = {n}
    rss_import = rss()
    box = dk.build.box_for(n, 0.5, 0.2, periodic=True)
    rng = np.random.default_rng(1)
    x = dk.build.random_packing(n, 0.5, box, seed=rng)
    v = dk.build.thermal_velocities(n, 1.0, 1.0, seed=rng)
    p = dk.Particles(position=x, velocity=v, radius=0.5, mass=1.0)
    del x, v
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=1000.0, damping=1.5)], box=box, skin=0.3)
    rss_scene = rss()
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
    sim.run(duration=0.01)
    steps = max(100, min(2000, int(1e8 / n)))  # 100 steps of 10^6 spheres: per-run costs (checks, copies) amortised as in real runs
    sim.run(duration=steps * 1e-3)
    st = sim.statistics
    nbytes = lambda arrays: sum(a.nbytes for a in arrays if isinstance(a, np.ndarray))
    lists = [getattr(pl, k) for pl in scene.state.lists for k in ("start", "end", "partner", "history", "bounds")]
    user = [getattr(p, k) for k in dk.scene.PARTICLE_FIELDS + ("ids",)] if scene.plan.sorted else []
    t = sim.trajectory
    frames = [t.position, t.velocity, t.image, t.radius, t.mass, t.inertia, t.ids]
    print("RESULT", json.dumps({{"n": n, "particle_steps_per_second": st["particle_steps_per_second"],
        "ns_per_particle_step": 1e9 / st["particle_steps_per_second"], "steps": steps,
        "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
        "rss_after_import_bytes": rss_import, "rss_after_scene_bytes": rss_scene,
        "state_bytes": nbytes(scene.arrays.values()), "list_bytes": nbytes(lists),
        "user_array_bytes": nbytes(user), "last_run_frames_bytes": nbytes(frames),
        "threads_used": st["threads"]}}))
""")


def part_scaling(quick):
    sizes = [1000, 10000, 100000] if quick else [1000, 10000, 100000, 1000000]
    rows = []
    for threads in (1, 2):
        for n in sizes:
            out = subprocess.run([sys.executable, "-c", SCALING_CHILD.format(n=n, threads=threads)],
                                 capture_output=True, text=True, check=True,
                                 env=dict(os.environ, NUMBA_NUM_THREADS="2"))
            row = json.loads([ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1][7:])
            row["threads"] = threads
            rows.append(row)
            print(json.dumps(row))
    plot_scaling(rows)
    return rows


def plot_scaling(rows):
    """benchmarks/results/nbody_scaling.png: ns per particle-step against N, one line per thread
    count, and the issue's target (1.3x the N = 1000 cost) dashed."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for threads in (1, 2):
        pts = [r for r in rows if r["threads"] == threads]
        label = "1 thread" if threads == 1 else "2 threads allowed (parallel=None; open: the run chose 1)"
        line, = ax.plot([r["n"] for r in pts], [r["ns_per_particle_step"] for r in pts], "-", label=label)
        for r in pts:
            used = r.get("threads_used", threads)
            ax.plot(r["n"], r["ns_per_particle_step"], "o", color=line.get_color(),
                    markerfacecolor=line.get_color() if used == threads else "white")
        first = min(pts, key=lambda r: r["n"])
        ax.hlines(1.3 * first["ns_per_particle_step"], first["n"], max(r["n"] for r in pts), linestyles="dashed",
                  colors=ax.lines[-1].get_color(), linewidth=0.8, label=f"target: 1.3x N = {first['n']:,}")
    ax.set_xscale("log")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("spheres N")
    ax.set_ylabel("ns per particle-step")
    ax.set_title("contact-only gas, phi = 0.2, periodic")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(HERE / "results" / "nbody_scaling.png", dpi=120)


def part_allpairs():
    code = textwrap.dedent("""
        import json, time, numba, numpy as np, demkit as dk
        numba.set_num_threads(2)
        n = 4000
        box = dk.build.box_for(n, 0.5, 0.05, periodic=False)
        rng = np.random.default_rng(2)
        x = dk.build.random_packing(n, 0.5, box, seed=rng)
        p = dk.Particles(position=x, radius=0.5, dipole=dk.build.random_directions(n, seed=rng))
        scene = dk.Scene(p, [dk.Dipole(prefactor=1.0)], parallel=True)
        scene.forces()
        t = time.perf_counter(); reps = 5
        for _ in range(reps):
            scene.forces()
        el = (time.perf_counter() - t) / reps
        print("RESULT", json.dumps({"n": n, "pairs": n * (n - 1) // 2, "seconds": el,
                                    "pair_evaluations_per_second": n * (n - 1) / 2 / el}))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=dict(os.environ, NUMBA_NUM_THREADS="2"))
    return json.loads([ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1][7:])


def part_unused():
    """The paper's two-sphere scene, Euler-Cromer dt = 0.01 (as bench_two_magnets.py), now."""
    from bench_two_magnets import demkit_rate
    before = json.loads((HERE / "results" / "two_magnets.json").read_text())["demkit_steps_per_s"]
    now = demkit_rate(repeats=5)
    return {"steps_per_s_now": now, "steps_per_s_before_nbody_engine": before, "ratio": now / before}


def main(argv):
    quick = "--quick" in argv
    parts = [a for a in argv if not a.startswith("--")] or ["speed", "memory", "scaling", "allpairs", "unused"]
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    with tempfile.TemporaryDirectory() as folder:
        for part in parts:
            t = time.perf_counter()
            if part == "speed":
                models = next((a.split("=", 1)[1].split(",") for a in argv if a.startswith("--models=")), MODELS)
                tier = int(next((a.split("=", 1)[1] for a in argv if a.startswith("--tier=")), 2))
                rows = part_speed(folder, quick, models, tier)
                key = "speed" if tier == 2 else "speed_tier1"
                rev = subprocess.run(["git", "-C", str(HERE.parent), "rev-parse", "--short", "HEAD"],
                                     capture_output=True, text=True).stdout.strip()
                when = f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} at {rev}"
                for row in rows:
                    row["measured"] = when
                kept = [r for r in results.get(key, []) if r["model"] not in models]  # --models: the others stay
                results[key] = sorted(kept + rows, key=lambda r: (MODELS.index(r["model"]), r["cores"]))
                results["speed_note"] = (f"each row: median of {1 if quick else ROUNDS} alternating demkit/LAMMPS "
                                         "round(s), measured when its 'measured' says")
            elif part == "memory":
                results["memory"] = part_memory(folder)
            elif part == "scaling":
                results["scaling"] = part_scaling(quick)
            elif part == "plot":  # the scaling plot again from the stored figures
                plot_scaling(results["scaling"])
            elif part == "allpairs":
                results["allpairs"] = part_allpairs()
            elif part == "unused":
                results["unused"] = part_unused()
            else:
                raise SystemExit(f"unknown part {part!r}")
            print(f"{part}: {time.perf_counter() - t:.0f} s", flush=True)
    results["machine"] = f"{os.uname().machine}, {os.cpu_count()} cores"
    results["date"] = time.strftime("%Y-%m-%d")
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
