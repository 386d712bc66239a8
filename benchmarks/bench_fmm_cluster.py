"""A contact-rich open cluster of 10^5 magnetic spheres with FMM dipoles: steps per second and
memory. Writes benchmarks/results/fmm_cluster.json.

The cluster: an fcc block of 29 x 29 x 30 cells (100,920 spheres of diameter 1, mass 1) in open
space, nearest neighbours 0.995 apart (12 contacts per sphere, 0.5 % overlap: ~6·10^5 touching
pairs from the first step), random moments of magnitude 1, prefactor 1 (touching pull 6),
frictionless Hooke contacts k = 1000 with dashpot 1.5, and Dipole(1, long_range=FMM(1e-6)): FMM3D
sums all ~5·10^9 dipole pairs (the exact sum would take ~100 s per evaluation on one core,
benchmarks/results/fmm.json). One thread (NUMBA_NUM_THREADS=1, OMP_NUM_THREADS=1).

* velocity Verlet, dt = 1e-3: every step evaluates the FMM sum;
* MultipleTimeStep(1e-2, inner=10): the FMM sum once per outer step, the contacts ten times.

Reported: seconds per step of each (after an untimed first step: compilation, lists), the number
of touching pairs, the peak resident memory of the process (ru_maxrss; and its resident memory before the
scene was built: Python, numpy, numba and FMM3D loaded), demkit's estimate of the scene's arrays
(Scene.memory_estimate), and whether the energy stayed finite.

    python benchmarks/bench_fmm_cluster.py [--quick]
"""
from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import demkit as dk  # noqa: E402

HERE = Path(__file__).resolve().parent


def block(cells, seed=1):
    pos, _ = dk.build.lattice("fcc", cells, spacing=0.995, periodic=False)
    rng = np.random.default_rng(seed)
    dip = dk.build.random_directions(len(pos), seed=rng)
    return dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip, velocity=np.zeros_like(pos),
                        angular_velocity=np.zeros_like(pos))


def resident_bytes():
    """Resident memory of this process now (VmRSS), bytes."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmRSS:"))


def timed_steps(scene, integrator, steps):
    sim = dk.Simulation(scene, integrator)
    t = time.perf_counter()
    sim.run(duration=integrator.dt, progress=False)  # compiles (or loads), builds the lists
    first = time.perf_counter() - t
    t = time.perf_counter()
    sim.run(duration=steps * integrator.dt, progress=False)
    seconds = (time.perf_counter() - t) / steps
    energy = scene.energy()
    return {"integrator": repr(integrator), "first_step_seconds": first, "seconds_per_step": seconds,
            "steps_per_second": 1.0 / seconds, "simulated_time_per_second": integrator.dt / seconds,
            "timed_steps": steps,
            "energy_finite": bool(all(np.isfinite(v) for v in energy.values())),
            "max_speed": float(np.max(np.linalg.norm(scene.particles.velocity, axis=1)))}


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true", help="8 x 8 x 8 cells (2048 spheres)")
    opts = args.parse_args(argv)
    cells = (8, 8, 8) if opts.quick else (29, 29, 30)
    before = resident_bytes()
    p = block(cells)
    n = len(p)
    inters = [dk.Dipole(1.0, long_range=dk.FMM(1e-6, exact_below=0)), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)]
    scene = dk.Scene(p, inters, parallel=False)
    touching = int(len(scene.contacts().pairs))
    runs = [timed_steps(scene, dk.VelocityVerlet(1e-3), 2),
            timed_steps(scene, dk.MultipleTimeStep(1e-2, inner=10), 2)]
    result = {"machine": {"platform": platform.platform(), "date": time.strftime("%Y-%m-%d %H:%M"), "threads": 1,
                          "load_average_at_start": os.getloadavg()[0]},
              "n": n, "cells": cells, "touching_pairs_at_start": touching,
              "memory": {"peak_resident_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
                         "scene_estimate_bytes": scene.memory_estimate()["total"]},
              "runs": runs}
    result["memory"]["resident_bytes_before_the_scene"] = before
    result["memory"]["peak_above_that_per_sphere"] = (result["memory"]["peak_resident_bytes"] - before) / n
    out = HERE / "results" / ("fmm_cluster_quick.json" if opts.quick else "fmm_cluster.json")
    out.write_text(json.dumps(result, indent=1, default=float) + "\n")
    print(json.dumps(result, indent=1, default=float))
    print("written", out)


if __name__ == "__main__":
    main()
