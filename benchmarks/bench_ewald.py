"""What a dipolar Ewald sum costs and what it buys: accuracy against time, and cut-off dipoles
against the full periodic sum. Writes benchmarks/results/ewald.json and ewald.png.

Scenes: N spheres of diameter 1 placed at random in a periodic cube at volume fraction 0.2, random
moments of magnitude 1, prefactor A = 1 (so the touching pull is 6), one thread.

* ``costs``: for N = 500 ... 4000 at accuracy 1e-6, the tuned parameters, the wall time of one
  force evaluation (best of 5, lists built), split into the reciprocal sum (timed alone, through
  its compiled function) and the rest (real-space pairs, lists, the passes); the cost per sphere
  and wave vector of the reciprocal sum and per listed pair of the real-space sum, the two
  constants of demkit's tuning (RECIPROCAL_COST) and of ``demkit info`` (cost.RECIPROCAL_VECTOR).
* ``methods``: Ewald against P3M at N = 1000 ... 8000, accuracy 1e-4 and 1e-6: one evaluation, the
  time the Scene takes to tune, the measured force error (up to N = 4000).
* ``energy``: 10^5 velocity-Verlet steps of a dilute periodic dipolar gas (64 spheres) with Ewald
  and with P3M at 1e-6: the total energy's drift and swings against the magnetic energy's swings.
* ``accuracy``: N = 1000, accuracy 1e-2 ... 1e-9: the measured RMS force error against accuracy
  1e-12 (relative to the touching pull, as ``accuracy`` is), against the estimate, and the time of
  one evaluation; and cut-off dipoles (r_c = 2 ... 6, at most half the box) against the same
  reference: their error and time. The plot shows error against time for both.

    python benchmarks/bench_ewald.py [--quick] [costs] [energy] [methods] [accuracy]
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

import demkit as dk
from demkit.interactions.ewald import reciprocal_sum

HERE = Path(__file__).resolve().parent
PHI = 0.2


def gas(n, seed=1):
    side = (n * np.pi / 6.0 / PHI) ** (1.0 / 3.0)
    box = dk.Box(side, periodic=True)
    pos = dk.build.random_packing(n, 0.5, box, seed=seed)
    rng = np.random.default_rng(seed + 1)
    dip = rng.normal(size=(n, 3))
    return pos, dip / np.linalg.norm(dip, axis=1)[:, None], box


def scene_of(pos, dip, box, dipole):
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip)
    return dk.Scene(p, [dipole], box=box, parallel=False)


def best_time(fn, repeats=5):
    fn()
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def listed_pairs(scene):
    return int(sum(len(scene.candidate_pairs(inter)) for inter in scene.interactions))


def part_costs(sizes):
    rows = []
    for n in sizes:
        pos, dip, box = gas(n)
        scene = scene_of(pos, dip, box, dk.Dipole(1.0, long_range=dk.Ewald(1e-6)))
        tuned = scene.long_range[0]
        total = best_time(scene.forces)
        table = tuned.table_values()
        force, torque = np.zeros((n, 3)), np.zeros((n, 3))
        size = np.asarray(box.size, dtype=np.float64)
        status = np.zeros(4, dtype=np.int64)
        reciprocal = best_time(lambda: reciprocal_sum(pos, dip, size, table, 0, force, torque, True, status))
        k = np.stack(np.meshgrid(*[np.arange(-m, m + 1) for m in tuned.kmax], indexing="ij"), -1).reshape(-1, 3)
        vectors = int((((2 * np.pi * k / size) ** 2).sum(1) <= tuned.kcut ** 2).sum() - 1) // 2
        pairs = listed_pairs(scene)
        row = dict(n=n, side=float(box.size[0]), cutoff=tuned.cutoff, alpha=tuned.alpha, kmax=tuned.kmax,
                   wave_vectors=vectors, listed_pairs=pairs, estimated_error=tuned.estimated_error,
                   seconds=total, reciprocal_seconds=reciprocal, rest_seconds=total - reciprocal,
                   ns_per_sphere_and_vector=1e9 * reciprocal / (n * vectors),
                   ns_per_listed_pair=1e9 * (total - reciprocal) / pairs)
        print(json.dumps(row))
        rows.append(row)
    return rows


def part_methods(sizes, accuracies):
    """Ewald against P3M: one evaluation (best of 5) at each size and accuracy, the tuned
    parameters, the time Scene() takes to tune, and each method's error against Ewald at 1e-10
    (up to N = 4000; beyond, the reference costs too much)."""
    rows = []
    for n in sizes:
        pos, dip, box = gas(n)
        reference = None
        if n <= 4000:
            reference = scene_of(pos, dip, box, dk.Dipole(1.0, long_range=dk.Ewald(1e-10))).forces()[0]
        for accuracy in accuracies:
            for method in (dk.Ewald, dk.P3M):
                t = time.perf_counter()
                scene = scene_of(pos, dip, box, dk.Dipole(1.0, long_range=method(accuracy)))
                tuning = time.perf_counter() - t
                seconds = best_time(scene.forces)
                row = dict(n=n, method=method.__name__, accuracy=accuracy, seconds=seconds, tuning_seconds=tuning,
                           tuned=repr(scene.long_range[0]))
                if reference is not None:
                    row["force_error"] = rms(scene.forces()[0], reference) / 6.0
                print(json.dumps(row))
                rows.append(row)
    return rows


def part_energy(steps, method):
    """Energy conservation over ``steps`` velocity-Verlet steps of a dilute periodic dipolar gas
    (64 spheres at volume fraction 0.05, moments 0.5, kT = 1, elastic contacts that hardly ever
    touch), the long-range sum at accuracy 1e-6: the total energy's drift and swings against the
    magnetic energy's swings."""
    n, phi = 64, 0.05
    side = (n * np.pi / 6.0 / phi) ** (1.0 / 3.0)
    box = dk.Box(side, periodic=True)
    pos = dk.build.random_packing(n, 0.5, box, seed=3)
    rng = np.random.default_rng(4)
    dip = rng.normal(size=(n, 3))
    dip = 0.5 * dip / np.linalg.norm(dip, axis=1)[:, None]
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip, velocity=rng.normal(size=(n, 3)),
                     angular_velocity=rng.normal(size=(n, 3)))
    scene = dk.Scene(p, [dk.Dipole(1.0, long_range=method(1e-6)), dk.KelvinVoigt(stiffness=1e4, damping=0.0)],
                     box=box)
    dt = 1e-3
    t = time.perf_counter()
    energy = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=steps * dt, record_every=steps * dt / 200,
                                                              progress=False).energy
    total, magnetic = energy["total"], energy["magnetic"]
    row = dict(method=method.__name__, steps=steps, n=n, seconds=time.perf_counter() - t,
               total_drift=float(total[-1] - total[0]), total_swing=float(np.ptp(total)),
               magnetic_swing=float(np.ptp(magnetic)), kinetic_mean=float(np.mean(energy["kinetic"])),
               contact_swing=float(np.ptp(energy["contact"])))
    print(json.dumps(row))
    return row


def rms(a, b):
    return float(np.sqrt(np.mean(((a - b) ** 2).sum(1))))


def part_accuracy(n, accuracies, cutoffs):
    pos, dip, box = gas(n, seed=7)
    pull = 6.0
    reference = scene_of(pos, dip, box, dk.Dipole(1.0, long_range=dk.Ewald(1e-12)))
    f_ref, t_ref = reference.forces()
    e_ref = reference.energy()["magnetic"] / n
    ewald, cut = [], []
    for accuracy in accuracies:
        scene = scene_of(pos, dip, box, dk.Dipole(1.0, long_range=dk.Ewald(accuracy)))
        f, t = scene.forces()
        tuned = scene.long_range[0]
        row = dict(accuracy=accuracy, force_error=rms(f, f_ref) / pull, torque_error=rms(t, t_ref) / pull,
                   estimated=tuned.estimated_error, energy_error=abs(scene.energy()["magnetic"] / n - e_ref),
                   seconds=best_time(scene.forces), cutoff=tuned.cutoff, alpha=tuned.alpha, kmax=tuned.kmax)
        print(json.dumps(row))
        ewald.append(row)
    for rc in cutoffs:
        if 2 * rc >= box.size[0]:
            continue
        scene = scene_of(pos, dip, box, dk.Dipole(1.0, cutoff=rc))
        f, t = scene.forces()
        row = dict(cutoff=rc, force_error=rms(f, f_ref) / pull, torque_error=rms(t, t_ref) / pull,
                   energy_error=abs(scene.energy()["magnetic"] / n - e_ref), seconds=best_time(scene.forces))
        print(json.dumps(row))
        cut.append(row)
    return dict(n=n, side=float(box.size[0]), reference_energy_per_sphere=e_ref, ewald=ewald, cutoff=cut)


def plot(accuracy, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    e = accuracy["ewald"]
    ax.loglog([r["seconds"] * 1e3 for r in e], [r["force_error"] for r in e], "o-", label="Ewald (measured)")
    ax.loglog([r["seconds"] * 1e3 for r in e], [r["accuracy"] for r in e], "k:", label="Ewald (requested accuracy)")
    c = accuracy["cutoff"]
    ax.loglog([r["seconds"] * 1e3 for r in c], [r["force_error"] for r in c], "s-", label="cut-off dipoles")
    for r in c:
        ax.annotate(f"r_c={r['cutoff']:g}", (r["seconds"] * 1e3, r["force_error"]), fontsize=7)
    ax.set_xlabel("one force evaluation (ms, one thread)")
    ax.set_ylabel("RMS force error / touching pull")
    ax.set_title(f"N = {accuracy['n']} dipoles, periodic cube, volume fraction {PHI}")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true")
    args.add_argument("parts", nargs="*", choices=("costs", "energy", "methods", "accuracy"),
                      help="parts to run (default: all); their results replace those in ewald.json")
    opts = args.parse_args(argv)
    parts = opts.parts or ["costs", "energy", "methods", "accuracy"]
    sizes = (500, 1000) if opts.quick else (500, 1000, 2000, 4000)
    accuracies = (1e-2, 1e-4, 1e-6) if opts.quick else (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9)
    path = HERE / "results" / "ewald.json"
    result = json.loads(path.read_text()) if path.exists() and opts.parts else {}
    result["machine"] = dict(platform=platform.platform(), processor=platform.processor(),
                             date=time.strftime("%Y-%m-%d %H:%M"), parts=parts)
    if "costs" in parts:
        result["costs"] = part_costs(sizes)
    if "energy" in parts:
        result["energy"] = [part_energy(2000 if opts.quick else 100000, m) for m in (dk.Ewald, dk.P3M)]
    if "methods" in parts:
        result["methods"] = part_methods((1000, 2000, 4000, 8000) if not opts.quick else (1000,), (1e-4, 1e-6))
    if "accuracy" in parts:
        result["accuracy"] = part_accuracy(1000, accuracies, (2.0, 3.0, 4.0, 5.0, 6.0))
    path.write_text(json.dumps(result, indent=1) + "\n")
    if "accuracy" in result:
        plot(result["accuracy"], HERE / "results" / "ewald.png")
    print("written", path)


if __name__ == "__main__":
    main()
