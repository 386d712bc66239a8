"""Guards before and during runs (demkit.guards): each check refuses the scene it is for, with the
numbers to change, and lets sane scenes through."""
import math
import re

import numpy as np
import pytest

import demkit as dk
from demkit import guards

from conftest import R_PAPER, two_magnets


def advice(message, name):
    """The value of 'Use <name> <= x' or 'Use <name> >= x' in a guard's message."""
    found = re.search(rf"Use {name} [<>]= ([0-9][0-9.e+-]*[0-9])", message)
    assert found, message
    return float(found.group(1))


def refusal(scene, integrator):
    with pytest.raises(ValueError) as info:
        dk.Simulation(scene, integrator)
    return str(info.value)


def magnet_pair(distance=1.5, contact=None, prefactor=1.0 / 3.0, **extra):
    """Two unit-diameter spheres (m = 1) with head-to-tail unit moments, at rest."""
    p = dk.Particles(position=[[0, 0, 0], [distance, 0, 0]], radius=0.5, mass=1.0,
                     dipole=[[1, 0, 0], [1, 0, 0]], **extra)
    return dk.Scene(p, [dk.Dipole(prefactor)] + ([contact] if contact is not None else []))


# ---- 1: dipoles ---------------------------------------------------------------------------------
def rotated(v, phi):
    t = np.linalg.norm(phi)
    if t == 0:
        return v
    k = phi / t
    return v * math.cos(t) + np.cross(k, v) * math.sin(t) + k * (k @ v) * (1 - math.cos(t))


def pair_hessian_rate(scene, free):
    """Largest |eigenvalue| of the mass-weighted Hessian of the magnetic energy over the positions and
    small rotations of the spheres in ``free`` (central differences)."""
    p = scene.particles
    x0, m0 = p.position.copy(), p.dipole.copy()
    dofs = [(k, kind, a) for k in free for kind in ("x", "phi") for a in range(3)]
    weight = np.array([p.mass[k] if kind == "x" else p.inertia[k] for k, kind, _ in dofs])
    h = 1e-4

    def energy(steps):
        p.position[:] = x0
        p.dipole[:] = m0
        phi = np.zeros((len(p), 3))
        for (k, kind, a), s in zip(dofs, steps):
            if kind == "x":
                p.position[k, a] += s
            else:
                phi[k, a] += s
        for k in free:
            p.dipole[k] = rotated(m0[k], phi[k])
        return scene.energy()["magnetic"]

    n = len(dofs)
    hess = np.zeros((n, n))
    for a in range(n):
        for b in range(a, n):
            e = []
            for sa, sb in ((h, h), (h, -h), (-h, h), (-h, -h)):
                steps = np.zeros(n)
                steps[a] += sa
                steps[b] += sb
                e.append(energy(steps))
            hess[a, b] = hess[b, a] = (e[0] - e[1] - e[2] + e[3]) / (4 * h * h)
    energy(np.zeros(n))
    return float(np.abs(np.linalg.eigvalsh(hess / np.sqrt(np.outer(weight, weight)))).max())


@pytest.mark.parametrize("case", ["aligned", "random", "unequal", "one fixed", "one fixed, random"])
def test_dipole_rate_bounds_the_pair_hessian(case):
    """omega^2 = a/r^5 + b/r^3 bounds the largest eigenvalue of the pair's mass-weighted Hessian
    (positions and rotations): within a factor 2 of it for head-to-tail moments (where the pull
    is strongest), 3 for random ones."""
    rng = np.random.default_rng(7)
    aligned = "random" not in case and case != "unequal"
    moments = [[1, 0, 0], [1, 0, 0]] if aligned else rng.normal(size=(2, 3))
    mass = [1.0, 2.5] if case == "unequal" else 1.0
    factor = [0.4, 0.1] if case == "unequal" else 0.4
    fixed = [True, False] if case.startswith("one fixed") else None
    second = [1.1, 0, 0] if aligned else [1.1, 0.2, -0.1]
    p = dk.Particles(position=[[0, 0, 0], second], radius=0.5, mass=mass, inertia_factor=factor, dipole=moments,
                     fixed=fixed)
    dipole = dk.Dipole(0.7)
    scene = dk.Scene(p, [dipole])
    i, j = np.array([0]), np.array([1])
    a, b = dipole.rate_coefficients(p, i, j)
    r = np.linalg.norm(p.position[1] - p.position[0])
    predicted = float(a[0] / r**5 + b[0] / r**3)
    measured = pair_hessian_rate(scene, [1] if fixed else [0, 1])
    assert measured <= predicted * (1 + 1e-6)
    assert measured > predicted / (2.0 if aligned else 3.0)  # measured ratios 1.62, 1.60; 1.97, 1.91, 2.76


def test_dipole_only_scene_at_a_large_step_is_refused_with_the_step_to_use():
    # observed before the guard: dt = 5 ran silently to spheres thrown hundreds of diameters apart
    message = refusal(magnet_pair(), dk.VelocityVerlet(5.0))
    assert message.startswith("time step dt = 5 is too large for the dipole forces")
    assert "closest distance now" in message
    dt = advice(message, "dt")
    # the advice: omega dt = 0.5 at the closest pair, omega^2 = 24 A (2/m)/r^5 + 3 A/(I r^3)
    omega = math.sqrt(24 / 3 * 2 / 1.5**5 + 3 / 3 / (0.1 * 1.5**3))
    assert dt == pytest.approx(0.5 / omega, rel=1e-3)
    dk.Simulation(magnet_pair(), dk.VelocityVerlet(dt))


def test_dipole_only_scene_is_rechecked_at_the_closest_pair_while_stepping():
    scene = magnet_pair(distance=4.0)
    dt = 0.3
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt))
    assert guards.while_stepping(scene, sim.integrator) is None
    scene.particles.position[1, 0] = 1.05  # the pair fell together
    message = guards.while_stepping(scene, sim.integrator)
    assert message.startswith("time step dt = 0.3 is too large for the dipole forces")
    assert "r = 1.05" in message and "during a run" in message


def test_multiple_time_stepping_outer_step_is_checked_against_the_dipoles():
    """Contacts on the inner step are fine; the dipoles on the outer step are not."""
    def scene():
        p = dk.Particles(position=[[0.0, 0.0, 0.0], [1.6, 0.5, 0.0]], velocity=[[0, 0, 0], [-0.6, 0, 0]],
                         radius=0.5, dipole=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        return dk.Scene(p, [dk.Dipole(prefactor=1.0 / 3.0), dk.KelvinVoigt(2000.0, 2.0)])

    limit = scene().max_time_step()
    dk.Simulation(scene(), dk.MultipleTimeStep(10 * limit, inner=20))  # omega dt = 0.25 at touching
    message = refusal(scene(), dk.MultipleTimeStep(40 * limit, inner=80))
    assert message.startswith(f"time step dt = {40 * limit:.6g} is too large for the dipole forces: touching")
    dt = advice(message, "dt")
    assert 10 * limit < dt < 40 * limit  # omega dt = 0.5 at touching: 0.098
    dk.Simulation(scene(), dk.MultipleTimeStep(dt, inner=80))


def test_very_strong_dipoles_are_refused_for_both_reasons():
    # observed before the guard: Dipole(prefactor=1e12) ran to spheres 5e13 apart
    message = refusal(magnet_pair(1.2, dk.KelvinVoigt(1.0, 0.1), prefactor=1e12), dk.VelocityVerlet(0.01))
    lines = message.split(" Also: ")
    assert lines[0].startswith("contact stiffness = 1 is too soft for the magnetic attraction")
    assert lines[1].startswith("time step dt = 0.01 is too large for the dipole forces")


def test_a_uniform_field_sets_a_time_step():
    p = dk.Particles(position=[[0, 0, 0]], radius=0.5, mass=1.0, dipole=[[1, 0, 0]])
    scene = dk.Scene(p, [dk.UniformField((0, 1000.0, 0))])
    omega = math.sqrt(1000.0 / 0.1)  # |m||B|/I
    assert scene.max_time_step() == pytest.approx(0.5 / omega)
    message = refusal(scene, dk.VelocityVerlet(0.01))
    assert message.startswith("time step dt = 0.01 is too large for UniformField")
    dk.Simulation(scene, dk.VelocityVerlet(advice(message, "dt")))


# ---- 2: spins -------------------------------------------------------------------------------------
def test_spins_that_feel_torques_turn_at_most_a_radian_per_step():
    dt = 0.01

    def spinning(turn, interactions):
        p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=0.5, dipole=[[1, 0, 0], [0, 1, 0]],
                         angular_velocity=[[0, 0, turn / dt], [0, 0, 0]])
        return dk.Scene(p, interactions)

    message = refusal(spinning(1.5, [dk.Dipole(1.0)]), dk.VelocityVerlet(dt))
    assert message.startswith("time step dt = 0.01 is too large for the spin of particle 0: |omega| = 150 "
                              "turns it by 1.5 rad per step")
    assert advice(message, "dt") == pytest.approx(1 / 150, rel=1e-3)
    sim = dk.Simulation(spinning(0.9, [dk.Dipole(1.0)]), dk.VelocityVerlet(dt))
    # free spin is exact at any rate: no torque on a sphere without dipole interactions or friction
    dk.Simulation(spinning(5.0, [dk.KelvinVoigt(1.0)]), dk.VelocityVerlet(dt))
    # during a run, twice the limit
    assert guards.while_stepping(sim.scene, sim.integrator) is None
    sim.scene.particles.angular_velocity[0, 2] = 2.5 / dt
    assert "turns it by 2.5 rad per step" in guards.while_stepping(sim.scene, sim.integrator)


# ---- 3: Hertz at the approach speed -----------------------------------------------------------
def test_hertz_contacts_are_resolved_at_the_speed_magnets_snap_together_with():
    law = dk.Hertz(young=1e6, poisson=0.3, restitution=0.5)
    scene = magnet_pair(1.5, law)
    assert scene.max_time_step() == math.inf  # at rest: the law alone sees no speed
    message = refusal(scene, dk.VelocityVerlet(2e-3))
    assert message.startswith("time step dt = 0.002 is too large for the stiffest contact (Hertz")
    snap = math.sqrt(2 * (2 / 3) / 0.5)  # energy 2 A/d^3 released into the reduced mass 1/2
    assert f"{snap:.4g} of magnets snapping together" in message
    dt = advice(message, "dt")
    assert dt == pytest.approx(law.max_time_step(scene.particles, snap), rel=1e-3)
    sim = dk.Simulation(magnet_pair(1.5, law), dk.VelocityVerlet(dt))
    traj = sim.run(3.0, record_every=dt)  # they snap and bounce: resolved, and still trusted
    assert guards.while_stepping(sim.scene, sim.integrator) is None
    assert np.isfinite(traj.position).all()


def test_hertz_contacts_are_rechecked_when_the_speeds_grow():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], velocity=[[0.1, 0, 0], [0, 0, 0]], radius=0.5)
    law = dk.Hertz(young=1e6, poisson=0.3)
    scene = dk.Scene(p, [law])
    dt = scene.max_time_step()
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt))
    assert guards.while_stepping(scene, sim.integrator) is None
    p.velocity[0, 0] = 0.1 * 2**5 * 0.9  # contact time ~ v^(-1/5): still within twice the safe step
    assert guards.while_stepping(scene, sim.integrator) is None
    p.velocity[0, 0] = 0.1 * 2**5 * 1.1
    message = guards.while_stepping(scene, sim.integrator)
    assert message.startswith(f"time step dt = {dt:.6g} is too large for the stiffest contact (Hertz")
    assert "fastest speed now" in message and "up to 2 times it is accepted" in message


# ---- 3b: gravity, walls and moving walls bound the impact speed before stepping ------------------
def falling(position, walls, gravity=(0.0, 0.0, -9.81), velocity=None, fixed=None):
    """Spheres (R = 0.5, m = 1) under gravity among ``walls``, with a Hertz contact (no kernel is compiled)."""
    p = dk.Particles(position=position, velocity=velocity, radius=0.5, mass=1.0, fixed=fixed)
    return dk.Scene(p, [dk.Hertz(1e6, 0.3), dk.Gravity(gravity)] + walls)


def test_the_fastest_impact_is_the_free_fall_speed_over_the_drop_to_the_walls():
    g, h, R = 9.81, 2.0, 0.5
    floor = dk.Wall((0, 0, 0), (0, 0, 1))
    scene = falling([[0, 0, R + h], [3, 0, R + h / 4]], [floor])
    speed, why = guards.fastest_impact(scene)
    assert speed == pytest.approx(math.sqrt(2 * g * h), rel=1e-12)
    assert why.startswith("particle 0 falling from speed 0 through h = 2 under g = 9.81")
    # spheres at rest: before, no largest step (inf); now Hertz at twice the fall speed
    limit, why = guards.largest_safe_step(scene)
    law = scene.interactions[0]
    assert limit == pytest.approx(law.max_time_step(scene.particles, 2 * math.sqrt(2 * g * h)), rel=1e-12)
    assert "twice the fastest impact speed" in why
    # a speed present adds in energy, sqrt(v0^2 + 2 g h); a fixed sphere neither falls nor counts
    scene = falling([[0, 0, R + h], [3, 0, 10.0]], [floor], velocity=[[0, 3.0, 0], [0, 0, 0]], fixed=[False, True])
    assert guards.fastest_impact(scene)[0] == pytest.approx(math.sqrt(9 + 2 * g * h), rel=1e-12)
    # a moving wall adds its speed
    scene = falling([[0, 0, R + h]], [dk.Wall((0, 0, 0), (0, 0, 1), velocity=(0.0, 0.7, 0.0))])
    assert guards.fastest_impact(scene)[0] == pytest.approx(math.sqrt(2 * g * h) + 0.7, rel=1e-12)
    # gravity tilted onto a V-shaped trough: the smallest sphere's lowest place is the bottom of the V,
    # its centre R sqrt(2) above the edge, wherever the sphere starts (it slides down a flank)
    trough = [dk.Wall((0, 0, 0), (1, 0, 1)), dk.Wall((0, 0, 0), (-1, 0, 1))]
    tilt = (0.0, 9.81 * math.sin(0.3), -9.81 * math.cos(0.3))  # along the trough's edge: no bottom
    assert guards.fall_heights(falling([[2.0, 0, 5.0]], trough, gravity=tilt))[0] is None
    heights, size, _ = guards.fall_heights(falling([[2.0, 0, 5.0]], trough))
    assert size == 9.81 and heights[0] == pytest.approx(5.0 - R * math.sqrt(2), rel=1e-9)
    # a tilted floor with nothing at its foot does not bound the fall: said so, nothing made up
    slope = falling([[0, 0, 3.0]], [dk.Wall((0, 0, 0), (0.2, 0, 1))])
    speed, why = guards.fastest_impact(slope)
    assert speed == 0.0 and "no plane wall below the spheres to stop their fall" in why
    limit, why = guards.largest_safe_step(slope)
    assert limit == math.inf and "gravity with a wall below" in why


def test_a_pour_from_rest_runs_to_its_end_at_the_step_the_guards_give():
    """40 Hertz spheres with friction, nearly at rest (1e-5 m/s), poured 0.3 m onto a floor. Before,
    the largest safe step came from the speeds at the start: half of it (what dt = "auto" takes) was
    stopped at step 16, when the fall had reached 0.08 m/s (measured). Now it is set by the impact
    at sqrt(2 g h) = 2.47 m/s, and the pour runs to its end (the fastest sphere reaches 2.35 m/s)."""
    n, R, g = 40, 0.01, 9.81
    rng = np.random.default_rng(2)
    k = np.arange(n)
    x = np.stack([0.025 * (k % 3), 0.025 * ((k // 3) % 3), 0.02 + 0.3 * (k // 9) / ((n - 1) // 9)], axis=1)
    x[:, :2] += rng.uniform(-0.002, 0.002, size=(n, 2))
    p = dk.Particles(position=x, velocity=rng.normal(0.0, 1e-5, size=(n, 3)), radius=R, mass=4e-3)
    scene = dk.Scene(p, [dk.Hertz(1e7, 0.3, 0.5, friction=dk.Friction(0.3)), dk.Wall((0, 0, 0), (0, 0, 1)),
                         dk.Gravity((0, 0, -g))])
    limit, _ = guards.largest_safe_step(scene)
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.5 * limit))
    traj = sim.run(0.35, record_every=0.01)
    assert traj.time[-1] > 0.35 - sim.integrator.dt  # to its end (a whole number of steps)
    speed = math.sqrt(2 * g * (x[:, 2].max() - R))
    assert np.linalg.norm(traj.velocity, axis=2).max() < speed  # the bound held
    assert p.position[:, 2].max() < 0.1  # they landed
    assert guards.while_stepping(scene, sim.integrator) is None


def test_dt_auto_in_a_scene_file_takes_the_fall_onto_the_floor_into_account():
    """Before, "auto" in a file of spheres at rest above a floor found no largest safe step."""
    text = """
[particles]
position = [[0.0, 0.0, 2.5], [2.0, 0.0, 1.0]]
radius = 0.5
[interactions.hertz]
young = 1e6
poisson = 0.3
[interactions.gravity]
acceleration = [0.0, 0.0, -9.81]
[[interactions.wall]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[integrator]
dt = "auto"
[run]
duration = 1.0
"""
    loaded = dk.parse_scene(text)
    law = loaded.scene.interactions[0]
    expected = law.max_time_step(loaded.scene.particles, 2 * math.sqrt(2 * 9.81 * 2.0))
    assert loaded.step_choice.stable == pytest.approx(0.5 * expected, rel=1e-12)  # stage 1 of "auto"
    assert loaded.integrator.dt <= loaded.step_choice.stable


# ---- 4: geometry at every run start --------------------------------------------------------------
def test_a_sphere_behind_a_wall_is_refused_at_the_start_of_every_run():
    p = dk.Particles(position=[[0, 0, 1.0]], radius=0.5)
    scene = dk.Scene(p, [dk.KelvinVoigt(100.0), dk.Wall((0, 0, 0), (0, 0, 1))])
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.01))
    sim.run(0.1)
    p.position[0, 2] = -0.2  # moved through the floor between runs
    with pytest.raises(ValueError, match="particle 0 at .* starts behind the wall"):
        sim.run(0.1)


# ---- 5: can the contact hold the magnets? -------------------------------------------------------
def test_a_contact_too_soft_for_the_magnets_is_refused_with_the_stiffness_needed():
    # observed before the guard: the README's k = 1 with these magnets let them pass through each
    # other (total energy from 0.72 to 4.4e9, no error)
    message = refusal(magnet_pair(1.5, dk.KelvinVoigt(1.0, 0.1)), dk.VelocityVerlet(0.01))
    assert message.startswith("contact stiffness = 1 is too soft for the magnetic attraction")
    # static pull 6 A/d^4 = 2 needs an overlap of 2/k = 4 R; the snap's 2 A/d^3 needs sqrt(4/3) R
    assert "overlap of 4 of the smaller radius" in message and "needs 2.31 of it" in message
    k = advice(message, "stiffness")
    # stores in 0.35 R = 0.175 the energy released down to that overlap, (2/3) / (1 - 0.175)^3
    assert k == pytest.approx(2 * (2 / 3) / (1 - 0.175) ** 3 / 0.175**2, rel=1e-3)
    scene = magnet_pair(1.5, dk.KelvinVoigt(k, 0.0))
    dt = scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(6.0, record_every=dt)
    gap = traj.position[:, 1, 0] - traj.position[:, 0, 0]
    # they snap together and are held, at most 0.35 R deep (the stiffness the energy estimate without
    # the growth of the attraction advised, 43.5, let them reach 0.59 R: past the deep-overlap stop)
    assert 1.0 - 0.175 * 1.01 < gap.min() < 1.0
    # the same soft contact is accepted while the magnets are far apart, and refused when they come close
    far = magnet_pair(2.5, dk.KelvinVoigt(1.0, 0.1))
    sim = dk.Simulation(far, dk.VelocityVerlet(0.01))
    assert guards.while_stepping(far, sim.integrator) is None
    far.particles.position[1, 0] = 1.9
    assert guards.while_stepping(far, sim.integrator).startswith("contact stiffness = 1 is too soft")


def test_a_hertz_contact_too_soft_for_the_magnets_names_the_young_modulus_needed():
    message = refusal(magnet_pair(1.5, dk.Hertz(young=100.0, poisson=0.3)), dk.VelocityVerlet(1e-4))
    assert message.startswith("contact young = 100 is too soft for the magnetic attraction")
    young = advice(message, "young")
    law = dk.Hertz(young=young * 1.0001, poisson=0.3)
    p = magnet_pair(1.5, law).particles
    grow = 1 / (1 - 0.175)  # the attraction at an overlap of 0.35 R
    _, stored = law.overlaps(p, np.array([0]), np.array([1]), 2.0 * grow**4, 2 / 3 * grow**3)
    assert stored[0] == pytest.approx(0.35 * 0.5, rel=1e-3)
    assert not guards._contact_problems(magnet_pair(1.5, law))


def test_polydisperse_scenes_are_checked_against_their_extreme_spheres():
    n = 100  # more kinds of sphere than KINDS_MAX: each is paired with the extreme ones
    radius = np.linspace(0.3, 0.6, n)
    x = np.zeros((n, 3))
    x[1:, 0] = np.cumsum(radius[:-1] + radius[1:] + 0.1)  # a row, 0.1 apart
    p = dk.Particles(position=x, radius=radius, dipole=np.tile([1.0, 0.0, 0.0], (n, 1)))
    message = refusal(dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(100.0, 1.0)]), dk.VelocityVerlet(1e-3))
    assert message.startswith("contact stiffness = 100 is too soft")
    # the truth, over every pair closer than twice its contact distance: the stiffness that holds
    # the pull 6A/s^4 and stores the energy 2A/s^3 released down to s = r - 0.35 of the smaller radius
    i, j = np.triu_indices(n, 1)
    r = radius[i] + radius[j]
    near = np.abs(x[j, 0] - x[i, 0]) < 2 * r
    small = 0.35 * np.minimum(radius[i], radius[j])
    s = r - small
    needed = np.maximum(6 / s**4 / small, 2 * 2 / s**3 / small**2)[near].max()
    assert advice(message, "stiffness") == pytest.approx(needed, rel=1e-3)


# ---- legitimate scenes pass ------------------------------------------------------------------------
def test_sane_scenes_pass_before_and_while_stepping():
    # the seed paper's collision, mid-contact too
    sim = dk.Simulation(two_magnets(), dk.EulerCromer(0.01))
    assert guards.while_stepping(sim.scene, sim.integrator) is None
    traj = sim.run(27000.0, record_every=10.0)
    assert np.linalg.norm(np.diff(traj.position, axis=1), axis=2).min() < 2.01 * R_PAPER  # they met
    assert guards.while_stepping(sim.scene, sim.integrator) is None
    # the benchmarks' magnetic gas (docs/builders.md)
    n, r = 300, 0.5
    box = dk.build.box_for(n, r, volume_fraction=0.2)
    rng = np.random.default_rng(1)
    p = dk.Particles(position=dk.build.random_packing(n, r, box, seed=rng), radius=r,
                     velocity=dk.build.thermal_velocities(n, kT=1.0, mass=1.0, seed=rng),
                     dipole=2.0 * dk.build.random_directions(n, seed=rng))
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=4.0), dk.KelvinVoigt(1000.0, 1.5)], box=box)
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.5 * scene.max_time_step()))
    assert guards.while_stepping(scene, sim.integrator) is None


def test_the_lowest_place_between_walls_is_scipys_linear_programme():
    """guards.lowest_place (duality, by enumeration: no scipy.optimize at a scene's start) against
    scipy's linprog on 600 random sets of one to eight walls: the same lowest place (to 1e-9 of the
    planes' scale, round-off of 3 x 3 solves) and the same verdict where the walls do not stop the fall."""
    from scipy.optimize import linprog
    rng = np.random.default_rng(11)
    bounded = unbounded = 0
    for _ in range(600):
        m = int(rng.integers(1, 9))
        normals = rng.normal(size=(m, 3))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        if rng.random() < 0.4:
            normals[0] = (0.0, 0.0, 1.0)  # a floor
        planes = rng.normal(size=m)
        down = np.array([0.0, 0.0, -1.0]) if rng.random() < 0.7 else rng.normal(size=3)
        down /= np.linalg.norm(down)
        lp = linprog(-down, A_ub=-normals, b_ub=-planes, bounds=[(None, None)] * 3, method="highs")
        if lp.status == 2:  # no room at all: an upper bound only (documented)
            continue
        ours = guards.lowest_place(normals, planes, down)
        if lp.status == 0:
            assert ours == pytest.approx(float(down @ lp.x), abs=1e-9)
            bounded += 1
        else:
            assert lp.status == 3 and ours is None
            unbounded += 1
    assert bounded > 100 and unbounded > 100
