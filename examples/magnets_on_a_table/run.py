"""Magnetic balls dropped on a table roll into chains and rings.

    python examples/magnets_on_a_table/run.py [--output DIR] [--n N] [--seed S] [--quick]

A lab scene in SI units: 30 NdFeB balls of 5 mm diameter (the desk-toy kind), magnetised along a
random direction in the horizontal plane, are let go a few millimetres above a table, scattered
with gaps between them. They fall, snap together, roll and slide on the table (Hertz contacts with
Coulomb friction and rolling resistance, against each other and against the table) and settle as
chains and closed rings. Writes into DIR (default ``output/`` next to this script) a VTK series
``vtk/particles.pvd`` with its contact network ``vtk/particles_contacts.pvd`` for ParaView,
``table.gif`` (top view), ``final.png`` and ``energy.png``, and prints a summary.
"""
import argparse
import math
import sys
from pathlib import Path

import numpy as np

import demkit as dk
from demkit.interactions.hertz import hertz_impact

HERE = Path(__file__).resolve().parent

# The balls: sintered NdFeB, nickel plated, as sold in 5 mm magnetic-ball puzzles.
R = 2.5e-3  # radius, m (5 mm diameter)
DENSITY = 7500.0  # kg/m^3, sintered NdFeB (makers' data sheets: 7.5 g/cm^3)
REMANENCE = 1.3  # T, between grades N42 (Br 1.28-1.32 T) and N45 (1.32-1.38 T)
YOUNG, POISSON = 160e9, 0.24  # Pa and -, sintered NdFeB (data sheets: 1.6e11 N/m^2, 0.24)
RESTITUTION = 0.5  # normal restitution of a ball-ball and ball-table impact (a chosen, plausible value)
FRICTION = 0.3  # sliding friction coefficient, ball on ball and ball on table
ROLLING = 0.02  # ball on ball rolling resistance: the largest rolling torque is ROLLING * R* * F_n
TABLE_ROLLING = 0.1  # ball on table: largest rolling torque 0.1 R F_n, a lever of 0.25 mm
G = 9.81  # m/s^2

VOLUME = 4.0 / 3.0 * math.pi * R**3
MASS = DENSITY * VOLUME  # 0.49 g
MOMENT = REMANENCE * VOLUME / dk.units.MU0  # 0.068 A m^2: a uniformly magnetised sphere, m = Br V / mu0
PREFACTOR = dk.units.MU0 / (4.0 * math.pi)  # dk.Dipole's prefactor in SI: mu0 / (4 pi)

TOUCH = 0.02  # in the summary, spheres closer than 1.02 diameters touch
STEPS_PER_CONTACT = 40  # time steps in the fastest impact (docs/contacts.md: 50-100 for forces to 1e-3)


def build(n, area_fraction, seed):
    """Particles at rest, scattered over a square patch of table at ``area_fraction`` with at least
    0.6 diameters between surfaces, each 0.5-3 mm above the table, moments in the horizontal plane.
    Returns the particles and the side of the patch (m)."""
    rng = np.random.default_rng(seed)
    side = math.sqrt(n * math.pi * R**2 / area_fraction)
    spacer = 1.6 * R  # place spheres of 1.6 R, then shrink them: gaps of at least 0.6 d
    patch = dk.Box((side, side, 2 * spacer))
    position = dk.build.random_packing(n, spacer, patch, seed=rng)
    position[:, 2] = R + rng.uniform(0.5e-3, 3e-3, n)  # height of the ball's bottom: 0.5-3 mm
    angle = rng.uniform(0.0, 2 * math.pi, n)
    direction = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
    particles = dk.Particles(position=position, radius=R, mass=MASS, dipole=MOMENT * direction)
    return particles, side


def time_step(law, steps_per_contact=STEPS_PER_CONTACT):
    """A time step that resolves the fastest impact with ``steps_per_contact`` steps, and that impact:
    (dt, approach speed, contact time, largest overlap).

    The scene starts at rest, so the library's own check (scene.max_time_step(): a tenth of the
    Hertz contact time at twice the fastest speed present) has nothing to go on yet. The speeds come
    from the magnets: two balls snapping head to tail release 2 (mu0/4pi) m^2 / d^3, and the fastest
    approach is the one that turns all of it into relative speed (measured: 7.4 m/s, the bound 7.7).
    """
    released = 2.0 * PREFACTOR * MOMENT**2 / (2 * R) ** 3
    snap = math.sqrt(2.0 * released / (MASS / 2))  # relative speed, reduced mass m/2
    overlap, force, duration = hertz_impact(law.young_eff, R / 2, MASS / 2, snap)
    return duration / steps_per_contact, snap, duration, overlap


def structures(position):
    """What the balls form: clusters (lone balls count), the largest, touching neighbours per ball,
    the clusters that are plain rings (every ball touches two others) and plain chains (an open
    line) with their sizes, and the closed loops of the contact network (independent cycles, so a
    ring hanging on a chain counts too)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    d = 2 * R
    label = dk.viz.clusters(position, R, gap=TOUCH * d)  # 0 is the largest cluster
    contacts = dk.viz.contacts(position, R, tolerance=TOUCH)
    pairs = dk.clustering.close_pairs(position, R, scale=1 + TOUCH)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(position),) * 2)
    components = connected_components(graph, directed=False)[0]
    rings, chains = dk.clustering.rings_and_chains(label, contacts)
    return {"clusters": int(label.max() + 1), "largest": int(np.sum(label == 0)),
            "free": int(np.sum(contacts == 0)), "linked": int(np.sum((contacts == 1) | (contacts == 2))),
            "junctions": int(np.sum(contacts >= 3)), "contacts": int(len(pairs)),
            "loops": int(len(pairs) - len(position) + components),  # cycle rank of the contact graph
            "rings": rings, "chains": chains}


def plot_energy(traj, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    e, t = traj.energy, traj.time * 1e3  # ms
    mj = 1e3  # J -> mJ
    lifted = e["gravity"] - MASS * G * R * traj.position.shape[1]  # m g (z - R), summed: height above rest
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6.5))
    top.plot(t, mj * e["magnetic"], label="magnetic")
    top.plot(t, mj * e["dissipated"], label="dissipated (contacts, friction, rolling)")
    top.plot(t, mj * e["total"], label="total (kinetic + magnetic + gravity + springs)")
    top.plot(t, mj * (e["total"] + e["dissipated"]), "k--", label="total + dissipated")
    top.set_ylabel("energy (mJ)")
    top.set_title(f"{traj.position.shape[1]} NdFeB balls of 5 mm on a table")
    top.legend(fontsize=8)
    for key, values in (("kinetic", e["kinetic"]), ("rotational", e["rotational"]),
                        ("gravity above rest, m g (z - R)", lifted), ("contact and table springs", e["contact"] + e["wall"])):
        bottom.semilogy(t, mj * np.maximum(values, 1e-12), label=key)
    bottom.set_ylim(1e-7, None)
    bottom.set_ylabel("energy (mJ)")
    bottom.set_xlabel("time (ms)")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def dipole_angle(pvd):
    """Azimuth of every ball's moment in every frame of the series, degrees (-180..180): colours
    the pictures, so that head-to-tail neighbours have nearby colours and a ring shows every one."""
    series = dk.read_series(pvd)
    return np.degrees(np.arctan2(series.dipole[:, :, 1], series.dipole[:, :, 0]))


def main(argv=None):
    """Run, write and summarise; ``argv`` are command-line options (None: the defaults).
    Returns the summary numbers and the paths written, as a dict."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--n", type=int, default=30, help="number of balls (at most 64: all-pairs dipoles)")
    parser.add_argument("--area-fraction", type=float, default=0.03, help="table area covered by the balls")
    parser.add_argument("--duration", type=float, default=0.6, help="simulated time, s")
    parser.add_argument("--frames", type=int, default=100, help="frames in the animation")
    parser.add_argument("--seed", type=int, default=4)
    parser.add_argument("--steps-per-contact", type=float, default=STEPS_PER_CONTACT,
                        help="time steps in the fastest impact (sets dt)")
    parser.add_argument("--quick", action="store_true", help="12 balls for 0.4 s, 3 frames (for tests)")
    args = parser.parse_args([] if argv is None else argv)
    if args.quick:
        args.n, args.duration, args.frames = 12, 0.4, 3
    args.output.mkdir(parents=True, exist_ok=True)

    particles, side = build(args.n, args.area_fraction, args.seed)
    contact = dk.Hertz(young=YOUNG, poisson=POISSON, restitution=RESTITUTION,
                       friction=dk.Friction(FRICTION), rolling=dk.RollingResistance(ROLLING))
    # The table: a rigid plane (Hertz against a wall uses E* = E / (1 - nu^2), R* = R, m* = m) with
    # its own law, the balls' but for a larger rolling resistance.
    on_table = dk.Hertz(young=YOUNG, poisson=POISSON, restitution=RESTITUTION,
                        friction=dk.Friction(FRICTION), rolling=dk.RollingResistance(TABLE_ROLLING))
    table = dk.Wall(point=(0, 0, 0), normal=(0, 0, 1), contact=on_table)
    # Dipoles: the exact sum over all pairs (no cutoff; a scene of at most 64 spheres needs no lists).
    scene = dk.Scene(particles, [contact, dk.Dipole(prefactor=PREFACTOR), table, dk.Gravity((0, 0, -G))])
    dt, snap, impact, squeeze = time_step(contact, args.steps_per_contact)
    frames = 100  # VTK frames; a whole number of steps between them, so the last is the end of the run
    steps = frames * math.ceil(args.duration / dt / frames)
    dt = args.duration / steps
    print(f"{args.n} balls of {2e3 * R:g} mm, {1e3 * MASS:.3g} g, moment {MOMENT:.3g} A m^2, on a "
          f"{1e3 * side:.0f} mm square of table")
    print(f"fastest snap {snap:.2g} m/s: Hertz contact {1e6 * impact:.3g} us, overlap {1e6 * squeeze:.3g} um; "
          f"dt = {dt:.3g} s, {steps} steps")

    writer = dk.VTKWriter(args.output / "vtk", every=args.duration / frames, overwrite=True, contacts=True)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=dt), writers=[writer])
    traj = sim.run(args.duration, record_every=args.duration / 200)
    sim.close()
    stats = sim.statistics
    print(f"t = 0 .. {args.duration:g} s in {stats['seconds']:.1f} s: {stats['steps_per_second']:.0f} steps/s")
    # the library's own time-step limit, now that it can see speeds (at the end: the balls are slow)
    limit = scene.max_time_step()

    # What formed
    start, end = structures(traj.position[0]), structures(traj.position[-1])
    print(f"clusters {start['clusters']} -> {end['clusters']}, largest {start['largest']} -> {end['largest']} "
          f"balls, touching pairs {start['contacts']} -> {end['contacts']}")
    print(f"balls touching 1 or 2 others (in chains and rings) {end['linked']}, 3 or more (junctions) "
          f"{end['junctions']}, none {end['free']}")
    print(f"plain rings {len(end['rings'])} {end['rings']}, plain chains {len(end['chains'])} {end['chains']}, "
          f"closed loops in the contact network {end['loops']}")

    # Contacts now, as the contact laws see them (scene.contacts(): forces, sliding, dissipation)
    c = scene.contacts()
    on_table, between = c.wall >= 0, c.wall < 0
    print(f"contacts at the end: {between.sum()} ball-ball ({c.sliding[between].sum()} sliding), "
          f"{on_table.sum()} ball-table ({c.sliding[on_table].sum()} sliding); strongest ball-ball "
          f"{c.normal_force[between].max(initial=0):.3g} N (weight of a ball {MASS * G:.2g} N)")

    # Energy: total + dissipated should keep its starting value. It does so to first order in dt:
    # the dashpots see the velocities of half a step before (friction's work is booked exactly).
    energy = traj.energy
    budget = energy["total"] + energy["dissipated"]
    closure = abs(budget[-1] - budget[0]) / energy["dissipated"][-1]
    released = energy["magnetic"][0] - energy["magnetic"][-1]
    print(f"magnetic energy {1e3 * energy['magnetic'][0]:.3g} -> {1e3 * energy['magnetic'][-1]:.4g} mJ, "
          f"dissipated {1e3 * energy['dissipated'][-1]:.4g} mJ; |total + dissipated - initial| / dissipated "
          f"= {closure:.2%}")

    # At rest on the table?
    height = traj.position[:, :, 2] - R  # height of each ball's bottom above the table
    speed = np.linalg.norm(traj.velocity[-1], axis=1)
    print(f"at the end: speeds median {1e3 * np.median(speed):.2g} mm/s, largest {1e3 * speed.max():.3g} mm/s; "
          f"heights above the table {1e6 * height[-1].min():.3g} .. {1e6 * height[-1].max():.3g} um; "
          f"deepest into the table during the run {-1e6 * height.min():.3g} um; "
          f"kinetic + rotational {1e3 * (energy['kinetic'][-1] + energy['rotational'][-1]):.2g} mJ")
    spin = 0.5 * traj.inertia * traj.angular_velocity[-1, :, 2] ** 2  # spin about the vertical, J
    print(f"rotational energy left {1e3 * energy['rotational'][-1]:.2g} mJ, {spin.sum() / energy['rotational'][-1]:.0%} "
          f"of it spin about the vertical (largest {abs(traj.angular_velocity[-1, :, 2]).max():.3g} rad/s): this "
          f"run leaves out twisting resistance (see the README)")
    print(f"library time-step limit at the end {limit:.3g} s (dt {dt:.3g})")

    plot_energy(traj, args.output / "energy.png")
    movie, picture = args.output / "table.gif", args.output / "final.png"
    # Top view of every ball, coloured by the direction of its moment in the table's plane, in
    # degrees (a cyclic colour map: a ring shows every colour once).
    look = dict(view="xy", frame="all", color_by=dipole_angle(writer.pvd), cmap="twilight", clim=(-180, 180),
                color_label="azimuth (deg)")
    try:
        dk.viz.animate(writer.pvd, movie, max_frames=args.frames, fps=12, window_size=(600, 540),
                       trail=args.duration / 10, **look)
        dk.viz.snapshot(writer.pvd, picture, window_size=(700, 630), trail=0, **look)
    except dk.viz.RenderingUnavailable as err:  # no OpenGL here: the series and plot are still there
        print(f"no pictures: {err}")
        movie = picture = None
    contacts_pvd = writer.contact_series.pvd
    print(f"wrote {writer.pvd}, {contacts_pvd}, {movie}, {picture}, {args.output / 'energy.png'}")
    return {"start": start, "end": end, "closure": closure, "steps_per_second": stats["steps_per_second"],
            "dt": dt, "magnetic": [float(energy["magnetic"][0]), float(energy["magnetic"][-1])],
            "released": float(released), "dissipated": float(energy["dissipated"][-1]),
            "lowest": float(height.min()), "final_height": [float(height[-1].min()), float(height[-1].max())],
            "final_speed": [float(np.median(speed)), float(speed.max())],
            "contacts": {"ball_ball": int(between.sum()), "ball_ball_sliding": int(c.sliding[between].sum()),
                         "ball_table": int(on_table.sum()), "ball_table_sliding": int(c.sliding[on_table].sum())},
            "pvd": str(writer.pvd), "contacts_pvd": str(contacts_pvd), "movie": movie and str(movie),
            "picture": picture and str(picture), "energy_plot": str(args.output / "energy.png")}


if __name__ == "__main__":
    main(sys.argv[1:])
