"""Cylindrical walls (demkit.Cylinder): tubes, posts and rotating drums, checked against their geometry,
the rolling of a sphere in a drum (a pendulum of period 2 pi sqrt(7 (R_c - R) / 5 g)), the angle a turning
drum carries a sliding block to (tan theta = mu), energy conservation, and the plane wall's law they reuse."""
import math

import numpy as np
import pytest

import demkit as dk
from demkit.interactions.cylinder import cylinder_plane

R, RC, G = 0.5, 3.0, 9.81


def drum_scene(theta0=0.0, omega=0.0, friction=None, damping=None, k=1e5, position=None, velocity=None, tier=None):
    """One sphere of radius R in a horizontal drum (axis z, radius R_c), gravity along -y, a
    Kelvin-Voigt contact (critically damped normal by default), the sphere at angle theta0 from
    the bottom (towards +x), resting on the wall."""
    c = 2.0 * math.sqrt(k * 1.0) if damping is None else damping
    arm = RC - R + 1.0 / k * G  # (the static overlap: the sphere starts at rest, pressed by its weight)
    if position is None:
        position = [[arm * math.sin(theta0), -arm * math.cos(theta0), 0.0]]
    p = dk.Particles(position=position, velocity=velocity if velocity is not None else [[0.0, 0.0, 0.0]], radius=R,
                     mass=1.0)
    law = dk.KelvinVoigt(k, c, friction=friction)
    return dk.Scene(p, [law, dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=omega),
                        dk.Gravity((0, -G, 0))], tier=tier)


def test_the_tangent_plane_is_the_nearest_point_of_the_surface(rng):
    """cylinder_plane against the geometry done by hand: distance from the axis, the radial direction,
    the surface point and its velocity omega a x (S - p), inside and outside, for a tilted axis."""
    point, axis = np.array([0.3, -1.0, 2.0]), np.array([1.0, 2.0, 2.0]) / 3.0
    for inside in (True, False):
        cyl = dk.Cylinder(point, 3 * axis, 2.5, inside=inside, angular_velocity=-0.7)
        x = point + rng.normal(scale=2.0, size=(50, 3))
        r = x - point
        radial = r - np.outer(r @ axis, axis)
        d = np.linalg.norm(radial, axis=1)
        e = radial / d[:, None]
        surface = point + np.outer(r @ axis, axis) + 2.5 * e
        normal = -e if inside else e
        for k in range(len(x)):
            plane, nx, ny, nz, ux, uy, uz = cylinder_plane(*x[k], *cyl.shape_values())
            assert np.allclose([nx, ny, nz], normal[k], atol=1e-14)
            assert plane == pytest.approx(surface[k] @ normal[k], abs=1e-12)
            assert np.allclose([ux, uy, uz], -0.7 * np.cross(axis, surface[k] - point), atol=1e-13)
        assert np.allclose(cyl.heights(x), 2.5 - d if inside else d - 2.5, atol=1e-13)
        assert np.allclose(cyl.normals(x), normal, atol=1e-14)
    # a centre on the axis: some radial direction across the axis, a unit normal
    plane, nx, ny, nz, *_ = cylinder_plane(*point, *dk.Cylinder(point, axis, 1.0).shape_values())
    assert math.hypot(nx, ny, nz) == pytest.approx(1.0) and abs(np.dot([nx, ny, nz], axis)) < 1e-15


def test_bad_cylinders_and_spheres_that_do_not_fit_are_refused():
    with pytest.raises(ValueError, match="radius"):
        dk.Cylinder((0, 0, 0), (0, 0, 1), -1.0)
    with pytest.raises(ValueError, match="zero length"):
        dk.Cylinder((0, 0, 0), (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="angular_velocity"):
        dk.Cylinder((0, 0, 0), (0, 0, 1), 1.0, angular_velocity=math.nan)
    with pytest.raises(ValueError, match="inside"):
        dk.Cylinder((0, 0, 0), (0, 0, 1), 1.0, inside="yes")
    law = dk.KelvinVoigt(1e4, 1.0)
    p = dk.Particles(position=[[0.0, 0.0, 0.0]], radius=1.2, mass=1.0)
    with pytest.raises(ValueError, match="does not fit inside the cylinder"):
        dk.Scene(p, [law, dk.Cylinder((0, 0, 0), (0, 0, 1), 1.0)])
    p = dk.Particles(position=[[2.9, 0.0, 0.0]], radius=0.5, mass=1.0)
    with pytest.raises(ValueError, match="deep inside the cylinder of radius 3"):
        dk.Scene(p, [law, dk.Cylinder((0, 0, 0), (0, 0, 1), 3.0)])
    with pytest.raises(ValueError, match="plane walls that stand still only"):
        dk.Simulation(drum_scene(), dk.VelocityVerlet(1e-4, resolve_contacts=True))


def test_a_sphere_resting_in_a_drum_presses_its_weight_on_the_wall():
    """At the bottom of a drum the contact is the plane wall's: overlap m g / k, force m g up,
    the contact point on the surface (distance R_c from the axis)."""
    scene = drum_scene()
    dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(1.0, progress=False)
    c = scene.contacts()
    assert len(c.overlap) == 1 and c.wall[0] == 0
    assert c.overlap[0] == pytest.approx(G / 1e5, rel=1e-6)
    assert c.normal_force[0] == pytest.approx(G, rel=1e-6)
    assert np.allclose(c.normal[0], [0.0, 1.0, 0.0], atol=1e-9)
    assert math.hypot(*c.point[0][:2]) == pytest.approx(RC, abs=1e-9)


@pytest.mark.parametrize("inside", [True, False], ids=["tube", "post"])
def test_a_hertz_sphere_resting_on_a_cylinder_takes_the_contact_radius_of_its_curvature(inside):
    """A Hertz sphere (R = 0.5) resting at the bottom of a drum of radius 3 (or on top of a post of radius
    1) under gravity: the wall's curvature across, -1/R_c inside and +1/R_c outside, 0 along its axis,
    gives the contact radius 1/R_e = 1/R -+ 1/(2 R_c) (the mean of the relative principal curvatures), so
    the overlap is delta = (3 m g / (4 E* sqrt(R_e)))^(2/3), E* = E/(1 - nu^2) (a rigid wall): 2.9 %
    less than a plane's inside, 7.7 % more outside. Measured 7e-14 and 2e-14 (asserted 1e-7: the
    settling's last swings); the contact table's force is m g to round-off."""
    young, poisson, g = 1e5, 0.3, 9.81
    rc = 3.0 if inside else 1.0
    law = dk.Hertz(young=young, poisson=poisson, restitution=0.3, friction=dk.Friction(0.5))
    reff = 1.0 / (1.0 / R + (-1.0 if inside else 1.0) / (2.0 * rc))
    delta = (3.0 * g / (4.0 * young / (1 - poisson ** 2) * math.sqrt(reff))) ** (2.0 / 3.0)
    y = -(rc - R + delta) if inside else rc + R - delta
    p = dk.Particles(position=[[0.0, y, 0.0]], radius=R, mass=1.0)
    scene = dk.Scene(p, [law, dk.Cylinder((0, 0, 0), (0, 0, 1), rc, inside=inside), dk.Gravity((0, -g, 0))])
    dk.Simulation(scene, dk.VelocityVerlet(2e-4)).run(1.0, progress=False)
    c = scene.contacts()
    assert c.overlap[0] == pytest.approx(delta, rel=1e-7) and c.normal_force[0] == pytest.approx(g, rel=1e-7)
    plane = (3.0 * g / (4.0 * young / (1 - poisson ** 2) * math.sqrt(R))) ** (2.0 / 3.0)
    assert abs(delta / plane - 1.0) > 0.015  # (the curvature is seen)


@pytest.mark.parametrize("friction, beta", [(dk.Friction(1.0), 7 / 5), (None, 1.0)], ids=["rolling", "sliding"])
def test_a_sphere_in_a_drum_oscillates_with_the_period_of_rolling_or_sliding(friction, beta):
    """A sphere let go 5 degrees up the side of a fixed drum: with friction it rolls without
    slipping, a pendulum of period T = 2 pi sqrt(beta (R_c - R) / g), beta = 7/5 (its moment of
    inertia 2/5 m R^2 adds to the mass); frictionless, it slides, beta = 1. Measured over three
    periods from the crossings of the bottom. Tolerance 0.3 %: the amplitude adds theta0^2 / 16
    = 0.048 %, the tangential spring's compliance and the normal overlap (1e-4 of the arm) less
    (measured +0.056 % rolling, +0.050 % sliding); the two periods differ by 18 %."""
    expected = 2 * math.pi * math.sqrt(beta * (RC - R) / G)
    scene = drum_scene(theta0=math.radians(5.0), friction=friction)
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(3.2 * expected, record_every=1e-3, progress=False)
    x = traj.position[:, 0, 0]
    up = np.flatnonzero((x[:-1] > 0.0) & (x[1:] <= 0.0))  # downward crossings of the bottom, once a period
    t = traj.time[up] + (traj.time[up + 1] - traj.time[up]) * x[up] / (x[up] - x[up + 1])
    assert len(t) >= 3
    period = (t[-1] - t[0]) / (len(t) - 1)
    assert period == pytest.approx(expected, rel=3e-3)
    if friction is not None:  # rolling: the spin follows the orbit, w R = -(R_c - R) d(theta)/dt
        theta_rate = np.gradient(np.arctan2(x, -traj.position[:, 0, 1]), traj.time)
        w = traj.angular_velocity[:, 0, 2]
        fast = np.abs(theta_rate) > 0.5 * np.abs(theta_rate).max()
        assert np.allclose(w[fast] * R, -(RC - R) * theta_rate[fast], rtol=2e-2)


def test_a_turning_drum_rolls_a_sphere_without_slip_at_the_surface_speed():
    """No gravity: a sphere sliding round the inside of a drum turning at omega (pressed on it by its
    own centripetal force) is dragged by friction until it rolls on the drum without slipping: the
    point of the sphere touching the drum then moves with the drum's surface, v - R w x n = omega R_c
    (a x e) (n the wall's normal, into the drum), and nothing dissipates any more. Measured after
    10 s; tolerance 1e-4 of the surface speed (the tangential spring's creep)."""
    omega, k = 2.0, 1e5
    p = dk.Particles(position=[[RC - R, 0.0, 0.0]], velocity=[[0.0, 1.0, 0.0]], radius=R, mass=1.0)  # sliding round
    contact = dk.KelvinVoigt(k, 2 * math.sqrt(k), friction=dk.Friction(0.5))
    scene = dk.Scene(p, [contact, dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=omega)])
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(10.0, record_every=0.5, progress=False)
    x, v, w = traj.position[-1, 0], traj.velocity[-1, 0], traj.angular_velocity[-1, 0]
    e = np.array([x[0], x[1], 0.0]) / math.hypot(x[0], x[1])
    touching = v + np.cross(w, R * e)  # the sphere's point at x + R e
    assert touching == pytest.approx(omega * RC * np.cross([0, 0, 1], e), abs=1e-4 * omega * RC)
    assert np.ptp(traj.energy["dissipated"][-4:]) < 1e-4 * traj.energy["dissipated"][-1]  # (measured 4e-6)
    assert traj.energy["dissipated"][-1] > 0.01  # (it slid first)
    c = scene.contacts()
    assert not c.sliding[0] and c.normal_force[0] > 0.0


@pytest.mark.parametrize("mu", [0.3, 0.6])
def test_a_turning_drum_carries_a_sliding_block_to_tan_theta_mu_and_it_swings_about_there(mu):
    """A sphere that cannot turn (inertia 2.5e8 times a ball's: a sliding block) carried by a slowly
    turning drum (omega = 0.01 rad/s) sticks to the wall until the friction it needs, m g sin theta,
    reaches mu N = mu m g cos theta (the centripetal part is 6e-6 of it): it slips at tan theta = mu.
    Kinetic friction mu N then pushes it up the wall at every angle, so it swings undamped about
    theta* = atan mu, at Omega^2 = g / ((R_c - R) cos theta*), with the amplitude its speed when it
    slipped gives, A = theta'_stuck / Omega (theta'_stuck = omega R_c / (R_c - R): its point of
    contact moving with the wall). Measured: carried with the wall to 1.7e-4 of theta* (the tangential
    spring's stretch), the middle of the swing within 2.4e-5 of atan mu, the amplitude within 0.02 %;
    bounds 1e-3, 1e-3 and 1 % (the nonlinear pendulum's asymmetry is O(A^2) ~ 4e-5)."""
    omega, k = 0.01, 1e5
    arm = RC - R + G / k
    stuck = omega * RC / (RC - R)  # the centre's angular rate while the sphere moves with the wall
    p = dk.Particles(position=[[0.0, -arm, 0.0]], velocity=[[stuck * arm, 0.0, 0.0]], radius=R, mass=1.0,
                     inertia_factor=1e8)
    law = dk.KelvinVoigt(k, 2 * math.sqrt(k), friction=dk.Friction(mu))
    scene = dk.Scene(p, [law, dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=omega), dk.Gravity((0, -G, 0))])
    star = math.atan(mu)
    swing = math.sqrt(G / ((RC - R) * math.cos(star)))
    duration = 1.15 * star / stuck + 2 * (2 * math.pi / swing)  # carried up, then two swings
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(duration, record_every=0.01, progress=False)
    theta = np.arctan2(traj.position[:, 0, 0], -traj.position[:, 0, 1])
    carried = traj.time < 0.95 * star / stuck
    assert theta[carried] == pytest.approx(stuck * traj.time[carried], abs=1e-3 * star)  # moving with the wall
    swinging = theta[traj.time > 1.15 * star / stuck]
    assert 0.5 * (swinging.max() + swinging.min()) == pytest.approx(star, rel=1e-3)
    assert 0.5 * (swinging.max() - swinging.min()) == pytest.approx(stuck / swing, rel=0.01)


def test_a_rolling_sphere_in_a_turning_drum_swings_about_the_bottom_spinning_with_the_wall():
    """A ball at rest at the bottom of a drum that turns at omega = 0.5 rad/s under gravity slides until it
    rolls, then rolls without slip: no friction is needed at the bottom once it spins at omega R_c / R,
    so it swings about theta = 0 as the rolling pendulum of period 2 pi sqrt(7 (R_c - R) / 5 g), its
    mean spin omega R_c / R, and nothing more is dissipated. Measured after 1 s: the middle of the
    swing 8e-8 rad from the bottom (amplitude 0.10 rad), the periods within 0.19 % (crossings read
    from frames 0.005 apart: 0.13 % of a period; the amplitude's correction A^2/16 is 6e-4), the
    mean spin over whole swings 6.5e-5, the dissipated energy constant to 1.8e-6; bounds 1e-5 rad,
    0.3 %, 1e-3, 1e-5."""
    omega, k = 0.5, 1e5
    p = dk.Particles(position=[[0.0, -(RC - R + G / k), 0.0]], radius=R, mass=1.0)
    law = dk.KelvinVoigt(k, 2 * math.sqrt(k), friction=dk.Friction(0.5))
    scene = dk.Scene(p, [law, dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=omega), dk.Gravity((0, -G, 0))])
    period = 2 * math.pi * math.sqrt(7 * (RC - R) / (5 * G))
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(1.0 + 3 * period, record_every=0.005, progress=False)
    late = traj.time > 1.0
    theta, t = np.arctan2(traj.position[late, 0, 0], -traj.position[late, 0, 1]), traj.time[late]
    assert abs(0.5 * (theta.max() + theta.min())) < 1e-5 and theta.max() > 0.05
    up = t[1:][(theta[:-1] < 0) & (theta[1:] >= 0)]  # upward crossings of the bottom
    assert np.diff(up) == pytest.approx(period, rel=3e-3)
    whole = (t >= up[0]) & (t < up[-1])
    assert traj.angular_velocity[late, 0, 2][whole].mean() == pytest.approx(omega * RC / R, rel=1e-3)
    assert np.ptp(traj.energy["dissipated"][late]) < 1e-5 * traj.energy["dissipated"][-1]
    assert not scene.contacts().sliding[0]


@pytest.mark.parametrize("wall", ["drum", "cone"])
def test_a_sphere_turning_with_a_wall_as_one_body_feels_no_rolling_or_twisting_torque(wall):
    """Rolling and twisting resistance act on the sphere's spin relative to the wall's own: a sphere on a
    drum (no gravity) or on the face of a hopper cone (gravity along -a) turning at omega = 1.5, where the
    contact's force alone keeps it going round (its overlap m omega^2 d / k; on the cone at d = g / (omega^2
    tan(alpha)), where the normal force's axial part carries its weight), moving and spinning with the
    wall as one rigid body (v = omega a x x, w = omega a), feels the normal force alone: no friction (its
    contact point moves with the surface), no rolling torque, no twisting torque (on the cone the wall's
    spin has a part along the normal, omega a.n = omega sin(alpha), which a wall taken at rest would twist
    against), to round-off. On the drum it keeps turning with it over 2000 steps: its spin within 1e-5 of
    omega (measured 3e-6: the friction that the discrete orbit's small slip calls up). A sphere going round
    the same way but not spinning (w = 0) is braked (torque 1.7 after 100 steps on the drum; > 0.1 asserted;
    the first evaluation of a run gives no friction beyond the Coulomb limit, so it is read after them)."""
    omega, k, g = 1.5, 1e4, 9.81
    law = dk.KelvinVoigt(k, 20.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.1),
                         twisting=dk.TwistingResistance())
    if wall == "drum":
        surface, gravity = dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=omega), (0.0, 0.0, 0.0)
        delta = omega ** 2 * (RC - R) / (k - omega ** 2)  # k delta = m omega^2 (R_c - R + delta)
        x = np.array([RC - R + delta, 0.0, 0.0])
    else:
        alpha = math.radians(30.0)
        surface, gravity = dk.Cone((0, 0, 0), (0, 0, 1), alpha, upper=20.0, angular_velocity=omega), (0.0, 0.0, -g)
        d = g / (omega ** 2 * math.tan(alpha))
        delta = math.hypot(g, omega ** 2 * d) / k
        x = np.array([d, 0.0, (R - delta + d * math.cos(alpha)) / math.sin(alpha)])
    axis = np.array([0.0, 0.0, 1.0])
    for spin, still in ((omega * axis, True), (np.zeros(3), False)):
        p = dk.Particles(position=[x], velocity=[omega * np.cross(axis, x)], angular_velocity=[spin], radius=R,
                         mass=1.0)
        scene = dk.Scene(p, [law, surface, dk.Gravity(gravity)])
        c = scene.contacts()
        assert len(c.overlap) == 1 and c.overlap[0] == pytest.approx(delta, rel=1e-9)
        if still:
            assert np.linalg.norm(c.torque_j[0]) < 1e-12 and np.linalg.norm(c.tangential_force[0]) < 1e-12
            if wall == "drum":  # (the cone's orbit is unstable along its generator: friction soon acts)
                dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(0.2, progress=False)
                assert np.abs(scene.particles.angular_velocity[0] - omega * axis).max() < 1e-5
        else:
            dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(0.01, progress=False)
            assert np.linalg.norm(scene.contacts().torque_j[0]) > 0.1


@pytest.mark.parametrize("inside", [True, False], ids=["tube", "post"])
def test_an_elastic_sphere_bouncing_on_a_cylinder_keeps_its_energy(inside):
    """No damping, no friction: a sphere bouncing around inside a tube (or off a post) keeps its
    energy to the integrator's second order: the largest deviation falls 4x when the step is
    halved (measured 4.0 and 3.8; a plane wall: 4.6), 9.5e-4 and 6.3e-4 of the energy at 50 steps
    per contact (a plane wall: 8.8e-4)."""
    k = 1e4
    contact_time = math.pi / math.sqrt(k)
    deviations = []
    for steps in (50, 100):
        start = [[0.5, 0.2, 0.0]] if inside else [[2.5, 0.3, 0.0]]
        p = dk.Particles(position=start, velocity=[[3.0, 1.7, 0.4]] if inside else [[-3.0, 0.5, 0.0]], radius=R,
                         mass=1.0)
        scene = dk.Scene(p, [dk.KelvinVoigt(k, 0.0), dk.Cylinder((0, 0, 0), (0, 0, 1), 2.0 if inside else 1.0,
                                                                  inside=inside)])
        traj = dk.Simulation(scene, dk.VelocityVerlet(contact_time / steps)).run(6.0, record_every=0.01, progress=False)
        e = traj.energy["total"]
        deviations.append(np.max(np.abs(e - e[0])) / e[0])
        assert np.max(traj.energy["wall"]) > 0.3 * e[0]  # it did bounce
        if inside:
            assert np.max(np.hypot(traj.position[:, 0, 0], traj.position[:, 0, 1])) < 2.0 - R + 0.05
    assert deviations[0] < 2e-3 and 3.0 < deviations[0] / deviations[1] < 5.0


@pytest.mark.parametrize("omega, rolling", [(1.3, None), (0.0, dk.RollingResistance(0.1))], ids=["turning", "rolling"])
def test_a_cylinder_acts_as_the_plane_wall_tangent_to_it_where_the_sphere_touches(omega, rolling):
    """A sphere pressed into a cylinder feels the force and torque of the plane wall tangent to the
    cylinder where it touches, sliding at the surface's velocity omega a x (S - p) there
    (Kelvin-Voigt with friction, and rolling resistance on a cylinder at rest; the sphere moving and
    spinning; the tangent plane computed here by hand): agreement to round-off."""
    law = dk.KelvinVoigt(1e4, 3.0, friction=dk.Friction(0.4), rolling=rolling)
    point, axis = np.array([0.2, 0.1, -0.3]), np.array([0.0, 0.6, 0.8])
    x = point + np.array([2.6, 0.4, -0.3])
    p = dk.Particles(position=[x], velocity=[[0.3, -0.2, 0.1]], angular_velocity=[[1, 2, 3]], radius=R, mass=1.0)
    r = x - point
    e = (r - (r @ axis) * axis) / np.linalg.norm(r - (r @ axis) * axis)
    surface = point + (r @ axis) * axis + RC * e
    curved = dk.Scene(p, [law, dk.Cylinder(point, axis, RC, angular_velocity=omega)])
    flat = dk.Scene(p, [law, dk.Wall(surface, -e, velocity=omega * np.cross(axis, surface - point))])
    assert curved.contacts().overlap[0] == pytest.approx(R - (RC - np.linalg.norm(r - (r @ axis) * axis)), rel=1e-12)
    for a, b in zip(curved.forces(), flat.forces()):
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12)


def test_a_drum_from_a_scene_file_is_the_python_drum(tmp_path):
    """[[interactions.cylinder]] builds the same Cylinder (and refuses unknown keys by name)."""
    text = f"""
[particles]
position = [[0.0, {-(RC - R)}, 0.0]]
radius = {R}
[interactions.kelvin_voigt]
stiffness = 1e5
damping = 600.0
[interactions.gravity]
acceleration = [0.0, {-G}, 0.0]
[[interactions.cylinder]]
point = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
radius = {RC}
angular_velocity = 1.5
[integrator]
dt = 2e-4
[run]
duration = 0.1
"""
    (tmp_path / "drum.toml").write_text(text)
    loaded = dk.load_scene(tmp_path / "drum.toml")
    drum = loaded.scene.effects[-1]
    assert isinstance(drum, dk.Cylinder) and drum.radius == RC and drum.inside and drum.angular_velocity == 1.5
    assert np.array_equal(drum.geometry_values(),
                          dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=1.5).geometry_values())
    (tmp_path / "bad.toml").write_text(text.replace("angular_velocity = 1.5", "angular_speed = 1.5"))
    with pytest.raises(ValueError, match="angular_speed"):
        dk.load_scene(tmp_path / "bad.toml")


def test_moving_walls_work_on_the_spheres_so_no_energy_balance_is_watched():
    """A turning drum (like a sliding plane wall) gives the spheres energy: max_energy_growth refuses
    such a scene by name, and the run's notes report no energy balance."""
    for wall in (dk.Cylinder((0, 0, 0), (0, 0, 1), RC, angular_velocity=1.0),
                 dk.Wall((0, -RC, 0), (0, 1, 0), velocity=(1.0, 0.0, 0.0))):
        p = dk.Particles(position=[[0.0, -(RC - R), 0.0]], radius=R, mass=1.0)
        scene = dk.Scene(p, [dk.KelvinVoigt(1e5, 600.0, friction=dk.Friction(0.5)), wall, dk.Gravity((0, -G, 0))])
        with pytest.raises(ValueError, match="moving wall works on the spheres"):
            dk.Simulation(scene, dk.VelocityVerlet(1e-4), max_energy_growth=0.1)
        sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4))
        sim.run(0.5, progress=False)
        assert not any("energy balance" in note for note in sim.statistics["notes"])
        assert sim.statistics.get("energy_drift") is None


def test_the_lammps_export_refuses_the_cylinders_lammps_cannot_draw(tmp_path):
    """LAMMPS' cylinder region runs along x, y or z and the export turns it (rotate) but does not carry
    it: an oblique or a travelling cylinder is refused with the reason, and so is one whose own contact
    law has demkit's friction rules (strict export), nothing written. (A turning
    one along an axis is compared with LAMMPS in tests/test_lammps_export.py.)"""
    p = dk.Particles(position=[[0.0, -1.0, 0.0]], radius=0.5, mass=1.0)
    for cylinder, reason in ((dk.Cylinder([0, 0, 0], [0, 1, 1], 3.0), "runs along x, y or z"),
                             (dk.Cylinder([0, 0, 0], [0, 0, 1], 3.0, velocity=[0.1, 0, 0]), "carried by a velocity"),
                             (dk.Cylinder([0, 0, 0], [0, 0, 1], 3.0, contact=dk.KelvinVoigt(1e3, 1.0, friction=dk.Friction(0.5))),
                              "sliding='lammps'")):  # its own law with demkit's friction rules (strict)
        scene = dk.Scene(p.copy(), [dk.KelvinVoigt(1e3, 1.0), cylinder])
        with pytest.raises(ValueError, match=reason):
            dk.export_lammps(scene, dk.VelocityVerlet(1e-4), tmp_path, duration=0.01)
    assert not list(tmp_path.iterdir())  # nothing written


def test_a_cylinder_must_run_along_a_periodic_axis_or_fit_inside_the_box_across_it():
    """A tube along z in a box periodic along z is a periodic pipe; one across x in a box periodic
    along x must fit within the box (else the spheres' periodic copies sit on the wrong side)."""
    p = dk.Particles(position=[[5.0, 5.0, 1.0]], radius=0.5, mass=1.0)
    law = dk.KelvinVoigt(1e4, 1.0)
    dk.Scene(p, [law, dk.Cylinder((5, 5, 0), (0, 0, 1), 3.0)], box=dk.Box(10.0, periodic=[False, False, True]))
    dk.Scene(p, [law, dk.Cylinder((5, 5, 0), (0, 0, 1), 3.0)], box=dk.Box(10.0, periodic=[True, True, True]))
    with pytest.raises(ValueError, match="periodic axis x"):
        dk.Scene(p, [law, dk.Cylinder((5, 5, 0), (0, 0, 1), 6.0)], box=dk.Box(10.0, periodic=[True, False, False]))
    with pytest.raises(ValueError, match="periodic axis y"):  # a post: outside it, the copies are everywhere
        dk.Scene(dk.Particles(position=[[9.0, 5.0, 1.0]], radius=0.5, mass=1.0),
                 [law, dk.Cylinder((5, 5, 0), (0, 0, 1), 3.0, inside=False)],
                 box=dk.Box(10.0, periodic=[False, True, False]))


def test_a_plane_wall_must_not_cut_a_periodic_axis():
    """A floor across the periodic x and y of a box is fine; a wall whose normal leans along a periodic
    axis would put the spheres' periodic copies behind it (LAMMPS refuses a wall in a periodic
    dimension too): a ValueError naming the axis."""
    p = dk.Particles(position=[[5.0, 5.0, 1.0]], radius=0.5, mass=1.0)
    law = dk.KelvinVoigt(1e4, 1.0)
    box = dk.Box(10.0, periodic=[True, True, False])
    dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1))], box=box)
    with pytest.raises(ValueError, match="periodic axis x"):
        dk.Scene(p, [law, dk.Wall((0, 0, 0), (0.1, 0, 1))], box=box)


def confined_column(sigma=4.0, checkpoint=None):
    """Nine spheres (three layers of three) in a tube periodic along its axis (L = 3.3), no gravity, the
    tube's radius servo-controlled to hold the stress sigma on its side."""
    ang = 2 * math.pi * np.arange(3) / 3
    pos = [[2.0 + 0.75 * math.cos(a), 2.0 + 0.75 * math.sin(a), 0.55 + 1.1 * layer]
           for layer in range(3) for a in ang + layer * math.pi / 3]
    p = dk.Particles(position=pos, radius=R, mass=1.0)
    tube = dk.Cylinder((2.0, 2.0, 0.0), (0, 0, 1), 1.8, servo=dk.Servo(stress=sigma, max_speed=1.0))
    return dk.Scene(p, [dk.KelvinVoigt(1e4, 20.0, friction=dk.Friction(0.3)), tube],
                    box=dk.Box((4.0, 4.0, 3.3), periodic=(False, False, True))), tube


def test_a_servo_cylinder_holds_a_confining_stress_on_a_column_of_spheres(tmp_path):
    """A tube whose radius a servo moves to hold sigma = 4 on its side (a triaxial cell's membrane): it
    closes in at max_speed (1.0) until it touches the column, then holds the push F = sigma 2 pi R_c L at
    the radius it has reached. Its time series (servo_state and current_radius between runs): the radius
    falls by 0.25 a quarter time unit, the push reaches its target to 2.5e-3 at t = 1 and 1e-12 from
    t = 1.5 (tolerance 1e-9); the contact table's normal forces on the tube sum to it (1e-12); each sphere
    is at rest (pair forces balance the tube's: the column is squeezed, not pushed). A run resumed from a
    checkpoint gives the bits of one run; a servo cylinder holding a force, or outside a box periodic along
    its axis, or moving, is refused; the LAMMPS export refuses it."""
    sigma, L = 4.0, 3.3
    scene, tube = confined_column(sigma)
    sim = dk.Simulation(scene, dk.VelocityVerlet(5e-4))
    radii, pushes = [], []
    for _ in range(8):
        sim.run(0.25, progress=False)
        radii.append(tube.current_radius())
        pushes.append(tube.servo_state()[2])
    assert radii[0] == pytest.approx(1.55, abs=1e-12) and radii[1] == pytest.approx(1.30, abs=1e-12)
    target = sigma * 2 * math.pi * radii[-1] * L
    assert 0.9 < radii[-1] < 1.3 and pushes[-1] == pytest.approx(target, rel=1e-9)
    assert pushes[-3] == pytest.approx(sigma * 2 * math.pi * radii[-3] * L, rel=1e-9)
    c = scene.contacts()
    assert c.normal_force[c.wall == 0].sum() == pytest.approx(target, rel=1e-12)
    assert np.abs(scene.particles.velocity).max() < 1e-6
    one, _ = confined_column(sigma)
    dk.Simulation(one, dk.VelocityVerlet(5e-4)).run(1.2, progress=False)
    first, _ = confined_column(sigma)
    dk.Simulation(first, dk.VelocityVerlet(5e-4), checkpoint=dk.Checkpoint(tmp_path / "c.npz")).run(0.9, progress=False)
    again, tube = confined_column(sigma)
    dk.Simulation(again, dk.VelocityVerlet(5e-4)).resume(tmp_path / "c.npz").run(0.3, progress=False)
    assert again.particles.position.tobytes() == one.particles.position.tobytes()
    assert tube.servo_state() == one.effects[-1].servo_state()
    p = dk.Particles(position=[[2.0, 2.0, 1.0]], radius=R, mass=1.0)
    with pytest.raises(ValueError, match="holds a stress on its side"):
        dk.Cylinder((2, 2, 0), (0, 0, 1), 1.8, servo=dk.Servo(force=1.0, max_speed=1.0))
    with pytest.raises(ValueError, match="no velocity"):
        dk.Cylinder((2, 2, 0), (0, 0, 1), 1.8, velocity=(0.1, 0, 0), servo=dk.Servo(stress=1.0, max_speed=1.0))
    with pytest.raises(ValueError, match="periodic along its axis"):
        dk.Scene(p, [dk.KelvinVoigt(1e4, 1.0), dk.Cylinder((2, 2, 0), (0, 0, 1), 1.8,
                                                          servo=dk.Servo(stress=1.0, max_speed=1.0))])
    with pytest.raises(ValueError, match="no servo"):
        dk.export_lammps(confined_column()[0], dk.VelocityVerlet(5e-4), tmp_path / "out", strict=False)
