"""Calibrate the cost model of `demkit info` (demkit/cost.py): what one force evaluation costs per
sphere, per wall, per listed pair, per touching pair and per dipole pair, on this machine.

Each part is timed on a scene at rest built for it (no list rebuilds, nothing changes while timed),
one thread, warm kernel caches, the median of three timings of >= 0.4 s each, and solved from
differences between two scenes that differ only in that part:

  dilute      4000 spheres, volume fraction 0.02, Kelvin-Voigt, periodic  -> per sphere (+ few listed pairs)
  dense       the same at volume fraction 0.3                             -> per listed pair that does not touch
  walls       the dilute scene (frictional Hertz) in a box of 5 walls       -> per sphere and wall
  touching    a simple cubic lattice, spacing 0.98 d: 3 touching pairs per sphere, for each contact law
  dipole list 4000 dipoles cut at 4 d (+ Kelvin-Voigt), volume fraction 0.2 -> per listed dipole pair
  all pairs   400 and 1000 dipoles in open space (+ Kelvin-Voigt)          -> per pair of the exact sum

    python benchmarks/bench_cost_model.py            # writes benchmarks/results/cost_model.json
"""
from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
import numpy as np  # noqa: E402

import demkit as dk  # noqa: E402
from demkit.cost import pair_counts  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results" / "cost_model.json"
R = 0.5


def seconds_per_step(scene, integrator=None):
    """Median wall seconds of one step over three timings of >= 0.4 s (one thread, warm)."""
    integrator = integrator or dk.VelocityVerlet(1e-3)
    sim = dk.Simulation(scene, integrator, notes=False)
    sim.run(duration=10 * integrator.dt, progress=False)
    steps, clock = 10, time.perf_counter()
    while time.perf_counter() - clock < 0.1:
        sim.run(duration=steps * integrator.dt, progress=False)
        steps *= 2
    rate = steps / (time.perf_counter() - clock)
    count = max(20, int(0.4 * rate))
    times = []
    for _ in range(3):
        clock = time.perf_counter()
        sim.run(duration=count * integrator.dt, progress=False)
        times.append((time.perf_counter() - clock) / count)
    return statistics.median(times)


def gas(n, fraction, interactions, periodic=True, dipoles=False, seed=1):
    box = dk.build.box_for(n, R, fraction, periodic=periodic)
    pos = dk.build.random_packing(n, R, box, seed=seed)
    dip = None
    if dipoles:
        d = np.random.default_rng(seed).normal(size=(n, 3))
        dip = d / np.linalg.norm(d, axis=1)[:, None]
    p = dk.Particles(position=pos, radius=R, mass=1.0, dipole=dip)
    return dk.Scene(p, interactions, box=box if periodic else None, parallel=False), box


def listed(scene):
    return sum(count for group, _, count in pair_counts(scene) if group.kind == "list")


def main():
    kv = dk.KelvinVoigt(stiffness=1000.0, damping=1.0)
    out = {"machine": platform.node(), "python": platform.python_version(), "numba": __import__("numba").__version__}
    n = 4000
    dilute, _ = gas(n, 0.02, [kv])
    dense, _ = gas(n, 0.3, [kv])
    t_dilute, t_dense = seconds_per_step(dilute), seconds_per_step(dense)
    l_dilute, l_dense = listed(dilute), listed(dense)
    pair_test = (t_dense - t_dilute) / (l_dense - l_dilute)
    sphere = (t_dilute - l_dilute * pair_test) / n
    out["sphere_seconds"], out["listed_pair_seconds"] = sphere, pair_test
    print(f"per sphere {sphere * 1e9:.1f} ns, per listed pair {pair_test * 1e9:.2f} ns", flush=True)

    # walls: the dilute spheres in a closed, open box (5 walls; nothing touches them), frictional
    # Hertz contacts (the dearest law, whose walls keep history)
    hertz = dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5))
    closed, box = gas(n, 0.02, [hertz], periodic=False)
    side = box.size[0]
    walls = [dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 0), (1, 0, 0)), dk.Wall((0, 0, 0), (0, 1, 0)),
             dk.Wall((side, side, 0), (-1, 0, 0)), dk.Wall((side, side, 0), (0, -1, 0))]
    walled = dk.Scene(closed.particles, [hertz, *walls], parallel=False)
    out["wall_seconds"] = (seconds_per_step(walled) - seconds_per_step(closed)) / (5 * n)
    print(f"per sphere and wall {out['wall_seconds'] * 1e9:.2f} ns", flush=True)

    # touching pairs: a simple cubic lattice squeezed to 0.98 d, at rest; 3 pairs per sphere
    laws = {"KelvinVoigt": kv, "Hertz": dk.Hertz(young=2e4, poisson=0.3, restitution=0.5),
            "KelvinVoigt+Friction": dk.KelvinVoigt(stiffness=1000.0, damping=1.0, friction=dk.Friction(0.5)),
            "Hertz+Friction": dk.Hertz(young=2e4, poisson=0.3, restitution=0.5, friction=dk.Friction(0.5))}
    pos, box = dk.build.lattice("sc", 16, spacing=0.98)
    touching = {}
    for name, law in laws.items():
        lat = dk.Scene(dk.Particles(position=pos, radius=R, mass=1.0), [law], box=box, parallel=False)
        spaced = dk.Scene(dk.Particles(position=pos * (1.1 / 0.98), radius=R, mass=1.0), [law],
                          box=dk.Box(box.size * (1.1 / 0.98)), skin=0.2, parallel=False)
        m = len(pos)
        # the same lists (6 partners within reach) with and without contact: the difference is the law
        touching[name] = (seconds_per_step(lat) - seconds_per_step(spaced)) / (3 * m)
        print(f"per touching pair, {name}: {touching[name] * 1e9:.1f} ns", flush=True)
    out["touching_pair_seconds"] = touching

    # listed dipole pairs: a dipolar gas at rest, dipoles cut at 4 d, with and without a contact law
    dipole = dk.Dipole(prefactor=1e-6, cutoff=4.0)
    by_group = {}
    for name, inters in {"Dipole": [dipole], "Dipole+KelvinVoigt": [dipole, kv],
                         "Dipole+Hertz+Friction": [dipole, laws["Hertz+Friction"]]}.items():
        sc, _ = gas(n, 0.2, inters, dipoles=True)
        pairs = max(c for _, _, c in pair_counts(sc))
        by_group[name] = (seconds_per_step(sc) - n * sphere) / pairs
        print(f"per listed dipole pair, {name}: {by_group[name] * 1e9:.1f} ns", flush=True)
    out["dipole_list_pair_seconds"] = by_group

    # all pairs: open clusters of dipoles, two sizes (the per-sphere part solved out)
    times = {}
    for m in (400, 1000):
        sc, _ = gas(m, 0.05, [dk.Dipole(prefactor=1e-6), kv], periodic=False, dipoles=True)
        times[m] = seconds_per_step(sc)
    p400, p1000 = 400 * 399 / 2, 1000 * 999 / 2
    all_pair = (times[1000] - times[400]) / (p1000 - p400)
    out["all_pair_seconds"] = all_pair
    out["all_pairs_sphere_seconds"] = (times[400] - p400 * all_pair) / 400
    print(f"per pair of the exact sum {all_pair * 1e9:.1f} ns (+ {out['all_pairs_sphere_seconds'] * 1e9:.0f} ns per sphere)",
          flush=True)
    # the machine's speed today, to compare calibrations across days (this machine has measured up
    # to ~1.8x slower on some days than on others): the paper's two-sphere scene (docs/nbody.md:
    # 24.7 million steps/s when that page was measured) and a plain Python loop
    paper = seconds_per_step(dk.two_magnets.TwoMagnets(b_over_R=4.0).scene(), dk.EulerCromer(0.01))
    clock, x = time.perf_counter(), 0.0
    for i in range(10**7):
        x += i * 0.5
    out["machine_speed"] = {"paper_scene_steps_per_second": 1.0 / paper,
                            "python_loop_1e7_seconds": time.perf_counter() - clock}
    print(f"machine: the paper's scene {1e-6 / paper:.1f} million steps/s, a Python loop of 1e7 "
          f"{out['machine_speed']['python_loop_1e7_seconds']:.2f} s", flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    sys.exit(main())
