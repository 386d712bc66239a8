"""What accuracy costs in time: integrators against each other. Writes benchmarks/results/integrators.json.

Parts (all by default; name some to run only those):

* ``collision``: the seed paper's collision (b/R = 4, paper units, the paper's start x0 = 150):
  the state 300 time units after the first contact (max position error) and the energy balance of
  the whole run (|total + dissipated - initial| over the energy scale of the collision, the
  magnetic energy of the pair touching head to tail, 2 A / d^3 = 2.5e-4, about what it dissipates)
  against a reference, for plain velocity Verlet and velocity Verlet with contact
  events resolved, dt halving from 0.2. The reference is the resolved method at dt = 0.2 / 2^10,
  checked against the run at twice its step. For each method: the wall time it needs for a state
  error of 1e-6 and an energy balance of 1e-6 of the scale (interpolated on the measured
  power law, or extrapolated along its measured order when no run reaches it; said which).
* ``mts``: the N-body reference scene (benchmarks/reference_scene.py, N = 8000 by default:
  periodic, phi = 0.2, dipoles of 2, Kelvin-Voigt 1000 / 1.5, dipoles cut at 4 with a switch of
  width 1 so that energy is a conserved quantity of the force field), first run for 2 time
  units so that chains and contacts form; then from that state, 0.5 time units of velocity Verlet
  at several dt and multiple time stepping at several (dt, inner): energy error max_t |total +
  dissipated - initial| per sphere (units of kT) against wall time on 2 threads. The target: the
  same energy error at least 3x faster than velocity Verlet.

Run it alone on the machine (2 cores).

    python benchmarks/bench_integrators.py [collision] [mts] [--n 8000] [--quick]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
RESULTS = HERE / "results" / "integrators.json"

import demkit as dk  # noqa: E402
from demkit.two_magnets.scene import TwoMagnets  # noqa: E402


def timed_run(make_scene, integrator, duration, record_every=None):
    """(trajectory, seconds) of a run of a fresh scene, after an untimed one-step run that compiles."""
    dk.Simulation(make_scene(), integrator).run(integrator.dt)
    sim = dk.Simulation(make_scene(), integrator)
    clock = time.perf_counter()
    traj = sim.run(duration, record_every=record_every)
    return traj, time.perf_counter() - clock


def cost_for(target, rows, key):
    """Wall time to reach error ``target`` along the measured rows (sorted by dt, descending):
    log-log interpolation between the two runs around the target (the first such pair), or, when
    none reaches it, extrapolation along a least-squares power law error ~ time^p through the four
    finest runs (reported with p; "not converging" when p > -0.5)."""
    points = [(r["seconds"], r[key]) for r in rows if r[key] > 0]
    for (t1, e1), (t2, e2) in zip(points, points[1:]):
        if e1 >= target >= e2:
            f = math.log(target / e1) / math.log(e2 / e1)
            return {"seconds": t1 * (t2 / t1) ** f, "how": "interpolated"}
    if points[-1][1] < target:
        return {"seconds": points[-1][0], "how": "reached at the largest step measured"}
    t, e = np.log([q[0] for q in points[-4:]]), np.log([q[1] for q in points[-4:]])
    slope, offset = np.polyfit(t, e, 1)
    if slope > -0.5:
        return {"seconds": math.inf, "how": f"not converging (error ~ time^{slope:.2f} over the four finest runs)"}
    return {"seconds": float(math.exp((math.log(target) - offset) / slope)),
            "how": f"extrapolated along error ~ time^{slope:.2f} (least squares, four finest runs)"}


# ---- the paper's collision -----------------------------------------------------------------------

def part_collision(quick):
    collision = TwoMagnets(b_over_R=4.0)
    contact_time = collision.approach_time()
    duration = contact_time + 300.0
    # the energy scale of the collision: the magnetic energy of the pair touching head to tail,
    # 2 A m^2 / d^3 (unit moments), about the work the collision dissipates
    scale = 2 * collision.prefactor / (2 * collision.radius) ** 3
    levels = range(0, 6 if quick else 9)

    def measure(integrator):
        traj, seconds = timed_run(collision.scene, integrator, duration)
        budget = traj.energy["total"] + traj.energy["dissipated"]
        return traj.position[-1], abs(budget[-1] - budget[0]) / scale, seconds

    clock = time.perf_counter()
    truth = dk.accuracy.reference(collision.scene(), duration, rtol=1e-12)
    reference = truth.position[-1]
    seconds = time.perf_counter() - clock
    finest = 0.2 / 2 ** (7 if quick else 10)
    check, _, _ = measure(dk.VelocityVerlet(finest, resolve_contacts=True))
    out = {"scene": "TwoMagnets(b_over_R=4), x0 = 150", "duration": duration, "first_contact": contact_time,
           "energy_scale": scale, "reference": f"adaptive DOP853 rtol 1e-12, {truth.evaluations} force evaluations, "
                                               f"{truth.restarts} restarts, {seconds:.1f} s",
           "reference_check": {"dt": finest, "state_difference": float(np.abs(check - reference).max())},
           "methods": {}}
    print(f"collision: {out['reference']}; resolved velocity Verlet at dt {finest:.3g} differs by "
          f"{out['reference_check']['state_difference']:.2e}", flush=True)
    for name, resolve in (("velocity_verlet", False), ("velocity_verlet_resolved", True)):
        rows = []
        for k in levels:
            dt = 0.2 / 2**k
            x, balance, seconds = measure(dk.VelocityVerlet(dt, resolve_contacts=resolve))
            rows.append({"dt": dt, "state_error": float(np.abs(x - reference).max()), "energy_balance": balance,
                         "seconds": seconds})
            print(f"  {name:26s} dt {dt:9.3g}  state {rows[-1]['state_error']:.2e}  balance {balance:.2e}  "
                  f"{seconds:.3f} s", flush=True)
        out["methods"][name] = {"rows": rows, "cost_state_1e-6": cost_for(1e-6, rows, "state_error"),
                                "cost_balance_1e-6": cost_for(1e-6, rows, "energy_balance")}
    plain, resolved = out["methods"]["velocity_verlet"], out["methods"]["velocity_verlet_resolved"]
    for key in ("cost_state_1e-6", "cost_balance_1e-6"):
        out[f"speedup_{key[5:]}"] = plain[key]["seconds"] / resolved[key]["seconds"]
        print(f"  {key}: plain {plain[key]}, resolved {resolved[key]}, speed-up {out[f'speedup_{key[5:]}']:.3g}")
    return out


# ---- multiple time stepping on the N-body scene --------------------------------------------------

def part_mts(n, quick):
    from reference_scene import make_reference_scene, particles_and_box

    scene_data = make_reference_scene(n)
    particles, box = particles_and_box(scene_data)

    def interactions():
        return [dk.Dipole(prefactor=1.0, cutoff=4.0, switch_width=1.0), dk.KelvinVoigt(1000.0, 1.5)]

    settle = dk.Scene(particles.copy(), interactions(), box=box)
    clock = time.perf_counter()
    dk.Simulation(settle, dk.VelocityVerlet(1e-3)).run(0.5 if quick else 2.0)
    start = settle.particles.copy()
    contacts = len(settle.contacts())
    print(f"mts: N = {n}, settled in {time.perf_counter() - clock:.1f} s, {contacts} contacts", flush=True)
    duration = 0.1 if quick else 0.5

    def make():
        return dk.Scene(start.copy(), interactions(), box=box)

    runs = [dk.VelocityVerlet(dt) for dt in (2e-3, 1e-3, 5e-4, 2.5e-4)]
    runs += [dk.MultipleTimeStep(dt, inner=k) for dt, k in ((4e-3, 2), (4e-3, 4), (4e-3, 8), (8e-3, 8), (8e-3, 16))]
    runs += [dk.VelocityVerlet(dt, resolve_contacts=True) for dt in (2e-3, 1e-3, 5e-4)]
    runs += [dk.MultipleTimeStep(dt, inner=k, resolve_contacts=True)
             for dt, k in ((2e-3, 2), (4e-3, 2), (4e-3, 4), (8e-3, 4), (8e-3, 8))]
    rows = []
    for integrator in runs:
        traj, seconds = timed_run(make, integrator, duration, record_every=duration / 10)
        budget = traj.energy["total"] + traj.energy["dissipated"]
        rows.append({"method": repr(integrator), "dt": integrator.dt, "inner": integrator.inner,
                     "resolve_contacts": integrator.resolve_contacts,
                     "energy_error_per_sphere": float(np.abs(budget - budget[0]).max() / n),
                     "dissipated_per_sphere": float(traj.energy["dissipated"][-1] / n), "seconds": seconds})
        print(f"  {rows[-1]['method']:66s} energy error/N {rows[-1]['energy_error_per_sphere']:.3e}  "
              f"{seconds:.2f} s", flush=True)
    return {"n": n, "contacts": contacts, "duration": duration, "threads": int(os.environ.get("NUMBA_NUM_THREADS", 2)),
            "rows": rows}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", default=["collision", "mts"])
    ap.add_argument("--n", type=int, default=8000)
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    for part in a.parts:
        if part == "collision":
            results["collision"] = part_collision(a.quick)
        elif part == "mts":
            results["mts"] = part_mts(a.n, a.quick)
        else:
            raise SystemExit(f"unknown part {part!r}")
        results["load_average"] = os.getloadavg()[0]
        RESULTS.parent.mkdir(exist_ok=True)
        RESULTS.write_text(json.dumps(results, indent=1))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
