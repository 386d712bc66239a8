"""A dilute gas of magnetic spheres assembles into chains and rings.

    python examples/magnetic_cluster/run.py [--output DIR] [--3d] [--quick]

400 spheres with randomly oriented dipoles start far apart, with thermal speeds. They attract,
turn head to tail and stick; damped contacts carry the released magnetic energy away, and the gas
ends up as chains and closed (flux-closure) rings. Writes into DIR (default ``output/`` next to
this script) a VTK series ``vtk/particles.pvd`` for ParaView, ``assembly.gif``, ``final.png`` and
``energy.png``, and prints a summary.

Units: sphere diameter d = 1, mass m = 1, starting temperature kT = 1 (time unit d sqrt(m/kT)).
The dipole prefactor is 1, so a moment mu gives the dipolar coupling lambda = mu^2 / (d^3 kT):
two touching spheres head to tail have the energy -2 lambda kT.
"""
import argparse
import math
import sys
from pathlib import Path

import numpy as np

import demkit as dk

HERE = Path(__file__).resolve().parent
R = 0.5  # sphere radius: diameter 1
TOUCH = 0.02  # in the summary, spheres closer than 1.02 diameters touch


def build(n, coupling, flat, seed):
    """Particles of a dilute random gas (thermal velocities, kT = 1) and the box they start in.

    flat: a monolayer, the default. Chains and rings then lie in one plane and a picture shows every
    one of them face-on; in a 3D gas they cross in front of each other and rings are hard to tell
    from tangles. It needs no walls: with all centres in the plane z = R and all moments in it, the
    forces lie in the plane and the torques point along z, so nothing ever leaves the plane.
    """
    rng = np.random.default_rng(seed)
    if flat:
        side = math.sqrt(n * math.pi * R**2 / 0.1)  # area fraction 0.1: spheres 2.8 d apart
        box = dk.Box((side, side, 2 * R))  # open; it only says where to place the spheres
        position = dk.build.random_packing(n, R, box, seed=rng)  # every centre at z = R
        angle = rng.uniform(0.0, 2 * math.pi, n)
        direction = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
    else:
        box = dk.build.box_for(n, R, volume_fraction=0.03, periodic=False)  # 2.6 d apart
        position = dk.build.random_packing(n, R, box, seed=rng)
        direction = dk.build.random_directions(n, seed=rng)
    velocity = dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=rng)
    if flat:
        velocity[:, 2] = 0.0
    particles = dk.Particles(position=position, velocity=velocity, radius=R, mass=1.0,
                             dipole=math.sqrt(coupling) * direction)
    return particles, box


def structures(position):
    """What the spheres form: clusters (lone spheres count), the largest, touching neighbours per
    sphere, and the clusters that are plain rings (every sphere touches two others) or plain
    chains (an open line: two ends, links between) with their sizes."""
    label = dk.viz.clusters(position, R, gap=TOUCH)  # 0 is the largest cluster
    contacts = dk.viz.contacts(position, R, tolerance=TOUCH)
    rings, chains = dk.clustering.rings_and_chains(label, contacts)
    return {"clusters": int(label.max() + 1), "largest": int(np.sum(label == 0)),
            "free": int(np.sum(contacts == 0)), "linked": int(np.sum((contacts == 1) | (contacts == 2))),
            "junctions": int(np.sum(contacts >= 3)), "contacts": int(contacts.sum() // 2),
            "rings": rings, "chains": chains}


def plot_energy(traj, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    e, t = traj.energy, traj.time
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    top.plot(t, e["magnetic"], label="magnetic")
    top.plot(t, e["total"], label="total")
    top.plot(t, e["total"] + e["dissipated"], "k--", label="total + dissipated")
    top.set_ylabel("energy (kT)")
    top.set_title(f"{traj.position.shape[1]} magnetic spheres")
    top.legend()
    bottom.plot(t, e["kinetic"], label="kinetic")
    bottom.plot(t, e["rotational"], label="rotational")
    bottom.plot(t, e["contact"], label="contact springs")
    bottom.set_ylabel("energy (kT)")
    bottom.set_xlabel("time (d sqrt(m/kT))")
    bottom.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    """Run, write and summarise; ``argv`` are command-line options (None: the defaults).
    Returns the summary numbers and the paths written, as a dict."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--n", type=int, default=400, help="number of spheres")
    parser.add_argument("--coupling", type=float, default=20.0, help="dipolar coupling lambda")
    parser.add_argument("--duration", type=float, default=12.0, help="simulated time")
    parser.add_argument("--frames", type=int, default=80, help="frames in the animation")
    parser.add_argument("--3d", dest="flat", action="store_false", help="a 3D gas instead of a monolayer")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--quick", action="store_true", help="150 spheres, t = 3, 3 frames (for tests)")
    args = parser.parse_args([] if argv is None else argv)
    if args.quick:
        args.n, args.duration, args.frames = 150, 3.0, 3
    args.output.mkdir(parents=True, exist_ok=True)

    particles, box = build(args.n, args.coupling, args.flat, args.seed)
    mu2 = args.coupling  # mu^2 (prefactor 1, d = kT = 1)
    # Contacts: stiff enough that the pull of two touching spheres head to tail, 6 mu^2 / d^4,
    # squeezes them by only 1 % of d (impacts briefly press up to 7 %); damped so that a collision
    # keeps 70 % of the approach speed (restitution 0.7): the magnetic energy set free by the
    # collapse goes into the dashpots.
    stiffness = 6 * mu2 / 0.01
    e = 0.7
    zeta = -math.log(e) / math.hypot(math.pi, math.log(e))  # the damping ratio that gives it
    damping = 2 * zeta * math.sqrt(stiffness * 0.5)  # 0.5: reduced mass of two spheres
    # Dipoles: open space (no box) and the exact sum over all pairs, no cutoff: N^2/2 pair terms,
    # 80,000 for 400 spheres, about 1000 steps a second on one core. A periodic box would need a
    # cutoff, which makes the energy depend on its length and drops the long-range pull between
    # chains and rings; here the spheres that fly off simply leave.
    # (One thread: demkit starts threads from 2000 spheres; below, they gain little.)
    scene = dk.Scene(particles, [dk.Dipole(prefactor=1.0), dk.KelvinVoigt(stiffness, damping)])
    # Time step: half the contact limit (max_time_step is a tenth of a contact), far shorter
    # than the time a dipole takes to swing round in its neighbour's field, sqrt(I d^3 / mu^2).
    # A whole number of steps between the 100 VTK frames, so the last frame is the end of the run.
    steps = 100 * math.ceil(args.duration / (0.5 * scene.max_time_step()) / 100)
    dt = args.duration / steps
    swing = math.sqrt(0.4 * R**2 / mu2)  # I = 2/5 m R^2
    print(f"{args.n} spheres, coupling {args.coupling:g}, stiffness {stiffness:.3g}, damping {damping:.3g}; "
          f"dt = {dt:.3g} (dipole swing time {swing:.3g}), {steps} steps")

    writer = dk.VTKWriter(args.output / "vtk", every=args.duration / 100, overwrite=True)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=dt), writers=[writer])
    traj = sim.run(args.duration, record_every=args.duration / 200)
    sim.close()
    stats = sim.statistics
    print(f"t = 0 .. {args.duration:g} in {stats['seconds']:.1f} s: {stats['steps_per_second']:.0f} steps/s")

    # What formed, and the energy balance. total + dissipated keeps its start value only to first
    # order in dt: demkit sums the dashpots' power at the velocities before each step's kick, which
    # counts about damping dt / m (1.8 % here, whatever the coupling) more work than they remove.
    start, end = structures(traj.position[0]), structures(traj.position[-1])
    energy = traj.energy
    budget = energy["total"] + energy["dissipated"]
    closure = abs(budget[-1] - budget[0]) / abs(energy["magnetic"][-1])
    print(f"clusters {start['clusters']} -> {end['clusters']}, largest {start['largest']} -> {end['largest']} "
          f"spheres, contacts {start['contacts']} -> {end['contacts']}")
    print(f"spheres touching 1 or 2 others (in chains and rings) {end['linked']}, 3 or more "
          f"(junctions, clumps) {end['junctions']}, none {end['free']}")
    print(f"plain rings {len(end['rings'])} ({sum(end['rings'])} spheres), plain chains "
          f"{len(end['chains'])} ({sum(end['chains'])} spheres)")
    print(f"energy balance |total + dissipated - initial| / |magnetic| = {closure:.2%}")

    plot_energy(traj, args.output / "energy.png")
    movie, picture = args.output / "assembly.gif", args.output / "final.png"
    # Colour by touching neighbours: 1 chain ends, 2 links of chains and rings, 3+ junctions. The
    # monolayer is framed on where it started (a few spheres fly off), a 3D gas on its largest cluster.
    lx, ly, lz = box.size + 1.0
    look = dict(color_by="contacts", clim=(0, 4), bounds=(-1, lx, -1, ly, -1, lz) if args.flat else None)
    try:
        dk.viz.animate(writer.pvd, movie, max_frames=args.frames, fps=10, window_size=(600, 520),
                       trail=args.duration / 20, **look)
        dk.viz.snapshot(writer.pvd, picture, window_size=(800, 700), trail=0, **look)
    except dk.viz.RenderingUnavailable as err:  # no OpenGL here: the series and plot are still there
        print(f"no pictures: {err}")
        movie = picture = None
    print(f"wrote {writer.pvd}, {movie}, {picture}, {args.output / 'energy.png'}")
    return {"start": start, "end": end, "closure": closure, "steps_per_second": stats["steps_per_second"],
            "pvd": writer.pvd, "movie": movie, "picture": picture, "energy_plot": args.output / "energy.png"}


if __name__ == "__main__":
    main(sys.argv[1:])
