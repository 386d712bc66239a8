"""LAMMPS on the N-body magnetic granular reference scene: does every model run, and how fast.

Writes benchmarks/results/lammps_reference.json. Builds the reference scene
(benchmarks/reference_scene.py) for N = 1000 and 8000 in a temporary folder, then

* checks: runs benchmarks/lammps/in.reference for every model (full, nofric, nodip, nodip_nofric)
  on both scenes for a few hundred steps on one rank, recording the initial contacts (0 for a
  packing without overlaps), the pairs within the dipole cutoff and the thermo state at the end;
* speed: N = 8000, models full and nodip_nofric, on 1 rank (``lmp``) and 2 ranks
  (``mpirun -np 2 lmp``), best of ``--repeats``, in atom-steps per second.

    python benchmarks/bench_lammps_reference.py [--repeats 3] [--keep DIR]

Needs ``lmp`` (Debian package ``lammps``) and, for 2 ranks, ``mpirun``. The load average is stored
with the numbers: other work on the machine slows the 2-rank runs most.
"""
import argparse
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from lammps_run import command, run_deck  # noqa: E402
from reference_scene import write_reference_scene  # noqa: E402

DECK = HERE / "lammps" / "in.reference"
MODELS = ("full", "nofric", "nodip", "nodip_nofric")
CHECK_SIZES = (1000, 8000)
CHECK_STEPS = 300
SPEED_N = 8000
#: timed steps per speed run: about 2-5 s each on one core of this project's machines
SPEED_STEPS = {"full": 600, "nodip_nofric": 10000}


def structure(log):
    """(initial contacts, pairs within the dipole cutoff) from the deck's untimed run 0."""
    m = re.search(r"Step\s+v_contacts\s+v_pairs\s*\n\s*0\s+(\S+)\s+(\S+)", log)
    return (int(float(m.group(1))), int(float(m.group(2)))) if m else (None, None)


def final_thermo(log):
    """The last thermo row of the timed run as a dict (step, temp, ke, pe, erot, etotal per atom)."""
    block = log.split("Step Temp KinEng PotEng c_erot TotEng")[-1].split("Loop time")[0]
    rows = [line.split() for line in block.strip().splitlines() if line.strip()]
    values = [float(v) for v in rows[-1]]
    return dict(zip(("step", "temp", "ke", "pe", "erot", "etotal"), values))


def lammps_version(log):
    """The version from the first line of a log: LAMMPS (29 Sep 2021 - Update 2)."""
    m = re.search(r"^LAMMPS \((.+)\)", log, re.M)
    return m.group(1) if m else "unknown"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--keep", help="folder for the scene files (default: a temporary folder)")
    a = ap.parse_args(argv)
    if command(1) is None:
        sys.exit("lmp is not installed (Debian: apt-get install lammps)")
    folder_obj = None if a.keep else tempfile.TemporaryDirectory(prefix="demkit-scenes-")
    folder = Path(a.keep or folder_obj.name)
    load_before = os.getloadavg()
    data = {}
    for n in CHECK_SIZES:
        t = time.perf_counter()
        _, _, data[n] = write_reference_scene(n, folder)
        print(f"scene N = {n} built and written in {time.perf_counter() - t:.2f} s", flush=True)

    checks = []
    version = "unknown"
    for n in CHECK_SIZES:
        for model in MODELS:
            out = run_deck(DECK, {"data": data[n], "model": model, "nsteps": CHECK_STEPS, "nthermo": 100})
            contacts, pairs = structure(out["log"])
            version = lammps_version(out["log"])
            row = {"N": n, "model": model, "steps": out["steps"], "ranks": 1,
                   "atom_steps_per_s": out["atom_steps_per_s"], "initial_contacts": contacts,
                   "initial_pairs_within_4d": pairs, "end": final_thermo(out["log"])}
            checks.append(row)
            print(json.dumps(row), flush=True)

    speed = []
    for model, steps in SPEED_STEPS.items():
        for ranks in (1, 2):
            runs = []
            for _ in range(a.repeats):
                out = run_deck(DECK, {"data": data[SPEED_N], "model": model, "nsteps": steps}, ranks=ranks)
                if out is None:
                    break
                runs.append(out)
            if not runs:
                continue
            best = max(runs, key=lambda r: r["atom_steps_per_s"])
            row = {"N": SPEED_N, "model": model, "ranks": ranks, "steps": steps,
                   "atom_steps_per_s": best["atom_steps_per_s"], "timesteps_per_s": best["timesteps_per_s"],
                   "all_atom_steps_per_s": [r["atom_steps_per_s"] for r in runs],
                   "performance_line": best["performance_line"]}
            speed.append(row)
            print(json.dumps(row), flush=True)
    if folder_obj is not None:
        folder_obj.cleanup()

    summary = {f"{r['model']}_{r['ranks']}rank{'s' if r['ranks'] > 1 else ''}": r["atom_steps_per_s"]
               for r in speed}
    result = {
        "scene": "reference scene (benchmarks/reference_scene.py): d = 1, m = 1, periodic cube, phi = 0.2, "
                 "|mu| = 2, kT = 1, seed 1; deck benchmarks/lammps/in.reference (Hooke k_n = 1000, dashpot 1.5, "
                 "friction mu = 0.5 with history, dipoles cut at 4 d, dt = 0.001, skin 0.3)",
        "lammps": version,
        "atom_steps_per_s_N8000": summary,
        "speed": speed,
        "checks": checks,
        "machine": f"{os.uname().machine}, {os.cpu_count()} cores",
        "load_average_before_after": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "date": time.strftime("%Y-%m-%d"),
    }
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "lammps_reference.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
