"""Hard cases for the time step: stiff contacts, fast impacts, fast spins, a very long run."""
import math

import numpy as np
import pytest

import demkit as dk

from .conftest import advice, balance, refused

pytestmark = pytest.mark.hard_case

PAPER = dk.two_magnets.TwoMagnets(4.0, x0=30.0)  # the seed paper's collision, started closer


def test_contacts_ten_thousand_times_stiffer_get_time_step_advice_and_run_with_it():
    stiff = PAPER.with_(stiffness=1e4)  # contact 100x shorter than the paper's (2.2e-2)
    message = refused(lambda: stiff.simulation(0.01))
    assert message.startswith("time step dt = 0.01 is too large for the stiffest contact (KelvinVoigt")
    dt = advice(message, "dt")
    assert dt == pytest.approx(0.1 * math.pi * math.sqrt(0.5 / 1e4), rel=1e-3)  # a tenth of the contact
    traj = stiff.simulation(dt, dk.VelocityVerlet).run(6000.0, record_every=0.05)  # 2.7 million steps
    assert np.isfinite(traj.position).all()
    e = traj.energy
    released = e["magnetic"][0] - e["magnetic"].min()  # 2.45e-4: the snap
    assert e["dissipated"][-1] > 0  # they met (a nearly elastic contact: zeta = 7e-4)
    # total + dissipated keeps its value to 6.0e-4 of the energy the magnets release (measured)
    assert balance(traj) < 2e-3 * released


def test_impacts_at_a_hundred_times_the_papers_speed_keep_their_energy_balance():
    fast = PAPER.with_(b_over_R=1.0, speed=100 * PAPER.speed)  # 0.578 each way
    traj = fast.simulation(0.01, dk.VelocityVerlet).run(600.0, record_every=0.5)
    assert np.isfinite(traj.position).all()
    e = traj.energy
    gap = np.linalg.norm(traj.position[:, 1] - traj.position[:, 0], axis=1) - 2 * fast.radius
    assert -0.15 * fast.radius < gap.min() < 0  # they hit: overlap 0.088 R (measured)
    assert e["dissipated"][-1] > 0.2 * e["kinetic"][0]  # 27 % dissipated by the dashpot
    # the dashpot's work is first order in dt: 1.2e-3 of the initial energy at dt = 0.01, 5.7e-3 at 0.05
    assert balance(traj) < 3e-3 * e["total"][0]


def test_magnets_spinning_a_radian_per_step_keep_their_moments_and_energy():
    rng = np.random.default_rng(5)
    position, _ = dk.build.ring(8, 0.5, gap=0.3)
    moments = dk.build.random_directions(8, seed=rng)
    axes = dk.build.random_directions(8, seed=rng)

    def scene(turn):
        p = dk.Particles(position=position, radius=0.5, mass=1.0, dipole=moments)
        s = dk.Scene(p, [dk.Dipole(1.0), dk.KelvinVoigt(1000.0, 0.0)])
        dt = 0.5 * s.max_time_step()
        p.angular_velocity[:] = axes * turn / dt
        return s, dt

    s, dt = scene(1.2)
    message = refused(lambda: dk.Simulation(s, dk.VelocityVerlet(dt)))
    assert message.startswith(f"time step dt = {dt:.6g} is too large for the spin of particle")
    assert advice(message, "dt") == pytest.approx(dt / 1.2, rel=1e-3)
    s, dt = scene(0.9)
    traj = dk.Simulation(s, dk.VelocityVerlet(dt)).run(20000 * dt, record_every=10 * dt)
    assert np.isfinite(traj.position).all()
    # exact rotations: the moments keep their norms (measured 2e-14)
    np.testing.assert_allclose(np.linalg.norm(traj.dipole, axis=2), 1.0, rtol=0, atol=1e-12)
    # the coupling energy is sampled 0.9 rad apart: a bounded error of about (|w| dt)^2/6 of it per
    # pair (docs/stability.md), 0.47 here against the 2 A/d^3 = 2 of a touching pair; no drift
    err = np.abs(traj.energy["total"] - traj.energy["total"][0])
    half = len(err) // 2
    assert err.max() < 0.5 * 2.0
    assert err[half:].max() < 1.5 * err[:half].max()


def test_ten_million_steps_of_a_spinning_bound_pair_keep_the_energy_bounded():
    """The paper's final state: two magnets touching head to tail, revolving as a barbell at
    omega_f = 1.19e-3 with one moment tilted by 0.05 rad (it librates), no damping: 1e7 velocity-Verlet
    steps of dt = 0.01, 19 revolutions."""
    radius, k = PAPER.radius, 1.0
    distance = 2 * radius - 6 / 3 / (2 * radius) ** 4 / k  # held by the static overlap
    w, tilt = 1.19e-3, 0.05
    p = dk.Particles(position=[[-distance / 2, 0, 0], [distance / 2, 0, 0]],
                     velocity=[[0, -w * distance / 2, 0], [0, w * distance / 2, 0]], radius=radius, mass=1.0,
                     dipole=[[1, 0, 0], [math.cos(tilt), math.sin(tilt), 0]], angular_velocity=[[0, 0, w]] * 2)
    scene = dk.Scene(p, [dk.Dipole(1 / 3), dk.KelvinVoigt(k, 0.0)])
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.01))
    traj = sim.run(1e5, record_every=10.0)
    assert sim.step == 10_000_000
    e = traj.energy["total"]
    err = np.abs(e - e[0])
    half = len(e) // 2
    # bounded, no drift: 2.7e-15 of |E| = 1.5e-4 in either half (measured), not growing
    assert err.max() < 1e-9 * abs(e[0])
    assert err[half:].max() < 2 * err[:half].max() + 1e-18
    angle = np.unwrap(np.arctan2(*(traj.position[:, 1] - traj.position[:, 0])[:, 1::-1].T))
    assert (angle[-1] - angle[0]) / (2 * math.pi) == pytest.approx(w * 1e5 / (2 * math.pi), rel=1e-3)
    np.testing.assert_allclose(traj.angular_momentum[:, 2], traj.angular_momentum[0, 2], rtol=1e-10)
