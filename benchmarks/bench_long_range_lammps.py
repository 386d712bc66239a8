"""demkit's P3M against LAMMPS' pppm/dipole on the N = 8000 reference scene, side by side in one
run: force accuracy and speed. Writes benchmarks/results/long_range_lammps.json.

The scene is benchmarks/reference_scene.py's (periodic cube, volume fraction 0.2, moments of 2,
frictionless Hooke contacts; the `nofric` model of benchmarks/lammps/in.reference with
``kspace=pppm``). demkit: ``Dipole(1, long_range=P3M(1e-4))``, whose accuracy is relative to the
touching pull 6 A m^2 / d^4 = 24; LAMMPS: ``kspace_style pppm/dipole`` with its accuracy relative
to two unit charges one apart (1 here), so 1e-4 of demkit's is 2.4e-3 of LAMMPS' (the same absolute
RMS force error, 2.4e-3). Both tune their own real-space cutoff or splitting (LAMMPS' cutoff is the
deck's 4 d).

* accuracy: the forces at the start (no contacts yet) of each against demkit's Ewald sum at 1e-9
  (itself checked against lattice sums and the direct sum over images), RMS relative to the pull;
* speed: atom-steps per second of velocity Verlet, dt = 0.001, 200 timed steps after a warm-up,
  demkit on 1 and 2 threads, LAMMPS on 1 and 2 MPI ranks (best of 2).

    python benchmarks/bench_long_range_lammps.py [--quick]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
RESULTS = HERE / "results" / "long_range_lammps.json"
DECK = HERE / "lammps" / "in.reference"
N = 8000
ACCURACY = 1e-4
PULL = 6.0 * 2.0 ** 2  # 6 A m^2 / d^4 with A = 1, m = 2, d = 1

CHILD = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {here!r})
    import numba, numpy as np, demkit as dk
    from reference_scene import load_reference_scene, particles_and_box
    numba.set_num_threads({threads})
    p, box = particles_and_box(load_reference_scene({n}, {folder!r}))
    inters = [dk.Dipole(prefactor=1.0, long_range=dk.P3M({accuracy})), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)]
    scene = dk.Scene(p, inters, box=box, skin=0.3)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-3))
    sim.run(duration=0.01, progress=False)
    best = None
    for _ in range({repeats}):
        sim.run(duration={steps} * 1e-3, progress=False)
        st = sim.statistics
        if best is None or st["particle_steps_per_second"] > best["particle_steps_per_second"]:
            best = st
    best["tuned"] = repr(scene.long_range[0])
    print("RESULT", json.dumps(best, default=float))
""")


def demkit_rate(threads, folder, steps, repeats):
    code = CHILD.format(here=str(HERE), threads=threads, n=N, folder=str(folder), accuracy=ACCURACY, steps=steps,
                        repeats=repeats)
    env = dict(os.environ, NUMBA_NUM_THREADS=str(max(2, threads)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1]
    return json.loads(line[len("RESULT "):])


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--quick", action="store_true")
    opts = args.parse_args(argv)
    import demkit as dk
    from lammps_run import lammps_available, run_deck
    from reference_scene import load_reference_scene, particles_and_box, write_reference_scene
    folder = Path(tempfile.mkdtemp(prefix="demkit-lr-"))
    _, _, data = write_reference_scene(N, folder)
    p, box = particles_and_box(load_reference_scene(N, str(folder)))
    steps, repeats = (50, 1) if opts.quick else (200, 2)

    # accuracy at the start
    reference = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald(1e-9))], box=box).forces()[0]
    ours = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.P3M(ACCURACY))], box=box)
    accuracy = {"demkit_p3m": float(np.sqrt(np.mean(((ours.forces()[0] - reference) ** 2).sum(1))) / PULL),
                "demkit_tuned": repr(ours.long_range[0])}
    lammps_acc = ACCURACY * PULL  # the same absolute force error, relative to LAMMPS' unit force
    if lammps_available():
        dump = folder / "start.dump"
        run_deck(DECK, {"data": str(data), "model": "nofric", "nsteps": 1, "kspace": "pppm", "acc": lammps_acc,
                        "dumpevery": 1, "dump": str(dump)})
        lines = dump.read_text().splitlines()
        rows = np.array([[float(x) for x in ln.split()] for ln in lines[9:9 + len(p)]])  # frame 0 (step 0)
        theirs = rows[np.argsort(rows[:, 0])][:, 7:10]  # fx fy fz by id
        accuracy["lammps_pppm_dipole"] = float(np.sqrt(np.mean(((theirs - reference) ** 2).sum(1))) / PULL)
    print(json.dumps(accuracy))

    speed = []
    for cores in (1, 2):
        ours = demkit_rate(cores, folder, steps, repeats)
        theirs = None
        if lammps_available(cores):
            theirs = max(run_deck(DECK, {"data": str(data), "model": "nofric", "nsteps": steps, "kspace": "pppm",
                                         "acc": lammps_acc}, ranks=cores)["atom_steps_per_s"] for _ in range(repeats))
        speed.append({"cores": cores, "demkit_particle_steps_per_s": ours["particle_steps_per_second"],
                      "demkit_threads": ours.get("threads"), "lammps_atom_steps_per_s": theirs,
                      "ratio": None if theirs is None else ours["particle_steps_per_second"] / theirs,
                      "demkit_tuned": ours["tuned"]})
        print(json.dumps(speed[-1]))
    result = {"machine": {"date": time.strftime("%Y-%m-%d %H:%M"), "cores": os.cpu_count()}, "n": N,
              "accuracy_requested": ACCURACY, "lammps_accuracy_setting": lammps_acc, "force_error": accuracy,
              "speed": speed}
    RESULTS.write_text(json.dumps(result, indent=1) + "\n")
    print("written", RESULTS)


if __name__ == "__main__":
    main()
