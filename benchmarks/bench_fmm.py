"""Fast multipole sums (FMM3D) against demkit's exact all-pairs dipole sum in open clusters: time
of one force evaluation and the force error, N = 1000 ... 100000. Writes benchmarks/results/fmm.json.

Clusters: N spheres of diameter 1 packed at random at volume fraction 0.15 in a cube (open space),
random moments of magnitude 0.5-1.5, prefactor 1, one thread (NUMBA_NUM_THREADS=1 and FMM3D's
OpenMP on one thread, set before the imports). For each N: one evaluation (best of 3, after a
warm-up) with FMM at eps 1e-3, 1e-6, 1e-9 (scene.forces(): the whole force call, objmode and
copies included) and with the exact sum up to N = 20000 (beyond it the exact time is extrapolated
as N^2 from the largest measured); the RMS force error of FMM relative to the RMS force, where the
exact forces exist. The crossover is the smallest N where FMM at eps 1e-6 is faster.

    python benchmarks/bench_fmm.py [--quick]
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import demkit as dk  # noqa: E402

HERE = Path(__file__).resolve().parent
EXACT_MAX = 20000


def cluster(n, seed=1):
    rng = np.random.default_rng(seed)
    box = dk.build.box_for(n, 0.5, 0.15)
    pos = dk.build.random_packing(n, 0.5, box, seed=seed)
    dip = rng.normal(size=(n, 3))
    return pos, dip / np.linalg.norm(dip, axis=1)[:, None] * rng.uniform(0.5, 1.5, (n, 1))


def timed(scene, repeats=3):
    out = scene.forces()
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        scene.forces()
        best = min(best, time.perf_counter() - t)
    return best, out


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true")
    opts = args.parse_args(argv)
    sizes = (1000, 5000) if opts.quick else (1000, 2000, 5000, 10000, 20000, 50000, 100000)
    rows = []
    for n in sizes:
        pos, dip = cluster(n)
        p = dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip)
        row = dict(n=n)
        exact = None
        if n <= EXACT_MAX:
            seconds, exact = timed(dk.Scene(p, [dk.Dipole(1.0)], parallel=False), repeats=1 if n > 5000 else 3)
            row["exact_seconds"] = seconds
        for eps in (1e-3, 1e-6, 1e-9):
            seconds, (f, t) = timed(dk.Scene(p, [dk.Dipole(1.0, long_range=dk.FMM(eps, exact_below=0))], parallel=False))
            row[f"fmm_{eps:g}_seconds"] = seconds
            if exact is not None:
                scale = np.sqrt(np.mean((exact[0] ** 2).sum(1)))
                row[f"fmm_{eps:g}_force_error"] = float(np.sqrt(np.mean(((f - exact[0]) ** 2).sum(1))) / scale)
        print(json.dumps(row))
        rows.append(row)
    largest = max((r for r in rows if "exact_seconds" in r), key=lambda r: r["n"])
    for r in rows:
        if "exact_seconds" not in r:
            r["exact_seconds_extrapolated"] = largest["exact_seconds"] * (r["n"] / largest["n"]) ** 2
    exact_of = lambda r: r.get("exact_seconds", r.get("exact_seconds_extrapolated"))  # noqa: E731
    faster = [r["n"] for r in rows if r["fmm_1e-06_seconds"] < exact_of(r)]
    result = dict(machine=dict(platform=platform.platform(), date=time.strftime("%Y-%m-%d %H:%M"), threads=1),
                  rows=rows, crossover_at_eps_1e6=min(faster) if faster else None,
                  fmm_seconds_per_sphere={f"{eps:g}": float(np.median([r[f"fmm_{eps:g}_seconds"] / r["n"]
                                                                      for r in rows if r["n"] >= 10000] or [0]))
                                          for eps in (1e-3, 1e-6, 1e-9)})
    (HERE / "results" / "fmm.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps({k: result[k] for k in ("crossover_at_eps_1e6", "fmm_seconds_per_sphere")}))


if __name__ == "__main__":
    main()
