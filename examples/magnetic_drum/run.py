"""A rotating drum of magnetisable spheres: the angle of the free surface against the field.

    python examples/magnetic_drum/run.py [--output DIR] [--bond B1,B2,...] [--direction D1,D2] [--n N] [--length L] [--quick]

Soft magnetic spheres (susceptibility 1000, as steel) half fill a drum that turns slowly about a
horizontal axis. Without a field they roll down the free surface at their dynamic angle of repose; a
uniform field magnetises them, and the attraction of the induced moments (a cohesion that the field
tunes, with no change of the grains) holds the bed up to a steeper angle. The drum is periodic along
its axis (a slice of a long drum: no end caps). Writes into DIR (default ``output/`` next to this
script) ``angle.png`` (the angle against the magnetic Bond number), ``angle.csv``, ``beds.png`` (a
picture of each bed at the end) and a VTK series of each run with the drum (``vtk_bond_<B>/``), and
prints a summary.

Units: sphere diameter d = 1 (radii 0.45-0.55), mass of a d = 1 sphere 1, gravity g = 1 (time unit
sqrt(d/g)). The Dipole prefactor is 1, so a sphere of radius R in a field B0 carries the moment
m = beta R^3 B0 (beta = chi / (chi + 3) = 0.997). The magnetic Bond number Bo is the pull of two
touching unit spheres head to tail, 6 m^2 / d^4, over one sphere's weight, with the moments of lone
spheres (their mutual induction makes the real pull about 1.8 times that): B0 = 8 sqrt(Bo / 6).

The free surface's angle: for a bed with a flat surface, the line from the drum's axis to the bed's
centre of mass is perpendicular to the surface, so the surface's slope is the angle of that line from
the vertical, measured over the last part of the run (mean and standard deviation of the frames).
"""
import argparse
import csv
import math
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
CHI = 1000.0
SAMPLE = 0.25  # time between the measuring samples
FIELD_WORDS = {"across": "across the drum", "axis": "along the axis", "up": "vertical"}
DIRECTIONS = {"across": (1.0, 0.0, 0.0), "axis": (0.0, 0.0, 1.0), "up": (0.0, 1.0, 0.0)}
BETA = CHI / (CHI + 3.0)


def field_for(bond):
    """The field B0 that gives lone unit spheres the Bond number ``bond`` (module docstring)."""
    return 8.0 * math.sqrt(bond / 6.0)


def fill(drum_radius, length, n, seed):
    """n spheres of radii 0.45-0.55 on a loose lattice (spacing 1.15 or more, jittered) in the lowest part of a
    drum centred on x = y = 0, periodic along z with ``length``; returns (positions, radii)."""
    rng = np.random.default_rng(seed)
    g = np.arange(-drum_radius, drum_radius, 1.15)
    count = int(length // 1.15)  # layers along the periodic axis, evenly spaced (their copies too)
    if count < 1:
        raise ValueError(f"the drum's length must be at least 1.15 sphere diameters, got {length}")
    layers = (np.arange(count) + 0.5) * (length / count)
    x, y, z = (a.ravel() for a in np.meshgrid(g, g, layers, indexing="ij"))
    inside = np.hypot(x, y) < drum_radius - 0.7
    x, y, z = x[inside], y[inside], z[inside]
    if len(x) < n:
        raise ValueError(f"a drum of radius {drum_radius} and length {length} holds at most {len(x)} spheres here, asked {n}")
    lowest = np.argsort(y + 1e-6 * x, kind="stable")[:n]
    pos = np.stack([x[lowest], y[lowest], z[lowest]], axis=1) + rng.uniform(-0.04, 0.04, (n, 3))
    return pos, rng.uniform(0.45, 0.55, n)


def run_drum(bond, direction, drum_radius, length, n, omega, settle, measure, seed, folder):
    """One drum: spheres in a field of Bond number ``bond`` along ``direction``; the drum turns at
    ``omega`` for ``settle`` + ``measure`` time units. Returns the surface's angle in degrees at each
    sample of the measuring time (every SAMPLE), the torques of :func:`torque_balance` there, the scene
    at the end and the drum's centre."""
    pos, radius = fill(drum_radius, length, n, seed)
    centre = np.array([drum_radius + 1.0, drum_radius + 1.0, 0.0])  # the box's open axes: [0, 2 R_c + 2)
    box = dk.Box((2 * drum_radius + 2.0, 2 * drum_radius + 2.0, length), periodic=(False, False, True))
    magnetisable = {"susceptibility": CHI} if bond > 0 else {}  # (no field: plain spheres, no moments)
    p = dk.Particles(position=pos + centre, radius=radius, mass=(2 * radius) ** 3, velocity=np.zeros((n, 3)),
                     angular_velocity=np.zeros((n, 3)), **magnetisable)
    # contacts stiffer as the field grows: the pull of two touching magnetised spheres (up to about 1.8 Bo
    # weights, more in a chain) and the energy they release snapping together must be held within a
    # fraction of a radius (the run's guards check it); damped to a restitution of 0.3; friction 0.5.
    # The time step follows: 1.5e-3 at the softest, 30 steps a contact
    stiffness = 2e3 * max(1.0, bond / 4.0)
    dt = 1.5e-3 * math.sqrt(2e3 / stiffness)
    contact = dk.KelvinVoigt(stiffness, 2 * 0.36 * math.sqrt(stiffness * 0.5), friction=dk.Friction(0.5))
    interactions = [contact, dk.Gravity((0, -1.0, 0)),
                    dk.Cylinder(centre, (0, 0, 1), drum_radius, angular_velocity=omega)]
    b = None
    if bond > 0:
        b = field_for(bond) * np.array(DIRECTIONS[direction])
        # the moments' field cut off at 3 d, switched off smoothly (the solve needs a smooth field)
        interactions += [dk.Dipole(prefactor=1.0, cutoff=min(3.0, 0.45 * length), switch_width=0.5),
                         dk.UniformField(b)]
    scene = dk.Scene(p, interactions, box=box)
    sampler = Sampler(settle, centre, b)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt), writers=[dk.VTKWriter(folder, every=1.0, trails=False, overwrite=True),
                                                              sampler])  # (overwrite: the example's own folder)
    sim.run(settle + measure, progress=False)
    sim.close()
    return np.array(sampler.angles), np.array(sampler.torques), scene, centre


class Sampler:
    """A writer (called every SAMPLE time units, like the VTK writer every 1.0) that, once the drum has
    turned for ``start`` time units, records the surface's angle and the torques on the bed."""

    every = SAMPLE

    def __init__(self, start, centre, field):
        self.start, self.centre, self.field = start, centre, field
        self.times, self.angles, self.torques = [], [], []

    def open(self, simulation):
        effects = simulation.scene.effects
        self.drum = [k for k, e in enumerate(effects) if isinstance(e, dk.Cylinder)][0]  # its number in contacts().wall

    def close(self):
        pass

    def write(self, simulation):
        scene = simulation.scene
        if scene.time < self.start + 0.5 * SAMPLE or (self.times and scene.time <= self.times[-1]):
            return
        p = scene.particles
        cm = ((p.position[:, :2] - self.centre[:2]) * p.mass[:, None]).sum(axis=0) / p.mass.sum()
        # the drum turns +z (counter-clockwise seen from +z): its bottom moves towards +x and lifts the
        # bed up its +x side, so the centre of mass sits at +x of the lowest point
        self.times.append(scene.time)
        self.angles.append(math.degrees(math.atan2(cm[0], -cm[1])))
        self.torques.append(torque_balance(scene, self.drum, self.centre, cm, p.mass.sum(), self.field))


def torque_balance(scene, drum, centre, cm, mass, field):
    """The torques about the drum's axis (z) on the whole bed at this moment: (the drum's, number
    ``drum`` in ``scene.effects``, through its contacts, gravity's, -M g x_cm, and the field's on the
    moments, sum of (m x B0)_z). The spheres' own forces (contacts between them, dipoles) exert none on
    the bed as a whole."""
    c = scene.contacts()
    on = c.wall == drum
    arm = c.point[on, :2] - centre[:2]
    wall = float(np.sum(arm[:, 0] * c.force[on, 1] - arm[:, 1] * c.force[on, 0]))
    moments = scene.particles.dipole
    magnetic = float(np.cross(moments, field)[:, 2].sum()) if moments is not None and field is not None else 0.0
    return wall, -mass * cm[0], magnetic


def draw(results, folder):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plain = [r for r in results if r["bond"] == 0]
    fig, ax = plt.subplots(figsize=(5.2, 3.6), dpi=120)
    for direction in dict.fromkeys(r["direction"] for r in results if r["bond"] > 0):
        rows = plain + [r for r in results if r["direction"] == direction and r["bond"] > 0]
        ax.errorbar([r["bond"] for r in rows], [r["angle"] for r in rows], yerr=[r["spread"] for r in rows],
                    fmt="o-", capsize=3, label=f"field {FIELD_WORDS[direction]}")
    ax.set_xlabel("magnetic Bond number Bo (pull of two lone spheres / weight)")
    ax.set_ylabel("free surface angle (degrees)")
    ax.set_title("magnetisable spheres in a rotating drum")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(folder / "angle.png")
    plt.close(fig)
    fig, axes = plt.subplots(1, len(results), figsize=(2.6 * len(results), 3.0), dpi=110, squeeze=False)
    for ax, r in zip(axes[0], results):
        x, y = r["xy"].T
        ax.add_patch(plt.Circle((0, 0), r["drum"], fill=False, color="0.3"))
        for xi, yi, ri in zip(x, y, r["radius"]):
            ax.add_patch(plt.Circle((xi, yi), ri, color="tab:blue", alpha=0.6, lw=0))
        # the surface at the measured angle: the chord whose normal n = (-sin t, cos t) points out of the
        # bed, at the height n.x the top spheres reach (the 80th percentile of n.x + r)
        t = math.radians(r["angle"])
        normal, along = np.array([-math.sin(t), math.cos(t)]), np.array([math.cos(t), math.sin(t)])
        h = float(np.percentile(r["xy"] @ normal + r["radius"], 80))
        half = math.sqrt(max(r["drum"] ** 2 - h * h, 0.0))
        ends = np.array([h * normal - half * along, h * normal + half * along])
        ax.plot(ends[:, 0], ends[:, 1], "k--", lw=0.8)
        ax.set_xlim(-r["drum"] - 0.5, r["drum"] + 0.5)
        ax.set_ylim(-r["drum"] - 0.5, r["drum"] + 0.5)
        ax.set_aspect("equal")
        ax.set_axis_off()
        label = "no field" if r["bond"] == 0 else f"Bo {r['bond']:g} {r['direction']}"
        ax.set_title(f"{label}: {r['angle']:.1f}°", fontsize=9)
    fig.tight_layout()
    fig.savefig(folder / "beds.png")
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output")
    parser.add_argument("--bond", default="0,2,4,8", help="magnetic Bond numbers, comma-separated (0: no field)")
    parser.add_argument("--direction", default="across,axis",
                        help="the field's directions, comma-separated: across (horizontal, across the drum), "
                             "axis (along the drum's axis), up (vertical)")
    parser.add_argument("--n", type=int, default=300, help="spheres")
    parser.add_argument("--length", type=float, default=4.0, help="the drum's length along its (periodic) axis, in d")
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument("--quick", action="store_true", help="80 spheres in a small drum, two fields, short runs (tests)")
    args = parser.parse_args(argv)
    try:
        bonds = sorted({float(b) for b in args.bond.split(",")})
    except ValueError:
        raise SystemExit(f"--bond: comma-separated numbers, got {args.bond!r}") from None
    if any(not math.isfinite(b) or b < 0 for b in bonds):
        raise SystemExit(f"--bond: Bond numbers must be finite and >= 0, got {args.bond}")
    directions = list(dict.fromkeys(args.direction.split(",")))
    if any(d not in FIELD_WORDS for d in directions):
        raise SystemExit(f"--direction: choose among {', '.join(FIELD_WORDS)}, got {args.direction!r}")
    if args.n < 1:
        raise SystemExit(f"--n: at least one sphere, got {args.n}")
    if args.quick:
        drum_radius, length, n, settle, measure, bonds, directions = 5.0, 3.0, 80, 6.0, 6.0, [0.0, 4.0], ["across"]
    else:
        drum_radius, length, n, settle, measure = 8.0, args.length, args.n, 40.0, 60.0
    omega = 0.035 * math.sqrt(8.0 / drum_radius)  # Froude number omega^2 R_c / g = 0.01: the rolling regime
    args.output.mkdir(parents=True, exist_ok=True)
    print(f"{n} magnetisable spheres (chi {CHI:g}) in a drum of radius {drum_radius:g} d, {length:g} d long "
          f"(periodic), turning at {omega:.4f} (Froude number {omega**2 * drum_radius:.3f})")
    results = []
    runs = [(0.0, None)] if 0.0 in bonds else []
    runs += [(bond, direction) for direction in directions for bond in bonds if bond > 0]
    for bond, direction in runs:
        folder = args.output / (f"vtk_bond_{bond:g}" + (f"_{direction}" if direction else ""))
        angle, torque, scene, centre = run_drum(bond, direction, drum_radius, length, n, omega, settle, measure,
                                                args.seed, folder)
        p = scene.particles
        wall, gravity, field = torque.mean(axis=0)
        moments = np.linalg.norm(p.dipole, axis=1) if p.dipole is not None else np.zeros(n)
        lone = BETA * np.mean(p.radius**3) * field_for(bond)
        results.append({"bond": bond, "direction": direction or "none", "field": field_for(bond),
                        "angle": float(angle.mean()), "spread": float(angle.std()),
                        "torque_wall": wall, "torque_gravity": gravity, "torque_field": field,
                        "moment": float(moments.mean()), "lone": float(lone),
                        "xy": p.position[:, :2] - centre[:2], "radius": p.radius, "drum": drum_radius})
        where = f" {FIELD_WORDS[direction]}" if direction else ""
        print(f"Bo {bond:g}{where} (B0 {field_for(bond):.2f}): surface angle {angle.mean():.1f} +- {angle.std():.1f} "
              f"degrees; mean moment {moments.mean():.3f} (lone sphere of mean size {lone:.3f})", flush=True)
        print(f"      torques about the axis, averaged: the drum's {wall:.1f}, gravity's {gravity:.1f}, the field's "
              f"{field:.1f}; unbalanced {wall + gravity + field:+.1f} ({abs(wall + gravity + field) / abs(gravity):.1%} "
              f"of gravity's)", flush=True)
    with open(args.output / "angle.csv", "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["bond_number", "direction", "field", "angle_degrees", "spread_degrees", "torque_drum",
                      "torque_gravity", "torque_field", "mean_moment", "lone_moment"])
        for r in results:
            out.writerow([r["bond"], r["direction"], r["field"], r["angle"], r["spread"], r["torque_wall"],
                          r["torque_gravity"], r["torque_field"], r["moment"], r["lone"]])
    draw(results, args.output)
    print("wrote", args.output / "angle.png", args.output / "beds.png", args.output / "angle.csv")
    return results


if __name__ == "__main__":
    main()
