"""demkit's Ewald and P3M sums against LAMMPS' ewald/dipole and pppm/dipole on the reference scene:
accuracy of forces, torques and energy at N = 1000, force accuracy and speed of P3M at N = 8000.
Writes benchmarks/results/long_range_lammps.json (each part its own keys, the others' kept).

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
  demkit on 1 and 2 threads (its default choice, and on 2 cores also parallel=True), LAMMPS on 1
  and 2 MPI ranks (best of 2).

Part ``accuracy1000`` (key "n1000"): the N = 1000 scene at step 0, demkit's Ewald(1e-9) as the
truth; demkit's Ewald and P3M at 1e-3, 1e-4 and 1e-5 and LAMMPS' ewald/dipole and pppm/dipole at
the same absolute accuracy (24 times the number): RMS force error relative to the pull 24, RMS
torque error relative to pull x d (24 too), dipolar energy per sphere relative to the pair energy
2 A m^2 / d^3 = 8 (LAMMPS: thermo pe at step 0, no contacts yet), and each code's forces and
torques against the other's at equal accuracy. Both use tin-foil (metallic) surroundings. Also
LAMMPS' ewald/dipole at 2.4e-8, a check of the truth by the other code.

``--busy``: the speed part with a child process burning one core (a plain Python loop) throughout,
demkit's runs and LAMMPS' alike, as on a machine doing other work (key "speed_busy"; the idle figures
are kept).

    python benchmarks/bench_long_range_lammps.py [--part speed8000|accuracy1000] [--quick] [--busy]
"""
from __future__ import annotations

import argparse
import json
import os
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
RESULTS = HERE / "results" / "long_range_lammps.json"
DECK = HERE / "lammps" / "in.reference"
N = 8000
ACCURACY = 1e-4
PULL = 6.0 * 2.0 ** 2  # 6 A m^2 / d^4 with A = 1, m = 2, d = 1; torques relative to PULL x d (24 too)
PAIR_ENERGY = 2.0 * 2.0 ** 2  # 2 A m^2 / d^3: energies per sphere relative to it
ACCURACIES_1000 = (1e-3, 1e-4, 1e-5)
# thermo row at step 0 of the deck's timed run (thermo_modify norm yes: per sphere)
THERMO = re.compile(r"^\s*Step Temp KinEng PotEng.*\n\s*0\s+\S+\s+\S+\s+(\S+)", re.M)
LAMMPS_TUNED = re.compile(r"G vector \(1/distance\) = \S+|grid = .*|kxmax kymax kzmax\s+= .*")


def rms_error(a, b, scale=PULL):
    """Root-mean-square length of the rows of a - b, relative to ``scale``."""
    return float(np.sqrt(np.mean(((a - b) ** 2).sum(1))) / scale)


def demkit_start(particles, box, long_range):
    """demkit's dipole forces, torques and energy per sphere at the start: (force, torque, energy, tuned)."""
    import demkit as dk
    scene = dk.Scene(particles, [dk.Dipole(1.0, long_range=long_range)], box=box)
    force, torque = scene.forces()
    return force, torque, scene.energy()["magnetic"] / len(particles), repr(scene.long_range[0])


def lammps_start(data, kspace, accuracy, folder):
    """LAMMPS' forces, torques (by id) and potential energy per sphere at step 0 of the deck's
    ``nofric`` model with ``kspace`` (ewald or pppm) at ``accuracy`` (LAMMPS' relative one), and the
    parameters it chose: (force, torque, energy, tuned), or None without LAMMPS. No sphere touches
    another at step 0, so the forces, torques and energy are the dipoles' alone."""
    from demkit.lammps import read_dump
    from lammps_run import run_deck
    dump = Path(folder) / f"start_{kspace}_{accuracy:g}.dump"
    out = run_deck(DECK, {"data": str(data), "model": "nofric", "nsteps": 1, "kspace": kspace, "acc": accuracy,
                          "dumpevery": 1, "dump": str(dump)})
    if out is None:
        return None
    first = read_dump(dump)[0]
    energy = float(THERMO.search(out["log"]).group(1))
    tuned = "; ".join(dict.fromkeys(LAMMPS_TUNED.findall(out["log"])))  # once (run 0 and the run print it)
    return first[:, 7:10], first[:, 10:13], energy, tuned


CHILD = textwrap.dedent("""
    import json, sys
    sys.path.insert(0, {here!r})
    import numba, numpy as np, demkit as dk
    from reference_scene import load_reference_scene, particles_and_box
    numba.set_num_threads({threads})
    p, box = particles_and_box(load_reference_scene({n}, {folder!r}))
    inters = [dk.Dipole(prefactor=1.0, long_range=dk.P3M({accuracy})), dk.KelvinVoigt(stiffness=1000.0, damping=1.5)]
    scene = dk.Scene(p, inters, box=box, skin=0.3, parallel={parallel})
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


def demkit_rate(threads, folder, steps, repeats, parallel=None):
    code = CHILD.format(here=str(HERE), threads=threads, n=N, folder=str(folder), accuracy=ACCURACY, steps=steps,
                        repeats=repeats, parallel=parallel)
    env = dict(os.environ, NUMBA_NUM_THREADS=str(max(2, threads)))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")][-1]
    return json.loads(line[len("RESULT "):])


def accuracy1000():
    """Part accuracy1000: the "n1000" entry of the results (module docstring)."""
    import demkit as dk
    from lammps_run import lammps_available
    from reference_scene import particles_and_box, write_reference_scene
    n = 1000
    folder = Path(tempfile.mkdtemp(prefix="demkit-lr1000-"))
    scene, _, data = write_reference_scene(n, folder)
    p, box = particles_and_box(scene)
    force, torque, energy, tuned = demkit_start(p, box, dk.Ewald(1e-9))
    out = {"date": time.strftime("%Y-%m-%d %H:%M"), "n": n,
           "truth": {"method": "demkit Ewald(1e-9)", "tuned": tuned, "energy_per_sphere": energy},
           "units": {"force": "pull 6 A m^2/d^4 = 24", "torque": "pull x d = 24",
                     "energy": "per sphere, pair energy 2 A m^2/d^3 = 8"}, "rows": []}

    def errors(name, accuracy, result, demkit=None):
        """A row of errors against the truth (and against demkit's (force, torque) at equal accuracy)."""
        f, t, e, tuned = result
        row = {"code": name, "accuracy": accuracy, "force_error": rms_error(f, force),
               "torque_error": rms_error(t, torque), "energy_error": (e - energy) / PAIR_ENERGY,
               "energy_per_sphere": e, "tuned": tuned}
        if demkit is not None:
            row.update(force_vs_demkit=rms_error(f, demkit[0]), torque_vs_demkit=rms_error(t, demkit[1]))
        print(json.dumps(row))
        out["rows"].append(row)
        return f, t

    for accuracy in ACCURACIES_1000:
        ours = {"ewald": errors("demkit Ewald", accuracy, demkit_start(p, box, dk.Ewald(accuracy))),
                "pppm": errors("demkit P3M", accuracy, demkit_start(p, box, dk.P3M(accuracy)))}
        if lammps_available():
            for kspace in ("ewald", "pppm"):
                errors(f"LAMMPS {kspace}/dipole", accuracy, lammps_start(data, kspace, accuracy * PULL, folder),
                       ours[kspace])
    if lammps_available():
        errors("LAMMPS ewald/dipole", 1e-9, lammps_start(data, "ewald", 1e-9 * PULL, folder))
    return out


def write_results(update):
    """Merge ``update`` into the results file (the other part's keys are kept)."""
    result = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    result.update(update)
    RESULTS.write_text(json.dumps(result, indent=1) + "\n")
    print("written", RESULTS)


def main(argv=None):
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--part", choices=("speed8000", "accuracy1000"), default="speed8000")
    args.add_argument("--quick", action="store_true")
    args.add_argument("--busy", action="store_true", help="speed with one core kept busy by another process")
    opts = args.parse_args(argv)
    if opts.part == "accuracy1000":
        write_results({"n1000": accuracy1000()})
        return
    import demkit as dk
    from lammps_run import lammps_available
    from reference_scene import load_reference_scene, particles_and_box, write_reference_scene
    folder = Path(tempfile.mkdtemp(prefix="demkit-lr-"))
    _, _, data = write_reference_scene(N, folder)
    p, box = particles_and_box(load_reference_scene(N, str(folder)))
    steps, repeats = (50, 1) if opts.quick else (200, 2)

    lammps_acc = ACCURACY * PULL  # the same absolute force error, relative to LAMMPS' unit force
    accuracy = None
    if not opts.busy:  # accuracy at the start
        reference = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald(1e-9))], box=box).forces()[0]
        ours = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.P3M(ACCURACY))], box=box)
        accuracy = {"demkit_p3m": float(np.sqrt(np.mean(((ours.forces()[0] - reference) ** 2).sum(1))) / PULL),
                    "demkit_tuned": repr(ours.long_range[0])}
        if lammps_available():
            accuracy["lammps_pppm_dipole"] = rms_error(lammps_start(data, "pppm", lammps_acc, folder)[0], reference)
        print(json.dumps(accuracy))

    burner = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if opts.busy else None
    try:
        speed = _speeds(data, folder, steps, repeats)
    finally:
        if burner is not None:
            burner.kill()
            burner.wait()
    if opts.busy:
        write_results({"speed_busy": {"date": time.strftime("%Y-%m-%d %H:%M"), "rows": speed}})
        return
    write_results({"machine": {"date": time.strftime("%Y-%m-%d %H:%M"), "cores": os.cpu_count()}, "n": N,
                   "accuracy_requested": ACCURACY, "lammps_accuracy_setting": lammps_acc, "force_error": accuracy,
                   "speed": speed})


def _speeds(data, folder, steps, repeats):
    """demkit's and LAMMPS' atom-steps per second on one and two cores (a row each)."""
    from lammps_run import lammps_available, run_deck
    lammps_acc = ACCURACY * PULL  # the same absolute force error, relative to LAMMPS' unit force
    speed = []
    for cores in (1, 2):
        ours = demkit_rate(cores, folder, steps, repeats)
        theirs = None
        if lammps_available(cores):
            theirs = max(run_deck(DECK, {"data": str(data), "model": "nofric", "nsteps": steps, "kspace": "pppm",
                                         "acc": lammps_acc}, ranks=cores)["atom_steps_per_s"] for _ in range(repeats))
        speed.append({"cores": cores, "demkit_particle_steps_per_s": ours["particle_steps_per_second"],
                      "demkit_threads": ours.get("threads"), "demkit_threads_reason": ours.get("threads_reason"),
                      "lammps_atom_steps_per_s": theirs,
                      "ratio": None if theirs is None else ours["particle_steps_per_second"] / theirs,
                      "demkit_tuned": ours["tuned"]})
        if cores > 1:  # and on threads throughout (parallel=True), as a user may force
            forced = demkit_rate(cores, folder, steps, repeats, parallel=True)["particle_steps_per_second"]
            speed[-1].update(demkit_forced_threads_particle_steps_per_s=forced,
                             ratio_forced_threads=None if theirs is None else forced / theirs)
        print(json.dumps(speed[-1]))
    return speed


if __name__ == "__main__":
    main()
