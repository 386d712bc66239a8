"""What induced dipoles cost: a step of the reference scene with magnetisable spheres against the
same step with permanent moments (issue: induced dipoles), with dipoles cut plainly at 4 d (as the
LAMMPS deck) and switched off over [3 d, 4 d].

The N-body reference scene (benchmarks/reference_scene.py: phi = 0.2, d = 1, dipoles cut at 4 d, dt = 0.001; Kelvin-Voigt
contacts k = 5000 with dashpot 1.5, stiffer than the deck's 1000, which the guards find too soft for
the aligned induced moments) twice: with its permanent moments of 2,
and with soft spheres (chi = 1000, beta = 0.997) in a uniform field B0 that gives a lone sphere the
same moment 2. After a warm-up, steps are timed in alternating blocks (the machine's speed drifts):
seconds per step, median over blocks, with the conjugate-gradient iterations per solve.

    python benchmarks/bench_induction.py [--sizes 1000 8000] [--tolerance 1e-8 1e-6] [--threads 1]

Writes benchmarks/results/induction.json.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numba
import numpy as np

import demkit as dk

sys.path.insert(0, str(Path(__file__).parent))
from reference_scene import make_reference_scene  # noqa: E402

RESULTS = Path(__file__).parent / "results" / "induction.json"
CHI = 1000.0
DT = 1e-3
#: the switched variants' switch width: the field then changes smoothly and the solve's linear
#: predictor works (a plain cutoff makes the field jump as pairs cross it)
SWITCH = 1.0


def scene_of(ref, induced, tolerance, switch_width=None):
    """The reference scene with permanent moments, or with soft spheres of the same lone moment
    (dipoles cut at 4 d, plainly or switched off over ``switch_width``)."""
    n = len(ref["x"])
    box = dk.Box([ref["L"]] * 3, periodic=True)
    radius = ref["d"] / 2
    common = dict(velocity=ref["v"], radius=radius, mass=ref["m"], angular_velocity=ref["omega"])
    law = dk.KelvinVoigt(5000.0, 1.5)  # stiffer than the deck's 1000: induced moments align and pull harder
    if not induced:
        p = dk.Particles(ref["x"], dipole=ref["mu"], **common)
        return dk.Scene(p, [dk.Dipole(1.0, cutoff=4.0, switch_width=switch_width), law], box=box)
    alpha = CHI / (CHI + 3.0) * radius**3  # prefactor 1
    p = dk.Particles(ref["x"], susceptibility=np.full(n, CHI), **common)
    field = dk.UniformField((0.0, 0.0, 2.0 / alpha))
    dipole = dk.Dipole(1.0, cutoff=4.0, switch_width=switch_width, induction=dk.Induction(tolerance))
    return dk.Scene(p, [dipole, law, field], box=box)


def field_seconds(scene, repeats=20):
    """(seconds of one field evaluation of the solve, pairs it visits): the compiled field_of on the
    scene's state (its Dipole's list), median of ``repeats``."""
    from demkit.interactions.induction import field_of
    a, solver = scene.arrays, scene.induction
    lists = scene.state.lists[solver.group]
    args = (a["position"], a["dipole"], a["box"], a["periodic"], scene.params, scene.induction_slot, lists.start,
            lists.end, lists.partner, np.zeros(0))
    field_of(*args)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        field_of(*args)
        times.append(time.perf_counter() - t)
    return float(np.median(times)), int(lists.start[-1])


def time_steps(sim, steps):
    t = time.perf_counter()
    sim.run(steps * DT)
    return (time.perf_counter() - t) / steps


def measure(n, tolerances, blocks, steps):
    ref = make_reference_scene(n)
    sims = {"permanent": dk.Simulation(scene_of(ref, False, None), dk.VelocityVerlet(DT))}
    for tol in tolerances:
        sims[f"induced {tol:g}"] = dk.Simulation(scene_of(ref, True, tol), dk.VelocityVerlet(DT))
    sims["permanent, switched"] = dk.Simulation(scene_of(ref, False, None, SWITCH), dk.VelocityVerlet(DT))
    for tol in tolerances:
        sims[f"induced {tol:g}, switched"] = dk.Simulation(scene_of(ref, True, tol, SWITCH), dk.VelocityVerlet(DT))
    for sim in sims.values():  # compile and settle
        sim.run(20 * DT)
    times = {name: [] for name in sims}
    for _ in range(blocks):
        for name, sim in sims.items():
            times[name].append(time_steps(sim, steps))
    out = {"n": n, "steps_per_block": steps, "blocks": blocks}
    for name, sim in sims.items():
        base = float(np.median(times["permanent, switched" if "switched" in name else "permanent"]))
        seconds = float(np.median(times[name]))
        row = {"seconds_per_step": seconds, "relative_to_permanent": seconds / base}
        solver = sim.scene.induction
        model = dk.cost.estimate(sim.scene, sim.integrator, DT).per_step
        row["cost_model_seconds_per_step"] = model
        if solver is not None:
            field, pairs = field_seconds(sim.scene)
            row.update(iterations_per_solve=solver.mean_iterations, most_iterations=solver.most_iterations,
                       mean_moment=float(np.linalg.norm(sim.scene.particles.dipole, axis=1).mean()),
                       field_seconds=field, field_pairs=pairs, field_seconds_per_pair=field / pairs)
        out[name] = row
        print(f"N = {n}: {name}: {seconds * 1e3:.2f} ms/step ({seconds / base:.2f}x; cost model {model * 1e3:.2f})"
              + (f", {row['iterations_per_solve']:.1f} iterations per solve, field {field * 1e3:.2f} ms "
                 f"({field / pairs * 1e9:.1f} ns a pair)" if solver is not None else ""), flush=True)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 8000])
    parser.add_argument("--tolerance", type=float, nargs="+", default=[1e-8, 1e-6])
    parser.add_argument("--threads", type=int, default=None, help="numba threads (default: the machine's)")
    parser.add_argument("--blocks", type=int, default=5)
    parser.add_argument("--steps", type=int, default=50)
    args = parser.parse_args(argv)
    if args.threads:
        numba.set_num_threads(args.threads)
    rows = [measure(n, args.tolerance, args.blocks, args.steps) for n in args.sizes]
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps({"threads": numba.get_num_threads(), "chi": CHI, "dt": DT, "sizes": rows},
                                  indent=1) + "\n")
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
