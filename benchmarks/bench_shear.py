"""What Lees-Edwards shear and homogeneous deformation cost per step: the N = 8000 reference scene (benchmarks/reference_scene.py:
periodic, phi = 0.2, dipoles cut at 4 d, Kelvin-Voigt contacts k = 1000, c = 1.5, dt = 0.001) in a
fixed box and sheared along x with gradient y at a few rates (the images one period up slide at
gammadot L = 2.8 gammadot, against thermal speeds of about 1), on one tier; the list rebuilds per
1000 steps beside it (the sliding counts against the skin). With ``--deform R ...`` the box deforms
instead (dk.Deform(x=-R, y=R): x shrinks, y grows; positions remapped after each step).

    python benchmarks/bench_shear.py [--tier 1] [--n 8000] [--rates 0 0.01 0.1 1] [--deform 0.01]
        [--steps 300] [--rounds 5] [--out benchmarks/results/shear.json]

The scenes are stepped in turn, round by round (the order alternating), and each keeps its best round; and
each round's rate is divided by the fixed box's of the same round (``paired_median`` and the quartiles over
the rounds): on a shared machine the load moves more than the difference between them.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path


import demkit as dk

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference_scene import load_reference_scene, particles_and_box  # noqa: E402


def scene_of(n, rate, tier, folder, deform=False):
    ref = load_reference_scene(n, folder)
    p, box = particles_and_box(ref)
    if rate is not None and deform:
        box = dk.Box(box.size, periodic=True, deform=dk.Deform(x=-rate, y=rate))
    elif rate is not None:
        box = dk.Box(box.size, periodic=True, shear=dk.Shear(rate, "x", "y"))
        p.velocity[:, 0] += rate * (p.position[:, 1] - 0.5 * box.size[1])  # started in the flow's profile
    law = dk.KelvinVoigt(1000.0, 1.5)
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0), law], box=box, tier=tier)


def measure(n, rates, tier, steps, folder, rounds=5, deform=False):
    """Steps per second (the best of ``rounds``) and list rebuilds per 1000 steps of the fixed box and
    of each rate, the scenes stepped in turn round by round (the machine's swings hit all of them)."""
    runs = []
    for rate in [None, *rates]:
        scene = scene_of(n, rate, tier, folder, deform)
        sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
        sim.run(duration=0.02, progress=False)  # compile, first lists
        runs.append({"rate": rate, "scene": scene, "sim": sim, "best": 0.0, "rebuilds": scene.counters[0]})
    for k in range(rounds):
        for run in (runs if k % 2 == 0 else runs[::-1]):  # (alternating the order: no scene always first)
            t = time.perf_counter()
            run["sim"].run(duration=steps * 1e-3, progress=False)
            run.setdefault("rates", []).append(steps / (time.perf_counter() - t))
            run["best"] = max(run["best"], run["rates"][-1])
    fixed = runs[0]["best"]
    rows = []
    for run in runs:
        # paired: each round's rate over the fixed box's in the same round (a swing of the machine that
        # lasts longer than a round hits both), the median and quartiles over the rounds
        paired = [r / f for r, f in zip(run["rates"], runs[0]["rates"])]
        quartiles = statistics.quantiles(paired, n=4) if len(paired) > 1 else paired * 3
        rows.append({"rate": run["rate"], "tier": run["sim"].statistics["tier"], "steps_per_s": round(run["best"], 2),
                     "of_the_fixed_box": round(run["best"] / fixed, 3),
                     "paired_median": round(statistics.median(paired), 3),
                     "paired_quartiles": [round(quartiles[0], 3), round(quartiles[2], 3)],
                     "rebuilds_per_1000": round(1000.0 * float(run["scene"].counters[0] - run["rebuilds"])
                                                / (rounds * steps), 1)})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=8000)
    ap.add_argument("--tier", type=int, default=1)
    ap.add_argument("--rates", type=float, nargs="+", default=[0.0, 0.01, 0.1, 1.0])
    ap.add_argument("--deform", type=float, nargs="+", default=None, help="deforming boxes at these rates instead")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default=None, help="a JSON file for the results")
    a = ap.parse_args(argv)
    deform = a.deform is not None
    rows = measure(a.n, a.deform if deform else a.rates, a.tier, a.steps, tempfile.mkdtemp(), a.rounds, deform)
    for row in rows:
        print("fixed box" if row["rate"] is None else ("deforming" if deform else "sheared"), row, flush=True)
    if a.out:
        Path(a.out).write_text(json.dumps({"n": a.n, "deform": deform, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
