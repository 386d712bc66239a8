"""The flow curve of a sheared magnetic monolayer, with and without a field: a yield stress from chains.

    python examples/magnetorheology/run.py [--output DIR] [--quick]

A monolayer of frictional spheres (area fraction 0.35) fills a periodic box sheared by Lees-Edwards
sliding images (dk.Shear: flow along x, gradient along y). With the field on, every sphere carries a
moment held along the field (y, across the flow) by a strong applied field: the spheres chain along
the field, the chains span the gradient, and the flow tilts them until they break and re-form. The
shear stress then stays finite as the rate falls: a field-induced yield stress. Without the field
the same spheres are a dry granular gas, whose stress falls as the square of the rate (Bagnold).
Each run shears to a strain of 10 and measures the stress during its second half (dk.StressSeries):
the spheres start moving with the imposed flow, and collisions build the gas's stress up over the
first strains (about 5 at the fastest rate).

Writes into DIR (default ``output/`` next to this script) ``flow_curve.csv`` and ``flow_curve.png``
(shear stress against rate, both cases, with standard errors), ``chains.png`` (the field-on
monolayer at the end of the slowest run: chains tilted with the flow) and prints the table.

Units: sphere diameter d = 1, mass m = 1, dipole prefactor 1 and moment 1 (two spheres touching head
to tail: energy -2, pull 6); stress per layer (force per length: the box's depth is one diameter).
"""
import argparse
import csv
import math
import sys
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
R = 0.5
FIELD = 20.0  # the applied field B: a moment's energy m B = 20, ten times a chain bond's 2


def monolayer(n, rate, seed):
    """n spheres on a jittered square grid (spacing 1.5 d: area fraction 0.35) in the plane z = R of a
    box periodic along x and y, moving with the imposed flow v_x = rate (y - L/2)."""
    side = int(math.ceil(math.sqrt(n)))
    spacing = 1.5
    length = side * spacing
    rng = np.random.default_rng(seed)
    k = np.arange(side * side)[:n]
    position = np.stack([(k % side + 0.5) * spacing, (k // side + 0.5) * spacing, np.full(n, R)], axis=1)
    position[:, :2] += rng.uniform(-0.2, 0.2, (n, 2))
    velocity = 0.05 * rng.normal(size=(n, 3))
    velocity[:, 2] = 0.0
    velocity[:, 0] += rate * (position[:, 1] - 0.5 * length)
    return position, velocity, length


def scene(n, rate, field, seed=1):
    """The sheared monolayer; ``field``: moments along y held by the applied field, else none."""
    position, velocity, length = monolayer(n, rate, seed)
    box = dk.Box((length, length, 2 * R), periodic=(True, True, False), shear=dk.Shear(rate, flow="x", gradient="y"))
    dipole = np.tile([0.0, 1.0, 0.0], (n, 1)) if field else None
    p = dk.Particles(position=position, velocity=velocity, radius=R, mass=1.0, dipole=dipole)
    # contacts: the pull of a chain bond, 6, squeezes by 0.06 % of d, the fastest impacts (rate 1) by a
    # few percent; restitution 0.5; friction 0.5
    stiffness, e = 1e4, 0.5
    zeta = -math.log(e) / math.hypot(math.pi, math.log(e))
    law = dk.KelvinVoigt(stiffness, 2 * zeta * math.sqrt(stiffness * 0.5), friction=dk.Friction(0.5))
    interactions = [law]
    if field:
        interactions += [dk.Dipole(prefactor=1.0, cutoff=3.0, switch_width=0.5), dk.UniformField((0.0, FIELD, 0.0))]
    return dk.Scene(p, interactions, box=box)


def flow_point(n, rate, field, strain, samples=64):
    """Shear to ``strain`` at ``rate``; the rheology over the second half (dk.StressSeries) and the end state."""
    s = scene(n, rate, field)
    duration = strain / rate
    series = dk.StressSeries(every=duration / samples)
    sim = dk.Simulation(s, dk.VelocityVerlet(0.5 * s.max_time_step()), writers=[series])
    traj = sim.run(duration, record_every=duration / 4, progress=False)
    result = series.rheology(after=0.5 * duration)
    result["steps_per_second"] = sim.statistics["steps_per_second"]
    return result, traj


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4.5))
    for field, style in ((True, "o-"), (False, "s--")):
        pts = [r for r in rows if r["field"] == field]
        rate = np.array([r["rate"] for r in pts])
        sigma = np.array([r["shear_stress"] for r in pts])
        error = np.nan_to_num(np.array([r["shear_stress_error"] for r in pts]))
        ax.errorbar(rate, sigma, yerr=error, fmt=style, capsize=3,
                    label=f"field on (m B = {FIELD:g})" if field else "no field")
    rate = np.array(sorted({r["rate"] for r in rows}))
    off = [r for r in rows if not r["field"]]
    if off:  # Bagnold's rate squared through the fastest point without field
        top = max(off, key=lambda r: r["rate"])
        ax.plot(rate, top["shear_stress"] * (rate / top["rate"]) ** 2, ":", color="grey", label="rate squared")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("shear rate (1 / time unit)")
    ax.set_ylabel("shear stress (force / length)")
    ax.set_title("sheared magnetic monolayer, area fraction 0.35")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    """Run the flow curve and write its files; returns the rows and the paths written, as a dict."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--n", type=int, default=256, help="number of spheres")
    parser.add_argument("--rates", type=float, nargs="+", default=[0.03, 0.1, 0.3, 1.0])
    parser.add_argument("--strain", type=float, default=10.0, help="strain of each run")
    parser.add_argument("--quick", action="store_true", help="100 spheres, two rates, strain 4 (for tests)")
    args = parser.parse_args([] if argv is None else argv)
    if args.quick:
        args.n, args.rates, args.strain = 100, [0.2, 1.0], 4.0
    args.output.mkdir(parents=True, exist_ok=True)

    rows, slowest = [], None
    print(f"{args.n} spheres, strain {args.strain:g} per run; shear stress over the second half of each run")
    print(f"{'rate':>8} {'field':>6} {'shear stress':>14} {'error':>10} {'N1':>10} {'pressure':>10} {'steps/s':>9}")
    for rate in sorted(args.rates):
        for field in (True, False):
            result, traj = flow_point(args.n, rate, field, args.strain)
            rows.append(dict(result, field=field))
            if field and slowest is None:
                slowest = traj
            print(f"{rate:8.3g} {'on' if field else 'off':>6} {result['shear_stress']:14.4g} "
                  f"{result['shear_stress_error']:10.2g} {result['n1']:10.3g} {result['pressure']:10.3g} "
                  f"{result['steps_per_second']:9.0f}")
    table = args.output / "flow_curve.csv"
    with open(table, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=["rate", "field", "shear_stress", "shear_stress_error", "viscosity",
                                               "viscosity_error", "n1", "n1_error", "n2", "n2_error", "pressure",
                                               "pressure_error", "steps_per_second"])
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, args.output / "flow_curve.png")
    on = [r for r in rows if r["field"]]
    off = [r for r in rows if not r["field"]]
    ratio = on[0]["shear_stress"] / off[0]["shear_stress"]
    print(f"at the lowest rate {on[0]['rate']:g} the field multiplies the shear stress by {ratio:.3g}")
    dk.viz.snapshot(slowest, args.output / "chains.png", color_by="contacts", view="xy")
    return {"rows": rows, "ratio": ratio, "table": str(table), "plot": str(args.output / "flow_curve.png"),
            "chains": str(args.output / "chains.png")}


if __name__ == "__main__":
    main(sys.argv[1:])
