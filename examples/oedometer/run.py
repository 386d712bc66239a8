"""Oedometric compression of a packing of magnetic spheres, with and without a field.

    python examples/oedometer/run.py [--output DIR] [--n-side K] [--layers L] [--field B] [--quick]

Spheres with permanent moments settle under gravity onto a floor in a box periodic across (no side
walls: the layer is confined sideways by its own copies, the oedometer's zero lateral strain), once
with their moments free and once in a vertical field that stands them up. A piston then comes down
on each settled pile (a new scene of its spheres) at a slow constant speed and presses it: the stress
on the piston against the strain of the pile is the packing's oedometric response. Writes into DIR
(default ``output/`` next to this script) ``stress_strain.png``, ``stress_strain.csv``, a VTK series
of each run with its walls (``vtk_field_<B>/``) and ``final.png``, and prints a summary.

Units: sphere diameter d = 1, mass m = 1, gravity g = 1 (time unit sqrt(d/g)). The dipole prefactor
is 1; a moment mu gives the pull of two touching spheres head to tail, 6 mu^2 / d^4, in units of their
weight: the magnetic Bond number Bo = 6 mu^2 (3 by default). A field B along z turns a moment with the
energy -mu B.

Checks printed (and asserted by tests/test_oedometer_example.py): before the piston touches, the floor
carries the spheres' weight (statics: the magnetic forces are internal); while the pile is pressed,
the floor carries the weight and the piston's push (a quasi-static compression: the spheres'
inertia takes a small part).
"""
import argparse
import csv
import math
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
R = 0.5  # sphere radius: diameter 1
SPACING = 1.1  # of the starting lattice across, and the box's side per sphere


def build(n_side, layers, moment, field, seed):
    """Spheres on a loose lattice above the floor (gaps of 0.1 d across, jittered by up to 0.05 d, and
    0.15 d up), their moments random (no field) or up (a field); the box, periodic across."""
    rng = np.random.default_rng(seed)
    k = np.arange(n_side * n_side * layers)
    across = SPACING * (0.5 + np.stack([k % n_side, (k // n_side) % n_side], axis=1))
    pos = np.column_stack([across, 0.6 + 1.15 * (k // n_side**2)])
    pos[:, :2] += rng.uniform(-0.05, 0.05, (len(k), 2))
    direction = rng.normal(size=(len(k), 3)) if field == 0.0 else np.tile([0.0, 0.0, 1.0], (len(k), 1))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    particles = dk.Particles(position=pos, radius=R, mass=1.0, dipole=moment * direction,
                             velocity=np.zeros((len(k), 3)))
    side = SPACING * n_side
    return particles, dk.Box((side, side, 4.0 * layers), periodic=(True, True, False))


def press(n_side, layers, moment, field, speed, settle, strain_max, seed, folder, dt=5e-4):
    """Settle the pile on the floor for ``settle`` time units, then press it with a piston that starts
    a quarter diameter above it; returns the pressing scene, rows of (time, piston height, piston
    force, floor force) every 0.05 time units of the pressing, and the floor's load when settled."""
    particles, box = build(n_side, layers, moment, field, seed)
    # contacts: stiff enough that the magnetic pull of two touching spheres, Bo m g, squeezes them by
    # 0.03 % of d (3e-4 Bo), damped to a restitution of 0.3 (the settling is over in ~10 time units),
    # Coulomb friction 0.4
    stiffness = 1e4
    damping = 2 * 0.36 * math.sqrt(stiffness * 0.5)
    interactions = [dk.KelvinVoigt(stiffness, damping, friction=dk.Friction(0.4)),
                    # dipoles cut at 3 d (at most 0.45 of the box across, for the minimum image), switched off smoothly
                    dk.Dipole(prefactor=1.0, cutoff=min(3.0, 0.45 * box.size[0]), switch_width=0.5),
                    dk.Gravity((0, 0, -1.0))]
    if field:
        interactions.append(dk.UniformField((0.0, 0.0, field)))
    floor = dk.Wall((0, 0, 0), (0, 0, 1))
    pile = dk.Scene(particles, interactions + [floor], box=box)
    dk.Simulation(pile, dk.VelocityVerlet(dt)).run(settle, progress=False)  # (5e-4: 45 steps a contact)
    settled = pile.contacts()
    carried = settled.normal_force[settled.wall == pile.effects.index(floor)].sum()
    # the piston: a new scene of the settled spheres (their contacts' friction springs start afresh: the pile
    # settles again in the 5 time units the piston takes to arrive)
    p = pile.particles
    start = p.position[:, 2].max() + R + 0.25
    piston = dk.Wall((0, 0, start), (0, 0, -1), velocity=(0, 0, -speed))
    floor = dk.Wall((0, 0, 0), (0, 0, 1))
    again = dk.Particles(position=p.position.copy(), velocity=p.velocity.copy(), radius=R, mass=1.0,
                         dipole=p.dipole.copy(), angular_velocity=p.angular_velocity.copy())
    scene = dk.Scene(again, interactions + [floor, piston], box=box)
    writer = dk.VTKWriter(folder, every=0.5, overwrite=True, trails=False)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt), writers=[writer])
    lid, ground = scene.effects.index(piston), scene.effects.index(floor)
    rows, touched = [], None  # (the piston's height when it first touched)
    while touched is None or (touched - rows[-1][1]) / touched <= strain_max:
        sim.run(0.05, progress=False)
        contacts = scene.contacts()
        push = contacts.normal_force[contacts.wall == lid].sum()
        weight_on_floor = contacts.normal_force[contacts.wall == ground].sum()
        rows.append((sim.time, start - speed * sim.time, push, weight_on_floor))
        if touched is None and push > 0.0:
            touched = rows[-1][1]
    sim.close()
    return scene, np.array(rows), carried


def curve(rows, area):
    """(strain, stress, h0, first) from the piston's first touch, record ``first`` at height h0: strain
    (h0 - h) / h0, stress push / area."""
    first = int(np.argmax(rows[:, 2] > 0.0))
    h0 = rows[first, 1]
    return (h0 - rows[first:, 1]) / h0, rows[first:, 2] / area, h0, first


def main(argv=None):
    """Run both piles, write and summarise; ``argv`` are command-line options (None: the defaults).
    Returns the summary numbers and the paths written, as a dict."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--n-side", type=int, default=6, help="spheres along each side of the periodic box")
    parser.add_argument("--layers", type=int, default=6, help="layers of spheres")
    parser.add_argument("--bond", type=float, default=3.0, help="magnetic Bond number 6 mu^2 (touching pull / weight)")
    parser.add_argument("--field", type=float, default=10.0, help="the vertical field of the second run")
    parser.add_argument("--speed", type=float, default=0.05, help="the piston's speed")
    parser.add_argument("--strain", type=float, default=0.03, help="press until this strain")
    parser.add_argument("--seed", type=int, default=2)
    parser.add_argument("--quick", action="store_true",
                        help="3 x 3 x 4 spheres, dt = 1e-3, to 2 %% strain (for tests)")
    args = parser.parse_args([] if argv is None else argv)
    settle, dt = 14.0, 5e-4
    if args.quick:
        args.n_side, args.layers, args.strain = 3, 4, 0.02
        dt = 1e-3
    args.output.mkdir(parents=True, exist_ok=True)
    moment = math.sqrt(args.bond / 6.0)
    area = (SPACING * args.n_side) ** 2
    results, curves = {}, {}
    for field in (0.0, args.field):
        folder = args.output / f"vtk_field_{field:g}"
        scene, rows, carried = press(args.n_side, args.layers, moment, field, args.speed, settle, args.strain,
                                     args.seed, folder, dt)
        n = len(scene.particles.radius)
        strain, stress, h0, first = curve(rows, area)
        before = rows[first - 1]  # the last record before the piston touched (first > 0: it starts above the pile)
        end = rows[-1]
        fraction = n * math.pi / 6 / (area * h0)
        at = {s: float(np.interp(s, strain, stress)) for s in (0.005, 0.01, 0.02)}
        results[field] = {"spheres": n, "height": float(h0), "volume_fraction": fraction,
                          "floor_settled": float(carried), "floor_before": float(before[3]),
                          "weight": float(n),
                          "balance": float((end[3] - end[2]) / n), "stress": at, "vtk": str(folder / "particles.pvd")}
        curves[field] = (strain, stress)
        print(f"field {field:g}: {n} spheres settle to a pile {h0:.3f} high (volume fraction {fraction:.3f}); "
              f"the floor carries {carried:.2f} settled and {before[3]:.2f} as the piston arrives (their weight "
              f"{n}); at strain "
              f"{strain[-1]:.3f} the floor carries {end[3]:.1f} = weight + piston's {end[2]:.1f} "
              f"{'+' if end[3] - end[2] - n >= 0 else '-'} {abs(end[3] - end[2] - n):.1f}; stress at 0.5 / 1 / 2 % "
              f"strain: {at[0.005]:.2f} / {at[0.01]:.2f} / {at[0.02]:.2f}")
    table = args.output / "stress_strain.csv"
    with open(table, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["field", "strain", "stress"])
        for field, (strain, stress) in curves.items():
            out.writerows([field, e, s] for e, s in zip(strain, stress))
    figure = args.output / "stress_strain.png"
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for field, (strain, stress) in curves.items():
        ax.plot(100 * strain, stress, label=f"field {field:g}" if field else "no field")
    ax.set_xlabel("strain (%)")
    ax.set_ylabel("stress on the piston (m g / d$^2$)")
    ax.set_title(f"oedometric compression, Bo = {args.bond:g}")
    ax.legend()
    fig.tight_layout()
    fig.savefig(figure, dpi=120)
    plt.close(fig)
    picture = args.output / "final.png"
    try:
        dk.viz.snapshot(args.output / f"vtk_field_{args.field:g}", picture, view="xz", color_by="dipole",
                        window_size=(640, 480))
    except dk.viz.RenderingUnavailable as err:
        print(f"no picture: {err}")
        picture = None
    return {"results": {str(k): v for k, v in results.items()}, "figure": str(figure), "table": str(table),
            "picture": str(picture) if picture else None}


if __name__ == "__main__":
    main(__import__("sys").argv[1:])
