"""The stress of a dipolar Ewald sum, demkit against LAMMPS side by side: the N = 1000 reference
scene (benchmarks/reference_scene.py: moments of 2, d = 1, a periodic cube at volume fraction 0.2)
at its start, where no spheres touch, so that the virial is the dipoles' alone.

demkit: ``dk.measure.stress(scene).virial["Dipole"]`` (real-space pairs and the reciprocal and
surface terms, demkit/interactions/ewald_virial.py) with ``Ewald(1e-9)`` and ``P3M(1e-5)``; LAMMPS:
``lj/cut/dipole/long`` at 4 d with ``kspace_style ewald/dipole`` at 2.4e-8 (the same absolute force
error as demkit's 1e-9: LAMMPS' accuracy is relative to two unit charges one apart, demkit's to the
touching pull 6 A m^2/d^4 = 24) and ``pppm/dipole`` at 2.4e-4 (demkit's P3M(1e-5)) and ``compute pressure NULL virial`` times the volume, its six
components xx yy zz xy xz yz (LAMMPS keeps d_x F_y for xy, as demkit's W[0, 1]). Also the energy.

    python benchmarks/bench_stress_lammps.py      (needs lmp: Debian package lammps)

Writes benchmarks/results/stress_lammps.json.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results" / "stress_lammps.json"
N = 1000
PULL = 24.0

DECK = textwrap.dedent("""\
    units       lj
    atom_style  hybrid sphere dipole
    boundary    p p p
    read_data   {data}
    pair_style  lj/cut/dipole/long 4.0
    pair_coeff  * * 0.0 1.0
    kspace_style {kspace} {accuracy}
    compute     p all pressure NULL virial
    variable    vol equal vol
    thermo_style custom step pe v_vol c_p[1] c_p[2] c_p[3] c_p[4] c_p[5] c_p[6]
    thermo_modify norm no format float %.16g
    run         0
""")
ROW = re.compile(r"^\s*Step\s+PotEng\s+v_vol.*\n\s*0\s+(.*)$", re.M)
COMPONENTS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def lammps(data, kspace, accuracy, folder):
    """(potential energy, virial components xx yy zz xy xz yz) of LAMMPS' ``kspace`` sum (ewald/dipole,
    pppm/dipole) at step 0, or None."""
    import shutil
    if shutil.which("lmp") is None:
        return None
    deck = Path(folder) / "in.stress"
    deck.write_text(DECK.format(data=data, kspace=kspace, accuracy=accuracy))
    out = subprocess.run(["lmp", "-in", str(deck), "-log", str(Path(folder) / "log.stress")], capture_output=True,
                         text=True, cwd=folder, check=True).stdout
    values = [float(v) for v in ROW.search(out).group(1).split()]
    energy, volume, pressure = values[0], values[1], np.array(values[2:8])
    return energy, pressure * volume


def main():
    import demkit as dk
    from reference_scene import particles_and_box, write_reference_scene
    folder = Path(tempfile.mkdtemp(prefix="demkit-stress-"))
    scene, _, data = write_reference_scene(N, folder)
    p, box = particles_and_box(scene)
    rows = []
    for name, method in (("demkit Ewald(1e-9)", dk.Ewald(1e-9)), ("demkit P3M(1e-5)", dk.P3M(1e-5))):
        s = dk.Scene(p, [dk.Dipole(1.0, long_range=method)], box=box)
        clock = time.perf_counter()
        w = dk.measure.stress(s).virial["Dipole"]
        rows.append({"code": name, "energy": s.energy()["magnetic"], "seconds": time.perf_counter() - clock,
                     "virial": [w[a, b] for a, b in COMPONENTS], "tuned": repr(s.long_range[0])})
        print(json.dumps(rows[-1]), flush=True)
    for kspace, accuracy in (("ewald/dipole", 1e-9), ("pppm/dipole", 1e-5)):
        clock = time.perf_counter()
        theirs = lammps(data, kspace, accuracy * PULL, folder)
        if theirs is None:
            break
        rows.append({"code": f"LAMMPS {kspace} {accuracy * PULL:.2g}", "energy": theirs[0], "virial": list(theirs[1]),
                     "seconds_with_start": time.perf_counter() - clock})
        print(json.dumps(rows[-1]), flush=True)
    if len(rows) > 2:
        truth = np.array(rows[0]["virial"])
        scale = np.abs(truth).max()
        for row in rows[1:]:
            row["virial_vs_demkit_ewald"] = float(np.abs(np.array(row["virial"]) - truth).max() / scale)
            row["energy_vs_demkit_ewald"] = float(abs(row["energy"] - rows[0]["energy"]) / abs(rows[0]["energy"]))
    result = {"date": time.strftime("%Y-%m-%d %H:%M"), "n": N,
              "note": "virial components xx yy zz xy xz yz (sum d_a F_b, the dipoles' alone: nothing touches); "
                      "differences relative to the largest component of demkit's Ewald(1e-9)", "rows": rows}
    RESULTS.write_text(json.dumps(result, indent=1) + "\n")
    print("written", RESULTS)


if __name__ == "__main__":
    main()
