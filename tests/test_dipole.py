"""Dipole and power-law forces/torques against finite differences of their energy."""
import numpy as np
import pytest

import demkit as dk
from conftest import energy_gradient


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


@pytest.mark.parametrize("model", [dk.Dipole, dk.PowerLawDipole])
def test_force_is_minus_energy_gradient(rng, model):
    for _ in range(3):
        scene = random_scene(rng, model=model)
        p = scene.particles
        force, _ = scene.forces()
        for i in range(len(p)):
            fd = -energy_gradient(scene, "magnetic", i, h=1e-5)
            # central differences: error ~ h^2 U'" ~ 1e-10 relative to the force scale
            np.testing.assert_allclose(force[i], fd, rtol=1e-6, atol=1e-9 * np.abs(force).max())


def test_torque_is_minus_energy_derivative_under_rotation(rng):
    for _ in range(3):
        scene = random_scene(rng)
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


def test_pair_forces_and_torques_balance(rng):
    scene = random_scene(rng, n=5)
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
