"""The adaptive reference solver and work-precision reports (demkit.accuracy).

Scenes are tiny and durations short; two kernel modules are used (Kelvin-Voigt alone, and the
paper's Dipole + Kelvin-Voigt), both usually already in the on-disk kernel cache.
"""
import importlib
import math

import numpy as np
import pytest
from scipy.optimize import brentq

import demkit as dk
from demkit.interactions.contact import contact_duration, restitution

K, C = 1.0, 0.1  # Kelvin-Voigt stiffness and damping of the impact tests
M_EFF = 0.5  # two unit masses
U = 0.2  # approach speed (each sphere at 0.1): the overlap peaks at 0.13 radii
T_ONSET = 0.5  # the gap of 0.1 closes at speed 0.2


def impact_scene(no_tension=False):
    """Two unit spheres (R = 1, m = 1) approaching head-on at speed 0.1 each, no dipoles."""
    p = dk.Particles(position=[[-1.05, 0, 0], [1.05, 0, 0]], velocity=[[0.1, 0, 0], [-0.1, 0, 0]], radius=1.0,
                     mass=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(K, C, no_tension=no_tension)])


def overlap_and_rate(s):
    """Closed-form damped oscillator of the overlap, s time units after contact onset."""
    w0 = math.sqrt(K / M_EFF)
    zeta = C / (2 * math.sqrt(K * M_EFF))
    wd = w0 * math.sqrt(1 - zeta ** 2)
    decay = math.exp(-zeta * w0 * s)
    return U / wd * decay * math.sin(wd * s), U * decay * (math.cos(wd * s) - zeta * w0 / wd * math.sin(wd * s))


def analytic_distance(t, no_tension=False):
    """Centre distance r(t) of the head-on Kelvin-Voigt impact (centre of mass at rest)."""
    if t <= T_ONSET:
        return 2.1 - U * t
    tc = contact_duration(K, C, M_EFF)
    release, speed = tc, restitution(K, C, M_EFF) * U
    if no_tension:  # the force reaches zero (k delta + c delta' = 0) before the overlap does
        kink = brentq(lambda s: K * overlap_and_rate(s)[0] + C * overlap_and_rate(s)[1], 0.5 * tc, tc)
        delta, rate = overlap_and_rate(kink)
        release, speed = kink - delta / rate, -rate  # then free flight at constant speed
        if t - T_ONSET <= release and t - T_ONSET > kink:
            return 2.0 - (delta + rate * (t - T_ONSET - kink))
    s = t - T_ONSET
    if s <= release:
        return 2.0 - overlap_and_rate(s)[0]
    return 2.0 + speed * (s - release)


@pytest.mark.parametrize("no_tension", [False, True])
def test_reference_matches_the_analytic_kelvin_voigt_impact(no_tension):
    scene = impact_scene(no_tension)
    times = np.linspace(0.0, 6.0, 25)
    ref = dk.accuracy.reference(scene, 6.0, times=times)
    r = ref.position[:, 1, 0] - ref.position[:, 0, 0]
    exact = np.array([analytic_distance(t, no_tension) for t in times])
    # DOP853 at rtol 1e-12 on lengths of order 2: measured 7e-13. The same DOP853 without events
    # errs by 2e-10, with solve_ivp's terminal events restarted from the event state by 3e-11
    assert np.abs(r - exact).max() < 1e-11
    kinds = [e["kind"] for e in ref.events]
    assert kinds == (["contact", "dashpot clamp", "contact"] if no_tension else ["contact", "contact"])
    onset, release = ref.events[0]["time"], ref.events[-1]["time"]
    assert onset == pytest.approx(T_ONSET, abs=1e-11)
    if not no_tension:
        # contact duration pi / omega_d and restitution exp(-pi zeta / sqrt(1 - zeta^2)), both closed forms
        assert release - onset == pytest.approx(contact_duration(K, C, M_EFF), rel=1e-10)
        speed = ref.velocity[-1, 1, 0] - ref.velocity[-1, 0, 0]
        assert speed == pytest.approx(restitution(K, C, M_EFF) * U, rel=1e-10)
    e = ref.energy
    balance = np.abs(e["total"] + e["dissipated"] - e["total"][0] - e["dissipated"][0]).max()
    assert balance < 1e-10 * e["kinetic"][0]  # measured 7e-12 of the initial kinetic energy
    assert e["dissipated"][-1] > 0.1 * e["kinetic"][0]  # the dashpot did dissipate (restitution 0.8)
    assert ref.restarts == len(ref.events) and ref.evaluations > 0


def test_reference_leaves_the_scene_as_it_was():
    scene = impact_scene()
    before = (scene.particles.position.copy(), scene.particles.velocity.copy())
    energy = scene.energy()
    dk.accuracy.reference(scene, 3.0)
    assert np.array_equal(scene.particles.position, before[0])
    assert np.array_equal(scene.particles.velocity, before[1])
    assert scene.energy() == energy and scene.dissipated == 0.0
    # and a run afterwards is the run one would have had without the reference
    a = dk.Simulation(scene, dk.VelocityVerlet(0.01)).run(3.0)
    b = dk.Simulation(impact_scene(), dk.VelocityVerlet(0.01)).run(3.0)
    assert np.array_equal(a.position, b.position)


def smooth_scene(velocity_shift=None):
    """Two magnets that attract, turn and orbit for 4 time units without touching (the paper's
    Dipole + Kelvin-Voigt combination, so the contact law is present but idle)."""
    pos = np.array([[0.0, 0.0, 0.0], [3.0, 0.4, 0.2]])
    dip = np.array([[1.0, 0.3, 0.0], [0.0, 1.0, 0.5]])
    p = dk.Particles(position=pos, velocity=[[0, 0.1, 0], [0, -0.1, 0.05]], radius=0.5, mass=[1.0, 1.3], dipole=dip)
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0), dk.KelvinVoigt(1.0, 0.1)])
    if velocity_shift is not None:  # start Euler-Cromer half a step back: v - F dt / 2m, w - tau dt / 2I
        force, torque = scene.forces()
        p.velocity -= force / p.mass[:, None] * velocity_shift / 2
        p.angular_velocity -= torque / p.inertia[:, None] * velocity_shift / 2
    return scene


SMOOTH_T = 4.0
DTS = np.array([0.04, 0.02, 0.01, 0.005])


@pytest.fixture(scope="module")
def smooth_reference():
    return dk.accuracy.reference(smooth_scene(), SMOOTH_T, times=[0.0, 2.0, SMOOTH_T])


def slopes(make, ref, shift=False):
    pos, vel = [], []
    for dt in DTS:
        traj = dk.Simulation(smooth_scene(dt if shift else None), make(dt)).run(SMOOTH_T)
        assert np.linalg.norm(traj.position[-1, 0] - traj.position[-1, 1]) > 2.0  # never touched
        pos.append(np.abs(traj.position[-1] - ref.position[-1]).max())
        vel.append(np.abs(traj.velocity[-1] - ref.velocity[-1]).max())
    return np.polyfit(np.log(DTS), np.log(pos), 1)[0], np.polyfit(np.log(DTS), np.log(vel), 1)[0], pos


def test_velocity_verlet_converges_to_the_reference_at_second_order(smooth_reference):
    pos_order, vel_order, errors = slopes(dk.VelocityVerlet, smooth_reference)
    # measured 2.0000 and 2.0001: a clean power law down to 7e-7, far above the reference's ~1e-11
    assert pos_order == pytest.approx(2.0, abs=0.05) and vel_order == pytest.approx(2.0, abs=0.05)
    assert errors[-1] < 1e-6


def test_euler_cromer_is_velocity_verlet_started_half_a_step_late(smooth_reference):
    """Euler-Cromer's positions are velocity Verlet's from the initial velocity v0 + F0 dt/2m, and its
    velocities are Verlet's half-step ones. Started from the given v0 (F0 != 0 here) its positions
    are therefore first order; started from v0 - F0 dt/2m they are second order, and its velocities
    stay first order either way."""
    pos_order, vel_order, _ = slopes(dk.EulerCromer, smooth_reference)
    assert pos_order == pytest.approx(1.0, abs=0.1)  # measured 0.99
    assert vel_order == pytest.approx(1.0, abs=0.1)  # measured 0.93
    pos_order, vel_order, _ = slopes(dk.EulerCromer, smooth_reference, shift=True)
    assert pos_order == pytest.approx(2.0, abs=0.05)  # measured 2.0000
    assert vel_order == pytest.approx(1.0, abs=0.05)  # measured 0.999: half a step off
    dt = 0.01
    ec = dk.Simulation(smooth_scene(dt), dk.EulerCromer(dt)).run(SMOOTH_T, record_every=0.5)
    vv = dk.Simulation(smooth_scene(), dk.VelocityVerlet(dt)).run(SMOOTH_T, record_every=0.5)
    # the same sequence of positions and dipoles up to round-off (measured 7e-16)
    assert np.abs(ec.position - vv.position).max() < 1e-12
    assert np.abs(ec.dipole - vv.dipole).max() < 1e-12


def test_reference_conserves_energy_and_angular_momentum(smooth_reference):
    ref = smooth_reference
    e = ref.energy
    scale = np.abs(e["magnetic"]).max()
    # rtol 1e-12: measured 1.4e-12 of the largest |magnetic energy|, 4e-14 of |L|, 2e-12 of |m|
    assert np.abs(e["total"] - e["total"][0]).max() < 1e-10 * scale
    L = ref.angular_momentum
    assert np.abs(L - L[0]).max() < 1e-10 * np.linalg.norm(L[0])
    assert np.allclose(np.linalg.norm(ref.dipole, axis=2), np.linalg.norm(ref.dipole[0], axis=1), rtol=1e-10)


def test_reference_energy_balance_through_magnetic_bounces():
    """Two of the paper's magnets released close together: five dashpot contacts in 2500 time units."""
    setup = dk.two_magnets.TwoMagnets(b_over_R=2.0, x0=8.0)
    ref = dk.accuracy.reference(setup.scene(), 2500.0, times=np.linspace(0, 2500.0, 26))
    assert ref.restarts == 10 and {e["kind"] for e in ref.events} == {"contact"}
    e = ref.energy
    balance = np.abs(e["total"] + e["dissipated"] - e["total"][0]).max()
    assert e["dissipated"][-1] > 0.5 * e["kinetic"][0]  # the bounces did dissipate
    assert balance < 1e-10 * np.abs(e["magnetic"]).max()  # measured 5e-12
    L = ref.angular_momentum
    assert np.abs(L - L[0]).max() < 1e-10 * np.linalg.norm(L[0])  # measured 2e-12


def test_reference_refuses_history_and_large_scenes():
    p = dk.Particles(position=[[0, 0, 0], [2.5, 0, 0]], radius=1.0)
    friction = dk.Scene(p, [dk.KelvinVoigt(1.0, 0.1, friction=dk.Friction(0.5))])
    with pytest.raises(ValueError, match="history"):
        dk.accuracy.reference(friction, 1.0)
    many = dk.Particles(position=np.arange(201)[:, None] * np.array([[3.0, 0, 0]]), radius=1.0)
    with pytest.raises(ValueError, match="at most 200 spheres"):
        dk.accuracy.reference(dk.Scene(many, []), 1.0)


def test_work_precision_on_two_magnets(tmp_path):
    scene = smooth_scene()
    # 0.5 is above the contact law's safe step (a tenth of the 2.2-long contact): a stable=False row
    report = dk.accuracy.work_precision(scene, SMOOTH_T, methods=[dk.EulerCromer, lambda dt: dk.VelocityVerlet(dt)],
                                        dts=[0.5, 0.04, 0.02, 0.01], observable=lambda t: t.position[-1, 0, 0],
                                        repeats=1)
    assert report.reference["kind"] == "adaptive"
    assert [r["method"] for r in report.rows] == ["EulerCromer"] * 4 + ["VelocityVerlet"] * 4
    for method in ("EulerCromer", "VelocityVerlet"):
        rows = [r for r in report.rows if r["method"] == method]
        assert not rows[0]["stable"] and "too large" in rows[0]["message"] and math.isnan(rows[0]["position_error"])
        good = rows[1:]
        assert all(r["stable"] for r in good)
        for key in ("position_error", "velocity_error", "energy_error", "observable_error"):
            errors = [r[key] for r in good]
            # dt halves: errors fall by at least 1.8x (first order) per halving
            assert all(b < a / 1.8 for a, b in zip(errors, errors[1:])), (method, key, errors)
        assert [r["evaluations"] for r in good] == [100, 200, 400]
        assert all(r["angular_momentum_drift"] < 1e-12 for r in good)  # both are symmetric splittings
    vv = [r for r in report.rows if r["method"] == "VelocityVerlet"][1:]
    ec = [r for r in report.rows if r["method"] == "EulerCromer"][1:]
    assert all(a["position_error"] < 0.1 * b["position_error"] for a, b in zip(vv, ec))
    text = report.table()
    assert "VelocityVerlet" in text and "NO" in text and "adaptive DOP853" in text
    assert report.convergence_notes() == [] and "convergence:" not in text  # smooth: positions converge
    assert all(r["repeats"] == 1 and r["cpu_seconds"] > 0 for r in report.rows if r["stable"])
    pick = report.suggest(1e-4)
    assert pick and pick.row["method"] == "VelocityVerlet"  # EulerCromer never gets there
    assert not report.suggest(1e-12) and "no run meets" in str(report.suggest(1e-12))
    png = report.plot(tmp_path / "wp.png")
    assert png.stat().st_size > 10000
    report.to_csv(tmp_path / "wp.csv")
    assert len((tmp_path / "wp.csv").read_text().splitlines()) == 9
    assert '"kind": "adaptive"' in report.to_json()


def test_work_precision_falls_back_to_the_finest_run_for_history_scenes():
    p = dk.Particles(position=[[-1.05, 0, 0], [1.05, 0.3, 0]], velocity=[[0.1, 0, 0], [-0.1, 0, 0]], radius=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1.0, 0.1, friction=dk.Friction(0.5))])
    report = dk.accuracy.work_precision(scene, 3.0, methods=[dk.VelocityVerlet], dts=[0.02, 0.01, 0.005], repeats=1)
    assert report.reference["kind"] == "finest" and report.reference["dt"] == 0.005
    assert [r["is_reference"] for r in report.rows] == [False, False, True]
    assert report.rows[1]["position_error"] < report.rows[0]["position_error"]


def test_suggest_dt_meets_the_target_on_the_smooth_pair():
    target = 1e-6
    pick = dk.accuracy.suggest_dt(smooth_scene(), target, pilot=1.0, dt=0.04, duration=SMOOTH_T)
    assert pick.order == pytest.approx(2.0, abs=0.05)  # velocity Verlet on a smooth problem
    run = dk.Simulation(smooth_scene(), dk.VelocityVerlet(pick.dt)).run(SMOOTH_T)
    truth = dk.accuracy.reference(smooth_scene(), run.time[-1])  # the run ends on a whole step
    error = np.linalg.norm(run.position[-1] - truth.position[-1], axis=1).max()
    # an extrapolation from a quarter of the run (measured 1.5e-6 for 1e-6): within a factor 3
    assert target / 3 < error < 3 * target


def test_runs_ending_past_duration_on_a_whole_step_are_compared_there():
    # 4.0 / 0.045 = 88.9: the run takes 89 steps and ends at 4.005; its check time is 4.005
    report = dk.accuracy.work_precision(smooth_scene(), SMOOTH_T, methods=[dk.VelocityVerlet], dts=[0.045, 0.0225],
                                        repeats=1)
    assert all(r["stable"] for r in report.rows)
    coarse, fine = report.rows
    assert 3.5 < coarse["position_error"] / fine["position_error"] < 4.5  # second order at the shifted times


def test_reference_wall_impact_matches_the_closed_form():
    """A sphere hitting a Kelvin-Voigt wall: the pair formulas with m* = m (the wall is immovable)."""
    p = dk.Particles(position=[[0, 0, 1.05]], velocity=[[0, 0, -0.1]], radius=1.0, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(K, C), dk.Wall((0, 0, 0), (0, 0, 1))])
    ref = dk.accuracy.reference(scene, 6.0)
    assert [e["kind"] for e in ref.events] == ["wall contact", "wall contact"]
    onset, release = ref.events[0]["time"], ref.events[1]["time"]
    assert onset == pytest.approx(0.5, abs=1e-11)
    # measured 8e-13 and 8e-12 relative
    assert release - onset == pytest.approx(contact_duration(K, C, 1.0), rel=1e-10)
    assert ref.velocity[-1, 0, 2] == pytest.approx(0.1 * restitution(K, C, 1.0), rel=1e-10)


class ThreeStageVerlet(dk.VelocityVerlet):
    """A stand-in for another team's integrator: declares its cost and order, runs velocity Verlet."""

    evaluations_per_step = 3
    order = 4


def test_work_precision_takes_any_integrator_and_its_declared_cost():
    report = dk.accuracy.work_precision(smooth_scene(), SMOOTH_T, dts=[0.04, 0.02], reference="finest", repeats=1,
                                        methods={"EC": dk.EulerCromer, "three": lambda dt: ThreeStageVerlet(dt)})
    assert [r["method"] for r in report.rows] == ["EC", "EC", "three", "three"]
    assert [r["evaluations"] for r in report.rows] == [100, 200, 300, 600]
    # the finest run of the highest declared order is the reference
    assert report.reference["method"] == "three" and report.rows[-1]["is_reference"]
    assert math.isnan(report.rows[-1]["position_error"]) and report.rows[2]["position_error"] > 0


def test_reference_sphere_on_a_fixed_sphere_and_hertz_restitution():
    # a fixed sphere has infinite mass in the kernels: the pair formulas with m* = m, and it stays put
    p = dk.Particles(position=[[0, 0, 0], [2.1, 0, 0]], velocity=[[0, 0, 0], [-0.1, 0, 0]], radius=1.0,
                     fixed=np.array([True, False]))
    ref = dk.accuracy.reference(dk.Scene(p, [dk.KelvinVoigt(K, C)]), 6.0, times=np.linspace(0, 6, 7))
    assert np.array_equal(ref.position[:, 0], np.zeros((7, 3)))
    assert ref.velocity[-1, 1, 0] == pytest.approx(0.1 * restitution(K, C, 1.0), rel=1e-10)  # measured 8e-13
    # Hertz: its dashpot is clamped at zero force before the overlap closes (an event), and the
    # restitution it comes out with is the one its damping was calibrated for (scipy, rtol 1e-11)
    p = dk.Particles(position=[[-1.001, 0, 0], [1.001, 0, 0]], velocity=[[0.1, 0, 0], [-0.1, 0, 0]], radius=1.0)
    ref = dk.accuracy.reference(dk.Scene(p, [dk.Hertz(young=1e4, poisson=0.3, restitution=0.7)]), 1.0)
    assert [e["kind"] for e in ref.events] == ["contact", "dashpot clamp", "contact"]
    speed = ref.velocity[-1, 1, 0] - ref.velocity[-1, 0, 0]
    assert speed == pytest.approx(0.7 * 0.2, rel=1e-8)  # measured 8e-11


def test_reference_catches_grazes_within_one_step_and_simultaneous_contacts():
    law = dk.KelvinVoigt(K, C)
    # free flight past a sphere with an overlap of 1e-8 radii for 4e-4 time units, inside one
    # adaptive step of several time units: found by the Hermite check of the gap
    p = dk.Particles(position=[[0, 0, 0], [-5, 2.0 - 1e-8, 0]], velocity=[[0, 0, 0], [1.0, 0, 0]], radius=1.0)
    ref = dk.accuracy.reference(dk.Scene(p, [law]), 10.0)
    onset, release = (e["time"] for e in ref.events)
    assert onset == pytest.approx(5.0 - math.sqrt(4.0 - (2.0 - 1e-8) ** 2), abs=1e-9)
    assert 5.0 < release < 5.0003
    p = dk.Particles(position=[[0, 0, 0], [-5, 2.0, 0]], velocity=[[0, 0, 0], [1.0, 0, 0]], radius=1.0)
    assert dk.accuracy.reference(dk.Scene(p, [law]), 10.0).events == []  # touching exactly is no contact
    # a sphere at rest hit from both sides at once: both contacts are events of the same restart
    p = dk.Particles(position=[[-2.1, 0, 0], [0, 0, 0], [2.1, 0, 0]], velocity=[[0.1, 0, 0], [0, 0, 0], [-0.1, 0, 0]],
                     radius=1.0)
    ref = dk.accuracy.reference(dk.Scene(p, [law]), 10.0)
    assert ref.restarts == 2 and [e["particles"] for e in ref.events] == [(0, 1), (1, 2)] * 2
    assert np.allclose(ref.velocity[-1, :, 0], [-0.1 * restitution(K, C, 1.0), 0, 0.1 * restitution(K, C, 1.0)],
                       rtol=1e-10, atol=1e-14)


# ---- timing work-precision runs, and what the report says about its numbers -------------------------
def glancing_scene():
    """Two spheres meeting off-centre on a damped Kelvin-Voigt contact and parting again."""
    p = dk.Particles([[0.0, 0, 0], [2.2, 0.3, 0]], velocity=[[0.4, 0, 0], [-0.4, 0, 0]], radius=1.0)
    return dk.Scene(p, [dk.KelvinVoigt(50.0, 0.5)])


def test_repeated_runs_start_from_the_same_state_and_do_the_same_work():
    accuracy = importlib.import_module("demkit.accuracy.study")
    scene = glancing_scene()
    first = accuracy._run(scene, dk.VelocityVerlet, 0.01, 1.0, [0.5, 1.0], 0.01)[0]
    spare = accuracy._Spare(scene)
    assert spare.reuse  # no history: one copy, put back each time
    for _ in range(2):
        again = accuracy._run(scene, dk.VelocityVerlet, 0.01, 1.0, [0.5, 1.0], 0.01, fresh=spare.ready())[0]
        assert np.array_equal(again.position, first.position) and np.array_equal(again.velocity, first.velocity)
        assert np.array_equal(again.energy["dissipated"], first.energy["dissipated"])
        assert first.energy["dissipated"][-1] > 0  # the contact dissipated: the count starts again at 0


def test_short_runs_are_timed_again_and_the_least_time_kept(monkeypatch):
    """repeats=None: a run shorter than 0.2 s is timed again until its runs add up to 0.2 s (at least 5
    runs), keeping the least wall and CPU times and how much they varied; a long run is timed once;
    repeats=n: n runs. The results are the first run's."""
    accuracy = importlib.import_module("demkit.accuracy.study")
    real, walls = accuracy._run, []

    def scripted(*args, **options):  # a real run, with wall times from the script (CPU: half of it)
        trajectory, _, _, steps, integrator, message = real(*args, **options)
        wall = walls.pop(0)
        return trajectory, wall, wall / 2, steps, integrator, message
    monkeypatch.setattr(accuracy, "_run", scripted)
    scene = smooth_scene()
    walls[:] = [0.05, 0.01, 0.06, 0.02, 0.07, 0.04, 0.03]
    traj, steps, _, message, timing = accuracy._timed(scene, dk.VelocityVerlet, 0.04, 1.0, [1.0], 0.04, None)
    # 0.05 + 0.01 + 0.06 + 0.02 + 0.07 = 0.21 >= 0.2 after 5 runs; median 0.05
    assert timing == {"seconds": 0.01, "cpu_seconds": 0.005, "repeats": 5, "timing_spread": pytest.approx(4.0)}
    assert walls == [0.04, 0.03] and message == "" and steps == 25
    direct = dk.Simulation(smooth_scene(), dk.VelocityVerlet(0.04)).run(1.0, record_every=0.04)
    assert np.array_equal(traj.position, direct.position)
    walls[:] = [0.3, 0.01]
    assert accuracy._timed(scene, dk.VelocityVerlet, 0.04, 1.0, [1.0], 0.04, None)[4]["repeats"] == 1
    walls[:] = [0.3, 0.2, 0.25]
    timing = accuracy._timed(scene, dk.VelocityVerlet, 0.04, 1.0, [1.0], 0.04, 3)[4]
    assert timing["repeats"] == 3 and timing["seconds"] == 0.2 and timing["timing_spread"] == pytest.approx(0.25)
    with pytest.raises(ValueError, match="repeats must be None"):
        dk.accuracy.work_precision(scene, 1.0, dts=[0.04], repeats=0)


def synthetic(rows, length_scale=None):
    """A report from given rows (the keys the notes read) against a given reference."""
    full = [dict({"stable": True, "message": "", "is_reference": False, "repeats": 5, "timing_spread": 0.05,
                  "velocity_error": 1.0, "angular_momentum_drift": math.nan, "observable": math.nan,
                  "observable_error": math.nan}, **r) for r in rows]
    return dk.accuracy.WorkPrecision(full, {"kind": "given", "description": "given"}, 1.0, "given", [1.0], 1.0,
                                     length_scale=length_scale)


def timing_row(dt, evaluations, seconds, cpu, spread=0.05):
    return {"method": "EulerCromer", "dt": dt, "evaluations": evaluations, "seconds": seconds, "cpu_seconds": cpu,
            "timing_spread": spread, "position_error": dt, "energy_error": dt}


def test_the_report_says_when_its_timings_cannot_be_trusted():
    good = synthetic([timing_row(0.02, 50, 0.1, 0.1), timing_row(0.01, 100, 0.2, 0.19)])
    assert good.timing_notes() == []
    assert "timings: the least wall time of 5 runs each; repeats within 25%" in good.table()
    busy = synthetic([timing_row(0.02, 50, 0.1, 0.1, spread=0.8), timing_row(0.01, 100, 0.3, 0.1),
                      timing_row(0.005, 200, 0.15, 0.15)])
    notes = busy.timing_notes()
    assert len(notes) == 3
    assert notes[0].startswith("the repeats of 1 of 3 runs differ by more than 25% (up to 80%: EulerCromer dt = 0.02")
    assert notes[1].startswith("1 of 3 runs took more than 1.5x their CPU time in wall time (up to 3.0x: "
                               "EulerCromer dt = 0.01)")
    assert notes[2].startswith("EulerCromer: the wall time does not follow the work") and \
        "dt = 0.005 took 0.15 s for 200 force evaluations, dt = 0.01 0.3 s for 100" in notes[2]
    text = busy.table()
    assert "timings (the least wall time of 5 runs each) cannot be trusted:\n  - the repeats of 1 of 3" in text
    assert busy.as_dict()["timing_notes"] == notes


def test_the_report_says_why_position_errors_stall_while_energy_errors_converge():
    report = dk.accuracy.work_precision(glancing_scene(), 1.0, methods=[dk.VelocityVerlet],
                                        dts=[0.02, 0.01, 0.005, 0.0025], repeats=1, progress=False)
    energy = [r["energy_error"] for r in report.rows]
    assert all(b < a / 1.8 for a, b in zip(energy, energy[1:]))  # first order, steadily
    notes = report.convergence_notes()
    assert len(notes) == 1 and notes[0].startswith("VelocityVerlet: position errors do not converge with dt")
    assert "while energy errors do" in notes[0] and "when each contact begins and ends" in notes[0]
    assert "convergence:\n  - VelocityVerlet: position errors" in report.table()
    # errors of a good part of a radius: runs that parted from the reference, saturated at the scene's size
    parted = synthetic([dict(timing_row(dt, 0, 0.1, 0.1), position_error=e, energy_error=dt)
                        for dt, e in ((0.04, 0.5), (0.02, 0.6), (0.01, 0.55))], length_scale=1.0)
    assert "saturate at the size of the scene" in parted.convergence_notes()[0]
