"""Walls that move (dk.Wall / dk.Cylinder with velocity, amplitude, frequency): a sphere on a vibrated
plate leaves it at the phase where the plate falls faster than g, a piston squeezes a sphere by Hertz's
force-indentation law and does the work the sphere gains, the time loops evaluate the walls at the
right times (each integrator keeps its order), a moving wall is the static one moved there, and
restarts and bad input."""
import math

import numpy as np
import pytest

import demkit as dk

G = 9.81


def vibrated_bed(gamma, f=5.0, k=1e8, zeta=0.5, m=1.0, R=0.01, damping=None):
    """A sphere at rest on a floor that vibrates by A (1 - cos 2 pi f t) along z, Gamma = A (2 pi f)^2 / g,
    a Kelvin-Voigt contact of natural rate sqrt(k/m) (damping ratio zeta) that cannot pull."""
    w = 2 * math.pi * f
    amplitude = gamma * G / w**2
    c = 2 * zeta * math.sqrt(k * m) if damping is None else damping
    p = dk.Particles(position=[[0.0, 0.0, R - m * G / k]], radius=R, mass=m)
    law = dk.KelvinVoigt(k, c, no_tension=True)
    floor = dk.Wall((0, 0, 0), (0, 0, 1), amplitude=(0, 0, amplitude), frequency=f)
    return dk.Scene(p, [law, dk.Gravity((0, 0, -G)), floor]), law, floor


def contact_force(traj, m=1.0):
    """(times, force): the floor's force on the sphere between frames, m (dv/dt + g) from the recorded
    velocities (gravity is the only other force), at the middle of each interval."""
    t, v = traj.time, traj.velocity[:, 0, 2]
    return 0.5 * (t[1:] + t[:-1]), m * (np.diff(v) / np.diff(t) + G)


@pytest.mark.parametrize("gamma", [0.8, 1.5, 3.0])
def test_a_sphere_on_a_vibrated_plate_leaves_it_where_the_plate_falls_faster_than_g(gamma):
    """The plate's acceleration is A w^2 cos(w t) along z: below Gamma = 1 the sphere rides it (the
    contact force m (g + A w^2 cos w t) stays positive over two periods, to 1e-3 m g); above, the force
    first vanishes where A w^2 cos(w t) = -g, at w t = arccos(-1 / Gamma), and the sphere flies
    (acceleration -g). Tolerance 0.002 rad: the contact (natural rate 1e4 /s against w = 31 /s) lets
    the sphere lag the quasi-static force by about c / k = 1e-4 s (0.003 rad), and frames every 1e-5 s
    (0.0003 rad)."""
    scene, law, floor = vibrated_bed(gamma)
    w = 2 * math.pi * floor.frequency
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-5)).run(2.0 / floor.frequency, record_every=1e-5,
                                                               progress=False)
    t, force = contact_force(traj)
    riding = G + floor.amplitude[2] * w**2 * np.cos(w * t)
    if gamma < 1:
        assert np.allclose(force[t > 0.01], riding[t > 0.01], atol=1e-3 * G)  # (after the start's transient)
        return
    leave = np.flatnonzero(force <= 1e-6 * G)[0]
    assert w * t[leave] == pytest.approx(math.acos(-1 / gamma), abs=2e-3)
    assert np.allclose(force[t < t[leave] - 2e-4][1000:], riding[t < t[leave] - 2e-4][1000:], atol=1e-2 * G)
    assert np.abs(force[leave:leave + 1000]).max() < 1e-6 * G  # free flight


def test_a_piston_squeezes_a_sphere_by_hertz_law_and_its_work_is_the_energy_the_sphere_gains():
    """No gravity: a Hertz sphere between a floor and a piston coming down at speed v, the sphere
    moving down at v/2: by symmetry the two contacts share the closing of the gap, delta = (2 R - h) / 2
    each at all times, the forces balance and the sphere keeps its speed. Each contact pushes with
    F = 4/3 E/(1 - nu^2) sqrt(R) delta^(3/2) (a rigid flat on an elastic sphere): checked on the
    contact table at three depths to 1e-9 (round-off). Elastic (restitution 1): the work of the
    piston, the integral of F v over the run from the recorded state (trapezoid, 3000 frames), equals
    the elastic energy the two contacts gained to 1e-5 of it (the quadrature)."""
    R, E, nu, v = 0.5, 1e5, 0.3, 0.05
    p = dk.Particles(position=[[0.0, 0.0, R]], velocity=[[0.0, 0.0, -v / 2]], radius=R, mass=1.0)
    law = dk.Hertz(young=E, poisson=nu)
    floor, piston = dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, 2 * R), (0, 0, -1), velocity=(0, 0, -v))
    scene = dk.Scene(p, [law, floor, piston])
    sim = dk.Simulation(scene, dk.VelocityVerlet(2e-4))
    young = E / (1 - nu**2)
    frames = []
    for _ in range(3):
        frames.append(sim.run(0.2, record_every=2e-4, progress=False))
        gap = 2 * R - v * sim.time
        delta = (2 * R - gap) / 2
        c = scene.contacts()
        assert sorted(c.wall.tolist()) == [0, 1]
        assert np.allclose(c.overlap, delta, rtol=1e-9)
        assert np.allclose(c.normal_force, 4 / 3 * young * math.sqrt(R) * delta**1.5, rtol=1e-9)
    t = np.concatenate([f.time[1:] for f in frames])
    z = np.concatenate([f.position[1:, 0, 2] for f in frames])
    top = np.maximum(R - (2 * R - v * t - z), 0.0)
    work = np.trapezoid(4 / 3 * young * math.sqrt(R) * top**1.5 * v, t)
    energy = scene.energy()
    assert energy["kinetic"] == pytest.approx(0.5 * (v / 2) ** 2, rel=1e-9)
    assert energy["wall"] > 0 and work == pytest.approx(energy["wall"], rel=1e-5)


@pytest.mark.parametrize("integrator, order", [(dk.EulerCromer, 1), (dk.VelocityVerlet, 2), (dk.ForestRuth, 4),
                                               (dk.RK4, 4)], ids=["euler_cromer", "verlet", "forest_ruth", "rk4"])
def test_each_integrator_keeps_its_order_on_a_vibrated_plate(integrator, order):
    """A sphere riding a plate vibrated at Gamma = 0.3 (always in contact, a smooth problem): the error
    of the end state against the same method at dt/16 falls as dt^order from dt to dt/2 (measured
    order within 0.3 of it; Euler-Cromer, first order in general, gains one on an oscillator: at least
    its order). The wall is evaluated at each stage's own time: evaluated at the step's start
    instead, Forest-Ruth and RK4 fall to first order."""
    def end(dt):
        scene, _, _ = vibrated_bed(0.3, f=2.0, k=1e4, damping=0.0, R=0.1)
        dk.Simulation(scene, integrator(dt)).run(0.5, progress=False)
        return scene.particles.position[0, 2], scene.particles.velocity[0, 2]

    dt = 2e-3
    truth = np.array(end(dt / 16))
    errors = [np.abs(np.array(end(h)) - truth).max() for h in (dt, dt / 2)]
    measured = math.log2(errors[0] / errors[1])
    assert measured > order - 0.3 if integrator is dk.EulerCromer else measured == pytest.approx(order, abs=0.3)


def test_a_moving_wall_is_the_static_wall_moved_there():
    """At any time a moving wall's forces on spheres are those of the same wall built where it stands
    then, with the spheres' velocities taken relative to it (Galilean invariance of the contact): a
    tilted plane carried by a velocity and a vibration, and a turning cylinder shaken along a tilted
    direction, to round-off."""
    rng = np.random.default_rng(3)
    law = dk.KelvinVoigt(1e4, 5.0)
    moving = [dk.Wall((0, 0, -0.3), (0, 0.6, 0.8), velocity=(0.02, -0.01, 0.01), amplitude=(0.03, 0, 0.01),
                      frequency=1.3),
              dk.Cylinder((0.1, 0, 0), (0, 0, 1), 2.0, velocity=(0.005, 0.01, 0.0), amplitude=(0.01, -0.005, 0.005),
                          frequency=0.7, angular_velocity=0.4)]
    grid = np.array([[a, b] for a in (-1.0, 0.0, 1.0) for b in (-0.5, 0.5)])  # six spheres, apart
    for wall in moving:
        for t in (0.0, 0.37, 2.5):
            shift, speed = wall.displacement(t)
            depth = np.array([0.3, 0.32, 0.6, 0.27, 0.9, 0.33])  # centre to surface: below 0.35 touching
            if isinstance(wall, dk.Cylinder):
                angle = grid[:, 0] * 0.9
                radial = np.stack([np.cos(angle), np.sin(angle), np.zeros(len(grid))], axis=1)
                position = wall.point + shift + (2.0 - depth)[:, None] * radial + np.outer(grid[:, 1], wall.axis)
                still = dk.Cylinder(wall.point + shift, wall.axis, wall.radius, angular_velocity=0.4)
            else:
                u = np.cross(wall.normal, (1.0, 0, 0))
                u /= np.linalg.norm(u)
                v = np.cross(wall.normal, u)
                position = wall.point + shift + np.outer(grid[:, 0], u) + np.outer(grid[:, 1], v) + np.outer(depth,
                                                                                                            wall.normal)
                still = dk.Wall(wall.point + shift, wall.normal)
            velocity = rng.normal(size=(len(grid), 3))
            a = dk.Scene(dk.Particles(position=position, velocity=velocity, radius=0.35, mass=1.0), [law, wall])
            a.time = t
            b = dk.Scene(dk.Particles(position=position, velocity=velocity - speed, radius=0.35, mass=1.0),
                         [law, still])
            fa, fb = a.forces()[0], b.forces()[0]
            assert np.abs(fa).max() > 1.0  # some spheres touch
            assert np.allclose(fa, fb, rtol=1e-9, atol=1e-9 * np.abs(fa).max())
            assert np.allclose(a.contacts().normal_force, b.contacts().normal_force, rtol=1e-9)


def test_runs_cut_anywhere_and_resumed_from_checkpoints_give_the_same_bits(tmp_path):
    """The clock is the step count times dt: a run in pieces, and a run resumed from a checkpoint
    in the middle, give the bits of one run (a sphere bouncing on a plate vibrated at Gamma = 3)."""
    def fresh():
        return vibrated_bed(3.0, k=1e6)[0]

    one = fresh()
    dk.Simulation(one, dk.VelocityVerlet(1e-4)).run(0.3, progress=False)
    pieces = fresh()
    sim = dk.Simulation(pieces, dk.VelocityVerlet(1e-4))
    for _ in range(3):
        sim.run(0.1, progress=False)
    assert pieces.time == pytest.approx(0.3) and one.time == pieces.time
    assert pieces.particles.position.tobytes() == one.particles.position.tobytes()
    first = fresh()
    sim = dk.Simulation(first, dk.VelocityVerlet(1e-4), checkpoint=dk.Checkpoint(tmp_path / "c.npz"))
    sim.run(0.15, progress=False)
    again = fresh()
    resumed = dk.Simulation(again, dk.VelocityVerlet(1e-4)).resume(tmp_path / "c.npz")
    resumed.run(0.15, progress=False)
    assert again.particles.position.tobytes() == one.particles.position.tobytes()


def test_bad_motions_and_a_clock_that_jumps_are_refused():
    with pytest.raises(ValueError, match="amplitude and a frequency"):
        dk.Wall((0, 0, 0), (0, 0, 1), frequency=2.0)
    with pytest.raises(ValueError, match="amplitude and a frequency"):
        dk.Wall((0, 0, 0), (0, 0, 1), amplitude=(0, 0, 0.1))
    with pytest.raises(ValueError, match="frequency must be finite and >= 0"):
        dk.Wall((0, 0, 0), (0, 0, 1), amplitude=(0, 0, 0.1), frequency=-1.0)
    with pytest.raises(ValueError, match="Cylinder amplitude must be finite"):
        dk.Cylinder((0, 0, 0), (0, 0, 1), 2.0, amplitude=(0, math.nan, 0), frequency=1.0)
    scene = vibrated_bed(0.5, k=1e6)[0]
    dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(0.01, progress=False)
    with pytest.raises(ValueError, match="clock stands at t = 0.01.*would jump"):
        dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(0.01, progress=False)
    with pytest.raises(ValueError, match="stand still only"):
        dk.Simulation(scene, dk.VelocityVerlet(1e-4, resolve_contacts=True))
    with pytest.raises(ValueError, match="a moving wall works on the spheres"):
        dk.Simulation(scene, dk.VelocityVerlet(1e-4), max_energy_growth=0.1)
    # a piston run into the spheres stops the run with the deep overlap named, no NaN
    p = dk.Particles(position=[[0.0, 0.0, 0.5]], radius=0.5, mass=1.0)
    squeeze = dk.Scene(p, [dk.KelvinVoigt(10.0, 0.0), dk.Wall((0, 0, 0), (0, 0, 1)),
                           dk.Wall((0, 0, 1.0), (0, 0, -1), velocity=(0, 0, -5.0))])
    with pytest.raises(dk.SimulationError, match="overlaps Wall.*velocity=.0.0, 0.0, -5.0.*surface moves at up to 5"):
        dk.Simulation(squeeze, dk.VelocityVerlet(1e-3)).run(1.0, progress=False)
    assert np.isfinite(squeeze.particles.position).all()


def test_scene_files_and_the_lammps_export_take_the_motion(tmp_path):
    """[[interactions.wall]] with amplitude and frequency builds the vibrated wall; the export writes
    LAMMPS' wiggle (the same A (1 - cos 2 pi t / period) along the normal) and refuses a piston."""
    text = """
[particles]
position = [[0.0, 0.0, 0.5]]
radius = 0.4
[interactions.kelvin_voigt]
stiffness = 1000.0
damping = 1.0
[[interactions.wall]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
amplitude = [0.0, 0.0, 0.01]
frequency = 4.0
[[interactions.cylinder]]
point = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
radius = 3.0
velocity = [0.0, 0.0, 0.5]
[integrator]
method = "VelocityVerlet"
dt = 0.001
[run]
duration = 0.01
"""
    path = tmp_path / "bed.toml"
    path.write_text(text)
    scene = dk.load_scene(path).scene
    wall, cylinder = scene.effects
    assert wall.frequency == 4.0 and wall.amplitude.tolist() == [0, 0, 0.01] and wall.travels
    assert cylinder.velocity.tolist() == [0, 0, 0.5]
    contact = scene.interactions[0]
    files = dk.export_lammps(dk.Scene(scene.particles, [contact, wall]), dk.VelocityVerlet(1e-3), tmp_path / "out")
    assert "zplane 0 NULL wiggle z 0.01 0.25" in files.deck.read_text()
    piston = dk.Wall((0, 0, 0), (0, 0, 1), velocity=(0, 0, 0.1))
    with pytest.raises(ValueError, match="only by 'wiggle'"):
        dk.export_lammps(dk.Scene(scene.particles, [contact, piston]), dk.VelocityVerlet(1e-3), tmp_path / "out2")


def packing_under_a_lid(servo, n, g):
    """n spheres on a loose lattice in a 4 x 3 box periodic across, on a floor under gravity g, a lid with
    ``servo`` above them (Kelvin-Voigt contacts with friction): the scene and the lid."""
    box = dk.Box((4.0, 3.0, 20.0), periodic=(True, True, False))
    i = np.arange(n)
    position = np.stack([0.5 + (i % 4), 0.5 + (i // 4) % 3, 0.6 + 1.1 * (i // 12)], axis=1)
    rng = np.random.default_rng(1)
    p = dk.Particles(position=position + rng.uniform(-0.05, 0.05, (n, 3)) * [1, 1, 0], radius=0.5, mass=1.0)
    lid = dk.Wall((0, 0, 6.0), (0, 0, -1), servo=servo)
    law = dk.KelvinVoigt(1e4, 50.0, friction=dk.Friction(0.3))
    return dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1)), lid, dk.Gravity((0, 0, -g))], box=box), lid


def test_a_servo_lid_holds_its_force_on_a_sphere_and_on_a_packing():
    """A servo-controlled lid (dk.Servo) pressing with a target force F. On one sphere resting on a
    floor (no gravity): the lid comes down at its max speed, then settles where each contact carries
    F, overlap F / k (to 1e-6). On a packing of 48 spheres under gravity in a box periodic along x
    and y: after settling the lid's push is F (to 1e-3), and the floor, read from the contact table,
    carries F plus the spheres' weight (force balance, 1e-3): an independent measure of what the
    lid holds."""
    k, force = 1e4, 20.0
    p = dk.Particles(position=[[0.0, 0.0, 0.5]], radius=0.5, mass=1.0)
    lid = dk.Wall((0, 0, 1.2), (0, 0, -1), servo=dk.Servo(force=force, max_speed=1.0))
    scene = dk.Scene(p, [dk.KelvinVoigt(k, 2 * math.sqrt(k)), dk.Wall((0, 0, 0), (0, 0, 1)), lid])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    sim.run(0.1, progress=False)
    offset, speed, push, _ = lid.servo_state()
    assert offset == pytest.approx(0.1, rel=1e-9) and speed == pytest.approx(1.0) and push == 0.0  # coming down
    sim.run(3.0, progress=False)
    offset, speed, push, stiffness = lid.servo_state()
    assert push == pytest.approx(force, rel=1e-6) and stiffness == pytest.approx(k, rel=1e-3)
    assert np.allclose(scene.contacts().overlap, force / k, rtol=1e-6)
    assert offset == pytest.approx(0.2 + 2 * force / k, rel=1e-6)  # the lid stands at 1.2 - offset

    # a packing under gravity
    n, g = 48, 9.81
    scene, lid = packing_under_a_lid(dk.Servo(force=100.0, max_speed=2.0), n, g)
    sim = dk.Simulation(scene, dk.VelocityVerlet(5e-4))
    sim.run(8.0, progress=False)
    pushes = []
    for _ in range(20):
        sim.run(0.05, progress=False)
        pushes.append(lid.servo_state()[2])
    assert np.allclose(pushes, 100.0, rtol=1e-3)
    c = scene.contacts()
    floor = c.normal_force[c.wall == 0].sum()
    assert floor == pytest.approx(100.0 + n * g, rel=1e-3)


def test_a_servo_wall_restarts_exactly_and_refuses_motions_of_its_own(tmp_path):
    """A run resumed from a checkpoint taken while the lid moves gives the bits of one run (the servo's
    state is saved); a servo does not go with a vibration or a velocity along the normal."""
    def fresh():
        p = dk.Particles(position=[[0.0, 0.0, 0.5], [0.2, 0.1, 1.5]], radius=0.5, mass=1.0)
        lid = dk.Wall((0, 0, 2.3), (0, 0, -1), servo=dk.Servo(force=5.0, max_speed=1.0, gain=0.3))
        return dk.Scene(p, [dk.KelvinVoigt(1e4, 20.0), dk.Wall((0, 0, 0), (0, 0, 1)), lid, dk.Gravity((0, 0, -1))])

    one = fresh()
    dk.Simulation(one, dk.VelocityVerlet(1e-3)).run(1.0, progress=False)
    first = fresh()
    dk.Simulation(first, dk.VelocityVerlet(1e-3), checkpoint=dk.Checkpoint(tmp_path / "c.npz")).run(0.4, progress=False)
    again = fresh()
    dk.Simulation(again, dk.VelocityVerlet(1e-3)).resume(tmp_path / "c.npz").run(0.6, progress=False)
    assert again.particles.position.tobytes() == one.particles.position.tobytes()
    lids = [next(e for e in scene.effects if getattr(e, "servo", None)) for scene in (again, one)]
    assert lids[0].servo_state() == lids[1].servo_state() and lids[0].servo_state()[2] > 0.0
    with pytest.raises(ValueError, match="no vibration and no velocity along its normal"):
        dk.Wall((0, 0, 0), (0, 0, 1), amplitude=(0, 0, 0.1), frequency=1.0, servo=dk.Servo(1.0, 1.0))
    with pytest.raises(ValueError, match="no servo"):
        dk.export_lammps(fresh(), dk.VelocityVerlet(1e-3), tmp_path / "out")
    with pytest.raises(ValueError, match="gain must lie in"):
        dk.Servo(1.0, 1.0, gain=2.0)
    with pytest.raises(ValueError, match="Servo force"):
        dk.Servo(-1.0, 1.0)


def test_a_servo_holding_a_stress_restarts_exactly(tmp_path):
    """A lid holding a stress resumes from a checkpoint to the bits of one run: the checkpoint's
    fingerprint leaves out the servo's target, which a new scene's block gets only at its first run (it
    refused such a checkpoint as another scene's before)."""
    def fresh():
        p = dk.Particles(position=[[0.5, 0.5, 0.5], [0.6, 0.4, 1.5]], radius=0.5, mass=1.0)
        lid = dk.Wall((0, 0, 2.3), (0, 0, -1), servo=dk.Servo(stress=5.0, max_speed=1.0, gain=0.3))
        return dk.Scene(p, [dk.KelvinVoigt(1e4, 20.0), dk.Wall((0, 0, 0), (0, 0, 1)), lid, dk.Gravity((0, 0, -1))],
                        box=dk.Box((2.5, 2.5, 4.0), periodic=(True, True, False)))

    one = fresh()
    dk.Simulation(one, dk.VelocityVerlet(1e-3)).run(0.6, progress=False)
    first = fresh()
    dk.Simulation(first, dk.VelocityVerlet(1e-3), checkpoint=dk.Checkpoint(tmp_path / "c.npz")).run(0.4, progress=False)
    again = fresh()
    dk.Simulation(again, dk.VelocityVerlet(1e-3)).resume(tmp_path / "c.npz").run(0.2, progress=False)
    assert again.particles.position.tobytes() == one.particles.position.tobytes()
    assert again.effects[1].servo_state() == one.effects[1].servo_state()


def test_a_servo_target_changes_within_a_run_along_its_points():
    """A lid on a layer of 12 spheres holding a stress given as (time, value) points: 50/12 until t = 2,
    ramping to 150/12 at t = 4, then held. The lid comes down at max_speed and meets the layer mid-ramp
    (t = 2.5). Along the ramp (rate r = 50 in force per time) the push lags its target by a constant
    r dt / g_eff: the servo corrects gain = 0.2 of its error a step as if the lid's contacts alone gave
    way, but the lid-sphere and sphere-floor contacts are in series, g_eff = gain / 2, lag 0.25 (measured
    0.2494 to 0.2496 from t = 3, once the meeting's transient has gone; 3e-3 asserted: the spheres' inertia). After the ramp it holds 150 to 1e-9 within 0.5 (measured 1e-11 at
    t = 4.5). The runs of 0.125 give the bits of one run of 6; target_at gives the target. Points
    refused: times not increasing, a value <= 0, not pairs; a list of more points than the scene was
    built with, at the next run."""
    n, g, dt = 12, 9.81, 5e-4
    points = [(0.0, 50.0 / 12), (2.0, 50.0 / 12), (4.0, 150.0 / 12), (6.0, 150.0 / 12)]
    scene, lid = packing_under_a_lid(dk.Servo(stress=points, max_speed=2.0), n, g)
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt))
    lag = []
    for _ in range(48):
        sim.run(0.125, progress=False)
        target = 12.0 * lid.servo.target_at(sim.time)
        if 2.95 < sim.time < 3.95:
            lag.append(target - lid.servo_state()[2])
        if sim.time > 4.45:
            assert lid.servo_state()[2] == pytest.approx(150.0, rel=1e-9)
    assert len(lag) == 8 and np.allclose(lag, 50.0 * dt / (0.2 / 2), rtol=3e-3)
    one, _ = packing_under_a_lid(dk.Servo(stress=points, max_speed=2.0), n, g)
    dk.Simulation(one, dk.VelocityVerlet(dt)).run(6.0, progress=False)
    assert one.particles.position.tobytes() == scene.particles.position.tobytes()
    assert lid.servo.target_at(3.0) == pytest.approx(100.0 / 12)
    for bad in ([(1.0, 2.0), (1.0, 3.0)], [(0.0, 1.0), (1.0, -1.0)], [1.0, 2.0], [(0.0, 1.0, 2.0)]):
        with pytest.raises(ValueError, match="Servo stress"):
            dk.Servo(stress=bad, max_speed=1.0)
    lid.servo.stress = points + [(8.0, 1.0)]
    with pytest.raises(ValueError, match="4 points|built for 4"):
        sim.run(0.01, progress=False)
    lid.servo.stress = 10.0  # (fewer: fine)
    sim.run(0.01, progress=False)


def test_a_scene_file_servo_takes_its_targets_at_times(tmp_path):
    """[interactions.wall.servo] with force = [...] and times = [...] is the Servo of those (time, value)
    points: the same bits over a run as the Python scene; a list without its times, times of another
    length and times beside one value are refused, naming the keys."""
    text = """
[particles]
position = [[0.0, 0.0, 0.5]]
radius = 0.4
[interactions.kelvin_voigt]
stiffness = 1000.0
damping = 1.0
[[interactions.wall]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[interactions.wall]]
point = [0.0, 0.0, 0.95]
normal = [0.0, 0.0, -1.0]
[interactions.wall.servo]
force = [1.0, 1.0, 3.0]
times = [0.0, 0.5, 1.0]
max_speed = 1.0
[integrator]
method = "VelocityVerlet"
dt = 0.005
[run]
duration = 1.5
"""
    path = tmp_path / "lid.toml"
    path.write_text(text)
    loaded = dk.load_scene(path)
    lid = loaded.scene.effects[1]
    assert list(lid.servo.force) == [(0.0, 1.0), (0.5, 1.0), (1.0, 3.0)] and lid.servo.target_at(0.75) == 2.0
    dk.Simulation(loaded.scene, dk.VelocityVerlet(0.005)).run(1.5, progress=False)
    p = dk.Particles(position=[[0.0, 0.0, 0.5]], radius=0.4, mass=1.0)
    same = dk.Scene(p, [dk.KelvinVoigt(1000.0, 1.0), dk.Wall((0, 0, 0), (0, 0, 1)),
                        dk.Wall((0, 0, 0.95), (0, 0, -1), servo=dk.Servo(force=[(0.0, 1.0), (0.5, 1.0), (1.0, 3.0)],
                                                                         max_speed=1.0))])
    dk.Simulation(same, dk.VelocityVerlet(0.005)).run(1.5, progress=False)
    assert same.particles.position.tobytes() == loaded.scene.particles.position.tobytes()
    assert same.effects[1].servo_state()[2] == pytest.approx(3.0, rel=0.01)  # (nearing the last target: 3.01)
    for old, bad, problem in (("times = [0.0, 0.5, 1.0]\n", "", "give times"),
                              ("times = [0.0, 0.5, 1.0]", "times = [0.0, 0.5]", "give times"),
                              ("force = [1.0, 1.0, 3.0]", "force = 1.0", "go with a list")):
        path.write_text(text.replace(old, bad))
        with pytest.raises(ValueError, match=problem):
            dk.load_scene(path)


def test_a_servo_holds_a_stress_over_the_box_cross_section_and_follows_staged_targets():
    """The packing of the test above under a lid holding a stress: 100 / 12 on the 4 x 3 cross-section
    of the box is the force 100, held to 1e-3; the stress doubled between runs (staged loading), the
    lid holds 200 and the floor carries 200 plus the weight (force balance, read from the contact
    table); halved again, 100. A stress needs a box periodic along the wall's plane."""
    n, g = 48, 9.81
    scene, lid = packing_under_a_lid(dk.Servo(stress=100.0 / 12.0, max_speed=2.0), n, g)
    sim = dk.Simulation(scene, dk.VelocityVerlet(5e-4))
    for stress, settle in ((100.0 / 12.0, 8.0), (200.0 / 12.0, 4.0), (100.0 / 12.0, 4.0)):
        lid.servo.stress = stress
        sim.run(settle, progress=False)
        pushes = []
        for _ in range(10):
            sim.run(0.05, progress=False)
            pushes.append(lid.servo_state()[2])
        assert np.allclose(pushes, 12.0 * stress, rtol=1e-3)
        c = scene.contacts()
        assert c.normal_force[c.wall == 0].sum() == pytest.approx(12.0 * stress + n * g, rel=1e-3)
    assert repr(lid.servo) == f"Servo(stress={100.0 / 12.0!r}, max_speed=2.0, gain=0.2)"
    # refusals: no box, a wall across a periodic axis's plane, both targets, neither, a bad value set later
    sphere = dk.Particles(position=[[0.0, 0.0, 0.5]], radius=0.5, mass=1.0)
    with pytest.raises(ValueError, match="holds a stress.*no box.*give the Servo a force"):
        dk.Scene(sphere, [dk.KelvinVoigt(1e4, 1.0), dk.Wall((0, 0, 2.0), (0, 0, -1), servo=dk.Servo(stress=1.0,
                                                                                                   max_speed=1.0))])
    with pytest.raises(ValueError, match="holds a stress"):
        dk.Scene(sphere, [dk.KelvinVoigt(1e4, 1.0), dk.Wall((0, 0, 2.0), (0, 0, -1), servo=dk.Servo(stress=1.0,
                                                                                                   max_speed=1.0))],
                 box=dk.Box((4.0, 3.0, 20.0), periodic=(True, False, False)))
    with pytest.raises(ValueError, match="force or a stress.*one of them"):
        dk.Servo(force=1.0, stress=1.0, max_speed=1.0)
    with pytest.raises(ValueError, match="force or a stress"):
        dk.Servo(max_speed=1.0)
    with pytest.raises(ValueError, match="needs max_speed"):
        dk.Servo(force=1.0)
    with pytest.raises(ValueError, match="Servo stress"):
        lid.servo.stress = -1.0
