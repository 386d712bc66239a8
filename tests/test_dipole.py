"""Dipole and power-law forces/torques against finite differences of their energy; plain and
switched truncation at a cutoff."""
from functools import partial

import numpy as np
import pytest

import demkit as dk
from conftest import energy_gradient
from demkit.interactions.dipole import switch, switched_dipole_force, switched_dipole_energy

#: random_scene's pair distances run from 2.5 to ~20: with r_c = 6, w = 2 some pairs are below the
#: switch, some in it and some beyond the cutoff
SWITCHED = partial(dk.Dipole, cutoff=6.0, switch_width=2.0)
SWITCHED_POWER_LAW = partial(dk.PowerLawDipole, cutoff=6.0, switch_width=2.0)


def random_scene(rng, n=4, model=dk.Dipole):
    # spheres far enough apart that the configuration is smooth; random 3D moments
    pos = rng.uniform(-6, 6, size=(n, 3))
    while True:
        d = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.eye(n) * 10
        if d.min() > 2.5:
            break
        pos = rng.uniform(-6, 6, size=(n, 3))
    dip = rng.normal(size=(n, 3))
    p = dk.Particles(position=pos, radius=0.5, mass=rng.uniform(1, 2, n), dipole=dip)
    return dk.Scene(p, [model(prefactor=0.7)])


def rotate(v, axis, angle):
    axis = axis / np.linalg.norm(axis)
    return (v * np.cos(angle) + np.cross(axis, v) * np.sin(angle)
            + axis * (axis @ v) * (1 - np.cos(angle)))


@pytest.mark.parametrize("model", [dk.Dipole, dk.PowerLawDipole, SWITCHED, SWITCHED_POWER_LAW])
def test_force_is_minus_energy_gradient(rng, model):
    for _ in range(3):
        scene = random_scene(rng, model=model)
        p = scene.particles
        force, _ = scene.forces()
        for i in range(len(p)):
            fd = -energy_gradient(scene, "magnetic", i, h=1e-5)
            # central differences: error ~ h^2 U'" ~ 1e-10 relative to the force scale
            np.testing.assert_allclose(force[i], fd, rtol=1e-6, atol=1e-9 * np.abs(force).max())


@pytest.mark.parametrize("model", [dk.Dipole, SWITCHED])
def test_torque_is_minus_energy_derivative_under_rotation(rng, model):
    for _ in range(3):
        scene = random_scene(rng, model=model)
        p = scene.particles
        _, torque = scene.forces()
        h = 1e-6
        for i in range(len(p)):
            for a in range(3):
                axis = np.eye(3)[a]
                m0 = p.dipole[i].copy()
                p.dipole[i] = rotate(m0, axis, h)
                up = scene.energy()["magnetic"]
                p.dipole[i] = rotate(m0, axis, -h)
                down = scene.energy()["magnetic"]
                p.dipole[i] = m0
                # tau . axis = -dU/d(angle about axis)
                assert torque[i, a] == pytest.approx(-(up - down) / (2 * h), rel=1e-6,
                                                     abs=1e-9 * np.abs(torque).max())


def test_torque_equals_m_cross_b_of_independent_field(rng):
    scene = random_scene(rng, n=3)
    p = scene.particles
    _, torque = scene.forces()
    for i in range(3):
        field = np.zeros(3)
        for j in range(3):
            if j != i:  # B of dipole j at x_i: A/r^3 [3 (m.n) n - m]
                r = p.position[i] - p.position[j]
                n = r / np.linalg.norm(r)
                field += 0.7 / np.linalg.norm(r) ** 3 * (3 * (p.dipole[j] @ n) * n - p.dipole[j])
        np.testing.assert_allclose(torque[i], np.cross(p.dipole[i], field), rtol=1e-12, atol=1e-14)


def test_head_to_tail_attract_and_side_by_side_repel():
    def force_on_second(m):
        p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=1.0, dipole=[m, m])
        return dk.Scene(p, [dk.Dipole(prefactor=1.0)]).forces()[0][1]

    # head to tail: F_j = -6 A m^2 / r^4 along n
    np.testing.assert_allclose(force_on_second([1, 0, 0]), [-6 / 3**4, 0, 0], rtol=1e-14)
    # side by side, parallel: repulsive, +3 A m^2 / r^4
    np.testing.assert_allclose(force_on_second([0, 1, 0]), [3 / 3**4, 0, 0], rtol=1e-14)


@pytest.mark.parametrize("model", [dk.Dipole, SWITCHED])
def test_pair_forces_and_torques_balance(rng, model):
    scene = random_scene(rng, n=5, model=model)
    p = scene.particles
    force, torque = scene.forces()
    scale = np.abs(force).max() * 10
    assert np.abs(force.sum(axis=0)).max() < 1e-13 * scale
    total = torque.sum(axis=0) + np.cross(p.position, force).sum(axis=0)
    assert np.abs(total).max() < 1e-13 * scale


def test_power_law_has_no_torque_and_paper_magnitude():
    p = dk.Particles(position=[[0, 0, 0], [2.5, 0, 0]], radius=1.0, dipole=[[0, 2, 0], [0, 0, 3]])
    scene = dk.Scene(p, [dk.PowerLawDipole(prefactor=0.5)])
    force, torque = scene.forces()
    np.testing.assert_allclose(force[1], [-6 * 0.5 * 6 / 2.5**4, 0, 0], rtol=1e-14)
    assert not torque.any()
    assert scene.energy()["magnetic"] == pytest.approx(-2 * 0.5 * 6 / 2.5**3, rel=1e-14)


def test_cutoff_skips_distant_pairs():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0], [10, 0, 0]], radius=1.0, dipole=[[1, 0, 0]] * 3)
    full = dk.Scene(p.copy(), [dk.Dipole(1.0)]).forces()[0]
    cut = dk.Scene(p.copy(), [dk.Dipole(1.0, cutoff=5.0)]).forces()[0]
    np.testing.assert_allclose(cut[0], [6 / 3**4, 0, 0], rtol=1e-14)
    assert not np.allclose(full[0], cut[0])


# ---- truncation at a cutoff: plain (default) and switched -------------------------------------

CUTOFF, WIDTH = 4.0, 1.0          # the switch runs over [3, 4]


def pair(rng, r, model):
    """Two spheres at distance r along a random direction, random moments; (scene, n = d/r)."""
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    x0 = rng.uniform(-1, 1, 3)
    p = dk.Particles(position=[x0, x0 + r * n], radius=0.5, dipole=rng.normal(size=(2, 3)))
    return dk.Scene(p, [model]), n


def pair_values(scene):
    force, torque = scene.forces()
    return scene.energy()["magnetic"], force, torque


def test_switch_width_is_validated():
    with pytest.raises(ValueError, match="switch_width needs a cutoff"):
        dk.Dipole(1.0, switch_width=0.5)
    with pytest.raises(ValueError, match="smaller than the cutoff"):
        dk.Dipole(1.0, cutoff=4.0, switch_width=4.0)
    with pytest.raises(ValueError, match="smaller than the cutoff"):
        dk.PowerLawDipole(1.0, cutoff=4.0, switch_width=5.0)
    for bad in (0.0, -0.5, np.nan, np.inf):
        with pytest.raises(ValueError, match="switch_width must be a positive finite number"):
            dk.Dipole(1.0, cutoff=4.0, switch_width=bad)
    plain = dk.Dipole(1.0, cutoff=4.0)
    assert plain.switch_width is None and plain.parameters == ("prefactor",)
    switched = dk.Dipole(1.0, cutoff=4.0, switch_width=0.5)
    assert switched.switch_on == 3.5
    assert repr(switched) == "Dipole(prefactor=1.0, cutoff=4.0, switch_width=0.5)"
    assert dk.Dipole(1.0).pair_functions() == (dk.Dipole.force_function, dk.Dipole.energy_function)


@pytest.mark.parametrize("r", [2.0, 2.999, 3.001, 3.3, 3.6, 3.9, 3.99])
@pytest.mark.parametrize("make", [dk.Dipole, dk.PowerLawDipole])
def test_switched_pair_derivatives(rng, r, make):
    """force = -grad U_s and torque = -dU_s/d(angle) below, inside and at the ends of the switch.

    U_s = S U is C2 in r, so central differences err by h^2/6 |U_s'''| (S''' <= 60/w^3 times
    |U| ~ 0.1 here: ~1e-10 at h = 1e-5) plus round-off eps |U| / h ~ 1e-12; near r_c, where
    U_s ~ 1e-5 U, both shrink with U_s. rtol 1e-6 (atol 1e-9 of the largest component) leaves
    a wide margin; a wrong sign of the -U S' n term fails it by orders of magnitude.
    """
    for _ in range(3):
        scene, _ = pair(rng, r, make(prefactor=0.7, cutoff=CUTOFF, switch_width=WIDTH))
        p = scene.particles
        force, torque = scene.forces()
        for i in range(2):
            fd = -energy_gradient(scene, "magnetic", i, h=1e-5)
            np.testing.assert_allclose(force[i], fd, rtol=1e-6, atol=1e-9 * np.abs(force).max())
            for a in range(3 if make.torque else 0):    # the power law has no torque
                m0 = p.dipole[i].copy()
                p.dipole[i] = rotate(m0, np.eye(3)[a], 1e-6)
                up = scene.energy()["magnetic"]
                p.dipole[i] = rotate(m0, np.eye(3)[a], -1e-6)
                down = scene.energy()["magnetic"]
                p.dipole[i] = m0
                assert torque[i, a] == pytest.approx(-(up - down) / 2e-6, rel=1e-6,
                                                     abs=1e-9 * np.abs(torque).max())


@pytest.mark.parametrize("r", [3.001, 3.25, 3.5, 3.75, 3.999])
def test_switched_values_are_s_times_plain(rng, r):
    """U_s = S U, F_s = S F - U S' n (force on j, n = d/r), tau_s = S tau, from the plain values."""
    for _ in range(3):
        switched, n = pair(rng, r, dk.Dipole(prefactor=0.7, cutoff=CUTOFF, switch_width=WIDTH))
        plain = dk.Scene(switched.particles.copy(), [dk.Dipole(prefactor=0.7)])
        u, f, t = pair_values(plain)
        us, fs, ts = pair_values(switched)
        s, ds = switch(r, CUTOFF, WIDTH)
        assert us == pytest.approx(s * u, rel=1e-12)
        np.testing.assert_allclose(fs[1], s * f[1] - u * ds * n, rtol=1e-10, atol=1e-13 * np.abs(f).max())
        np.testing.assert_allclose(fs[0], -fs[1], rtol=1e-15)
        np.testing.assert_allclose(ts, s * t, rtol=1e-10, atol=1e-13 * np.abs(t).max())


def test_switched_goes_continuously_to_zero_at_the_cutoff(rng):
    """Just inside r_c, at r = r_c - e w: S = 10e^3 - 15e^4 + 6e^5 <= 10 e^3 and |S'| <= 30 e^2 / w,
    so |U_s| <= 10e^3 |U|, |F_s| <= 10e^3 |F| + 30e^2 |U| / w, |tau_s| <= 10e^3 |tau|, with U, F, tau
    the plain values there; at and beyond r_c everything is exactly 0. The plain truncation
    jumps from U to 0 instead."""
    for _ in range(3):
        for eps in (1e-2, 1e-3, 1e-4):
            r = CUTOFF - eps * WIDTH
            switched, _ = pair(rng, r, dk.Dipole(prefactor=0.7, cutoff=CUTOFF, switch_width=WIDTH))
            u, f, t = pair_values(dk.Scene(switched.particles.copy(), [dk.Dipole(prefactor=0.7)]))
            us, fs, ts = pair_values(switched)
            slack = 1 + 1e-9
            assert abs(us) <= slack * 10 * eps**3 * abs(u)
            assert np.linalg.norm(fs[1]) <= slack * (10 * eps**3 * np.linalg.norm(f[1]) + 30 * eps**2 * abs(u) / WIDTH)
            for k in range(2):
                assert np.linalg.norm(ts[k]) <= slack * 10 * eps**3 * np.linalg.norm(t[k])
            # plain truncation at the same distance keeps the full values: a jump of U at r_c
            up, fp, tp = pair_values(dk.Scene(switched.particles.copy(), [dk.Dipole(prefactor=0.7, cutoff=CUTOFF)]))
            assert (up, fp.tolist(), tp.tolist()) == (u, f.tolist(), t.tolist())
    # at and beyond r_c: the pair loop skips r >= r_c, and the pair functions return 0 on their own
    for r in (CUTOFF, CUTOFF * (1 + 1e-15), CUTOFF + 0.5):
        scene, n = pair(rng, r, dk.Dipole(prefactor=0.7, cutoff=CUTOFF, switch_width=WIDTH))
        us, fs, ts = pair_values(scene)
        assert us == 0 and not fs.any() and not ts.any()
        d = r * n
        dip = scene.particles.dipole
        args = (0, 1, d[0], d[1], d[2], d @ d, dip, 0.7, CUTOFF - WIDTH, 1 / WIDTH)
        assert switched_dipole_energy(*args) == 0.0
        assert not any(switched_dipole_force(*args))


def test_switched_equals_plain_below_the_switch_exactly(rng):
    """Below r_on = r_c - w the switched pair functions do the plain arithmetic: bit for bit."""
    pos = rng.uniform(0, 6, size=(12, 3))        # pair distances from ~0.5 to ~10
    keep = [0]
    for k in range(1, len(pos)):                 # no two closer than 1.2 (overlap check)
        if all(np.linalg.norm(pos[k] - pos[q]) > 1.2 for q in keep):
            keep.append(k)
    p = dk.Particles(position=pos[keep], radius=0.5, dipole=rng.normal(size=(len(keep), 3)))
    plain = dk.Scene(p.copy(), [dk.Dipole(prefactor=0.7, cutoff=CUTOFF)])
    switched = dk.Scene(p.copy(), [dk.Dipole(prefactor=0.7, cutoff=CUTOFF, switch_width=WIDTH)])
    pairs, e_plain = plain.pair_energies()
    _, e_switched = switched.pair_energies()
    r = np.linalg.norm(p.position[pairs[:, 1]] - p.position[pairs[:, 0]], axis=1)
    below, inside, beyond = r <= CUTOFF - WIDTH, (r > CUTOFF - WIDTH) & (r < CUTOFF), r >= CUTOFF
    assert below.sum() >= 3 and inside.sum() >= 3 and beyond.sum() >= 3
    assert np.array_equal(e_switched[below], e_plain[below])
    assert not np.any(e_switched[beyond]) and not np.any(e_plain[beyond])
    assert np.all(np.abs(e_switched[inside]) < np.abs(e_plain[inside]))
    # forces and torques of a scene whose pairs are all below the switch: identical arrays
    close = dk.Particles(position=[[0, 0, 0], [1.5, 0.3, 0], [0.2, 2.1, 0.4], [1.1, 1.2, 1.3]], radius=0.5,
                         dipole=rng.normal(size=(4, 3)))
    a = dk.Scene(close.copy(), [dk.Dipole(prefactor=0.7)])
    b = dk.Scene(close.copy(), [dk.Dipole(prefactor=0.7, cutoff=CUTOFF, switch_width=WIDTH)])
    for x, y in zip(a.forces(), b.forces()):
        assert np.array_equal(x, y)
    assert np.array_equal(a.pair_energies()[1], b.pair_energies()[1])
    # the summed energy may differ in the last bit: the compiler is free to fuse the plain pair's last
    # multiplication with the accumulation (fused multiply-add), which the switch's branch prevents
    assert b.energy()["magnetic"] == pytest.approx(a.energy()["magnetic"], rel=4e-16)


# ---- energy conservation in a cluster whose pairs cross the cutoff ------------------------------

def gas(seed, n=40, side=8.0, gap=1.8, speed=0.7):
    """n unit spheres (d = 1, m = 1) placed at random in a cube at least ``gap`` apart, random unit
    moments, random velocities and spins: an open cluster that spreads, pairs crossing r_c often."""
    rng = np.random.default_rng(seed)
    pos = []
    while len(pos) < n:
        x = rng.uniform(0, side, 3)
        if all(np.linalg.norm(x - y) > gap for y in pos):
            pos.append(x)
    dip = rng.normal(size=(n, 3))
    vel = rng.normal(scale=speed, size=(n, 3))
    return dk.Particles(position=pos, velocity=vel - vel.mean(axis=0), angular_velocity=rng.normal(scale=speed, size=(n, 3)),
                        dipole=dip / np.linalg.norm(dip, axis=1)[:, None], radius=0.5, mass=1.0)


def energy_error(seed, dt, switch_width, duration=2.0, cutoff=2.5):
    """max |E(t) - E(0)| of a velocity-Verlet run, and the number of times a pair crossed r_c."""
    p = gas(seed)
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=cutoff, switch_width=switch_width),
                         dk.KelvinVoigt(stiffness=200.0, damping=0.0)])
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt=dt)).run(duration=duration, record_every=0.008)
    e = traj.energy["total"]
    i, j = np.triu_indices(len(p), 1)
    inside = np.linalg.norm(traj.position[:, j] - traj.position[:, i], axis=2) < cutoff
    return np.abs(e - e[0]).max(), np.count_nonzero(inside[1:] != inside[:-1])


def test_switched_truncation_conserves_energy_to_second_order():
    """40 dipoles (|m| = 1, A = 1), r_c = 2.5, soft contacts, 2 time units: ~80 cutoff crossings a
    run. Plain truncation: the energy jumps by U(r_c) at each crossing (|U| up to 2A/r_c^3 = 0.13),
    whatever dt. Switched (w = 0.5): the error is bounded and falls 4x when dt halves.

    The runs are chaotic and every contact adds an error whose size depends on where in a step it
    starts, so one run's max error scatters around the dt^2 law by tens of percent; summed over
    8 clusters the ratio is 3.5-4.2 for any 8 seeds tried (32 seeds): accepted 3.0-5.3.
    """
    seeds = range(1, 9)
    dts = (0.008, 0.004, 0.002)
    switched = np.array([[energy_error(s, dt, 0.5) for dt in dts] for s in seeds])  # (seed, dt, 2)
    crossings = switched[:, :, 1]
    assert crossings.min() >= 40
    err = switched[:, :, 0].sum(axis=0)
    assert 3.0 < err[0] / err[1] < 5.3 and 3.0 < err[1] / err[2] < 5.3
    assert switched[:, -1, 0].max() < 3e-3       # measured 1e-3 at dt = 0.002 (total energy ~30)
    plain = np.array([[energy_error(s, dt, None)[0] for dt in dts[1:]] for s in seeds[:4]])
    # no convergence with dt, and 100x the switched error
    assert np.all(plain[:, 1] > 0.8 * plain[:, 0])
    assert plain[:, 1].min() > 100 * switched[:4, -1, 0].max()
