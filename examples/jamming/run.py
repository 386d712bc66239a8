"""Jamming by compression: a gas of spheres squeezed in a shrinking periodic box until it is rigid.

    python examples/jamming/run.py [--output DIR] [--spheres N] [--rate R] [--quick]

A bidisperse gas (half the spheres of diameter 1, half 1.4, as O'Hern et al. used) fills a periodic box
at volume fraction 0.3. The box then shrinks at the same engineering strain rate along x, y and z
(``dk.Deform``: the spheres are remapped affinely after every step, their velocities left alone) while a
``dk.StressSeries`` records the pressure. While the spheres are a gas, the pressure is a small
collisional one; once they form a contact network spanning the box it rises steeply, linearly in the
volume fraction for these linear (Kelvin-Voigt) contacts: p = K (phi - phi_J). The jamming fraction
phi_J is where that line meets p = 0. Frictionless spheres jam at random close packing, phi_J = 0.639
(O'Hern, Silbert, Liu, Nagel, Phys. Rev. E 68, 011306 (2003), 3-D bidisperse harmonic spheres); with
Coulomb friction mu = 0.5 the packing holds at a looser fraction, phi_J = 0.58-0.59 (Silbert, Soft Matter
6, 2918 (2010), fig. 1). A run stops once its pressure passes a few per cent of the contacts' stiffness
per diameter (typical overlaps of 3-5 % then: demkit notes them as soft contacts).

Writes into DIR (default ``output/`` next to this script) ``pressure.png`` (the pressure against the
volume fraction, both runs, with the fitted lines), ``pressure.csv`` and ``packing.png`` (the frictional
packing at the end, coloured by each sphere's number of contacts), and prints phi_J of each run.

Units: the small spheres' diameter d = 1 and mass 1; contacts k = 1e4 (the time unit is the mass over
the stiffness's square root times 100), damped, so that the gas cools as it is squeezed.
"""
import argparse
import csv
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
STIFFNESS = 1e4
START = 0.3  # the gas's volume fraction at the start
STOP = 0.02 * STIFFNESS  # the pressure at which a run stops (k / d units)


def gas(n, seed):
    """(particles, box side): n spheres, half of radius 0.5 and half 0.7, at random in a cube at START."""
    radius = np.where(np.arange(n) % 2 == 0, 0.5, 0.7)
    volume = float(np.sum(4.0 / 3.0 * np.pi * radius ** 3))
    side = (volume / START) ** (1.0 / 3.0)
    position = dk.build.random_packing(n, radius, dk.Box(side, periodic=True), seed=seed)
    return dk.Particles(position=position, velocity=np.zeros((n, 3)), radius=radius, mass=(radius / 0.5) ** 3,
                        angular_velocity=np.zeros((n, 3))), side, volume


def compress(n, rate, friction, seed, samples=400):
    """Squeeze the gas at ``rate`` (< 0) until its pressure passes STOP; returns (volume fractions,
    pressures, the trajectory of the last stretch of the run)."""
    particles, side, volume = gas(n, seed)
    law = dk.KelvinVoigt(STIFFNESS, 30.0, friction=dk.Friction(friction) if friction else None)
    box = dk.Box(side, periodic=True, deform=dk.Deform(x=rate, y=rate, z=rate))
    scene = dk.Scene(particles, [law], box=box)
    end = (1.0 - (START / 0.75) ** (1.0 / 3.0)) / -rate  # (the time the box reaches 0.75: never)
    series = dk.StressSeries(every=end / samples)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1.5e-3), writers=[series])
    while sim.time < end:
        trajectory = sim.run(end / 40, record_every=end / 40, progress=False)
        if np.trace(series.pressure_tensor[-1]) / 3.0 > STOP:
            break
    fraction = volume / np.array([box.volume_at(t) for t in series.time])
    return fraction, np.trace(series.pressure_tensor, axis1=1, axis2=2) / 3.0, trajectory


def jamming_fraction(fraction, pressure):
    """(phi_J, K): the line p = K (phi - phi_J) fitted to the samples above a tenth of the last pressure."""
    rigid = pressure > 0.1 * pressure[-1]
    slope, intercept = np.polyfit(fraction[rigid], pressure[rigid], 1)
    return float(-intercept / slope), float(slope)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--spheres", type=int, default=1000, help="number of spheres")
    parser.add_argument("--rate", type=float, default=-0.002, help="the box's strain rate along each axis (< 0)")
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument("--quick", action="store_true", help="250 spheres, five times faster (a test's run)")
    args = parser.parse_args(argv)
    if args.quick:
        args.spheres, args.rate = 250, -0.01
    if not args.rate < 0.0:
        raise SystemExit(f"--rate must be negative (a shrinking box), got {args.rate}")
    out = args.output
    out.mkdir(parents=True, exist_ok=True)
    results, curves = {}, {}
    for friction in (0.0, 0.5):
        fraction, pressure, trajectory = compress(args.spheres, args.rate, friction, args.seed)
        phi_j, slope = jamming_fraction(fraction, pressure)
        curves[friction] = (fraction, pressure, phi_j, slope)
        results[str(friction)] = {"phi_J": phi_j, "slope": slope, "final_fraction": float(fraction[-1]),
                                  "final_pressure": float(pressure[-1])}
        print(f"friction {friction:g}: jams at phi_J = {phi_j:.3f} (p = {slope:.4g} (phi - phi_J) above it; "
              f"stopped at phi = {fraction[-1]:.3f}, p = {pressure[-1]:.4g})")
    table = out / "pressure.csv"
    with open(table, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["friction", "volume_fraction", "pressure"])
        for friction, (fraction, pressure, _, _) in curves.items():
            w.writerows([friction, f, p] for f, p in zip(fraction, pressure))
    figure = out / "pressure.png"
    plot(curves, figure)
    packing = out / "packing.png"
    try:
        dk.viz.snapshot(trajectory, packing, color_by="contacts", trail=0)
    except dk.viz.RenderingUnavailable as why:
        print(f"no picture: {why}")
    print("O'Hern et al. (2003): frictionless phi_J = 0.639; Silbert (2010): mu = 0.5, phi_J = 0.58-0.59")
    return {"results": results, "figure": str(figure), "table": str(table), "picture": str(packing)}


def plot(curves, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for (friction, (fraction, pressure, phi_j, slope)), colour in zip(curves.items(), ("C0", "C3")):
        ax.plot(fraction, pressure / STIFFNESS, color=colour, label=f"friction {friction:g}: phi_J = {phi_j:.3f}")
        line = np.linspace(phi_j, fraction[-1], 20)
        ax.plot(line, slope * (line - phi_j) / STIFFNESS, "--", color=colour, lw=1)
    ax.axvline(0.639, color="0.5", lw=0.8, ls=":", label="O'Hern et al. 2003: 0.639")
    ax.set_xlabel("volume fraction phi")
    ax.set_ylabel("pressure p d / k")
    ax.set_xlim(0.5, None)
    ax.set_ylim(0, None)
    ax.legend(frameon=False, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
