"""The Langevin thermostat against the statistics of free Brownian spheres and rotors.

Every test uses the same kind of scene (dipoles, a uniform field, the thermostat; field zero where
it is not wanted), so the file compiles one kernel module. Tolerances are 5 standard errors of the
estimate (stated at each check), computed from the number of independent samples: a correct
thermostat fails one of them about once in 10^6 runs, a 3 % error in temperature or drag fails.
"""
import math

import numpy as np
import pytest

import demkit as dk

R, MASS = 0.5, 1.0
INERTIA = 0.4 * MASS * R * R  # solid sphere: 0.1


def free_spheres(n, kT, drag, rotational_drag, field=0.0, seed=7, spacing=3.0):
    """n spheres with unit dipoles along x on a loose cubic lattice (they never touch: no pair
    interactions), a field along z and the thermostat."""
    side = math.ceil(n ** (1 / 3))
    grid = np.stack(np.meshgrid(*[np.arange(side) * spacing] * 3, indexing="ij"), -1).reshape(-1, 3)[:n]
    dipole = np.tile([1.0, 0.0, 0.0], (n, 1))
    p = dk.Particles(position=grid, velocity=np.zeros((n, 3)), radius=R, mass=MASS, dipole=dipole)
    bath = dk.Langevin(temperature=kT, drag=drag, rotational_drag=rotational_drag, seed=seed)
    return dk.Scene(p, [dk.UniformField([0.0, 0.0, field]), bath])


def test_equipartition_at_a_long_step_translation_and_rotation():
    # gamma dt / m = 0.5 and gamma_r dt / I = 0.5: velocity Verlet's on-step velocities keep the
    # bath temperature exactly for free spheres (docs/thermostat.md), whatever the step
    # (dt = 0.1 also keeps the fastest thermal spins under the 2 rad a step the spin guard allows)
    n, kT, drag, rot = 512, 0.7, 5.0, 0.5
    scene = free_spheres(n, kT, drag, rot)
    dt = 0.5 * MASS / drag
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt))
    sim.run(duration=20 * MASS / drag, progress=False)  # from rest to equilibrium (relaxation m/gamma = 0.2)
    v2, w2 = [], []
    frames = 200
    for _ in range(frames):  # frames 4 relaxation times apart: correlation e^-8 between them
        sim.run(duration=4 * max(MASS / drag, INERTIA / rot), progress=False)
        v2.append(np.mean(scene.particles.velocity ** 2))
        w2.append(np.mean(scene.particles.angular_velocity ** 2))
    t_trans, t_rot = MASS * np.mean(v2), INERTIA * np.mean(w2)
    # each frame: 3n squared normals, relative standard deviation sqrt(2 / (3n)); frames independent
    sigma = kT * math.sqrt(2.0 / (3 * n * frames))
    assert abs(t_trans - kT) < 5 * sigma, (t_trans, kT, sigma)
    assert abs(t_rot - kT) < 5 * sigma, (t_rot, kT, sigma)


def test_free_diffusion_has_d_equal_kt_over_gamma():
    n, kT, drag = 4000, 1.3, 4.0
    scene = free_spheres(n, kT, drag, 0.5)
    tau = MASS / drag
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.2 * tau))
    sim.run(duration=20 * tau, progress=False)  # equilibrated velocities
    start = scene.particles.position.copy()
    t = 100 * tau
    sim.run(duration=t, progress=False)
    msd = np.mean(np.sum((scene.particles.position - start) ** 2, axis=1))
    d = kT / drag
    expected = 6 * d * (t - tau * (1 - math.exp(-t / tau)))  # Ornstein-Uhlenbeck, from equilibrium
    # |dr|^2 / <|dr|^2> is chi-squared with 3 degrees of freedom over 3: variance 2/3 per sphere
    sigma = expected * math.sqrt(2.0 / (3 * n))
    assert abs(msd - expected) < 5 * sigma, (msd, expected, sigma)


def test_a_free_rotor_forgets_its_orientation_as_exp_minus_2_dr_t():
    # overdamped rotors: I / gamma_r = 0.01, well below the decay time 1 / (2 D_r) = 5
    n, kT, rot = 4000, 1.0, 10.0
    scene = free_spheres(n, kT, 1.0, rot)
    dr = kT / rot
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.5 * INERTIA / rot))
    sim.run(duration=0.2, progress=False)  # equilibrated spins (20 relaxation times), orientation barely moved
    u0 = scene.particles.dipole / np.linalg.norm(scene.particles.dipole, axis=1)[:, None]
    elapsed = 0.0
    for t in (2.5, 5.0):
        sim.run(duration=t - elapsed, progress=False)
        elapsed = t
        u = scene.particles.dipole / np.linalg.norm(scene.particles.dipole, axis=1)[:, None]
        c = np.mean(np.sum(u * u0, axis=1))
        expected = math.exp(-2 * dr * t)
        # u.u0 lies in [-1, 1] with variance below 1/3 + C^2: standard error sqrt(that / n)
        sigma = math.sqrt((1 / 3 + expected**2) / n)
        assert abs(c - expected) < 5 * sigma, (t, c, expected, sigma)
    assert np.allclose(np.linalg.norm(scene.particles.dipole, axis=1), 1.0, atol=1e-9)  # rotated, not stretched


@pytest.mark.parametrize("xi", [0.5, 2.0])
def test_dipoles_in_a_field_follow_the_langevin_law(xi):
    # <cos theta> = coth(xi) - 1/xi for non-interacting moments mu in a field B, xi = mu B / kT
    n, kT, rot = 2000, 1.0, 1.0
    scene = free_spheres(n, kT, 1.0, rot, field=xi * kT)
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.02))
    sim.run(duration=10.0, progress=False)  # orientations relax in 1 / (2 D_r) = 0.5
    samples, frames = [], 20
    for _ in range(frames):  # frames 2 relaxation times apart
        sim.run(duration=1.0, progress=False)
        samples.append(np.mean(scene.particles.dipole[:, 2] / np.linalg.norm(scene.particles.dipole, axis=1)))
    langevin = 1 / math.tanh(xi) - 1 / xi
    variance = 1 - 2 * langevin / xi - langevin**2  # of cos theta in the Langevin distribution
    sigma = math.sqrt(variance / (n * frames))
    assert abs(np.mean(samples) - langevin) < 5 * sigma, (np.mean(samples), langevin, sigma)


def test_the_same_seed_gives_the_same_run_and_a_restart_is_bit_identical(tmp_path):
    def run(seed, pieces, path=None):
        scene = free_spheres(64, 1.0, 2.0, 0.3, field=0.5, seed=seed, spacing=10.0)  # apart: no overlaps
        done = 0.0
        for k, until in enumerate(pieces):
            sim = dk.Simulation(scene, dk.VelocityVerlet(0.05),
                                checkpoint=dk.Checkpoint(path) if path else None)
            if k:
                sim.resume()
            sim.run(until=until, progress=False)
            done = until
        assert done == pieces[-1]
        p = scene.particles
        return np.concatenate([p.position, p.velocity, p.angular_velocity, p.dipole])

    whole = run(5, [3.0])
    assert np.array_equal(run(5, [3.0]), whole)  # run to run
    assert not np.array_equal(run(6, [3.0]), whole)  # another seed, other kicks
    assert np.array_equal(run(5, [1.05, 2.0, 3.0], tmp_path / "bath.ckpt"), whole)  # the stream is in the checkpoint


def test_drag_alone_at_zero_temperature_is_exponential_decay():
    scene = free_spheres(8, 0.0, 2.0, 0.4)
    scene.particles.velocity[:] = [1.0, -2.0, 0.5]
    scene.particles.angular_velocity[:] = [0.0, 0.0, 3.0]
    dt, steps = 0.01, 100
    sim = dk.Simulation(scene, dk.VelocityVerlet(dt))
    sim.run(duration=steps * dt, progress=False)
    # velocity Verlet on dv/dt = -(gamma/m) v: the half-step velocity shrinks by (1 - a) per step
    # and the on-step one lags it by a half kick: v_n = (1 - a/2) (1 - a)^(n-1) ... (exact algebra below)
    a = 2.0 * dt / MASS
    u = (1 - a / 2) * 1.0  # half-kicked velocity after the first half kick from the start
    for _ in range(steps - 1):
        u *= 1 - a
    v = u * (1 - a / 2)
    assert scene.particles.velocity[0, 0] == pytest.approx(v, rel=1e-12)
    # ... which is the continuous decay e^(-gamma t / m) to first order in a = 0.02 (2 % here)
    assert v == pytest.approx(math.exp(-2.0 * steps * dt), rel=2 * a)


def test_bad_thermostats_and_integrators_are_refused():
    with pytest.raises(ValueError, match="temperature"):
        dk.Langevin(temperature=-1.0, drag=1.0)
    with pytest.raises(ValueError, match="temperature"):
        dk.Langevin(temperature=float("nan"), drag=1.0)
    with pytest.raises(ValueError, match="drag"):
        dk.Langevin(temperature=1.0, drag=0.0)
    with pytest.raises(ValueError, match="rotational_drag"):
        dk.Langevin(temperature=1.0, drag=1.0, rotational_drag=-2.0)
    with pytest.raises(ValueError, match="seed"):
        dk.Langevin(temperature=1.0, drag=1.0, seed=1.5)
    scene = free_spheres(8, 1.0, 2.0, 0.4)
    for integrator in (dk.EulerCromer(0.01), dk.RK4(0.01), dk.VelocityVerlet(0.01, resolve_contacts=True)):
        with pytest.raises(ValueError, match="VelocityVerlet"):
            dk.Simulation(scene, integrator).run(duration=0.01, progress=False)
    with pytest.raises(ValueError, match="max_energy_growth"):
        dk.Simulation(scene, dk.VelocityVerlet(0.01), max_energy_growth=0.1)
    # a step with gamma dt / m > 1 is refused like any unstable step
    with pytest.raises(ValueError, match="time step"):
        dk.Simulation(scene, dk.VelocityVerlet(0.6)).run(duration=0.6, progress=False)


def test_a_scene_file_thermostat_is_the_python_one():
    text = """
[particles]
position = [[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]]
dipole = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
radius = 0.5
[interactions.uniform_field]
field = [0.0, 0.0, 0.0]
[interactions.langevin]
temperature = 0.5
drag = 2.0
rotational_drag = 0.2
seed = 9
[integrator]
method = "VelocityVerlet"
dt = 0.01
[run]
duration = 0.5
"""
    loaded = dk.parse_scene(text)
    bath = [e for e in loaded.scene.effects if isinstance(e, dk.Langevin)]
    assert len(bath) == 1 and repr(bath[0]) == repr(dk.Langevin(0.5, 2.0, rotational_drag=0.2, seed=9))
    with pytest.raises(dk.SceneFileError, match="tempreature"):
        dk.parse_scene(text.replace("temperature = 0.5", "tempreature = 0.5"))
    with pytest.raises(dk.SceneFileError, match="drag"):
        dk.parse_scene(text.replace("drag = 2.0", "drag = 0.0"))
