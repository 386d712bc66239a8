"""Slab sums (demkit.interactions.slab): Ewald and P3M in a box periodic along x and y, against the
direct sum over the layer's in-plane copies (tests/slab_reference.py) and against LAMMPS'
pppm/dipole and ewald/dipole with `kspace_modify slab`; and what a slab costs against the same
spheres in a periodic box. Writes benchmarks/results/slab.json (each part its own key, the others kept).

Part ``lammps``: a layer of 60 spheres (d = 0.7) with random moments (normal, <|m|^2> = 3) in a
6 x 6 cell 2 thick. demkit's Ewald and P3M at 1e-6 (RMS force error relative to the touching pull
6 A <|m|^2> / d^4) against the direct sum (energy) and against LAMMPS (benchmarks/lammps/in.slab;
pppm/dipole and ewald/dipole at the same absolute accuracy, slab factors 3, 6 and 10): RMS force
and torque differences relative to the pull (pull x d), energy per sphere, and LAMMPS' energy with
the layer term (2 pi A / V') M_z^2 added (demkit includes it; see the note written with the numbers).

Part ``cost``: 1000 spheres of diameter 1 (volume fraction 0.15, unit moments) in a 30 x 30 x 4 slab:
``dk.compare_dipole_sums`` (cutoffs, Ewald and P3M at 1e-3 ... 1e-6) on one thread, written with its
work-precision plot to benchmarks/results/slab_sums.png (the tuned sums, with their gaps, in the rows).

    python benchmarks/bench_slab.py [--part lammps|cost]
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
RESULTS = HERE / "results" / "slab.json"
DECK = HERE / "lammps" / "in.slab"
THERMO = re.compile(r"^\s*Step PotEng\s*\n\s*0\s+(\S+)", re.M)
DIAMETER = 0.7


def layer(n=60, side=6.0, thickness=2.0, seed=7):
    """(position, dipole, box) of the LAMMPS comparison's layer."""
    import demkit as dk
    box = dk.Box([side, side, thickness], periodic=[True, True, False])
    position = dk.build.random_packing(n, 0.5 * DIAMETER, box, seed=seed)
    dipole = np.random.default_rng(seed).normal(size=(n, 3))
    return position, dipole, box


def pull_of(dipole):
    """The touching pull 6 A <|m|^2> / d^4 (A = 1) demkit's accuracy is relative to."""
    return 6.0 * float(np.mean((dipole ** 2).sum(1))) / DIAMETER ** 4


def write_data(position, dipole, box, path):
    """A LAMMPS data file (atom_style hybrid sphere dipole) of these spheres."""
    lines = ["slab layer (benchmarks/bench_slab.py)", "", f"{len(position)} atoms", "1 atom types", ""]
    lines += [f"0 {float(length)!r} {a}lo {a}hi" for length, a in zip(box.size, "xyz")]
    lines += ["", "Atoms # hybrid", ""]
    for i, (x, m) in enumerate(zip(position, dipole)):
        lines.append(f"{i + 1} 1 {' '.join(repr(float(v)) for v in x)} {DIAMETER!r} 1.0 0.0 "
                     f"{' '.join(repr(float(v)) for v in m)}")
    Path(path).write_text("\n".join(lines) + "\n")


def lammps_slab(position, dipole, box, kspace, accuracy, factor, folder):
    """LAMMPS' (force, torque, energy per sphere) at step 0 with ``kspace`` (pppm | ewald) at its
    ``accuracy`` and slab ``factor``, or None without LAMMPS."""
    from demkit.lammps import read_dump
    from lammps_run import run_deck
    folder = Path(folder)
    data = folder / "slab.data"
    write_data(position, dipole, box, data)
    dump = folder / f"slab_{kspace}_{accuracy:g}_{factor:g}.dump"
    out = run_deck(DECK, {"data": str(data), "kspace": kspace, "acc": accuracy, "slab": factor, "dump": str(dump)})
    if out is None:
        return None
    frame = read_dump(dump)[0]
    return frame[:, 1:4], frame[:, 4:7], float(THERMO.search(out["log"]).group(1))


def demkit_slab(position, dipole, box, long_range):
    """demkit's (force, torque, energy per sphere, the tuned sum) of a slab sum."""
    import demkit as dk
    scene = dk.Scene(dk.Particles(position, radius=0.5 * DIAMETER, mass=1.0, dipole=dipole),
                     [dk.Dipole(1.0, long_range=long_range)], box=box)
    force, torque = scene.forces()
    return force, torque, scene.energy()["magnetic"] / len(position), scene.long_range[0]


def rms(a):
    return float(np.sqrt(np.mean((a ** 2).sum(1))))


def part_lammps(accuracy=1e-6):
    import demkit as dk
    from slab_reference import layer_energy
    position, dipole, box = layer()
    n, pull = len(position), pull_of(dipole)
    side = float(box.size[0])
    direct = layer_energy(position, dipole, [side, 0, 0], [0, side, 0]) / n
    out = dict(n=n, cell=[float(x) for x in box.size], accuracy=accuracy, pull=pull, direct_energy=direct,
               demkit={}, lammps=[])
    ours = {}
    for method in (dk.Ewald, dk.P3M):
        t = time.perf_counter()
        force, torque, energy, tuned = demkit_slab(position, dipole, box, method(accuracy))
        ours[method.__name__] = force, torque
        out["demkit"][method.__name__] = dict(energy=energy, energy_minus_direct=energy - direct, tuned=repr(tuned),
                                              seconds=time.perf_counter() - t)
    out["ewald_vs_p3m"] = dict(force=rms(ours["Ewald"][0] - ours["P3M"][0]) / pull,
                               torque=rms(ours["Ewald"][1] - ours["P3M"][1]) / (pull * DIAMETER))
    mz = float(dipole[:, 2].sum())
    with tempfile.TemporaryDirectory() as folder:
        for kspace in ("pppm", "ewald"):
            for factor in (3.0, 6.0, 10.0):
                got = lammps_slab(position, dipole, box, kspace, accuracy * pull, factor, folder)
                if got is None:
                    out["lammps"] = "not installed"
                    return out
                force, torque, energy = got
                layer_term = 2.0 * np.pi * mz * mz / (side * side * float(box.size[2]) * factor) / n
                out["lammps"].append(dict(
                    kspace=f"{kspace}/dipole", slab=factor, energy=energy, energy_minus_direct=energy - direct,
                    energy_with_layer_term_minus_direct=energy + layer_term - direct,
                    force_vs_demkit_ewald=rms(force - ours["Ewald"][0]) / pull,
                    torque_vs_demkit_ewald=rms(torque - ours["Ewald"][1]) / (pull * DIAMETER)))
    out["note"] = ("demkit's slab sums meet the direct sum's energy and each other's forces to their accuracy. "
                   "LAMMPS 2021's pppm/dipole with kspace_modify slab: forces and torques converge to demkit's as "
                   "the slab factor grows (its gap is factor - 1 times the layer's height, not chosen for the "
                   "accuracy), while its energy misses the layer term (2 pi A / V') M_z^2 less a remainder that "
                   "also falls with the factor; its ewald/dipole with slab parts from both further as the factor "
                   "grows.")
    return out


def part_cost():
    import demkit as dk
    n, side, thickness = 1000, 30.0, 4.0
    slab = dk.Box([side, side, thickness], periodic=[True, True, False])
    position = dk.build.random_packing(n, 0.5, slab, seed=11)
    d = np.random.default_rng(11).normal(size=(n, 3))
    p = dk.Particles(position, radius=0.5, mass=1.0, dipole=d / np.linalg.norm(d, axis=1)[:, None])
    report = dk.compare_dipole_sums(p, slab, 1.0)
    report.plot(HERE / "results" / "slab_sums.png", title=f"{n} spheres in a {side:g} x {side:g} x {thickness:g} slab")
    return dict(n=n, slab=[side, side, thickness], report=report.as_dict(), table=report.table().splitlines())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=("lammps", "cost"), action="append")
    args = parser.parse_args(argv)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    for part in args.part or ("lammps", "cost"):
        results[part] = part_lammps() if part == "lammps" else part_cost()
        RESULTS.write_text(json.dumps(results, indent=1, default=float))
        print(json.dumps(results[part], indent=1, default=float)[:3000])


if __name__ == "__main__":
    main()
