"""What accuracy costs in a small dense dipolar cluster: 27 magnetic spheres released at rest from a
loose cubic arrangement collapse into touching chains (Kelvin-Voigt contacts), against
demkit.accuracy's adaptive reference, for every integrator demkit has.

    python examples/accuracy/cluster.py [--samples N] [--out DIR]

Writes, under DIR (default: the repository root), docs/figures/accuracy/cluster.png and
docs/data/accuracy/cluster.{txt,csv,json}. A few minutes on one core.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import demkit as dk

ROOT = Path(__file__).resolve().parents[2]
DURATION = 6.0
DTS = [4e-3, 2e-3, 1e-3, 5e-4]


def cluster_scene(seed=1):
    """27 unit spheres (d = 1, m = 1) on a cubic lattice of spacing 1.6 with random moments of 1
    (prefactor 1: contact energy 2 per head-to-tail pair, about 2x the dipolar energy scale of the
    N-body reference scene), jittered by 0.05, at rest; Kelvin-Voigt k = 1000, c = 1.5."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(*[np.arange(3)] * 3, indexing="ij"), -1).reshape(-1, 3) * 1.6
    position = grid + rng.uniform(-0.05, 0.05, grid.shape)
    dipole = dk.build.random_directions(27, seed=rng)
    particles = dk.Particles(position=position, radius=0.5, mass=1.0, dipole=dipole)
    return dk.Scene(particles, [dk.Dipole(prefactor=1.0), dk.KelvinVoigt(1000.0, 1.5)])


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=int, default=3, help="spread samples (0: none)")
    parser.add_argument("--out", type=Path, default=ROOT)
    args = parser.parse_args()
    methods = {
        "EulerCromer": dk.EulerCromer,
        "VelocityVerlet": dk.VelocityVerlet,
        "ForestRuth": dk.ForestRuth,
        "RK4": dk.RK4,
        "MTS(4)": lambda dt: dk.MultipleTimeStep(dt, inner=4),
        "VV resolved": lambda dt: dk.VelocityVerlet(dt, resolve_contacts=True),
        "MTS(4) resolved": lambda dt: dk.MultipleTimeStep(dt, inner=4, resolve_contacts=True),
    }
    clock = time.perf_counter()
    spread = dict(samples=args.samples, perturbation=1e-9) if args.samples else None
    report = dk.accuracy.work_precision(cluster_scene(), DURATION, methods=methods, dts=DTS,
                                        times=[0.5, 1.0, 2.0, 4.0, 6.0], spread=spread, record_every=0.01)
    figures, data = args.out / "docs" / "figures" / "accuracy", args.out / "docs" / "data" / "accuracy"
    figures.mkdir(parents=True, exist_ok=True)
    data.mkdir(parents=True, exist_ok=True)
    report.plot(figures / "cluster.png")
    report.to_csv(data / "cluster.csv")
    report.to_json(data / "cluster.json")
    text = report.table()
    if report.spread:
        text += "\n\nspread of references started 1e-9 apart, by check time: " + ", ".join(
            f"t={t:g}: {e:.2e}" for t, e in zip(report.times, report.spread["position"]))
    (data / "cluster.txt").write_text(text + "\n")
    print(text)
    print(f"({time.perf_counter() - clock:.0f} s)")


if __name__ == "__main__":
    main()
