"""Contact mechanics and surroundings: Hertz, friction with history, walls, gravity, fields, fixed spheres.

Independent truths: Hertz's analytic impact (Chung & Ooi 2011 tests 1-3), rigid-body limits of
oblique impacts in gross sliding (tests 4 and 6), the digitised reference curve of test 4,
counter-spinning spheres with zero slip (test 7), rolling without slipping at 5/7 of the sliding
speed, Coulomb's stick/slip threshold, and conservation laws.
"""
import math

import numpy as np
import pytest

import demkit as dk
from plugin_interactions import PullSmall
from demkit.interactions.hertz import hertz_impact
from demkit.interactions.hertz_restitution import damping_for_restitution, fitted_restitution, restitution_of_damping


def ball(R, rho):
    return rho * 4.0 / 3.0 * math.pi * R ** 3


def overlap_history(traj, R):
    gap = np.linalg.norm(traj.position[:, 1] - traj.position[:, 0], axis=1)
    return 2 * R - gap


@pytest.mark.parametrize("E, nu, rho", [(4.8e10, 0.20, 2800), (2.0e10, 0.25, 2500)])
def test_chung_ooi_1_elastic_hertz_impact_of_two_spheres(E, nu, rho):
    """Maximum overlap, force and contact time against Hertz's analytic values (1 %)."""
    R, v = 0.010, 10.0
    m = ball(R, rho)
    p = dk.Particles(position=[[-R, 0, 0], [R, 0, 0]], velocity=[[v, 0, 0], [-v, 0, 0]], radius=R, mass=m)
    law = dk.Hertz(young=E, poisson=nu, restitution=1.0)
    delta, force, tc = hertz_impact(law.young_eff, R / 2, m / 2, 2 * v)
    dt = tc / 2000
    traj = dk.Simulation(dk.Scene(p, [law]), dk.VelocityVerlet(dt)).run(1.5 * tc, record_every=dt)
    ov = overlap_history(traj, R)
    assert ov.max() == pytest.approx(delta, rel=1e-4)
    assert 4 / 3 * law.young_eff * math.sqrt(R / 2) * ov.max() ** 1.5 == pytest.approx(force, rel=1e-4)
    assert (ov > 0).sum() * dt == pytest.approx(tc, rel=1e-3)
    assert -traj.velocity[-1, 0, 0] / v == pytest.approx(1.0, abs=1e-6)
    # the published table: glass delta_max 274.113 um, t_c 40.339 us
    if E == 4.8e10:
        assert delta == pytest.approx(274.113e-6, rel=1e-5) and tc == pytest.approx(40.339e-6, rel=1e-4)


def test_chung_ooi_2_elastic_impact_on_a_rigid_wall():
    E, nu, rho, R, v = 7.0e10, 0.30, 2699, 0.10, 0.2
    m = ball(R, rho)
    p = dk.Particles(position=[[0, 0, R]], velocity=[[0, 0, -v]], radius=R, mass=m)
    law = dk.Hertz(young=E, poisson=nu)
    wall = dk.Wall(point=(0, 0, 0), normal=(0, 0, 1))
    delta, force, tc = hertz_impact(E / (1 - nu ** 2), R, m, v)
    assert delta == pytest.approx(49.717e-6, rel=1e-4) and tc == pytest.approx(731.66e-6, rel=1e-4)
    dt = tc / 2000
    traj = dk.Simulation(dk.Scene(p, [law, wall]), dk.VelocityVerlet(dt)).run(1.3 * tc, record_every=dt)
    ov = R - traj.position[:, 0, 2]
    assert ov.max() == pytest.approx(delta, rel=1e-4)
    assert (ov > 0).sum() * dt == pytest.approx(tc, rel=1e-3)
    assert traj.energy["wall"].max() == pytest.approx(0.5 * m * v ** 2, rel=1e-5)


@pytest.mark.parametrize("e", [0.2, 0.4, 0.6, 0.8, 1.0])
def test_chung_ooi_3_restitution_out_equals_restitution_in(e):
    E, nu, rho, R, v = 3.8e11, 0.23, 4000, 0.0025, 3.9
    m = ball(R, rho)
    p = dk.Particles(position=[[0, 0, R]], velocity=[[0, 0, -v]], radius=R, mass=m)
    tc = hertz_impact(E / (1 - nu ** 2), R, m, v)[2]
    sim = dk.Simulation(dk.Scene(p, [dk.Hertz(E, nu, restitution=e), dk.Wall((0, 0, 0), (0, 0, 1))]),
                        dk.VelocityVerlet(tc / 4000))
    sim.run(2.0 * tc)
    assert p.velocity[0, 2] / v == pytest.approx(e, rel=2e-3)  # 4000 steps a contact: 1e-4 measured


def test_damping_calibration_is_the_inverse_of_the_impact_equation():
    """The calibration inverts a Chebyshev fit of the impact solver (no solve at run time): the
    solver, run at the damping found, gives back the restitution asked to 1e-9 (measured 2e-10; the
    solver's own relative tolerance is 1e-11), from nearly perfectly elastic to nearly dead impacts;
    the fit itself matches the solver off its nodes to 1e-10."""
    for e in (1e-7, 0.002, 0.05, 0.3, 0.61, 0.9, 0.98, 1 - 1e-6, 1 - 1e-10):
        gamma = damping_for_restitution(e)
        assert restitution_of_damping(gamma) == pytest.approx(e, abs=1e-9)
    for gamma in (3e-9, 4e-4, 0.037, 0.77, 5.3, 91.0):
        assert fitted_restitution(gamma) == pytest.approx(restitution_of_damping(gamma), abs=1e-10)
    assert damping_for_restitution(1.0) == 0.0
    with pytest.raises(ValueError, match="too small to calibrate"):
        damping_for_restitution(1e-9)


# Chung & Ooi test 4, Al oxide: angle -> (tangential restitution, spin, rebound angle), Kratos' digitisation
TEST4 = {5: (0.948, 19.3, 3.76), 10: (0.687, 213.0, -1.56), 20: (0.616, 510.6, -7.54), 30: (0.684, 616.5, -3.55),
         40: (0.781, 544.8, 11.57), 60: (0.893, 357.5, 47.79), 85: (0.983, 63.1, 84.52)}


@pytest.mark.parametrize("angle", sorted(TEST4))
def test_chung_ooi_4_oblique_impacts_on_a_wall(angle):
    """Gross sliding (> 32.5 deg): the rigid-body limits to 0.1 %; below, the digitised published
    curve: e_t to 2 %, spin to 5 % or 10 rad/s (it rises by 40 rad/s per degree between 5 and 10 deg,
    so a quarter-degree reading error of the figure is 10 rad/s), rebound angle to 1.2 deg."""
    E, nu, rho, R, V, mu, e = 3.8e11, 0.23, 4000, 0.0025, 3.9, 0.092, 0.98
    a = math.radians(angle)
    vn, vt = V * math.cos(a), V * math.sin(a)
    p = dk.Particles(position=[[0, 0, R]], velocity=[[vt, 0, -vn]], radius=R, mass=ball(R, rho),
                     angular_velocity=[[0, 0, 0]])
    law = dk.Hertz(E, nu, restitution=e, friction=dk.Friction(mu))
    dk.Simulation(dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1))]), dk.VelocityVerlet(2e-9)).run(2e-5)
    v, w = p.velocity[0], p.angular_velocity[0]
    et, spin = v[0] / vt, abs(w[1])
    rebound = math.degrees(math.atan((v[0] - R * w[1]) / v[2]))
    assert v[2] / vn == pytest.approx(e, rel=1e-5)
    if math.tan(a) > 3.5 * mu * (1 + e):  # gross sliding: rigid-body limits
        assert et == pytest.approx(1 - mu * (1 + e) / math.tan(a), rel=1e-3)
        assert spin == pytest.approx(2.5 * mu * (1 + e) * vn / R, rel=4e-3)
    ref_et, ref_spin, ref_angle = TEST4[angle]
    assert et == pytest.approx(ref_et, rel=0.02)
    assert spin == pytest.approx(ref_spin, rel=0.05, abs=10.0)
    assert rebound == pytest.approx(ref_angle, abs=1.2)


def chung_ooi_5_impact(E, nu, rho, x, R, Vn, mu):
    """Chung & Ooi test 5: a sphere (R, rho; Hertz E, nu, restitution 1, friction mu) meets a rigid
    plane at normal speed Vn and tangential speed x mu Vn, without spin, resolved in 2000 steps per
    contact; returns its velocity and spin after 1.3 contact times."""
    m = ball(R, rho)
    law = dk.Hertz(E, nu, restitution=1.0, friction=dk.Friction(mu))
    contact_time = hertz_impact(2 * law.young_eff, R, m, Vn)[2]
    p = dk.Particles(position=[[0, 0, R]], velocity=[[x * mu * Vn, 0, -Vn]], radius=R, mass=m,
                     angular_velocity=[[0, 0, 0]])
    dk.Simulation(dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1))]), dk.VelocityVerlet(contact_time / 2000)).run(
        1.3 * contact_time)
    return p.velocity[0], p.angular_velocity[0]


@pytest.mark.parametrize("E, nu, rho, spin_tolerance", [(2.08e11, 0.30, 7850, 6e-3), (1.0e9, 0.40, 1400, 2.5e-2)])
@pytest.mark.parametrize("x", [8.0, 20.0])
def test_chung_ooi_5_oblique_impact_in_gross_sliding(E, nu, rho, spin_tolerance, x):
    """Steel and polyethylene microspheres (R = 10 um) at V_n = 5 m/s, x = V_t/(mu V_n) > 7: the
    rigid-body limits Omega = R w'/(mu V_n) = 5 and psi = (V_t' - R w')/(mu V_n') = x - 7. demkit's
    torque acts at the contact point, R - delta from the centre: the spin is short by about the
    peak delta/R (0.5 % steel, 2.2 % polyethylene; the published curves, with lever R, saturate at
    5.0 and 4.96), and psi is off by the same spin (0.03 and 0.11 of mu V_n)."""
    R, Vn, mu = 1e-5, 5.0, 0.3
    v, w = chung_ooi_5_impact(E, nu, rho, x, R, Vn, mu)
    assert v[2] / Vn == pytest.approx(1.0, rel=1e-6)
    spin = R * w[1] / (mu * Vn)
    assert spin == pytest.approx(5.0, rel=spin_tolerance)
    assert (v[0] - R * w[1]) / (mu * v[2]) == pytest.approx(x - 7, abs=5 * spin_tolerance)


# Chung & Ooi test 5, steel, below gross sliding: x -> Omega from LAMMPS 29 Sep 2021, pair_style granular
# hertz/material (E doubled, as LIGGGHTS-PFM does for the rigid plane) tangential mindlin NULL 0 0.3 against a
# frozen sphere of radius 1e-2 (R* = 0.999 R), 2000 steps a contact (deck: docs/data/chung_ooi/in.test5)
TEST5_LAMMPS_MINDLIN = {0.35: 0.012, 0.99: 0.230, 2.0: 1.629, 3.0: 2.858, 4.0: 3.854, 5.0: 4.591}


@pytest.mark.parametrize("x", sorted(TEST5_LAMMPS_MINDLIN))
def test_chung_ooi_5_below_gross_sliding_follows_mindlin_as_lammps(x):
    """Steel, x = V_t/(mu V_n) < 7: demkit's Omega = R w'/(mu V_n) against LAMMPS' `tangential mindlin`
    (the same law: no-slip spring 8 G* a on the accumulated displacement, Coulomb cap) to 0.03 of
    mu V_n (measured <= 0.02: demkit's lever R - delta against LAMMPS' R, and R* = 0.999 R there).

    Not the digitised published curve (0.43, 1.25, 2.52, 3.90, 4.84, 5.01 at x = 0.35 ... 5): no
    Mindlin-type law (LAMMPS mindlin, mindlin_rescale, mindlin/force, mindlin_rescale/force all give
    0.01-0.12 at x = 0.35 and 0.23-0.41 at x = 0.99) and no rescaling of either axis reproduces it,
    while test 4's digitised curve from the same paper (tested above), put in these variables, lies
    on demkit's. The test-5 curve is close (6 %) to a Mindlin spring of half the stiffness."""
    R, Vn, mu = 1e-5, 5.0, 0.3
    _, w = chung_ooi_5_impact(2.08e11, 0.30, 7850, x, R, Vn, mu)
    assert R * w[1] / (mu * Vn) == pytest.approx(TEST5_LAMMPS_MINDLIN[x], abs=0.03)


@pytest.mark.parametrize("X", [0.187, 0.551, 0.9])
def test_chung_ooi_6_spinning_sphere_in_gross_sliding(X):
    """beta = X - 1 (rigid limit) to 0.5 % of the initial contact-point speed."""
    E, nu, rho, R, Vn, mu, e = 7.0e10, 0.33, 2700, 0.10, 0.2, 0.4, 0.5
    w0 = 3.5 * mu * (1 + e) * Vn / (R * X)
    p = dk.Particles(position=[[0, 0, R]], velocity=[[0, 0, -Vn]], radius=R, mass=ball(R, rho),
                     angular_velocity=[[0, w0, 0]])
    law = dk.Hertz(E, nu, restitution=e, friction=dk.Friction(mu))
    dk.Simulation(dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1))]), dk.VelocityVerlet(5e-7)).run(1.5e-3)
    contact_point = p.velocity[0, 0] - R * p.angular_velocity[0, 1]
    beta = contact_point / (R * w0)
    assert beta == pytest.approx(X - 1, abs=5e-3)


@pytest.mark.parametrize("law", ["hertz", "linear"])
@pytest.mark.parametrize("w", [0.175, 5.0, 21.0])
def test_chung_ooi_7_counter_spinning_spheres_keep_their_spin(law, w):
    R, rho, v = 0.10, 2700, 0.2
    m = ball(R, rho)
    p = dk.Particles(position=[[-R, 0, 0], [R, 0, 0]], velocity=[[v, 0, 0], [-v, 0, 0]], radius=R, mass=m,
                     angular_velocity=[[0, 0, w], [0, 0, -w]])
    contact = (dk.Hertz(7e10, 0.33, 0.5, friction=dk.Friction(0.4)) if law == "hertz"
               else dk.KelvinVoigt(1e8, 1e3, friction=dk.Friction(0.4)))
    dk.Simulation(dk.Scene(p, [contact]), dk.VelocityVerlet(5e-7)).run(2e-3)
    assert p.velocity[0, 0] < 0  # it did bounce
    np.testing.assert_allclose(p.angular_velocity[:, 2], [w, -w], rtol=1e-12)
    assert np.abs(p.velocity[:, 1]).max() < 1e-12 * v


@pytest.mark.parametrize("make", [lambda: dk.KelvinVoigt(2e3, 0.5, friction=dk.Friction(0.3)),
                                  lambda: dk.Hertz(1e7, 0.3, 0.5, friction=dk.Friction(0.3))])
def test_a_sliding_sphere_ends_rolling_at_five_sevenths_of_its_speed(make):
    R, m, v0 = 0.01, 1e-3, 1.0
    p = dk.Particles(position=[[0, 0, R]], velocity=[[v0, 0, 0]], radius=R, mass=m)
    scene = dk.Scene(p, [make(), dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -9.81))])
    traj = dk.Simulation(scene, dk.VelocityVerlet(2e-6)).run(0.4, record_every=0.01)
    # rolling: v = w (R - delta), delta ~ m g / k << R
    assert p.velocity[0, 0] == pytest.approx(5 / 7 * v0, rel=2e-3)
    assert p.velocity[0, 0] == pytest.approx(p.angular_velocity[0, 1] * R, rel=2e-3)
    e = traj.energy
    balance = e["total"] + e["dissipated"] - e["total"][0]
    assert np.abs(balance).max() < 1e-3 * e["dissipated"][-1]


@pytest.mark.parametrize("ratio, sticks", [(0.5, True), (2.0, False)])
def test_coulomb_threshold_stick_below_slip_above(ratio, sticks):
    """A sphere that cannot roll (huge moment of inertia) pressed on a wall by g_n and pulled along it
    by g_t: it sticks for g_t < mu g_n and slides with acceleration g_t - mu g_n above."""
    R, m, mu, gn = 0.01, 1e-3, 0.4, 9.81
    gt = ratio * mu * gn
    p = dk.Particles(position=[[0, 0, R - m * gn / 1e4]], radius=R, mass=m, inertia_factor=1e9)
    law = dk.KelvinVoigt(1e4, 0.5, friction=dk.Friction(mu))
    sim = dk.Simulation(dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((gt, 0, -gn))]),
                        dk.VelocityVerlet(1e-5))
    sim.run(0.05)
    x0, v0 = p.position[0, 0], p.velocity[0, 0]
    sim.run(0.2)
    if sticks:
        assert abs(p.position[0, 0] - x0) < 1e-9 and abs(p.velocity[0, 0]) < 1e-7
    else:
        assert (p.velocity[0, 0] - v0) / 0.2 == pytest.approx(gt - mu * gn, rel=1e-3)


def test_friction_history_survives_rebuilds_and_sorting():
    """A sphere that cannot roll, held on a fixed sphere's flank by friction, among moving spheres that
    force hundreds of list rebuilds and re-sorts: it does not creep (losing its spring at a rebuild
    would let it slip a little every time); without friction it slides off."""
    rng = np.random.default_rng(3)
    grid, box = dk.build.lattice("sc", 10, spacing=3.0)  # a periodic box of side 30
    L = 30.0
    centre = np.full(3, L / 2 + 1.5)
    # the gas moves in rows along x, one speed per row, in lanes far from the resting pair: it forces
    # rebuilds and re-sorts but never touches anything
    chosen = grid[np.linalg.norm(grid[:, 1:] - centre[1:], axis=1) > 4.0]
    # the resting sphere sits on the fixed one's flank at 30 degrees from the top, pressed by gravity
    tilt = math.radians(30.0)
    on_top = centre + 0.9495 * np.array([math.sin(tilt), 0.0, math.cos(tilt)])  # radii 0.5 and 0.45
    pos = np.vstack([chosen, centre, on_top])
    n = len(pos)
    vel = np.zeros((n, 3))
    lanes, lane = np.unique(chosen[:, 1:], axis=0, return_inverse=True)
    vel[:-2, 0] = rng.normal(0, 8.0, size=len(lanes))[lane.ravel()]
    fixed = np.zeros(n, dtype=bool)
    fixed[-2] = True
    inertia = np.full(n, 0.4)
    inertia[-1] = 1e9  # cannot roll
    mass = np.ones(n)
    radius = np.full(n, 0.5)
    radius[-1] = 0.45
    p = dk.Particles(position=pos, velocity=vel, radius=radius, mass=mass, inertia_factor=inertia, fixed=fixed)
    law = dk.KelvinVoigt(1e4, 150.0, friction=dk.Friction(0.8, damping=80.0))  # settles in ~0.05 s
    field = PullSmall(0.49, (0.0, 0.0, -9.81))  # gravity on the resting sphere only: the gas floats
    scene = dk.Scene(p, [law, field], box=box, sort_every=50)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4))
    sim.run(0.3)
    start = p.position[-1].copy()
    sim.run(1.0)
    assert sim.statistics["neighbour_list_builds"] > 100
    assert scene.counters[2] > 10  # re-sorts
    # one lost spring would let it slip by its elastic displacement, m g sin(30) / k_t = 1.7e-3
    assert np.linalg.norm(p.position[-1] - start) < 1e-6
    assert np.linalg.norm(p.position[-2] - centre) == 0.0  # the fixed sphere did not move
    p.position[-1] = start
    p.velocity[-1] = 0.0
    frictionless = dk.Scene(p, [dk.KelvinVoigt(1e4, 5.0), PullSmall(0.49, (0.0, 0.0, -9.81))], box=box)
    dk.Simulation(frictionless, dk.VelocityVerlet(1e-4)).run(0.3)
    assert np.linalg.norm(p.position[-1] - start) > 0.05


def test_fixed_spheres_exert_and_feel_forces_but_never_move():
    p = dk.Particles(position=[[0, 0, 0], [0, 0, 1.2]], velocity=[[0, 0, 0], [0, 0, -1.0]], radius=0.5,
                     mass=1.0, fixed=np.array([True, False]))
    scene = dk.Scene(p, [dk.KelvinVoigt(1e4, 0.0)])
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(0.3, record_every=0.01)
    np.testing.assert_array_equal(traj.position[:, 0], 0.0)
    assert p.velocity[1, 2] == pytest.approx(1.0, rel=1e-4)  # elastic bounce off an immovable sphere
    assert np.isfinite(traj.energy["total"]).all()
    assert traj.energy["total"][-1] == pytest.approx(0.5, rel=1e-4)


def test_grazing_impacts_on_a_frictional_wall_never_gain_energy():
    """lammps#5007: a frictional wall once returned up to 34 % more kinetic energy at grazing angles."""
    R, m = 0.01, 1e-3
    for make in (lambda: dk.KelvinVoigt(1e4, 0.0, friction=dk.Friction(0.5, damping=0.0)),
                 lambda: dk.Hertz(1e8, 0.3, 1.0, friction=dk.Friction(0.5))):
        for angle in (80.0, 85.0, 88.0, 89.0, 89.5, 89.9):
            a = math.radians(angle)
            p = dk.Particles(position=[[0, 0, R]], velocity=[[math.sin(a), 0, -math.cos(a)]], radius=R, mass=m,
                             angular_velocity=[[0, 0, 0]])
            scene = dk.Scene(p, [make(), dk.Wall((0, 0, 0), (0, 0, 1))])
            traj = dk.Simulation(scene, dk.VelocityVerlet(1e-6)).run(0.01, record_every=0.001)
            kin = traj.energy["kinetic"] + traj.energy["rotational"]
            assert kin[-1] <= kin[0] * (1 + 1e-9), (angle, kin[-1] / kin[0])


def test_oblique_impact_at_size_ratio_1_to_20_matches_gross_sliding():
    """lammps#4244: rotating the tangential history caused unphysical sticking at large size ratios.
    A small sphere hits a fixed big one obliquely in gross sliding: tangential impulse mu J_n."""
    r, big, mu = 0.05, 1.0, 0.1
    m = 1.0
    a = math.radians(60.0)
    pos = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, big + r]])
    vel = np.array([[0.0, 0.0, 0.0], [math.sin(a), 0.0, -math.cos(a)]])
    p = dk.Particles(position=pos, velocity=vel, radius=[big, r], mass=[1e3, m], fixed=np.array([True, False]),
                     angular_velocity=np.zeros((2, 3)))
    law = dk.KelvinVoigt(1e7, 0.0, friction=dk.Friction(mu))
    dk.Simulation(dk.Scene(p, [law]), dk.VelocityVerlet(2e-6)).run(0.01)
    vn = math.cos(a)
    jn = 2 * m * vn  # elastic: normal velocity reverses
    assert p.velocity[1, 2] == pytest.approx(vn, rel=5e-3)
    assert p.velocity[1, 0] == pytest.approx(math.sin(a) - mu * jn / m, rel=5e-3)
    assert abs(p.angular_velocity[1, 1]) == pytest.approx(mu * jn * r / (0.4 * m * r * r), rel=5e-3)


def test_friction_conserves_angular_momentum_and_closes_the_energy_balance():
    rng = np.random.default_rng(5)
    R = 0.1
    x = np.array([[-0.1, 0, 0], [0.1, 0.0, 0]]) * 1.0001
    v = np.array([[0.6, 0.8, 0.1], [-0.6, -0.8, 0.2]])
    w = rng.normal(0, 3, size=(2, 3))
    balances = []
    for dt in (4e-6, 2e-6):
        p = dk.Particles(position=x, velocity=v, radius=R, mass=1.0, angular_velocity=w)
        law = dk.KelvinVoigt(1e6, 50.0, friction=dk.Friction(0.3))
        traj = dk.Simulation(dk.Scene(p, [law]), dk.VelocityVerlet(dt)).run(0.01, record_every=0.001)
        drift = np.abs(traj.angular_momentum - traj.angular_momentum[0]).max()
        assert drift < 1e-13
        e = traj.energy
        assert e["dissipated"][-1] > 0.01
        balances.append(abs(e["total"][-1] + e["dissipated"][-1] - e["total"][0]) / e["dissipated"][-1])
    # the dashpots' work is summed as dt x power at the half-step velocities: first order
    assert balances[0] < 5e-3 and balances[1] < 0.6 * balances[0]


def test_friction_books_the_work_its_kicks_do_exactly_and_a_frictional_balance_converges_at_second_order():
    """The dissipated work of a friction spring is booked as each force's work through the two
    kicks it acts in, F.(u + u_next) dt / 2 (demkit.interactions.spring). Before, F.u dt: a sphere
    sliding into rolling kept its analytic motion exactly while its balance drifted by 5.7e-3 at 20
    steps per contact, falling as dt."""
    R, m, k, g, v0, mu = 0.5, 1.0, 1000.0, 1.0, 1.0, 0.3
    z = R - m * g / k  # resting on the wall at the overlap that holds its weight
    for method in (dk.VelocityVerlet, dk.EulerCromer):
        p = dk.Particles(position=[[0, 0, z]], velocity=[[v0, 0, 0]], radius=R, mass=m)
        law = dk.KelvinVoigt(k, 3.0, friction=dk.Friction(mu))
        scene = dk.Scene(p, [dk.Wall((0, 0, 0), (0, 0, 1), contact=law), dk.Gravity((0, 0, -g))])
        dt = math.pi / math.sqrt(k / m) / 20
        traj = dk.Simulation(scene, method(dt)).run(3.0 * v0 / (mu * g), record_every=0.5)
        # rolling without slip at the end: v = a w with the lever arm a = R - delta = z, and
        # m v + (I / a) w = m v0 (angular momentum about the wall's contact line)
        ratio = 1.0 / (1.0 + 0.4 * (R / z) ** 2)
        assert p.velocity[0, 0] == pytest.approx(ratio * v0, rel=1e-12)
        e = traj.energy
        lost = 0.5 * m * v0 ** 2 * (1.0 - ratio)  # what the slip dissipates
        assert e["dissipated"][-1] == pytest.approx(lost, rel=1e-10)
        balance = np.abs(e["total"] + e["dissipated"] - e["total"][0])
        assert balance[-1] < 1e-12 * lost  # slid, rolled: every kick's work booked
        # while sliding, a frame lacks the half of its last force's work booked at the next update:
        # at most a step's work of the sliding force, dt mu m g v0
        assert balance.max() < dt * mu * m * g * v0
    # an oblique impact whose only dissipation is friction (no dashpots): the balance at the end
    # converges at second order (measured 1.78e-3, 4.96e-4, 1.21e-4 of the dissipated energy: 3.6x
    # and 4.1x per halving; the contact's start and end inside a step make it erratic) where booking
    # F.u dt gave first order
    balances = []
    for steps in (80, 160, 320):
        p = dk.Particles(position=[[-0.6, -0.3, 0], [0.6, 0.3, 0]], velocity=[[1.0, 0, 0], [-1.0, 0, 0]],
                         radius=R, mass=m)
        law = dk.KelvinVoigt(k, 0.0, friction=dk.Friction(0.2, damping=0.0))
        tc = math.pi / math.sqrt(k / (m / 2))
        traj = dk.Simulation(dk.Scene(p, [law]), dk.VelocityVerlet(tc / steps)).run(0.3 + 3 * tc, record_every=0.05)
        e = traj.energy
        assert e["dissipated"][-1] > 0.05  # it slid
        balances.append(abs(e["total"][-1] + e["dissipated"][-1] - e["total"][0]) / e["dissipated"][-1])
    assert balances[0] < 3e-3 and balances[1] < balances[0] / 2.8 and balances[2] < balances[1] / 2.8
    assert balances[2] < balances[0] / 10


def test_uniform_field_turns_a_dipole_like_a_pendulum():
    """Small oscillations of m in B: omega^2 = |m||B| / I; energy -m.B + I w^2/2 conserved."""
    I, mb = 0.4, 0.5
    angle = 0.01
    p = dk.Particles(position=[[0, 0, 0]], radius=1.0, mass=1.0, dipole=[[math.cos(angle), math.sin(angle), 0]])
    traj = dk.Simulation(dk.Scene(p, [dk.UniformField((mb, 0, 0))]), dk.VelocityVerlet(1e-3)).run(
        20.0, record_every=0.01)
    phi = np.arctan2(traj.dipole[:, 0, 1], traj.dipole[:, 0, 0])
    expected = angle * np.cos(math.sqrt(mb / I) * traj.time)
    assert np.abs(phi - expected).max() < 1e-3 * angle + 2e-6
    e = traj.energy["total"]
    assert np.abs(e - e[0]).max() < 1e-8
    np.testing.assert_allclose(traj.position[:, 0], 0.0)  # a uniform field does not pull


def test_gravity_free_fall_and_energy():
    p = dk.Particles(position=[[0, 0, 10.0]], radius=0.5, mass=2.0)
    traj = dk.Simulation(dk.Scene(p, [dk.Gravity((0, 0, -9.81))]), dk.VelocityVerlet(1e-3)).run(1.0, record_every=0.1)
    np.testing.assert_allclose(traj.position[:, 0, 2], 10.0 - 0.5 * 9.81 * traj.time ** 2, atol=1e-12)
    np.testing.assert_allclose(traj.energy["total"], traj.energy["total"][0], rtol=1e-13)
    assert traj.energy["gravity"][0] == pytest.approx(-2.0 * -9.81 * 10.0)


def test_a_scene_without_friction_keeps_no_history_and_compiles_no_friction():
    pos, box = dk.build.lattice("sc", 5, spacing=1.2)
    p = dk.Particles(position=pos, radius=0.5, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0), dk.Gravity((0, 0, -1))], box=box)
    assert all(lst.history.size == 0 for lst in scene.state.lists)
    assert scene.arrays["sphere_history"].size == 0
    assert "friction" not in scene.fused_source() and "wall" not in scene.fused_source()


@pytest.mark.parametrize("make, message", [
    (lambda: dk.Hertz(young=-1.0, poisson=0.3), "Young"),
    (lambda: dk.Hertz(young=float("nan"), poisson=0.3), "Young"),
    (lambda: dk.Hertz(young=1e9, poisson=0.5), "Poisson"),
    (lambda: dk.Hertz(young=1e9, poisson=-1.0), "Poisson"),
    (lambda: dk.Hertz(young=1e9, poisson=0.3, restitution=0.0), "restitution"),
    (lambda: dk.Hertz(young=1e9, poisson=0.3, restitution=1.2), "restitution"),
    (lambda: dk.Friction(coefficient=-0.1), "Friction coefficient"),
    (lambda: dk.Friction(coefficient=0.1, stiffness=0.0), "stiffness"),
    (lambda: dk.Wall(point=(0, 0, 0), normal=(0, 0, 0)), "zero length"),
    (lambda: dk.Wall(point=(0, 0), normal=(0, 0, 1)), "3-vector"),
    (lambda: dk.Wall(point=(0, 0, 0), normal=(0, 0, 1), frequency=2.0), "amplitude and a frequency"),
    (lambda: dk.UniformField((0, 1)), "3-vector"),
    (lambda: dk.UniformField((0, float("nan"), 1)), "finite"),
])
def test_bad_contact_and_surroundings_input(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_bad_scene_input_with_walls_and_fixed_spheres():
    law = dk.KelvinVoigt(1e3)
    p = dk.Particles(position=[[0, 0, 0.2]], radius=0.5)
    with pytest.raises(ValueError, match="deep inside the wall"):
        dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1))])
    with pytest.raises(ValueError, match="behind"):
        dk.Scene(dk.Particles(position=[[0, 0, -3.0]], radius=0.5), [law, dk.Wall((0, 0, 0), (0, 0, 1))])
    with pytest.raises(ValueError, match="contact law"):
        dk.Scene(dk.Particles(position=[[0, 0, 3.0]], radius=0.5), [dk.Wall((0, 0, 0), (0, 0, 1))])
    with pytest.raises(ValueError, match="dipole"):
        dk.Scene(dk.Particles(position=[[0, 0, 3.0]]), [dk.UniformField((0, 0, 1))])
    with pytest.raises(ValueError, match="fixed particle 0"):
        dk.Scene(dk.Particles(position=[[0, 0, 3.0]], velocity=[[1, 0, 0]], fixed=np.array([True])), [law])
    with pytest.raises(ValueError, match="booleans"):
        dk.Particles(position=[[0, 0, 3.0]], fixed=[1])
