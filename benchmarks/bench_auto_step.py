"""dt = "auto" measured: on every example scene and the scenes a new user wrote (auto_step_scenes.py),
the step dk.choose_time_step picks, what choosing cost, the run's energy balance and end-of-run notes
at that step, the same at the old "auto" (half the largest safe step), and the true error: the
run's energies at its end against a run at a quarter of the step (half when the run took over 20 s,
none over 60 s) (an eighth of the work's error
for a first-order balance; many-body runs are chaotic, so positions are not compared, energies
are: they are what the balance is made of).

    python benchmarks/bench_auto_step.py [case ...]    # all cases by default
    python benchmarks/bench_auto_step.py --table       # the results as a markdown table

Writes benchmarks/results/auto_step.json (after each case: a stopped run keeps what it measured).
"""
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
os.environ.setdefault("DEMKIT_QUIET", "1")
import demkit as dk  # noqa: E402
from auto_step_scenes import SCENES, build  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "auto_step.json"
#: the converged run is at this fraction of the chosen step ...
FINER = 4
#: ... unless the run at the chosen step took longer than this (wall s): then at half of it
FINER_BUDGET = 20.0
#: ... and none when it took longer than this
SKIP_TRUTH = 60.0


def run(name, dt):
    """(figures, trajectory) of one run of a fresh copy of the case at step dt."""
    case = build(name)
    integrator = case.method(dt)
    sim = dk.Simulation(case.scene, integrator)
    wall, cpu = time.perf_counter(), time.process_time()
    traj = sim.run(case.duration, record_every=case.record_every, progress=False)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    s = sim.statistics
    step_notes = [n for n in s.get("notes", []) if "energy balance" in n]
    return {"dt": dt, "steps": int(round(case.duration / integrator.dt)), "wall_s": wall, "cpu_s": cpu,
            "energy_drift": s.get("energy_drift"), "overlap_largest": s.get("overlap_largest"),
            "step_note": bool(step_notes), "notes": s.get("notes", [])}, traj


def energies_at_end(traj):
    e = traj.energy
    motion = e["kinetic"][-1] + e["rotational"][-1]
    potential = sum(v[-1] for k, v in e.items() if k not in ("kinetic", "rotational", "total", "dissipated"))
    parts = [v for k, v in e.items() if k not in ("total", "dissipated")]
    scale = float(np.max(np.abs(np.column_stack(parts)).sum(axis=1)))
    return float(motion), float(potential), scale


def spin(traj):
    """The final spin (z) of a two-sphere run: the mean over the last tenth of its frames."""
    if traj.angular_velocity is None or traj.position.shape[1] != 2:
        return None
    tail = max(1, len(traj.time) // 10)
    return float(np.mean(traj.angular_velocity[-tail:, :, 2]))


def measure(name):
    case = build(name)
    wall, cpu = time.perf_counter(), time.process_time()
    choice = dk.choose_time_step(case.scene, case.method, case.duration)
    choose = {"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu}
    print(f"{name}: {choice} ({choose['wall_s']:.2f} s)", flush=True)
    chosen, traj = run(name, choice.dt)
    print(f"  at the chosen step: drift {chosen['energy_drift']}, {chosen['wall_s']:.1f} s, notes {chosen['notes']}",
          flush=True)
    half = run(name, choice.stable)[0] if choice.dt < choice.stable else dict(chosen)
    print(f"  at half the safe step: drift {half['energy_drift']}, {half['wall_s']:.1f} s", flush=True)
    finer = FINER if chosen["wall_s"] <= FINER_BUDGET else 2
    if chosen["wall_s"] > SKIP_TRUTH:
        print(f"  no run at a finer step: the chosen step's took {chosen['wall_s']:.0f} s", flush=True)
        return {"note": case.note, "n": len(case.scene.particles), "duration": case.duration, "source_dt": case.dt,
                "chosen": {"dt": choice.dt, "stable": choice.stable, "dashpot": choice.dashpot, "why": choice.why,
                           "pilots": choice.pilots, **choose},
                "run": chosen, "half_safe_step": half, "truth": None}
    fine, fine_traj = run(name, choice.dt / finer)
    motion, potential, scale = energies_at_end(traj)
    fmotion, fpotential, _ = energies_at_end(fine_traj)
    truth = {"finer": finer, "kinetic_error": abs(motion - fmotion) / scale,
             "potential_error": abs(potential - fpotential) / scale, "fine_drift": fine["energy_drift"],
             "fine_wall_s": fine["wall_s"]}
    if spin(traj) is not None:
        truth["spin"], truth["fine_spin"] = spin(traj), spin(fine_traj)
        truth["spin_error"] = abs(truth["spin"] - truth["fine_spin"]) / abs(truth["fine_spin"])
    print(f"  against dt/{finer}: {truth}", flush=True)
    return {"note": case.note, "n": len(case.scene.particles), "duration": case.duration,
            "source_dt": case.dt, "chosen": {"dt": choice.dt, "stable": choice.stable, "dashpot": choice.dashpot,
                                             "why": choice.why, "pilots": choice.pilots, **choose},
            "run": chosen, "half_safe_step": half, "truth": truth,
            "choosing_cost": choose["wall_s"] / chosen["wall_s"] if chosen["wall_s"] > 0 else math.nan}


def main(names):
    results = json.loads(OUT.read_text()) if OUT.exists() else {}
    cases = results.setdefault("cases", {})
    for name in names:
        cases[name] = measure(name)
        results["date"] = time.strftime("%Y-%m-%d %H:%M")
        OUT.write_text(json.dumps(results, indent=1, default=float))
    print(f"wrote {OUT}")


def table():
    """The results as a markdown table (docs/accuracy.md)."""
    cases = json.loads(OUT.read_text())["cases"]
    print("| scene | N | steps | dt chosen / half the safe step | balance at it (note?) | at half the safe step "
          "| energies against dt/k | choosing / run (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, c in cases.items():
        ch, run_, half, truth = c["chosen"], c["run"], c["half_safe_step"], c["truth"]
        pct = lambda x: "not booked" if x is None else f"{100 * x:.2f} %"  # noqa: E731
        true = (f"{max(truth['kinetic_error'], truth['potential_error']):.1e} (k = {truth['finer']})" if truth
                else "not run (long)")
        if truth and "spin_error" in truth:
            true += f"; spin {truth['spin_error']:.1e}"
        print(f"| {name} | {c['n']} | {run_['steps']:,} | {ch['dt'] / ch['stable']:.3g} "
              f"| {pct(run_['energy_drift'])}{' (note)' if run_['step_note'] else ''} "
              f"| {pct(half['energy_drift'])}{' (note)' if half['step_note'] else ''} | {true} "
              f"| {ch['wall_s']:.1f} / {run_['wall_s']:.1f} |")


if __name__ == "__main__":
    if sys.argv[1:] == ["--table"]:
        table()
    else:
        main(sys.argv[1:] or list(SCENES))
