"""Steel balls in a uniform field form columns between two walls.

    python examples/steel_columns/run.py [--output DIR] [--n N] [--seed S] [--sum slab|cutoff] [--quick]

A lab scene in SI units: steel ball bearings of 2 mm diameter in a cell between two horizontal,
non-magnetic plates (``dk.Wall``) GAP diameters apart, periodic in x and y (a wide cell), under
gravity, in a vertical uniform field B0 (a pair of Helmholtz coils). Steel is magnetisable: each
ball carries the moment the field at its centre induces, m = alpha B, alpha = beta R^3 / A with
beta = chi / (chi + 3) (``dk.Particles(susceptibility=...)``), and the balls magnetise each other,
solved self-consistently before every force evaluation (``dk.Dipole(..., induction=dk.Induction())``).
The dipoles are cut off at CUTOFF diameters (``--sum cutoff``, the default), which misses the
layer's demagnetising field, or summed over every periodic copy of the cell in x and y by a slab
Ewald sum (``--sum slab``: an infinitely wide layer; about 20 times the time per step at 60 balls, as
the induced-moment solve evaluates the wave-vector sum 4-5 times a step). Either way, the moments
of the last positions are then also solved with the slab sum and checked against a dense solve
over every copy of the cell.
The balls start scattered at rest, chain along the field, fall, and settle as columns standing on
the floor, some of them spanning the gap to the top plate. Linear spring-dashpot contacts with
Coulomb friction, against each other and against the plates.

Writes into DIR (default ``output/`` next to this script) a VTK series ``vtk/particles.pvd`` with
the contact network ``vtk/particles_contacts.pvd`` for ParaView, ``columns.png`` (3-D view and
side view of the end, balls coloured by their moment), ``energy.png``, ``summary.json``, and prints
a summary: the moments in the columns against the lone ball and the infinite chain, the columns,
their heights and how many span the gap, and the energy balance.
"""
import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

import demkit as dk
from demkit.interactions.dipole import switch

HERE = Path(__file__).resolve().parent

# The balls: chrome-steel ball bearings (AISI 52100), 2 mm diameter.
R = 1.0e-3  # radius, m
D = 2 * R
DENSITY = 7850.0  # kg/m^3, steel
# Magnetic susceptibility chi = mu_r - 1. Makers' tables give initial relative permeabilities of
# ~100 for hardened carbon and bearing steels up to a few thousand for soft iron and annealed mild
# steel; we take chi = 1000. A sphere's polarisability saturates as chi grows (its own demagnetising
# field): beta = chi / (chi + 3) = 0.997 here, 0.971 for chi = 100, so the choice hardly matters.
CHI = 1000.0
B0 = 0.04  # T, vertical: 40 mT, what a pair of Helmholtz coils of some 10 cm gives with a few amperes x 1000 turns
GAP = 8.0  # distance between the plates, in diameters
G = 9.81  # m/s^2
STIFFNESS = 1.0e5  # N/m, linear contact spring (softer than steel: see README, "Contacts")
RESTITUTION = 0.5  # normal restitution, ball-ball and ball-plate (chosen: settles in a fraction of a second)
FRICTION = 0.3  # sliding friction, ball-ball and ball-plate (dry steel on steel: 0.3-0.6)
STEPS_PER_CONTACT = 30  # time steps in a contact (docs/contacts.md: 50-100 for forces to 1e-3)
CUTOFF = 4.0  # dipole cutoff, diameters (switched off smoothly over the last SWITCH)
SWITCH = 1.0
TOLERANCE = 1e-6  # relative residual of the induced-moment solve (dk.Induction's default)
SLAB_ACCURACY = 1e-4  # of the slab Ewald sum: RMS force (and field) error / touching pull

PREFACTOR = dk.units.MU0 / (4.0 * math.pi)  # A = mu0 / 4 pi: dk.Dipole's prefactor in SI
VOLUME = 4.0 / 3.0 * math.pi * R**3
MASS = DENSITY * VOLUME  # 32.9 mg
BETA = CHI / (CHI + 3.0)
ALPHA = BETA * R**3 / PREFACTOR  # polarisability, A m^2 per T
ZETA3 = 1.2020569031595942
LONE = ALPHA * B0  # moment of a lone ball, A m^2
CHAIN = ALPHA * B0 / (1.0 - 4.0 * ZETA3 * PREFACTOR * ALPHA / D**3)  # middle of an infinite straight chain

TOUCH = 0.01  # in the analysis, balls (or a ball and a plate) closer than 1% of R touch


def chain_with_cutoff(cutoff=CUTOFF, width=SWITCH):
    """The infinite chain's moment as the scene's dipole sum sees it (neighbours k d away weighted
    by the switch S(k d), none beyond the cutoff): sum_k 2 S / k^3 instead of 2 zeta(3)."""
    k = np.arange(1, int(cutoff) + 1, dtype=float)
    s = switch(k * D, cutoff * D, width * D)[0]
    coupling = 2.0 * np.sum(s / k**3)
    return ALPHA * B0 / (1.0 - 2.0 * coupling * PREFACTOR * ALPHA / D**3)


def build(n, volume_fraction, gap, seed):
    """Balls at rest scattered through the cell at ``volume_fraction``, at least 0.4 diameters
    between surfaces (placed as spheres of 1.4 R and shrunk), none touching a plate. Returns the
    particles and the periodic box (walls at z = 0 and z = gap)."""
    height = gap * D
    side = math.sqrt(n * VOLUME / (volume_fraction * height))
    box = dk.Box((side, side, height), periodic=(True, True, False))
    inner = dk.Box((side, side, height - 0.2 * R), periodic=(True, True, False))
    position = dk.build.random_packing(n, 1.4 * R, inner, seed=seed)
    position[:, 2] += 0.1 * R  # centres between 1.5 R and height - 1.5 R: no ball on a plate
    particles = dk.Particles(position=position, radius=R, mass=MASS, susceptibility=CHI)
    return particles, box


def slab_dipole():
    """The dipoles over every periodic copy of the cell in x and y: a slab Ewald sum, induced moments."""
    return dk.Dipole(PREFACTOR, long_range=dk.Ewald(SLAB_ACCURACY), induction=dk.Induction(tolerance=TOLERANCE))


def layer_moments(position, box):
    """(N, 3) moments the field B0 induces in balls at these positions, summed by the slab Ewald sum."""
    p = dk.Particles(position=position, radius=R, mass=MASS, susceptibility=CHI)
    scene = dk.Scene(p, [slab_dipole(), dk.UniformField((0, 0, B0))], box=box)
    scene.induce()
    return scene.particles.dipole.copy()


def contact_law():
    """Kelvin-Voigt spring-dashpot of the restitution RESTITUTION for two balls, with friction."""
    reduced = MASS / 2
    log = math.log(RESTITUTION)
    zeta = -log / math.sqrt(math.pi**2 + log**2)
    damping = 2.0 * zeta * math.sqrt(STIFFNESS * reduced)
    return dk.KelvinVoigt(STIFFNESS, damping, friction=dk.Friction(FRICTION))


def contact_time():
    """Duration of a ball-ball contact, pi / sqrt(k / m* - (c / 2 m*)^2), m* = m / 2."""
    law, reduced = contact_law(), MASS / 2
    return math.pi / math.sqrt(STIFFNESS / reduced - (law.damping / (2 * reduced)) ** 2)


def slab_tensor(position, size, images=None, cutoff=None, width=None):
    """(3N, 3N) dipole field operator T of the balls, B_i = sum_j T_ij m_j (tesla per A m^2).

    images=None: the scene's own sum, the minimum image within ``cutoff`` with demkit's switch.
    images=K: every periodic copy in x and y within a disc of K box sides, plus the copies beyond it
    as a continuous sheet (the exact sum for an infinitely wide layer between the plates; it
    converges absolutely: a sheet of dipoles falls off as 1/rho^3 over an area growing as rho^2)."""
    n = len(position)
    lx, ly = size[0], size[1]
    sep = position[None, :, :] - position[:, None, :]  # r_j - r_i
    sep[..., 0] -= lx * np.round(sep[..., 0] / lx)
    sep[..., 1] -= ly * np.round(sep[..., 1] / ly)
    shifts = [(0, 0)] if images is None else [(a, b) for a in range(-images, images + 1)
                                             for b in range(-images, images + 1) if a * a + b * b <= images**2]
    t = np.zeros((n, n, 3, 3))
    for a, b in shifts:
        r = sep + np.array([a * lx, b * ly, 0.0])
        r2 = np.einsum("ijk,ijk->ij", r, r)
        if a == 0 and b == 0:
            np.fill_diagonal(r2, np.inf)
        dist = np.sqrt(r2)
        weight = np.ones_like(dist)
        if images is None:
            x = np.clip((dist - (cutoff - width)) / width, 0.0, 1.0)
            weight = np.where(dist < cutoff, 1.0 - x**3 * (10.0 - x * (15.0 - 6.0 * x)), 0.0)
        scale = PREFACTOR * weight / (r2 * dist)
        t += scale[..., None, None] * (3.0 * r[..., :, None] * r[..., None, :] / r2[..., None, None] - np.eye(3))
    if images is not None:
        # beyond the disc: a sheet of 1/(lx ly) dipoles per area from radius rho on, whose field
        # at height z above or below it is T_zz = -2 pi A rho^2 / (lx ly (rho^2 + z^2)^1.5),
        # T_xx = T_yy = -T_zz / 2
        rho = math.sqrt(len(shifts) * lx * ly / math.pi)
        tzz = -2.0 * math.pi * PREFACTOR * rho**2 / (lx * ly * (rho**2 + sep[..., 2] ** 2) ** 1.5)
        t[..., 2, 2] += tzz
        t[..., 0, 0] -= 0.5 * tzz
        t[..., 1, 1] -= 0.5 * tzz
    return t.transpose(0, 2, 1, 3).reshape(3 * n, 3 * n)


def solve_moments(t):
    """The induced moments (N, 3) for the field operator ``t``: (I - alpha T) m = alpha B0, dense."""
    n = t.shape[0] // 3
    return np.linalg.solve(np.eye(3 * n) - ALPHA * t, ALPHA * np.tile([0.0, 0.0, B0], n)).reshape(n, 3)


def columns(scene, height):
    """What the balls form at the end. Columns are clusters of touching balls (dk.measure.clusters,
    gap TOUCH R); a column stands on the floor when one of its balls touches it, spans when it also
    touches the top plate. In-chain balls: balls touching exactly two others, one above and one
    below (contact normals within 25 degrees of the field), touching no plate, in a column of at
    least 4 balls: the balls whose moment to compare with the infinite chain's."""
    p = scene.particles
    z = p.position[:, 2]
    cl = dk.measure.clusters(scene, gap=TOUCH * R)
    floor = z < R * (1 + TOUCH)
    roof = z > height - R * (1 + TOUCH)
    c = scene.contacts()
    between = c.wall < 0
    pairs, normal = c.pairs[between], c.normal[between]
    n = len(p)
    count = np.bincount(pairs.ravel(), minlength=n)
    vertical = np.abs(normal[:, 2]) > math.cos(math.radians(25))
    upright = np.bincount(pairs[vertical].ravel(), minlength=n)
    size = cl.sizes[cl.labels]
    in_chain = (count == 2) & (upright == 2) & ~floor & ~roof & (size >= 4)
    rows = []
    for label in range(cl.count):
        members = np.flatnonzero(cl.labels == label)
        if len(members) < 2:
            continue
        rows.append({"balls": int(len(members)),
                     "height": float((z[members].max() - z[members].min()) / D + 1.0),  # in diameters
                     "floor": bool(floor[members].any()), "roof": bool(roof[members].any()),
                     "most_contacts": int(count[members].max())})
    spanning = sum(r["balls"] for r in rows if r["floor"] and r["roof"])
    in_columns = sum(r["balls"] for r in rows)
    return {"columns": rows, "lone": int(np.sum(cl.sizes == 1)), "in_columns": int(in_columns),
            "spanning_balls": int(spanning), "spanning_columns": int(sum(r["floor"] and r["roof"] for r in rows)),
            "standing_columns": int(sum(r["floor"] and not r["roof"] for r in rows)),
            "coordination": float(count.mean()), "in_chain": in_chain, "contacts": int(between.sum()),
            "on_floor": int(np.sum(floor)), "on_roof": int(np.sum(roof))}


def plot_energy(traj, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    e, t, uj = traj.energy, traj.time * 1e3, 1e6  # ms, J -> uJ
    fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6.5))
    top.plot(t, uj * e["magnetic"], label="magnetic (dipoles + field + induction)")
    top.plot(t, uj * (e["gravity"] - e["gravity"][0]), label="gravity, from the start")
    top.plot(t, uj * e["dissipated"], label="dissipated (dashpots, friction)")
    top.plot(t, uj * e["total"], label="total")
    top.plot(t, uj * (e["total"] + e["dissipated"]), "k--", label="total + dissipated")
    top.set_ylabel("energy (uJ)")
    top.set_title(title)
    top.legend(fontsize=8)
    bottom.semilogy(t, uj * np.maximum(e["kinetic"] + e["rotational"], 1e-12), label="kinetic + rotational")
    bottom.semilogy(t, uj * np.maximum(e["contact"] + e["wall"], 1e-12), label="contact and plate springs")
    bottom.set_ylabel("energy (uJ)")
    bottom.set_xlabel("time (ms)")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def pictures(pvd, path, moments):
    """columns.png: the last frame in 3-D and from the side, balls coloured by |m| / (alpha B0)."""
    from PIL import Image

    look = dict(color_by=moments, cmap="plasma", clim=(1.0, CHAIN / LONE), color_label="moment / alpha B0",
                arrows=False, trail=0, frame="box")
    tiles = []
    for view, name in (("iso", "3d"), ("xz", "side")):
        tile = path.with_name(f"columns_{name}.png")
        dk.viz.snapshot(pvd, tile, view=view, window_size=(640, 600), **look)
        tiles.append(Image.open(tile).convert("RGB"))
        tile.unlink()
    sheet = Image.new("RGB", (sum(t.width for t in tiles), max(t.height for t in tiles)), "white")
    x = 0
    for tile in tiles:
        sheet.paste(tile, (x, 0))
        x += tile.width
    sheet.quantize(128).save(path, optimize=True)
    return path


def main(argv=None):
    """Run, write and summarise; ``argv`` are command-line options (None: the defaults).
    Returns the summary numbers and the paths written, as a dict."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=HERE / "output", help="output folder")
    parser.add_argument("--n", type=int, default=200, help="number of balls")
    parser.add_argument("--volume-fraction", type=float, default=0.08, help="balls' volume / cell volume")
    parser.add_argument("--gap", type=float, default=GAP, help="distance between the plates, diameters")
    parser.add_argument("--duration", type=float, default=0.4, help="simulated time, s")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps-per-contact", type=float, default=STEPS_PER_CONTACT,
                        help="time steps in a contact (sets dt)")
    parser.add_argument("--sum", choices=("cutoff", "slab"), default="cutoff",
                        help="dipoles cut off at 4 d, or over every copy of the cell (slab Ewald sum)")
    parser.add_argument("--quick", action="store_true",
                        help="60 balls at volume fraction 0.05 for 0.12 s, 15 steps in a contact (for tests)")
    args = parser.parse_args([] if argv is None else argv)
    if args.quick:
        args.n, args.volume_fraction, args.duration, args.steps_per_contact = 60, 0.05, 0.12, 15
    args.output.mkdir(parents=True, exist_ok=True)
    height = args.gap * D

    particles, box = build(args.n, args.volume_fraction, args.gap, args.seed)
    law = contact_law()
    dipole = slab_dipole() if args.sum == "slab" else \
        dk.Dipole(PREFACTOR, cutoff=CUTOFF * D, switch_width=SWITCH * D, induction=dk.Induction(tolerance=TOLERANCE))
    floor = dk.Wall(point=(0, 0, 0), normal=(0, 0, 1))
    roof = dk.Wall(point=(0, 0, height), normal=(0, 0, -1))
    scene = dk.Scene(particles, [law, dipole, floor, roof, dk.Gravity((0, 0, -G)), dk.UniformField((0, 0, B0))],
                     box=box)
    contact = contact_time()
    frames = 60  # VTK frames; a whole number of steps between them, so the last is the end of the run
    steps = frames * math.ceil(args.duration / (contact / args.steps_per_contact) / frames)
    dt = args.duration / steps
    print(f"{args.n} steel balls of {1e3 * D:g} mm ({1e6 * MASS:.3g} mg, chi = {CHI:g}, beta = {BETA:.4f}) "
          f"between plates {args.gap:g} d = {1e3 * height:g} mm apart, cell {1e3 * box.size[0]:.1f} mm square "
          f"(periodic), volume fraction {args.volume_fraction:g}; B0 = {1e3 * B0:g} mT along z")
    print(f"dipoles: {scene.long_range[0] if scene.long_range else 'cut off at %g d, switched from %g d' % (CUTOFF, CUTOFF - SWITCH)}")
    print(f"moments: lone ball alpha B0 = {LONE:.4g} A m^2; infinite chain alpha B0 / (1 - 4 zeta(3) A alpha / d^3) "
          f"= {CHAIN:.4g} A m^2 ({CHAIN / LONE:.3f} x lone); the same chain through the cutoff at {CUTOFF:g} d "
          f"(switch from {CUTOFF - SWITCH:g} d) {chain_with_cutoff():.4g} A m^2 ({chain_with_cutoff() / CHAIN:.3f} x)")
    print(f"contact {1e6 * contact:.3g} us (k = {STIFFNESS:g} N/m, e = {RESTITUTION:g}); dt = {dt:.3g} s, "
          f"{steps} steps; library limit {scene.max_time_step():.3g} s")

    writer = dk.VTKWriter(args.output / "vtk", every=args.duration / frames, overwrite=True, contacts=True)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt=dt), writers=[writer])
    clock = time.perf_counter()
    traj = sim.run(args.duration, record_every=args.duration / 300)
    seconds = time.perf_counter() - clock
    sim.close()
    solver = scene.induction
    print(f"t = 0 .. {args.duration:g} s in {seconds:.1f} s ({steps / seconds:.0f} steps/s); induced moments: "
          f"{solver.solves} solves, {solver.mean_iterations:.2f} iterations each (at most {solver.most_iterations})")

    # The columns
    found = columns(scene, height)
    rows = sorted(found["columns"], key=lambda r: -r["balls"])
    print(f"columns (2 or more touching balls): {len(rows)}, holding {found['in_columns']} of {args.n} balls "
          f"({found['lone']} alone); {found['spanning_columns']} span the gap (floor to top plate) with "
          f"{found['spanning_balls']} balls ({found['spanning_balls'] / max(found['in_columns'], 1):.0%} of the balls "
          f"in columns), {found['standing_columns']} stand on the floor only")
    print("  balls:  " + " ".join(f"{r['balls']:4d}" for r in rows))
    print("  height: " + " ".join(f"{r['height']:4.1f}" for r in rows) + "  (diameters, bottom to top)")
    print("  spans:  " + " ".join(f"{'yes' if r['floor'] and r['roof'] else ('-' if r['floor'] else 'off'):>4}"
                                  for r in rows))
    print(f"mean contacts per ball {found['coordination']:.2f}; balls on the floor {found['on_floor']}, "
          f"on the top plate {found['on_roof']}")

    # The moments
    m = particles.dipole
    size = np.linalg.norm(m, axis=1)
    chain = found["in_chain"]
    inside = size[chain]
    print(f"|m| / alpha B0 over all balls: {np.min(size) / LONE:.3f} .. {np.max(size) / LONE:.3f} "
          f"(median {np.median(size) / LONE:.3f}); the infinite chain: {CHAIN / LONE:.3f}")
    if chain.any():
        print(f"in-chain balls ({int(chain.sum())}: two contacts, one above, one below, off the plates): "
              f"|m| / m_chain = {inside.min() / CHAIN:.3f} .. {inside.max() / CHAIN:.3f}, mean "
              f"{inside.mean() / CHAIN:.3f}; |m| / alpha B0 mean {inside.mean() / LONE:.3f}")
    # the run's moments against dense solves of the last positions: the exact sum over an infinitely
    # wide layer (every periodic copy in x, y) and the cutoff's sum
    position = particles.position.copy()
    exact = solve_moments(slab_tensor(position, box.size, images=12))
    cut = solve_moments(slab_tensor(position, box.size, cutoff=CUTOFF * D, width=SWITCH * D))
    own = exact if args.sum == "slab" else cut
    check = float(np.abs(own - m).max() / np.abs(m).max())
    wide = np.linalg.norm(exact, axis=1)
    ratio = np.linalg.norm(cut, axis=1) / wide
    layer = layer_moments(position, box)  # demkit's slab Ewald sum on the same positions
    slab_check = float(np.abs(layer - exact).max() / np.abs(exact).max())
    print(f"the same balls, the moments re-solved densely: the scene's own sum ({args.sum}) agrees with the "
          f"run's to {check:.1e} of the largest; the exact sum over every periodic copy gives |m| / alpha B0 "
          f"{wide.min() / LONE:.3f} .. {wide.max() / LONE:.3f} (demkit's slab Ewald sum: the same to "
          f"{slab_check:.1e}); a cutoff at {CUTOFF:g} d gives / exact {ratio.min():.3f} .. {ratio.max():.3f} "
          f"(in-chain balls: mean {ratio[chain].mean() if chain.any() else float('nan'):.3f})")

    # Energy: total + dissipated should keep its starting value (to first order in dt)
    energy = traj.energy
    budget = energy["total"] + energy["dissipated"]
    closure = float(abs(budget[-1] - budget[0]) / energy["dissipated"][-1])
    released = float(energy["magnetic"][0] - energy["magnetic"][-1])
    fallen = float(energy["gravity"][0] - energy["gravity"][-1])
    print(f"energy: magnetic {1e6 * energy['magnetic'][0]:.4g} -> {1e6 * energy['magnetic'][-1]:.5g} uJ, gravity "
          f"released {1e6 * fallen:.4g} uJ, dissipated {1e6 * energy['dissipated'][-1]:.5g} uJ; total at the end "
          f"{1e6 * energy['total'][-1]:.5g} uJ; |total + dissipated - initial| / dissipated = {closure:.2%}")
    kinetic = float(energy["kinetic"][-1] + energy["rotational"][-1])
    speed = np.linalg.norm(particles.velocity, axis=1)
    z = traj.position[:, :, 2]
    lowest, highest = float((z - R).min()), float((height - R - z).min())
    print(f"at the end: kinetic + rotational {1e6 * kinetic:.3g} uJ, speeds median {1e3 * np.median(speed):.3g} "
          f"mm/s, largest {1e3 * speed.max():.3g} mm/s; deepest into the floor {-1e6 * lowest:.3g} um, into the top "
          f"plate {-1e6 * highest:.3g} um over the run")

    title = f"{args.n} steel balls of 2 mm in {1e3 * B0:g} mT between plates {args.gap:g} d apart"
    plot_energy(traj, args.output / "energy.png", title)
    picture = args.output / "columns.png"
    try:
        pictures(writer.pvd, picture, size / LONE)
    except dk.viz.RenderingUnavailable as err:  # no OpenGL here: the series and plot are still there
        print(f"no pictures: {err}")
        picture = None
    print(f"wrote {writer.pvd}, {writer.contact_series.pvd}, {picture}, {args.output / 'energy.png'}")

    summary = {
        "balls": args.n, "sum": args.sum, "gap": args.gap, "box": [float(s) for s in box.size], "B0": B0, "dt": dt, "steps": steps,
        "seconds": seconds, "iterations": solver.mean_iterations,
        "lone": LONE, "chain": CHAIN, "chain_cutoff": float(chain_with_cutoff()),
        "moments": [float(v) for v in size], "in_chain": [bool(v) for v in chain],
        "exact_moments": [float(v) for v in wide], "cutoff_moments": [float(v) for v in np.linalg.norm(cut, axis=1)],
        "dense_check": check, "slab_check": slab_check,
        "columns": rows, "lone_balls": found["lone"], "in_columns": found["in_columns"],
        "spanning_balls": found["spanning_balls"], "spanning_columns": found["spanning_columns"],
        "standing_columns": found["standing_columns"],
        "closure": closure, "released": released, "fallen": fallen, "dissipated": float(energy["dissipated"][-1]),
        "kinetic": kinetic, "lowest": lowest, "highest": highest,
        "pvd": str(writer.pvd), "contacts_pvd": str(writer.contact_series.pvd),
        "picture": picture and str(picture), "energy_plot": str(args.output / "energy.png")}
    (args.output / "summary.json").write_text(json.dumps({k: v for k, v in summary.items()
                                                          if k not in ("moments", "in_chain", "exact_moments",
                                                                       "cutoff_moments")},
                                                         indent=1) + "\n")
    return summary


if __name__ == "__main__":
    main(sys.argv[1:])
