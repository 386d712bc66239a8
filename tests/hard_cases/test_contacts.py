"""Hard cases for contacts: a collapsing dense cluster, grazing impacts, a wedged sphere, a crushed
magnetic chain, friction at the stick-slip boundary."""
import math

import numpy as np
import pytest

import demkit as dk

from .conftest import balance

pytestmark = pytest.mark.hard_case

R = 0.5


def test_a_thousand_dipoles_collapsing_from_rest():
    """10 x 10 x 10 unit magnets 1.3 diameters apart, random moments, at rest, in open space; switched
    dipole cutoff (a genuine potential), damped contacts."""
    position, _ = dk.build.lattice("sc", 10, spacing=1.3, periodic=False)
    rng = np.random.default_rng(3)
    position += rng.normal(scale=0.02, size=position.shape)
    p = dk.Particles(position=position, radius=R, mass=1.0, dipole=dk.build.random_directions(1000, seed=rng))
    k = 1000.0
    law = dk.KelvinVoigt(k, 2 * 0.3 * math.sqrt(k * 0.5))
    scene = dk.Scene(p, [dk.Dipole(1.0, cutoff=3.0, switch_width=0.5), law])
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(4.0, record_every=0.1)
    assert np.isfinite(traj.position).all()
    e = traj.energy
    assert e["magnetic"][-1] < -1500  # collapsed: from +18 to -1800 (measured), 1054 contacts
    assert len(scene.contacts()) > 800
    assert scene.contacts().overlap.max() < 0.1 * R  # 0.047 R (measured)
    # the dashpots' work is counted with the velocities before each kick: first order, about
    # c dt / m of the work dissipated (docs/accuracy.md); measured 0.047 for c dt / m = 0.049
    assert balance(traj) < 1.5 * law.damping * dt * e["dissipated"][-1]


@pytest.mark.parametrize("eps", [1e-2, 1e-4, 1e-6, 1e-9, 0.0, -1e-6])
def test_grazing_impacts_never_gain_energy(eps):
    """Two spinning spheres with friction, impact parameter b = 2R (1 - eps): from a real contact to
    a touch of 1e-9 R, exactly 2R and a near miss."""
    b = 2 * R * (1 - eps)
    p = dk.Particles(position=[[-1, -b / 2, 0], [1, b / 2, 0]], velocity=[[1, 0, 0], [-1, 0, 0]], radius=R,
                     mass=1.0, angular_velocity=[[0, 0, 3.0], [0, 0, -1.0]])
    scene = dk.Scene(p, [dk.KelvinVoigt(1e4, 5.0, friction=dk.Friction(0.5))])
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(2.0, record_every=dt)
    assert np.isfinite(traj.position).all()
    e = traj.energy
    assert e["total"][-1] <= e["total"][0] * (1 + 1e-12)
    assert np.diff(e["dissipated"]).min() >= 0.0
    # first order in dt: 3.0e-3 of the energy at eps = 1e-2, 1.5e-4 at 1e-4, 0 without contact
    assert balance(traj) < 5e-3 * e["total"][0]
    assert np.abs(traj.angular_momentum - traj.angular_momentum[0]).max() < 1e-12  # 1e-13 (measured)


def wedge(friction, speed):
    """A sphere dropped into the gap between a wall (x = 0) and a fixed sphere 2.9 R away: the gap,
    1.9 R, is narrower than the sphere."""
    k = 1e5
    law = dk.KelvinVoigt(k, 2 * 0.5 * math.sqrt(k * 0.5), friction=dk.Friction(0.5) if friction else None)
    p = dk.Particles(position=[[2.9 * R, 0, 0], [R + 0.001, 0, 0.36]], velocity=[[0, 0, 0], [0, 0, -speed]],
                     radius=R, mass=1.0, fixed=[True, False])
    return dk.Scene(p, [law, dk.Wall((0, 0, 0), (1, 0, 0)), dk.Gravity((0, 0, -9.81))])


def test_a_sphere_wedged_between_a_wall_and_another_comes_to_rest_in_the_wedge():
    scene = wedge(friction=False, speed=0.0)
    law = scene.interactions[0]
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(2.0, record_every=0.01)
    assert np.isfinite(traj.position).all()
    assert np.linalg.norm(traj.velocity[-1, 1]) < 1e-3  # 3e-5 (measured)
    # frictionless: the statics of the wedge, N_sphere n_z = m g and N_wall = N_sphere n_x
    c = scene.contacts()
    n = (traj.position[-1, 1] - traj.position[-1, 0]) / np.linalg.norm(traj.position[-1, 1] - traj.position[-1, 0])
    on_wall = c.wall >= 0
    assert c.normal_force[~on_wall][0] == pytest.approx(9.81 / n[2], rel=2e-3)  # 3.22 weights
    assert c.normal_force[on_wall][0] == pytest.approx(-9.81 * n[0] / n[2], rel=2e-3)
    assert balance(traj) < 2 * law.damping * dt * traj.energy["dissipated"][-1]  # 7.5e-3 of it (measured)
    # thrown in at 3 m/s with friction: jammed, holding 19 weights by friction below its limit, no creep
    scene = wedge(friction=True, speed=3.0)
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(2.0, record_every=0.01)
    assert np.isfinite(traj.position).all()
    c = scene.contacts()
    assert c.normal_force.min() > 10 * 9.81
    assert np.all(np.linalg.norm(c.tangential_force, axis=1) < 0.5 * c.normal_force) and not c.sliding.any()
    assert np.abs(traj.position[-1, 1] - traj.position[-51, 1]).max() < 1e-9  # still over the last 0.5 s
    assert c.overlap.max() < 0.01 * R  # 0.0038 R (measured)
    # (a sticking spring books its loading's work exactly, zero dissipation up to round-off)
    assert np.diff(traj.energy["dissipated"]).min() >= -1e-12 * max(traj.energy["dissipated"][-1], 1e-9)


@pytest.mark.parametrize("offset", [0.0, 0.02])
def test_a_magnetic_chain_crushed_against_a_wall(offset):
    """Eight magnets standing head to tail on a floor; a sphere five times heavier dropped on top
    from two diameters up. On the axis the chain stays straight; 0.02 off it, it buckles and the
    heavy sphere falls off. Either way no sphere passes another or the floor."""
    k, n, heavy = 1000.0, 8, 5.0
    law = dk.KelvinVoigt(k, 2 * 0.7 * math.sqrt(k * 0.5))
    position, moments = dk.build.chain(n, R, start=(0, 0, R), direction=(0, 0, 1))
    p = dk.Particles(position=np.vstack([position, [[offset, 0, position[-1, 2] + 2.0]]]), radius=R,
                     mass=np.r_[np.ones(n), heavy], dipole=np.vstack([moments, [[0, 0, 0]]]))
    scene = dk.Scene(p, [dk.Dipole(1.0), law, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -1.0))])
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(8.0, record_every=0.01)
    x = traj.position
    assert np.isfinite(x).all()
    i, j = np.triu_indices(n + 1, 1)
    distance = np.linalg.norm(x[:, j] - x[:, i], axis=2)
    assert distance.min() > 1.6 * R  # deepest overlap 0.11 R on the axis, 0.16 R buckling (measured)
    assert x[:, :, 2].min() > 0.7 * R  # into the floor: 0.10 R, 0.17 R
    if offset == 0.0:
        assert np.all(np.diff(x[:, :, 2], axis=1) > 0)  # the order along the chain is kept
        assert np.abs(x[:, :, :2]).max() == 0.0
    # (a sticking spring books its loading's work exactly, zero dissipation up to round-off)
    assert np.diff(traj.energy["dissipated"]).min() >= -1e-12 * max(traj.energy["dissipated"][-1], 1e-9)
    assert balance(traj) < 1.5 * law.damping * dt * traj.energy["dissipated"][-1]  # 0.17 and 0.45 of it


def incline(ratio, tangential_damping):
    """A sphere resting on a floor tilted by theta, tan(theta) = ratio * 7/2 mu: rolling without
    slipping needs the friction force 2/7 m g sin(theta) = ratio * mu N, so ratio 1 is the boundary."""
    mu, g, k = 0.2, 9.81, 1e5
    theta = math.atan(ratio * 3.5 * mu)
    law = dk.KelvinVoigt(k, 2 * 0.3 * math.sqrt(k), friction=dk.Friction(mu, damping=tangential_damping))
    p = dk.Particles(position=[[0, 0, R - g * math.cos(theta) / k]], radius=R, mass=1.0)
    gravity = dk.Gravity(g * np.array([math.sin(theta), 0, -math.cos(theta)]))
    return dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1)), gravity]), theta, g, mu


@pytest.mark.parametrize("ratio", [0.98, 0.995, 1.0, 1.005, 1.02])
def test_friction_at_the_stick_slip_boundary(ratio):
    scene, theta, g, mu = incline(ratio, tangential_damping=0.0)
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(1.0, record_every=10 * dt)
    assert np.isfinite(traj.position).all()
    late = traj.time > 0.2
    acceleration = 2 * np.polyfit(traj.time[late], traj.position[late, 0, 0], 2)[0]
    rolling, sliding = 5 / 7 * g * math.sin(theta), g * (math.sin(theta) - mu * math.cos(theta))
    # rolls without slipping below the boundary, slides above (errors 1e-4, 1.3e-3 at 0.995: it
    # slips a little while its spring first loads, 0, 0, 0 measured)
    assert acceleration == pytest.approx(rolling if ratio <= 1 else sliding, rel=2e-3)
    # no chattering: the normal contact stays still, the dissipated work never decreases
    z = traj.position[:, 0, 2]
    assert z.max() - z.min() < 1e-9
    # (a sticking spring books its loading's work exactly, zero dissipation up to round-off)
    assert np.diff(traj.energy["dissipated"]).min() >= -1e-12 * max(traj.energy["dissipated"][-1], 1e-9)
    assert balance(traj) < 1e-5  # 5.7e-6 (measured) against up to 0.12 dissipated


def test_a_tangential_dashpot_can_book_negative_dissipation_while_sliding():
    """With the default tangential dashpot, a sliding update can store more in the spring than the
    slip's work (the spring holds the dashpot's share of the Coulomb force): the dissipated work dips
    by up to 0.3 % of itself at a step (measured), total + dissipated still closes."""
    scene, theta, g, mu = incline(0.98, tangential_damping=None)
    dt = 0.5 * scene.max_time_step()
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(1.0, record_every=10 * dt)
    dissipated = traj.energy["dissipated"]
    assert np.diff(dissipated).min() > -5e-3 * dissipated[-1]
    assert balance(traj) < 1e-5
