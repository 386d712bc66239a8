"""The measurements behind the thresholds of demkit.guards (docs/stability.md).

Writes benchmarks/results/stability.json. Measures
* the dipoles' time scale: a moment swinging in the field of a fixed neighbour (a rotational
  pendulum) and a free pair, energy error against omega dt for velocity Verlet and Euler-Cromer, and
  how far Dipole.rate_coefficients bounds the pair's mass-weighted Hessian;
* spins: a moment spinning next to another, the error of the coupling energy against |omega| dt
  for every integrator (and whether it drifts);
* Hertz contacts resolved with fewer steps: restitution, largest overlap and energy error of an
  elastic impact against steps per contact;
* magnets snapping together from rest on a contact too soft for them: the largest overlap reached
  against the guard's estimate (linear and Hertz), and where they pass through each other;
* the cost of guards.while_stepping and before_stepping at N = 8000.
Some runs go beyond what the guards accept: they are made with the guard switched off.

    python benchmarks/bench_stability.py       # about a minute on 2 cores
"""
import contextlib
import json
import math
import time
from pathlib import Path

import numpy as np

import demkit as dk
from demkit import guards, simulation

HERE = Path(__file__).resolve().parent


@contextlib.contextmanager
def unguarded():
    """Simulations made inside skip guards.before_stepping (to measure beyond the limits)."""
    keep = simulation.guards.before_stepping
    simulation.guards.before_stepping = lambda scene, integrator: None
    try:
        yield
    finally:
        simulation.guards.before_stepping = keep


def heavy_pair(moment2, fixed_first, spin=0.0):
    """Two unit moments (A = 1) one diameter apart whose translation is frozen (mass 1e9) while they
    turn freely (I = 0.1): sphere 1 has ``moment2`` and spin ``spin`` about z."""
    mass = 1e9
    p = dk.Particles(position=[[0, 0, 0], [1.0, 0, 0]], radius=0.5, mass=mass, inertia_factor=0.1 / (mass * 0.25),
                     dipole=[[1, 0, 0], moment2], angular_velocity=[[0, 0, 0], [0, 0, spin]],
                     fixed=[fixed_first, False])
    return dk.Scene(p, [dk.Dipole(1.0)])


def pendulum():
    out = {}
    for fixed in (True, False):
        scene = heavy_pair([math.cos(0.5), math.sin(0.5), 0.0], fixed)
        a, b = scene.interactions[0].rate_coefficients(scene.particles, np.array([0]), np.array([1]))
        omega = math.sqrt(float(a[0] + b[0]))  # r = 1; translation frozen: b dominates
        rows = {}
        for name, make in (("VelocityVerlet", dk.VelocityVerlet), ("EulerCromer", dk.EulerCromer)):
            for phase in (0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 1.9, 2.1):
                dt = phase / omega
                with unguarded():
                    s = heavy_pair([math.cos(0.5), math.sin(0.5), 0.0], fixed)
                    e0 = s.energy()
                    swing = e0["magnetic"] + 2.0  # above the aligned minimum -2 A
                    try:
                        t = dk.Simulation(s, make(dt)).run(20 * 2 * math.pi / omega, record_every=dt)
                        err = float(np.abs(t.energy["total"] - e0["total"]).max() / swing)
                    except dk.SimulationError:
                        err = math.inf
                rows.setdefault(name, {})[phase] = err
        out["one fixed" if fixed else "both free"] = {"omega_bound": omega, "energy_error_over_swing": rows}
    return out


def hessian_ratios():
    """Dipole.rate_coefficients over the largest eigenvalue of the mass-weighted Hessian (positions
    and rotations) of a pair at r = 1.1, random orientations (central differences)."""
    rng = np.random.default_rng(1)

    def rotate(v, phi):
        t = np.linalg.norm(phi)
        if t == 0:
            return v
        k = phi / t
        return v * math.cos(t) + np.cross(k, v) * math.sin(t) + k * (k @ v) * (1 - math.cos(t))

    def energy(q, m1, m2):
        a, c = rotate(m1, q[6:9]), rotate(m2, q[9:])
        d = np.array([1.1, 0, 0]) + q[3:6] - q[:3]
        r = np.linalg.norm(d)
        n = d / r
        return (a @ c - 3 * (a @ n) * (c @ n)) / r**3

    ratios = []
    for k in range(30):
        m1, m2 = (np.array([1.0, 0, 0]),) * 2 if k == 0 else (rng.normal(size=3), rng.normal(size=3))
        h, hess = 1e-4, np.zeros((12, 12))
        for i in range(12):
            for j in range(12):
                e = []
                for si, sj in ((h, h), (h, -h), (-h, h), (-h, -h)):
                    q = np.zeros(12)
                    q[i] += si
                    q[j] += sj
                    e.append(energy(q, m1, m2))
                hess[i, j] = (e[0] - e[1] - e[2] + e[3]) / (4 * h * h)
        weight = np.array([1.0] * 6 + [0.1] * 6)
        largest = np.abs(np.linalg.eigvalsh(hess / np.sqrt(np.outer(weight, weight)))).max()
        s = np.linalg.norm(m1) * np.linalg.norm(m2)
        bound = s * (24 * 2 / 1.1**5 + (2 / 0.1 + 1 / 0.1) / 1.1**3)
        ratios.append(bound / largest)
    return {"aligned": ratios[0], "random_min": min(ratios[1:]), "random_max": max(ratios[1:])}


def spins():
    out = {}
    dt = 0.1 / math.sqrt(20.0)
    for name, make in (("VelocityVerlet", dk.VelocityVerlet), ("EulerCromer", dk.EulerCromer),
                       ("ForestRuth", dk.ForestRuth), ("RK4", dk.RK4),
                       ("MultipleTimeStep(4)", lambda h: dk.MultipleTimeStep(h, inner=4))):
        for turn in (0.3, 0.5, 1.0, 1.5, 2.0, 3.0):
            with unguarded():
                s = heavy_pair([1.0, 0.0, 0.0], False, spin=turn / dt)
                e0 = s.energy()["total"]
                t = dk.Simulation(s, make(dt)).run(20000 * dt, record_every=10 * dt)
            err = np.abs(t.energy["total"] - e0) / 2.0  # over the coupling 2 A / r^3
            half = len(err) // 2
            norms = float(np.abs(np.linalg.norm(t.dipole, axis=2) - 1).max())
            out.setdefault(name, {})[turn] = {"first_half": float(err[:half].max()),
                                              "second_half": float(err[half:].max()), "norm_error": norms}
    return out


def hertz_steps():
    from demkit.interactions.hertz import hertz_impact
    law = dk.Hertz(young=1e5, poisson=0.3, restitution=1.0)
    v = 1.0
    overlap, _, duration = hertz_impact(law.young_eff, 0.25, 0.5, 2 * v)
    out = {}
    for steps in (40, 20, 10, 7, 5, 4, 3, 2):
        dt = duration / steps
        p = dk.Particles(position=[[-0.5 - 3 * v * dt, 0, 0], [0.5 + 3 * v * dt + 1e-3 * dt, 0, 0]],
                         velocity=[[v, 0, 0], [-v, 0, 0]], radius=0.5)
        with unguarded():
            t = dk.Simulation(dk.Scene(p, [law]), dk.VelocityVerlet(dt)).run(4 * duration, record_every=dt)
        r = np.linalg.norm(t.position[:, 1] - t.position[:, 0], axis=1)
        e = t.energy["total"]
        out[steps] = {"restitution": float(abs(t.velocity[-1, 1, 0]) / v),
                      "overlap_over_analytic": float((1 - r.min()) / overlap),
                      "energy_error": float(np.abs(e - e[0]).max() / e[0])}
    return out


def snaps():
    out = {"KelvinVoigt": [], "Hertz": []}
    stiffness = (100, 116, 130, 150, 178, 200, 300, 400, 800, 1600)
    laws = [("KelvinVoigt", dk.KelvinVoigt(kappa, 0.0)) for kappa in stiffness]
    for estimate in (0.2, 0.3, 0.35, 0.4, 0.5):  # E* for a snap estimate of this many radii
        young_eff = 2.0 / (8 / 15 * math.sqrt(0.25) * (0.5 * estimate) ** 2.5)
        laws.append(("Hertz", dk.Hertz(young_eff * 2 * (1 - 0.3**2), 0.3)))
    for kind, law in laws:
        p = dk.Particles(position=[[0, 0, 0], [3.0, 0, 0]], radius=0.5, dipole=[[1, 0, 0], [1, 0, 0]])
        with unguarded():
            scene = dk.Scene(p, [dk.Dipole(1.0), law])
            force, energy = scene.interactions[0].touching_attraction(p, np.array([0]), np.array([1]))
            static, stored = law.overlaps(p, np.array([0]), np.array([1]), force, energy)
            dt = 0.25 * min(law.max_time_step(p, 4.0) if kind == "Hertz" else law.max_time_step(p), 2e-3)
            t = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(12.0, record_every=10 * dt)
        gap = t.position[:, 1, 0] - t.position[:, 0, 0]
        out[kind].append({"estimate_static": float(static[0] / 0.5), "estimate_snap": float(stored[0] / 0.5),
                          "overlap_reached": float((1 - gap.min()) / 0.5) if gap.min() > 0 else None,
                          "passed_through": bool(gap.min() < 0)})
    return out


def guard_cost():
    n, r = 8000, 0.5
    box = dk.build.box_for(n, r, volume_fraction=0.2)
    rng = np.random.default_rng(1)
    x = dk.build.random_packing(n, r, box, seed=rng)
    mu = 2.0 * dk.build.random_directions(n, seed=rng)
    v = dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=rng)
    out = {}
    cases = {"dipoles + Kelvin-Voigt (benchmark scene)": [dk.KelvinVoigt(1000.0, 1.5)],
             "dipoles + Hertz with friction": [dk.Hertz(1e6, 0.3, 0.5, friction=dk.Friction(0.3))],
             "dipoles alone (closest pair by cell list)": []}
    for label, laws in cases.items():
        p = dk.Particles(position=x, velocity=v, radius=r, mass=1.0, dipole=mu)
        scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0)] + laws, box=box)
        integrator = dk.VelocityVerlet(1e-3)
        start = time.perf_counter()
        with contextlib.suppress(ValueError):
            guards.before_stepping(scene, integrator)
        before = time.perf_counter() - start
        guards.while_stepping(scene, integrator)
        times = []
        for _ in range(30):
            start = time.perf_counter()
            guards.while_stepping(scene, integrator)
            times.append(time.perf_counter() - start)
        out[label] = {"while_stepping_ms": 1e3 * float(np.median(times)), "before_stepping_ms": 1e3 * before}
    return out


def main():
    results = {"pendulum": pendulum(), "hessian_bound_over_largest_eigenvalue": hessian_ratios(),
               "spins": spins(), "hertz_steps_per_contact": hertz_steps(), "snaps": snaps(),
               "guard_cost_N8000": guard_cost()}
    path = HERE / "results" / "stability.json"
    path.write_text(json.dumps(results, indent=1) + "\n")
    print(json.dumps(results, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
