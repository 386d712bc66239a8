"""What the energy-balance drift of a dissipative run measures: the trajectory's error or the
bookkeeping of the dissipated energy (issue 42). Writes benchmarks/results/dissipation_order.json.

Three contacts with independent truths, each run with velocity Verlet and Euler-Cromer (and RK4 where no
friction spring is kept) at 10 ... 320 steps per contact time t_c:

* ``kelvin_voigt``: two spheres head on, linear spring-dashpot (k = 1000, c = 3, m = 1, damping
  ratio 0.067). Truth: the restitution coefficient of the linear oscillator,
  e = exp(-pi zeta / sqrt(1 - zeta^2)), and the energy it dissipates, m* v^2 (1 - e^2) / 2.
* ``sliding_to_rolling``: a sphere resting on a wall under gravity, launched sideways without spin,
  Coulomb friction (mu = 0.3, Kelvin-Voigt normal contact). Truth: it ends rolling at 5/7 of its
  launch speed (angular momentum about a point of the wall is conserved; with the lever arm
  R - delta of the resting overlap, 1 / (1 + 2 R^2 / (5 (R - delta)^2))) having dissipated
  m v0^2 / 7 (m v0^2 (1 - v / v0) / 2); here t_c is half the normal contact's period.
* ``oblique_friction``: two spheres meeting off centre (impact parameter 0.6 R), Kelvin-Voigt with
  Coulomb friction (mu = 0.5). Truth: the same collision at 2560 steps per contact.

And ``frictional_gas``: the issue's 200-sphere gas with friction (mu = 0.8), whose balance drifted
by 20 % at half the largest safe step, against a run 64 times finer.

For each impact: the balance |total + dissipated - initial| / dissipated at the end, the error of the
observable against the truth, and the dissipated energy's error against the truth, relative to it;
the orders are fitted between successive halvings. A balance that shrinks at the order of the true
error and has its size measures the trajectory; one much larger than the true error measures the
bookkeeping.

    python benchmarks/bench_dissipation_order.py
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

import demkit as dk

RESULTS = Path(__file__).resolve().parent / "results" / "dissipation_order.json"
STEPS_PER_CONTACT = (10, 20, 40, 80, 160, 320)
K, C, M, R = 1000.0, 3.0, 1.0, 0.5


def kelvin_voigt(integrator, steps):
    mstar = M / 2
    zeta = C / (2 * math.sqrt(K * mstar))
    tc = math.pi / (math.sqrt(K / mstar) * math.sqrt(1 - zeta ** 2))
    e_true = math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2))
    p = dk.Particles(position=[[-0.6, 0, 0], [0.6, 0, 0]], velocity=[[1.0, 0, 0], [-1.0, 0, 0]], radius=R, mass=M)
    traj = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(K, C)]), integrator(tc / steps)).run(0.3 + 3 * tc,
                                                                                         record_every=0.3 + 3 * tc)
    e = p.velocity[1, 0]
    return traj, e - e_true, 0.5 * mstar * 4.0 * (1 - e_true ** 2)


def sliding_to_rolling(integrator, steps, v0=1.0, g=1.0, mu=0.3):
    tc = math.pi / math.sqrt(K / M)  # half a period of the normal contact
    z = R - M * g / K  # resting at the overlap that holds its weight
    p = dk.Particles(position=[[0, 0, z]], velocity=[[v0, 0, 0]], radius=R, mass=M)
    law = dk.KelvinVoigt(K, C, friction=dk.Friction(mu))
    scene = dk.Scene(p, [dk.Wall((0, 0, 0), (0, 0, 1), contact=law), dk.Gravity((0, 0, -g))])
    duration = 3.0 * v0 / (mu * g)  # sliding stops after 2 v0 / (7 mu g)
    traj = dk.Simulation(scene, integrator(tc / steps)).run(duration, record_every=duration)
    # the friction acts at the contact point, a = R - delta from the centre, and rolling is v = a w:
    # m v + (I / a) w = m v0 gives v / v0 = 1 / (1 + I / (m a^2)) (5/7 for a = R), and the energy
    # lost is m v0^2 (1 - v / v0) / 2
    ratio = 1.0 / (1.0 + 0.4 * (R / z) ** 2)  # a = R - delta = z, the height of the centre
    return traj, p.velocity[0, 0] / v0 - ratio, 0.5 * M * v0 ** 2 * (1.0 - ratio)


def oblique_friction(integrator, steps, truth=None):
    mstar = M / 2
    zeta = C / (2 * math.sqrt(K * mstar))
    tc = math.pi / (math.sqrt(K / mstar) * math.sqrt(1 - zeta ** 2))
    p = dk.Particles(position=[[-0.6, -0.15, 0], [0.6, 0.15, 0]], velocity=[[1.0, 0, 0], [-1.0, 0, 0]], radius=R,
                     mass=M)
    law = dk.KelvinVoigt(K, C, friction=dk.Friction(0.5))
    traj = dk.Simulation(dk.Scene(p, [law]), integrator(tc / steps)).run(0.3 + 3 * tc, record_every=0.3 + 3 * tc)
    state = np.concatenate([p.velocity.ravel(), R * p.angular_velocity.ravel()])
    if truth is None:
        return traj, state, None
    return traj, float(np.abs(state - truth[0]).max()), truth[1]


def frictional_gas(steps_down=(1, 2, 4, 8, 16), reference=64, n=200, mu=0.8, duration=5.0):
    """The issue's frictional gas: 200 spheres (radius 0.5, mass 1) in a periodic box at volume
    fraction 0.3, Maxwellian velocities, Kelvin-Voigt (1000, 1.5) with Coulomb friction mu = 0.8,
    velocity Verlet at dt0 / k (dt0: half the largest safe step) against dt0 / 64: the run's balance
    (as the end-of-run note measures it), and the end's kinetic + rotational energy and the booked
    dissipated energy against the fine run's, over the energy scale. Many-body collisions are
    chaotic: the kinetic energies of two fine runs differ too (the floor)."""
    R = 0.5
    box = dk.build.box_for(n, R, 0.3)
    rng = np.random.default_rng(1)
    start = dk.Particles(position=dk.build.random_packing(n, R, box, seed=2), velocity=rng.normal(size=(n, 3)),
                         radius=R, mass=M)
    law = dk.KelvinVoigt(K, 1.5, friction=dk.Friction(mu))
    dt0 = 0.5 * dk.guards.largest_safe_step(dk.Scene(start.copy(), [law], box=box))[0]
    out = {}
    for k in (*steps_down, reference):
        sim = dk.Simulation(dk.Scene(start.copy(), [law], box=box), dk.VelocityVerlet(dt0 / k), notes=False)
        t = time.perf_counter()
        traj = sim.run(duration, record_every=duration / 50, progress=False)
        e = traj.energy
        scale = float(np.max(e["kinetic"] + e["rotational"] + np.abs(e["contact"])))
        out[k] = {"dt": dt0 / k, "balance": sim.statistics["energy_drift"], "motion": e["kinetic"][-1] + e["rotational"][-1],
                  "dissipated": e["dissipated"][-1], "scale": scale, "wall_s": time.perf_counter() - t}
    fine = out.pop(reference)
    rows = []
    for k, r in out.items():
        rows.append({"dt_fraction_of_half_safe": 1.0 / k, "balance": r["balance"],
                     "motion_error": abs(r["motion"] - fine["motion"]) / fine["scale"],
                     "dissipated_error": abs(r["dissipated"] - fine["dissipated"]) / fine["scale"], "wall_s": r["wall_s"]})
    return rows, fine["balance"]


def measure(case, integrator):
    rows = []
    truth = None
    if case is oblique_friction:
        traj, state, _ = case(integrator, 2560)
        truth = (state, float(traj.energy["dissipated"][-1]))
    for steps in STEPS_PER_CONTACT:
        t = time.perf_counter()
        traj, error, dissipated_true = case(integrator, steps) if truth is None else case(integrator, steps, truth)
        e = traj.energy
        dissipated = float(e["dissipated"][-1])
        rows.append({"steps_per_contact": steps,
                     "balance": abs(e["total"][-1] + dissipated - e["total"][0]) / dissipated,
                     "observable_error": abs(float(error)),
                     "dissipated_error": abs(dissipated - dissipated_true) / dissipated_true,
                     "wall_s": time.perf_counter() - t})
    for key in ("balance", "observable_error", "dissipated_error"):
        orders = [math.log2(a[key] / b[key]) if a[key] > 0 and b[key] > 0 else None for a, b in zip(rows, rows[1:])]
        for row, order in zip(rows[1:], orders):
            row[f"order_{key}"] = order
    return rows


def main():
    out = {"date": time.strftime("%Y-%m-%d %H:%M"), "cases": {}}
    for case in (kelvin_voigt, sliding_to_rolling, oblique_friction):
        methods = (("VelocityVerlet", dk.VelocityVerlet), ("EulerCromer", dk.EulerCromer))
        if case is kelvin_voigt:  # RK4 cannot carry friction's per-contact springs
            methods += (("RK4", dk.RK4),)
        for name, integrator in methods:
            rows = measure(case, integrator)
            out["cases"][f"{case.__name__}/{name}"] = rows
            print(case.__name__, name)
            for r in rows:
                print("  {steps_per_contact:4d} steps/t_c: balance {balance:.2e} ({o1}), observable {observable_error:.2e} "
                      "({o2}), dissipated {dissipated_error:.2e} ({o3})".format(
                          **r, o1=_fmt(r.get("order_balance")), o2=_fmt(r.get("order_observable_error")),
                          o3=_fmt(r.get("order_dissipated_error"))), flush=True)
    rows, floor = frictional_gas()
    out["cases"]["frictional_gas/VelocityVerlet"] = {"rows": rows, "reference_balance": floor}
    print("frictional_gas VelocityVerlet (against dt0/64, whose own balance is %.2g)" % floor)
    for r in rows:
        print("  dt0 x {dt_fraction_of_half_safe:<7g}: balance {balance:.2e}, kinetic + rotational {motion_error:.2e}, "
              "dissipated {dissipated_error:.2e} (of the energy scale)".format(**r), flush=True)
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=1))
    print("written", RESULTS)


def _fmt(order):
    return "order -" if order is None else f"order {order:.2f}"


if __name__ == "__main__":
    main()
