"""What accuracy costs on the seed paper's collision (b/R = 4): work-precision of Euler-Cromer,
velocity Verlet and velocity Verlet with contact events resolved, against demkit.accuracy's
adaptive reference.

    python examples/accuracy/run.py [--samples N] [--out DIR]

Two reports, both on dk.two_magnets.TwoMagnets(b_over_R=4.0) (the paper's settings):

* approach: the first 24000 time units, before the first contact (dipole forces only, smooth);
* collision: the whole 60000 time units (23 bounces, then the pair sticks and turns), with the final spin
  omega_f as the observable, and the spread of references started 1e-9 apart (``--samples``).

Writes, under DIR (default: the repository root), docs/figures/accuracy/{approach,collision}.png and
docs/data/accuracy/{approach,collision}.{txt,csv,json}. About 5 minutes on one core, most of it
the adaptive references of the collision (one per spread sample plus one).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path


import demkit as dk

ROOT = Path(__file__).resolve().parents[2]
DTS = [0.2, 0.1, 0.05, 0.025, 0.0125, 0.00625]


def final_spin(trajectory):
    """omega_f of the settled barbell (the paper's 5-revolution measurement)."""
    return dk.two_magnets.final_spin(trajectory)[0]


def per_time_table(report):
    """Position error of every run at every check time (plain text)."""
    head = ["method", "dt"] + [f"t={t:g}" for t in report.times]
    lines = [head]
    for r in report.rows:
        if r["stable"] and not r["is_reference"]:
            lines.append([r["method"], f"{r['dt']:g}"] + [f"{e:.2e}" for e in r["position_errors"]])
    if report.spread:
        lines.append(["spread (1e-9 apart)", ""] + [f"{e:.2e}" for e in report.spread["position"]])
    widths = [max(len(line[k]) for line in lines) for k in range(len(head))]
    return "\n".join("  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(line, widths)))
                     for line in lines)


def save(report, name, out, extra=""):
    figures, data = out / "docs" / "figures" / "accuracy", out / "docs" / "data" / "accuracy"
    figures.mkdir(parents=True, exist_ok=True)
    data.mkdir(parents=True, exist_ok=True)
    report.plot(figures / f"{name}.png")
    report.to_csv(data / f"{name}.csv")
    report.to_json(data / f"{name}.json")
    text = report.table() + "\n\nposition error at each check time:\n" + per_time_table(report) + extra + "\n"
    (data / f"{name}.txt").write_text(text)
    print(f"\n== {name} ==\n{text}")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=3, help="spread samples of the collision (0: none)")
    parser.add_argument("--out", type=Path, default=ROOT)
    args = parser.parse_args()
    setup = dk.two_magnets.TwoMagnets(b_over_R=4.0)
    methods = [dk.EulerCromer, dk.VelocityVerlet]

    clock = time.perf_counter()
    approach = dk.accuracy.work_precision(setup.scene(), 24000.0, methods=methods, dts=DTS)
    save(approach, "approach", args.out)
    print(f"({time.perf_counter() - clock:.0f} s)")

    clock = time.perf_counter()
    spread = dict(samples=args.samples, perturbation=1e-9) if args.samples else None
    # the collision also with contact events resolved (second order through the bounces)
    resolved = {"EulerCromer": dk.EulerCromer, "VelocityVerlet": dk.VelocityVerlet,
                "VV resolved": lambda dt: dk.VelocityVerlet(dt, resolve_contacts=True)}
    collision = dk.accuracy.work_precision(setup.scene(), 60000.0, methods=resolved, dts=DTS,
                                           times=[12000, 24000, 26000, 30000, 45000, 60000], record_every=1.0,
                                           observable=final_spin, spread=spread)
    extra = (f"\n\nfinal spin: reference {collision.reference['observable']:.10g}, rigid barbell "
             f"v b/(2.8 R^2) = {setup.expected_spin():.10g}")
    if collision.spread:
        values = ", ".join(f"{v:.10g}" for v in collision.spread["observable_values"])
        extra += f"; references started 1e-9 apart: {values}"
    save(collision, "collision", args.out, extra)
    print(f"({time.perf_counter() - clock:.0f} s)")
    for target in (1e-3, 1e-6):
        print(f"suggest(position {target:g}), approach: {approach.suggest(target)}")
    print(f"suggest(observable 1e-9), collision: {collision.suggest(1e-9, 'observable')}")


if __name__ == "__main__":
    main()
