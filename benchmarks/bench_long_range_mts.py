"""What multiple time stepping buys with a long-range dipole sum, at equal accuracy. Writes
benchmarks/results/long_range_mts.json.

The scene: benchmarks/reference_scene.py's N = 1000 spheres (periodic cube, volume fraction 0.2,
moments of 2, kT = 1) with frictionless Hooke contacts (k = 1000, dashpot 1.5, as the LAMMPS deck)
and ``Dipole(1, long_range=P3M(1e-4))`` (or Ewald with ``--sum ewald``). The whole sum is a slow
force: ``MultipleTimeStep(dt, inner)`` evaluates it once per outer step dt and the contacts
``inner`` times. Velocity Verlet evaluates both every step.

``dk.accuracy.work_precision`` runs velocity Verlet at dt = 1e-3 (the deck's step) and halvings,
and MultipleTimeStep with inner = 4 and 10 at outer steps 4e-3 ... 1e-3, for 0.1 time units
(one thread), against velocity Verlet at dt = 1e-3/32; then, for each method, the cheapest run
whose position error is at most velocity Verlet's at dt = 1e-3: the speed-up at equal accuracy.

    python benchmarks/bench_long_range_mts.py [--quick] [--sum p3m|ewald]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numba

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results" / "long_range_mts.json"


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true", help="N = 300, shorter run")
    args.add_argument("--sum", choices=("p3m", "ewald"), default="p3m")
    opts = args.parse_args(argv)
    import demkit as dk
    from reference_scene import load_reference_scene, particles_and_box
    numba.set_num_threads(1)
    n, duration = (300, 0.05) if opts.quick else (1000, 0.1)
    p, box = particles_and_box(load_reference_scene(n, tempfile.mkdtemp(prefix="demkit-mts-")))
    method = dk.P3M(1e-4) if opts.sum == "p3m" else dk.Ewald(1e-4)
    scene = dk.Scene(p, [dk.Dipole(1.0, long_range=method), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)],
                     box=box, parallel=False)
    base = 1e-3
    methods = {"VelocityVerlet": dk.VelocityVerlet}
    for inner in (4, 10):
        methods[f"MTS(inner={inner})"] = (lambda k: lambda dt: dk.MultipleTimeStep(dt, inner=k))(inner)
    dts = {"VelocityVerlet": [base, base / 2, base / 4, base / 8]}
    for inner in (4, 10):
        dts[f"MTS(inner={inner})"] = [dt for dt in (10 * base, 5 * base, 4 * base, 2 * base, base)
                                      if dt / inner <= base]
    started = time.time()
    # the reference: velocity Verlet at dt = base / 32 from a copy of the scene, frames every base
    ref_scene = dk.accuracy.copy_scene(scene)
    reference = dk.Simulation(ref_scene, dk.VelocityVerlet(base / 32)).run(duration=duration, record_every=base,
                                                                           progress=False)
    rows = []
    for label in methods:  # one study per method (each its own time steps), all against that reference
        study = dk.accuracy.work_precision(scene, duration, methods={label: methods[label]}, dts=dts[label],
                                           reference=reference, repeats=1, progress=False)
        rows += [r for r in study.rows if not r.get("is_reference")]
    keep = ("method", "dt", "steps", "evaluations", "seconds", "cpu_seconds", "stable", "position_error",
            "velocity_error", "energy_error")
    rows = [{k: r.get(k) for k in keep} for r in rows]
    target = next(r["position_error"] for r in rows if r["method"] == "VelocityVerlet" and r["dt"] == base)
    best = {}
    for label in methods:
        good = [r for r in rows if r["method"] == label and r["stable"] and r["position_error"] <= target]
        if good:
            fastest = min(good, key=lambda r: r["seconds"])
            best[label] = {"dt": fastest["dt"], "seconds": fastest["seconds"], "position_error": fastest["position_error"]}
    vv = best["VelocityVerlet"]["seconds"]
    for label in best:
        best[label]["speedup_vs_velocity_verlet"] = vv / best[label]["seconds"]
    result = {"machine": {"platform": platform.platform(), "date": time.strftime("%Y-%m-%d %H:%M"),
                          "load_average_at_start": os.getloadavg()[0], "threads": 1},
              "n": n, "duration": duration, "sum": repr(scene.long_range[0]),
              "reference": {"method": "VelocityVerlet", "dt": base / 32},
              "target_position_error": target, "rows": rows, "equal_accuracy": best,
              "wall_seconds": time.time() - started}
    RESULTS.parent.mkdir(exist_ok=True)
    out = RESULTS if not opts.quick else RESULTS.with_name("long_range_mts_quick.json")
    out.write_text(json.dumps(result, indent=1, default=float) + "\n")
    for r in rows:
        print(f"{r['method']:18s} dt={r['dt']:.2e} evals={r['evaluations']} {r['seconds']:.3f} s "
              f"pos_err={r['position_error']:.2e}")
    print(json.dumps(best, indent=1))
    print("written", out)


if __name__ == "__main__":
    main()
