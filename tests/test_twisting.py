"""Twisting resistance: rigid-body results for spinning spheres, conservation laws, bad input, cost.

Independent truths. A sphere spinning about the normal of a plane on which it rests under its weight
m g feels, while the contact pivots, the constant torque tau_max = l_tw m g (Marshall: l_tw = (2/3)
mu a, a = sqrt(R delta)), so its spin falls linearly at tau_max / I and stops at t = I w0 / tau_max.
Below the limit the twist spring holds it elastically: a torsion pendulum of period 2 pi sqrt(I/k_tw).
The resistance is a couple: two spheres pressed together and spinning about their line of centres
keep their total angular momentum about it while their relative spin decays at 2 tau_max / I.
"""
import math

import numpy as np
import pytest

import demkit as dk
from demkit.interactions.spring import HISTORY
from demkit.interactions.twisting import TWIST_HISTORY

R, M, G = 0.01, 1e-3, 9.81
I = 0.4 * M * R * R
MU = 0.5


def law(kind="kv", twisting="marshall", sliding="coulomb", rolling=None):
    """Kelvin-Voigt (k = 2000 N/m) or Hertz (E = 10 MPa) with friction 0.5 and twisting resistance
    (Marshall's by default; None: none)."""
    friction = dk.Friction(MU, sliding=sliding)
    twisting = dk.TwistingResistance() if twisting == "marshall" else twisting
    if kind == "kv":
        return dk.KelvinVoigt(2e3, 0.5, friction=friction, rolling=rolling, twisting=twisting)
    return dk.Hertz(1e7, 0.3, 0.5, friction=friction, rolling=rolling, twisting=twisting)


def resting_overlap(contact):
    """Overlap of a sphere resting on a rigid wall under its weight (no initial bounce)."""
    if isinstance(contact, dk.KelvinVoigt):
        return M * G / contact.stiffness
    return (M * G / (4.0 / 3.0 * 2.0 * contact.young_eff * math.sqrt(R))) ** (2.0 / 3.0)


def on_floor(contact, spin):
    """A sphere resting on the wall z = 0 under gravity, spinning about z; (particles, scene, overlap)."""
    delta = resting_overlap(contact)
    p = dk.Particles(position=[[0, 0, R - delta]], angular_velocity=[[0, 0, spin]], radius=R, mass=M)
    return p, dk.Scene(p, [contact, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -G))]), delta


def marshall_torque(delta):
    """Marshall's sliding torque (2/3) mu a m g on a plane, a = sqrt(R delta)."""
    return 2.0 / 3.0 * MU * math.sqrt(R * delta) * M * G


@pytest.mark.parametrize("kind, sliding", [("kv", "coulomb"), ("kv", "lammps"), ("hertz", "coulomb")])
def test_a_sphere_spinning_on_a_table_slows_linearly_and_stops_at_i_w0_over_tau_max(kind, sliding):
    w0 = 30.0
    contact = law(kind, sliding=sliding)
    p, scene, delta = on_floor(contact, w0)
    tau = marshall_torque(delta)
    stop = I * w0 / tau  # 1.66 s (Kelvin-Voigt), 1.95 s (Hertz)
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-5)).run(stop + 0.5, record_every=0.002)
    t, w = traj.time, traj.angular_velocity[:, 0, 2]
    pivoting = (t > 0.1 * stop) & (t < 0.9 * stop)
    slope = np.polyfit(t[pivoting], w[pivoting], 1)[0]
    # 1e-4: while the contact pivots the spring holds exactly tau_max and F_n = m g (the sphere starts
    # at its resting overlap); what remains is round-off
    assert -slope == pytest.approx(tau / I, rel=1e-4)
    k = int(np.argmax(w <= 0.0))
    crossing = t[k - 1] + w[k - 1] / (w[k - 1] - w[k]) * (t[k] - t[k - 1])
    # 2e-3: the spring first winds up to tau_max/k_tw (0.05 rad, 1.7 ms at 30 rad/s, half of it lost
    # torque: 5e-4 of the stop time), and the linear interpolation between records 2 ms apart
    assert crossing == pytest.approx(stop, rel=2e-3)
    # it stopped for good: the spring holds it elastically, oscillating by at most the limit torque's
    # amplitude tau_max / sqrt(k_tw I) (about 1 rad/s) and never pivoting on (no creep of the angle)
    after = t > stop + 0.02
    kt = 2.0 / 7.0 * contact.stiffness if kind == "kv" else 8.0 * 2.0 * contact.shear_eff * math.sqrt(R * delta)
    k_tw = 0.5 * kt * R * delta  # Marshall's k_t a^2 / 2 (a rigid wall doubles Mindlin's G*)
    assert np.abs(w[after]).max() <= 1.01 * tau / math.sqrt(k_tw * I)
    angle = np.cumsum(w[after]) * 0.002
    assert np.ptp(angle) < 2.1 * tau / k_tw
    e = traj.energy  # total + dissipated: the twist spring's energy and its dissipation are booked
    closing = np.abs(e["total"] + e["dissipated"] - e["total"][0]).max()
    assert e["dissipated"][-1] == pytest.approx(0.5 * I * w0 ** 2, rel=2e-2)
    assert closing < 1e-4 * e["dissipated"][-1]


def test_the_contact_table_holds_the_twisting_torque_and_its_dissipation():
    w0 = 30.0
    p, scene, delta = on_floor(law("kv"), w0)
    dk.Simulation(scene, dk.VelocityVerlet(1e-5)).run(0.02)  # past the spring's wind-up
    c = scene.contacts()
    tau = marshall_torque(delta)
    assert len(c) == 1 and c.wall[0] == 0
    # pivoting: the spring holds the limit, opposing the spin; a pure couple about the normal
    assert c.torque_j[0, 2] == pytest.approx(-tau, rel=1e-9)
    assert np.abs(c.torque_j[0, :2]).max() == 0.0 and np.abs(c.tangential_force).max() == 0.0
    assert c.dissipation[0] == pytest.approx(tau * p.angular_velocity[0, 2], rel=1e-9)
    force, torque = scene.forces()
    assert torque[0, 2] == pytest.approx(-tau, rel=1e-9)


@pytest.mark.parametrize("given", [True, False])
def test_a_small_twist_is_held_elastically_a_torsion_pendulum(given):
    """Below the limit: torque -k_tw theta, period 2 pi sqrt(I/k_tw) (given k_tw, no dashpot; or
    Marshall's k_tw = k_t a^2 / 2 with its own small dashpot, damping ratio 4e-3)."""
    delta = resting_overlap(law("kv"))
    if given:
        k_tw = 1e-5
        twisting = dk.TwistingResistance(stiffness=k_tw, damping=0.0, lever=1e-3)
    else:
        k_tw = 0.5 * 2.0 / 7.0 * 2e3 * R * delta
        twisting = "marshall"
    w0 = 0.3  # the largest torque w0 sqrt(k_tw I) stays below the limit (0.02 and 0.3 of it)
    p, scene, _ = on_floor(law("kv", twisting=twisting), w0)
    period = 2 * math.pi * math.sqrt(I / k_tw)  # 0.40 s, 0.34 s
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-5)).run(3.2 * period, record_every=1e-3)
    t, w = traj.time, traj.angular_velocity[:, 0, 2]
    k = np.flatnonzero((w[:-1] > 0) != (w[1:] > 0))  # sign changes, every half period
    crossings = t[k] + w[k] / (w[k] - w[k + 1]) * (t[k + 1] - t[k])
    measured = (crossings[-1] - crossings[0]) / (len(crossings) - 1) * 2
    # 1e-4: a damping ratio of 4e-3 shifts the period by 8e-6, Verlet's phase error (w dt)^2 / 24 is
    # 1e-10; interpolating between records 1 ms apart: below 1e-5 of the period
    assert len(crossings) == 6 and measured == pytest.approx(period, rel=1e-4)
    # torque -k_tw theta, theta the angle turned (analytic, undamped: (w0/W) sin(W t))
    theta = w0 / (2 * math.pi / period) * math.sin(2 * math.pi * t[-1] / period)
    c = scene.contacts()
    if given:
        # 1e-5: the twist angle is the midpoint sum of the spins, second order: (W dt)^2 ~ 3e-8
        assert c.torque_j[0, 2] == pytest.approx(-k_tw * theta, rel=1e-5)
        e = traj.energy  # no dashpot: the twist spring's energy closes the balance
        assert np.abs(e["total"] - e["total"][0]).max() < 1e-6 * 0.5 * I * w0 ** 2


def pressed_pair(w1, w2, twisting=True):
    """Two magnets (R = 0.5, m = 1, moments along x, head to tail) touching along x at their resting
    overlap, spinning about x; Kelvin-Voigt with friction 0.5 and Marshall's twisting resistance."""
    from scipy.optimize import brentq
    k = 1e3
    delta = brentq(lambda d: k * d - 6.0 / (1.0 - d) ** 4, 0.0, 0.1)  # dipole pull 6 A m^2 / r^4
    p = dk.Particles(position=[[0, 0, 0], [1.0 - delta, 0, 0]], radius=0.5, mass=1.0,
                     angular_velocity=[[w1, 0, 0], [w2, 0, 0]], dipole=[[1.0, 0, 0], [1.0, 0, 0]])
    contact = dk.KelvinVoigt(k, 2.0, friction=dk.Friction(MU),
                             twisting=dk.TwistingResistance() if twisting else None)
    return p, dk.Scene(p, [dk.Dipole(prefactor=1.0), contact]), k * delta, delta


def test_two_magnets_spinning_about_their_axis_keep_their_angular_momentum_while_the_twist_decays():
    w1, w2 = 4.0, -2.0
    p, scene, fn, delta = pressed_pair(w1, w2)
    inertia = 0.4 * 0.5 ** 2
    tau = 2.0 / 3.0 * MU * math.sqrt(0.25 * delta) * fn  # R* = 1/4
    stop = (w1 - w2) * inertia / (2 * tau)  # 3.7 s
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(stop + 1.0, record_every=0.01)
    L = traj.angular_momentum
    # the twisting torques are a couple: round-off only (the dipoles stay along the spin axis), at
    # most one rounding of the spins per step over the 47,000 steps (measured 1.06e-12, bound 6e-12)
    steps = len(traj.time) * 100
    assert np.abs(L - L[0]).max() < steps * np.finfo(float).eps * inertia * (abs(w1) + abs(w2))
    assert L[0, 0] == pytest.approx(inertia * (w1 + w2), rel=1e-15)
    t, w = traj.time, traj.angular_velocity[:, :, 0]
    relative = w[:, 0] - w[:, 1]
    pivoting = (t > 0.1 * stop) & (t < 0.9 * stop)
    slope = np.polyfit(t[pivoting], relative[pivoting], 1)[0]
    # 1e-4: the normal force is the dipoles' pull at the resting overlap, held exactly
    assert -slope == pytest.approx(2 * tau / inertia, rel=1e-4)
    # then co-rotating at the mean spin, up to the stick oscillation: the spring took the limit torque
    # at the stop, so the relative spin swings by at most tau_max / sqrt(k_tw I/2), 0.8 rad/s
    k_tw = 0.5 * (2.0 / 7.0 * 1e3) * 0.25 * delta
    late = t > stop + 0.05
    assert np.abs(relative[late]).max() <= 1.01 * tau / math.sqrt(k_tw * inertia / 2)
    e = traj.energy
    # 1e-4: the springs' work is booked through the kicks exactly; what remains is the dashpots'
    # first-order booking (2.6e-5 of the dissipated work at dt = 1e-4 when the springs' was too)
    assert np.abs(e["total"] + e["dissipated"] - e["total"][0]).max() < 1e-4 * e["dissipated"][-1]


@pytest.mark.parametrize("kind", ["kv", "hertz"])
def test_twisting_with_rolling_keeps_angular_momentum_and_closes_the_energy_balance(kind):
    """An oblique spinning impact of two spheres with friction, rolling and twisting resistance; the
    contact ends with energy left in its springs (booked as dissipated), first order in dt."""
    rng = np.random.default_rng(3)
    x = np.array([[-R, 0, 0], [R, 0, 0]]) * 1.0001
    v = np.array([[0.3, 0.4, 0.0], [-0.3, -0.4, 0.1]])
    w = rng.normal(0, 200, size=(2, 3))
    w[:, 0] += [300.0, -300.0]  # a strong relative spin about the line of centres
    results = {}
    for twisting, dt in ((False, 1e-6), (True, 1e-6), (True, 5e-7)):
        p = dk.Particles(position=x, velocity=v, radius=R, mass=M, angular_velocity=w)
        contact = law(kind, twisting="marshall" if twisting else None, rolling=dk.RollingResistance(0.2))
        traj = dk.Simulation(dk.Scene(p, [contact]), dk.VelocityVerlet(dt)).run(0.004, record_every=0.0002)
        assert np.abs(traj.angular_momentum - traj.angular_momentum[0]).max() < 1e-13 * M * R * 500
        e = traj.energy
        balance = abs(e["total"][-1] + e["dissipated"][-1] - e["total"][0]) / e["dissipated"][-1]
        assert balance < 5e-4
        results[twisting, dt] = (p.angular_velocity.copy(), e["dissipated"][-1], balance)
    assert np.abs(results[True, 1e-6][0] - results[False, 1e-6][0]).max() > 1.0  # twisting acted
    assert results[True, 1e-6][1] > results[False, 1e-6][1]
    assert results[True, 5e-7][2] < 0.6 * results[True, 1e-6][2]  # first order in dt


def test_unused_twisting_costs_nothing_and_used_adds_two_history_values():
    """Without twisting resistance a scene keeps today's history widths and its fused code has no
    twisting (its laws take the twisting law's arguments, lever 0, so that tier 1 runs both as one kind);
    with it, two more history values per contact and sphere-wall contact."""
    def scene(contact):
        p = dk.Particles(position=[[0, 0, 0.5], [0.99, 0, 0.5]], radius=0.5, mass=1.0)
        return dk.Scene(p, [contact, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -1))])

    for rolling, width in ((None, HISTORY), (dk.RollingResistance(0.1), 2 * HISTORY)):
        plain = dk.KelvinVoigt(1e3, 1.0, friction=dk.Friction(0.3), rolling=rolling)
        assert plain.history_size == width and plain.twisting is None and "twisting" not in repr(plain)
        assert len(plain.parameters) == 14 and plain.lever_tw == 0.0  # (the twisting law's arguments, lever 0)
        s = scene(plain)
        assert "twist" not in s.fused_source()
        assert s.effects[0].history_size == width and s.effects[0].table_values()[6] == 0.0  # (no twist)
        twisted = dk.KelvinVoigt(1e3, 1.0, friction=dk.Friction(0.3), rolling=rolling,
                                 twisting=dk.TwistingResistance())
        assert twisted.history_size == width + TWIST_HISTORY
        assert twisted.parameters == plain.parameters and twisted.parameters[-4:] == ("k_tw", "eta_tw", "lever_tw", "dt")
        s = scene(twisted)
        assert "kelvin_voigt_twisting_force" in s.fused_source() and s.effects[0].history_size == width + TWIST_HISTORY
        # the wall's table: (mu_r, k_r, eta_r, k_tw, eta_tw, l_tw), Marshall's as -1, then twisting on and the
        # wall's spin (demkit.interactions.wall.TABLE)
        np.testing.assert_array_equal(s.effects[0].table_values()[3:], [-1.0, -1.0, -1.0, 1.0, 0.0, 0.0, 0.0])
    hertz = dk.Hertz(1e7, 0.3, friction=dk.Friction(0.3), twisting=dk.TwistingResistance(1.0, 0.0, 1e-3))
    assert hertz.history_size == HISTORY + TWIST_HISTORY and (hertz.k_tw, hertz.eta_tw, hertz.lever_tw) == (1.0, 0.0, 1e-3)
    # no torque possible: no history kept (a zero lever, or Marshall's (2/3) mu a with mu = 0)
    assert dk.KelvinVoigt(1.0, friction=dk.Friction(0.3), twisting=dk.TwistingResistance(lever=0.0)).twisting is None
    assert dk.KelvinVoigt(1.0, friction=dk.Friction(0.0), twisting=dk.TwistingResistance()).history_size == HISTORY


def test_a_given_twist_spring_limits_the_time_step():
    p = dk.Particles(position=[[0, 0, 0], [0.99, 0, 0]], radius=0.5, mass=1.0)
    soft = dk.KelvinVoigt(1e3, 1.0, friction=dk.Friction(0.3))
    stiff = dk.KelvinVoigt(1e3, 1.0, friction=dk.Friction(0.3), twisting=dk.TwistingResistance(stiffness=1e6))
    assert stiff.max_time_step(p) == pytest.approx(0.1 * math.pi / math.sqrt(1e6 / 0.05))  # I* = 0.1 / 2
    assert dk.KelvinVoigt(1e3, 1.0, friction=dk.Friction(0.3),
                          twisting=dk.TwistingResistance()).max_time_step(p) == soft.max_time_step(p)


@pytest.mark.parametrize("make, error, message", [
    (lambda: dk.TwistingResistance(stiffness=-1.0), ValueError, "TwistingResistance stiffness"),
    (lambda: dk.TwistingResistance(stiffness=0.0), ValueError, "TwistingResistance stiffness"),
    (lambda: dk.TwistingResistance(stiffness=float("nan")), ValueError, "TwistingResistance stiffness"),
    (lambda: dk.TwistingResistance(damping=-1.0), ValueError, "TwistingResistance damping"),
    (lambda: dk.TwistingResistance(damping=float("inf")), ValueError, "TwistingResistance damping"),
    (lambda: dk.TwistingResistance(lever=-1e-3), ValueError, "TwistingResistance lever"),
    (lambda: dk.TwistingResistance(lever=float("nan")), ValueError, "TwistingResistance lever"),
    (lambda: dk.KelvinVoigt(1.0, twisting=dk.TwistingResistance()), ValueError, "needs friction"),
    (lambda: dk.Hertz(1e7, 0.3, twisting=dk.TwistingResistance()), ValueError, "needs friction"),
    (lambda: dk.KelvinVoigt(1.0, friction=dk.Friction(0.3), twisting=0.1), TypeError, "TwistingResistance"),
])
def test_bad_twisting_input(make, error, message):
    with pytest.raises(error, match=message):
        make()


SCENE = """
[particles]
position = [[0.0, 0.0, 0.0099], [0.05, 0.0, 0.0099]]
radius = 0.01
mass = 1e-3
[interactions.kelvin_voigt]
stiffness = 2e3
damping = 0.5
{friction}
{twisting}
[[interactions.wall]]
point = [0.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[integrator]
dt = 1e-5
[run]
duration = 1e-3
"""


def test_scene_files_give_the_contact_law_its_twisting_resistance():
    friction = "[interactions.friction]\ncoefficient = 0.5"
    loaded = dk.parse_scene(SCENE.format(friction=friction, twisting="[interactions.twisting_resistance]"))
    contact = loaded.scene.interactions[0]
    assert contact.twisting.marshall and contact.history_size == HISTORY + TWIST_HISTORY
    assert loaded.scene.effects[0].history_size == HISTORY + TWIST_HISTORY
    given = "[interactions.twisting_resistance]\nstiffness = 1e-5\ndamping = 0.0\nlever = 1e-3"
    contact = dk.parse_scene(SCENE.format(friction=friction, twisting=given)).scene.interactions[0]
    assert (contact.k_tw, contact.eta_tw, contact.lever_tw) == (1e-5, 0.0, 1e-3)
    with pytest.raises(dk.SceneFileError, match="twisting_resistance: needs .interactions.friction."):
        dk.parse_scene(SCENE.format(friction="", twisting=given))
    with pytest.raises(dk.SceneFileError, match="twisting_resistance.lever"):
        dk.parse_scene(SCENE.format(friction=friction, twisting="[interactions.twisting_resistance]\nlever = -1.0"))
