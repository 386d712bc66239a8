"""Error of truncating the dipole interaction at a cutoff, plain and switched, against the exact sum.

Writes benchmarks/results/dipole_truncation.json. For each of a few random configurations of
N = 1000 spheres (d = 1, open space, random sequential placement in a cube at volume fraction 0.2,
random moments of magnitude 2, prefactor A = 1) it compares, against the all-pairs sum without
cutoff,

* plain truncation at r_c = 4 (``Dipole(1, cutoff=4)``), and
* the switched truncation at r_c = 4 with switch widths 0.5 and 1.0 (``switch_width=...``):

relative RMS force error sqrt(<|F - F_exact|^2> / <|F_exact|^2>), RMS torque error (absolute and
relative the same way), and the energy per particle difference (E - E_exact)/N. It also times one
force evaluation of each (scene.forces(), best of 20), the plain and switched pair functions per
pair, and, when LAMMPS (`lmp`) is installed, checks
that LAMMPS' lj/cut/dipole/cut at the same cutoff gives the plain truncation's forces, torques
and energy. For reference it also measures, in numpy, a shifted-force truncation (the
alternative considered in docs/theory.md).

    python benchmarks/bench_dipole_truncation.py [--seeds 5]
"""
import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

import demkit as dk
from demkit.interactions.dipole import dipole_force, switched_dipole_force

HERE = Path(__file__).resolve().parent
N, PHI, MOMENT, PREFACTOR, CUTOFF, WIDTHS = 1000, 0.2, 2.0, 1.0, 4.0, (0.5, 1.0)


def configuration(seed, n=N, phi=PHI, moment=MOMENT):
    """Random non-overlapping unit-diameter spheres in a cube at volume fraction phi, random moments."""
    rng = np.random.default_rng(seed)
    side = (n * np.pi / 6 / phi) ** (1 / 3)
    # random sequential addition with a cell grid of cell size >= 1 (one diameter)
    cells = int(side)
    grid = {}
    pos = np.empty((n, 3))
    k = 0
    while k < n:
        x = rng.uniform(0.5, side - 0.5, 3)
        c = tuple((x / side * cells).astype(int))
        near = [q for dc in np.ndindex(3, 3, 3)
                for q in grid.get((c[0] + dc[0] - 1, c[1] + dc[1] - 1, c[2] + dc[2] - 1), ())]
        if near and np.min(np.sum((pos[near] - x) ** 2, axis=1)) < 1.0:
            continue
        pos[k] = x
        grid.setdefault(c, []).append(k)
        k += 1
    dip = rng.normal(size=(n, 3))
    dip *= moment / np.linalg.norm(dip, axis=1)[:, None]
    return dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip)


def evaluate(particles, **kwargs):
    scene = dk.Scene(particles.copy(), [dk.Dipole(prefactor=PREFACTOR, **kwargs)])
    force, torque = scene.forces()
    energy = scene.energy()["magnetic"]
    best = np.inf
    for _ in range(20):
        t0 = time.perf_counter()
        scene.forces()
        best = min(best, time.perf_counter() - t0)
    return force, torque, energy, best


def errors(result, exact, n):
    f, t, e, _ = result
    fe, te, ee, _ = exact
    rms = lambda a: float(np.sqrt(np.mean(np.sum(a * a, axis=1))))  # noqa: E731
    return {"force_rel_rms": rms(f - fe) / rms(fe),
            "torque_rms": rms(t - te), "torque_rel_rms": rms(t - te) / rms(te),
            "energy_per_particle_diff": (e - ee) / n, "energy_rel": (e - ee) / abs(ee)}


def shifted_force(particles, cutoff):
    """Reference (numpy) for an alternative energy-conserving truncation, not offered by demkit: the
    shifted-force form of both radial functions of U = A [(m_i.m_j) P(r) - 3 (m_i.d)(m_j.d) Q(r)],
    P = r^-3 and Q = r^-5 each replaced by f(r) - f(r_c) - f'(r_c) (r - r_c), so that U and its
    gradient vanish at r_c. It changes every pair inside r_c, not only those near it."""
    x, m = particles.position, particles.dipole
    i, j = np.triu_indices(len(x), 1)
    d = x[j] - x[i]
    r = np.linalg.norm(d, axis=1)
    keep = r < cutoff
    i, j, d, r = i[keep], j[keep], d[keep], r[keep]
    n, a, b, rc = d / r[:, None], m[i], m[j], cutoff
    P = r ** -3 - rc ** -3 + 3 * rc ** -4 * (r - rc)
    dP = -3 * r ** -4 + 3 * rc ** -4
    Q = r ** -5 - rc ** -5 + 5 * rc ** -6 * (r - rc)
    dQ = -5 * r ** -6 + 5 * rc ** -6
    ab, ad, bd = np.sum(a * b, axis=1), np.sum(a * d, axis=1), np.sum(b * d, axis=1)
    u = PREFACTOR * (ab * P - 3 * ad * bd * Q)
    grad = PREFACTOR * ((ab * dP - 3 * ad * bd * dQ)[:, None] * n
                        - 3 * Q[:, None] * (bd[:, None] * a + ad[:, None] * b))      # dU/dd = -F_j
    ti = -np.cross(a, PREFACTOR * (b * P[:, None] - 3 * d * (bd * Q)[:, None]))      # -m_i x dU/dm_i
    tj = -np.cross(b, PREFACTOR * (a * P[:, None] - 3 * d * (ad * Q)[:, None]))
    force, torque = np.zeros_like(x), np.zeros_like(x)
    np.add.at(force, j, -grad)
    np.add.at(force, i, grad)
    np.add.at(torque, i, ti)
    np.add.at(torque, j, tj)
    return force, torque, float(u.sum()), np.nan


@njit(cache=False)
def _sweep_plain(pairs, position, dipole, prefactor):
    """The plain force function on every listed pair; a checksum keeps the work alive."""
    total = 0.0
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        dx = position[j, 0] - position[i, 0]
        dy = position[j, 1] - position[i, 1]
        dz = position[j, 2] - position[i, 2]
        out = dipole_force(i, j, dx, dy, dz, dx * dx + dy * dy + dz * dz, dipole, prefactor)
        total += out[0] + out[3] + out[8]
    return total


@njit(cache=False)
def _sweep_switched(pairs, position, dipole, prefactor, switch_on, inv_width):
    """The same with the switched force function."""
    total = 0.0
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        dx = position[j, 0] - position[i, 0]
        dy = position[j, 1] - position[i, 1]
        dz = position[j, 2] - position[i, 2]
        out = switched_dipole_force(i, j, dx, dy, dz, dx * dx + dy * dy + dz * dz, dipole, prefactor,
                                    switch_on, inv_width)
        total += out[0] + out[3] + out[8]
    return total


def pair_cost(particles, width, repeats=50):
    """Nanoseconds per pair of the plain and the switched force function, over the pairs within CUTOFF."""
    x = particles.position
    i, j = np.triu_indices(len(x), 1)
    keep = np.linalg.norm(x[j] - x[i], axis=1) < CUTOFF
    pairs = np.ascontiguousarray(np.stack([i[keep], j[keep]], axis=1))
    out = {}
    for name, fn, args in (("plain", _sweep_plain, (pairs, x, particles.dipole, PREFACTOR)),
                           ("switched", _sweep_switched, (pairs, x, particles.dipole, PREFACTOR, CUTOFF - width, 1 / width))):
        fn(*args)
        best = np.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn(*args)
            best = min(best, time.perf_counter() - t0)
        out[name] = 1e9 * best / len(pairs)
    return out


def lammps_check(particles, lmp):
    """Forces, torques and energy of lj/cut/dipole/cut (epsilon = 0: dipoles only) at CUTOFF, run 0."""
    tmp = Path(tempfile.mkdtemp(prefix="demkit-lmp-"))
    try:
        x, mu = particles.position, particles.dipole
        lo, hi = x.min() - 10, x.max() + 10
        density = 1.0 / (np.pi / 6)
        with open(tmp / "scene.data", "w") as fh:
            fh.write(f"dipole truncation check\n\n{len(x)} atoms\n1 atom types\n\n")
            for a in "xyz":
                fh.write(f"{lo:.17g} {hi:.17g} {a}lo {a}hi\n")
            fh.write("\nMasses\n\n1 1.0\n\nAtoms # hybrid\n\n")
            for i in range(len(x)):  # id type x y z diameter density q mux muy muz
                fh.write(f"{i + 1} 1 {x[i, 0]:.17g} {x[i, 1]:.17g} {x[i, 2]:.17g} 1.0 {density:.17g} 0.0 "
                         f"{mu[i, 0]:.17g} {mu[i, 1]:.17g} {mu[i, 2]:.17g}\n")
        (tmp / "in.check").write_text(f"""units lj
atom_style hybrid sphere dipole
boundary f f f
atom_modify map array
read_data scene.data
pair_style lj/cut/dipole/cut {CUTOFF}
pair_coeff * * 0.0 1.0
neighbor 0.3 bin
thermo_style custom step pe
thermo_modify norm no
run 0
print "PE $(pe:%.17g)"
write_dump all custom forces.txt id fx fy fz tqx tqy tqz modify format float %.17g sort id
""")
        subprocess.run([lmp, "-in", "in.check", "-screen", "none", "-log", "log.lammps"], cwd=tmp,
                             capture_output=True, text=True, check=True)
        log = (tmp / "log.lammps").read_text()
        energy = float([line for line in log.splitlines() if line.startswith("PE ")][-1].split()[1])
        rows = np.loadtxt(tmp / "forces.txt", skiprows=9)
        return rows[:, 1:4], rows[:, 4:7], energy
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args(argv)
    # the task's comparison at r_c = 4, then, for reference, cutoffs moved out so that the switch
    # starts at 4 (r_on = 4), and plain truncation at those larger cutoffs
    variants = {"plain": {"cutoff": CUTOFF}}
    for w in WIDTHS:
        variants[f"switched_w{w:g}"] = {"cutoff": CUTOFF, "switch_width": w}
    for w in WIDTHS:
        variants[f"switched_rc{CUTOFF + w:g}_w{w:g}"] = {"cutoff": CUTOFF + w, "switch_width": w}
    for w in WIDTHS:
        variants[f"plain_rc{CUTOFF + w:g}"] = {"cutoff": CUTOFF + w}
    per_seed = {name: [] for name in variants}
    per_seed["shifted_force_numpy_reference"] = []
    times = {name: [] for name in ["exact", *variants]}
    pairs_in_switch = {w: [] for w in WIDTHS}
    pairs_within = {c: [] for c in sorted({kw["cutoff"] for kw in variants.values()})}
    lmp = shutil.which("lmp")
    lammps = []
    for seed in range(args.seeds):
        p = configuration(seed)
        exact = evaluate(p)
        times["exact"].append(exact[3])
        for name, kwargs in variants.items():
            result = evaluate(p, **kwargs)
            times[name].append(result[3])
            per_seed[name].append(errors(result, exact, N))
            if name == "plain" and lmp and seed == 0:
                lf, lt, le = lammps_check(p, lmp)
                scale_f, scale_t = np.abs(result[0]).max(), np.abs(result[1]).max()
                lammps.append({"max_force_diff_rel": float(np.abs(lf - result[0]).max() / scale_f),
                               "max_torque_diff_rel": float(np.abs(lt - result[1]).max() / scale_t),
                               "energy_diff_rel": float(abs(le - result[2]) / abs(result[2]))})
        per_seed["shifted_force_numpy_reference"].append(errors(shifted_force(p, CUTOFF), exact, N))
        i, j = np.triu_indices(N, 1)
        r = np.linalg.norm(p.position[j] - p.position[i], axis=1)
        within = np.count_nonzero(r < CUTOFF)
        for c in pairs_within:
            pairs_within[c].append(np.count_nonzero(r < c) / N)
        for w in WIDTHS:
            pairs_in_switch[w].append(np.count_nonzero((r > CUTOFF - w) & (r < CUTOFF)) / within)
        print(f"seed {seed}: " + ", ".join(f"{name} F {per_seed[name][-1]['force_rel_rms']:.4f}" for name in variants),
              flush=True)
    print(f"lammps: {lammps}")

    def summary(rows):
        keys = rows[0].keys()
        return {k: {"mean": float(np.mean([r[k] for r in rows])), "std": float(np.std([r[k] for r in rows])),
                    "rms": float(np.sqrt(np.mean([r[k] ** 2 for r in rows]))),
                    "per_seed": [float(r[k]) for r in rows]} for k in keys}

    result = {
        "benchmark": "dipole truncation error against the exact all-pairs sum (scene.forces(), scene.energy())",
        "scene": {"particles": N, "diameter": 1.0, "volume_fraction": PHI, "dipole_magnitude": MOMENT,
                  "prefactor": PREFACTOR, "space": "open (random sequential addition in a cube)",
                  "cutoff": CUTOFF, "switch_widths": list(WIDTHS), "seeds": args.seeds},
        "definitions": {
            "force_rel_rms": "sqrt(sum_i |F_i - F_i,exact|^2 / sum_i |F_i,exact|^2)",
            "torque_rms": "sqrt(mean_i |tau_i - tau_i,exact|^2)",
            "torque_rel_rms": "torque_rms / sqrt(mean_i |tau_i,exact|^2)",
            "energy_per_particle_diff": "(E - E_exact) / N",
            "energy_rel": "(E - E_exact) / |E_exact| (E_exact is small: random moments nearly cancel)",
            "mean/std/rms": "over the seeds (rms: root mean square of the signed per-seed values)"},
        "variants": dict(variants, shifted_force_numpy_reference={"cutoff": CUTOFF}),
        "exact": {"energy_per_particle": None, "force_rms": None, "torque_rms": None},
        "errors": {name: summary(rows) for name, rows in per_seed.items()},
        "fraction_of_pairs_within_cutoff_in_switch": {f"w{w:g}": float(np.mean(v)) for w, v in pairs_in_switch.items()},
        "pairs_within_cutoff_per_particle": {f"rc{c:g}": float(np.mean(v)) for c, v in pairs_within.items()},
        "force_evaluation_ms_scene": {k: 1e3 * float(np.min(v)) for k, v in times.items()},
        "force_evaluation_note": "scene.forces() (best of 20 x seeds) with the engine's default pair loop at the "
                                 "time of measurement; exact = no cutoff (all pairs)",
        "pair_function_ns_per_pair": {f"w{w:g}": pair_cost(configuration(0), w) for w in WIDTHS},
        "pair_function_note": "plain vs switched force function called on every pair within r_c = 4 of seed 0 "
                              "(one compiled loop, best of 50)",
        "lammps_lj_cut_dipole_cut_vs_plain": lammps[0] if lammps else "lmp not installed",
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
                    "platform": platform.platform()},
    }
    p = configuration(0)
    f, t, e, _ = evaluate(p)
    result["exact"] = {"energy_per_particle": e / N, "force_rms": float(np.sqrt(np.mean(np.sum(f * f, axis=1)))),
                       "torque_rms": float(np.sqrt(np.mean(np.sum(t * t, axis=1)))), "seed": 0}
    (HERE / "results").mkdir(exist_ok=True)
    (HERE / "results" / "dipole_truncation.json").write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: result[k] for k in ("exact", "fraction_of_pairs_within_cutoff_in_switch",
                                             "pairs_within_cutoff_per_particle", "force_evaluation_ms_scene",
                                             "pair_function_ns_per_pair",
                                             "lammps_lj_cut_dipole_cut_vs_plain")}, indent=2))
    for name, s in result["errors"].items():
        print(name, {k: f"{v['mean']:.4g} +- {v['std']:.2g} (rms {v['rms']:.3g})" for k, v in s.items()})


if __name__ == "__main__":
    sys.exit(main())
