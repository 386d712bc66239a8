"""The pressure tensor of dk.measure.stress against LAMMPS' ``compute pressure`` on the same state.

The N = 1000 magnetic granular scene of the reference decks (d = 1, m = 1, random moments of
magnitude 2, kT = 1 velocities, random spins, dipoles cut at 4 d, Hooke contacts k = 1000 with a
velocity dashpot 1.5 and Coulomb friction mu = 0.5 in LAMMPS' sliding rule), in a periodic box,
squeezed by 3 % from volume fraction 0.3 so that ~1000 contacts push: exported with
dk.export_lammps, and LAMMPS asked at step 0 (``run 0``) for the virial tensor (``compute pressure
NULL virial``) and the kinetic one (``compute pressure thermo_temp ke``), printed to 17 digits.
Writes benchmarks/results/pressure_lammps.json (demkit, LAMMPS, the largest relative difference).

    python benchmarks/bench_pressure_lammps.py        # needs lmp (Debian package lammps)
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

import demkit as dk

RESULTS = Path(__file__).resolve().parent / "results" / "pressure_lammps.json"
ORDER = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))  # LAMMPS' six components


def scene(n=1000, R=0.5, seed=3):
    box = dk.build.box_for(n, R, 0.3)
    rng = np.random.default_rng(seed)
    p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=seed) * 0.97, radius=R, mass=1.0,
                     dipole=2.0 * dk.build.random_directions(n, seed=seed + 1),
                     velocity=dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=seed + 2),
                     angular_velocity=rng.normal(size=(n, 3)))
    law = dk.KelvinVoigt(stiffness=1000.0, damping=1.5, friction=dk.Friction(0.5, slip_radius="full", sliding="lammps"))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0), law], box=dk.Box(box.size * 0.97, periodic=True))


def lammps_tensors(sc, folder):
    files = dk.export_lammps(sc, dk.VelocityVerlet(1e-3), folder, duration=1e-3)
    deck = files.deck.read_text()
    head = deck[:deck.index("compute     erot")]
    head += ("compute     pv all pressure NULL virial\ncompute     pk all pressure thermo_temp ke\n"
             "thermo_style custom step " + " ".join(f"c_pv[{k}]" for k in range(1, 7)) + " "
             + " ".join(f"c_pk[{k}]" for k in range(1, 7)) + "\nthermo_modify format float %.17g\nrun 0\n")
    (Path(folder) / "in.pressure").write_text(head)
    log = subprocess.run(["lmp", "-in", "in.pressure", "-screen", "none", "-log", "log.lammps"], cwd=folder,
                         capture_output=True, text=True, check=True)
    text = (Path(folder) / "log.lammps").read_text()
    row = re.search(r"^\s*0((\s+[-+.\deE]+){12})\s*$", text, re.M).group(1).split()
    values = np.array([float(v) for v in row])
    return values[:6], values[6:]


def main():
    sc = scene()
    s = dk.measure.stress(sc)
    virial = sum(s.virial.values()) / s.volume
    kinetic = s.kinetic / s.volume
    mine_v = np.array([virial[a, b] for a, b in ORDER])
    mine_k = np.array([kinetic[a, b] for a, b in ORDER])
    with tempfile.TemporaryDirectory() as folder:
        theirs_v, theirs_k = lammps_tensors(sc, folder)
    scale_v, scale_k = np.abs(theirs_v).max(), np.abs(theirs_k).max()
    out = {"spheres": len(sc.particles), "contacts": int(len(sc.contacts())),
           "demkit_virial": mine_v.tolist(), "lammps_virial": theirs_v.tolist(),
           "demkit_kinetic": mine_k.tolist(), "lammps_kinetic": theirs_k.tolist(),
           "virial_max_difference_over_largest": float(np.abs(mine_v - theirs_v).max() / scale_v),
           "kinetic_max_difference_over_largest": float(np.abs(mine_k - theirs_k).max() / scale_k),
           "components": "xx yy zz xy xz yz"}
    print(json.dumps(out, indent=1))
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
