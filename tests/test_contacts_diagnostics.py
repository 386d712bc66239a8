"""Per-contact diagnostics (scene.contacts()) and the contact network in VTK.

Truths: the contacts' forces and torques summed per sphere equal the kernels' forces (the same
physics evaluated another way), the analytic Kelvin-Voigt force and dashpot power of a head-on
impact, and Coulomb's sliding dissipation mu F_n |v_slip| for a sphere skidding on a floor.
"""
import math

import numpy as np
import pytest

import demkit as dk

R, M, G = 0.01, 1e-3, 9.81


def settled_pile(law):
    """120 spheres dropped into a box periodic in x and y onto a floor, moving still."""
    box = dk.Box([0.08, 0.08, 0.3], periodic=(True, True, False))
    x = dk.build.random_packing(120, R, box, seed=2)
    p = dk.Particles(position=x, radius=R, mass=M)
    scene = dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -G))], box=box)
    dk.Simulation(scene, dk.VelocityVerlet(2e-5)).run(0.25)
    return p, scene


@pytest.mark.parametrize("make", [
    lambda: dk.KelvinVoigt(2e3, 0.5),
    lambda: dk.KelvinVoigt(2e3, 0.5, friction=dk.Friction(0.3), rolling=dk.RollingResistance(0.05)),
    lambda: dk.Hertz(1e7, 0.3, 0.5, friction=dk.Friction(0.3)),
])
def test_contact_forces_and_torques_add_up_to_the_kernels_forces(make):
    p, scene = settled_pile(make())
    c = scene.contacts()
    assert len(c) > 100 and (c.wall >= 0).sum() > 5 and (c.wall < 0).sum() > 50
    force, torque = scene.forces()
    weight = np.zeros_like(force)
    weight[:, 2] = -G * M
    # 1e-11 of the largest force: the same terms summed in another order
    assert np.abs(c.net_force(len(p)) + weight - force).max() < 1e-11 * np.abs(force).max()
    total = np.zeros_like(torque)
    np.add.at(total, c.pairs[:, 1], c.torque_j)
    inner = c.pairs[:, 0] >= 0
    np.add.at(total, c.pairs[inner, 0], c.torque_i[inner])
    assert np.abs(total - torque).max() <= 1e-11 * max(np.abs(torque).max(), 1e-300)
    assert (c.overlap > 0).all() and (c.dissipation >= 0).all()
    np.testing.assert_allclose(np.linalg.norm(c.normal, axis=1), 1.0, rtol=1e-14)
    # contact points lie R_j - delta/2 from j's centre (R - delta: on the wall's plane)
    walls = c.wall >= 0
    np.testing.assert_allclose(c.point[walls, 2], 0.0, atol=1e-15)
    d = np.linalg.norm(c.point[~walls] - p.position[c.pairs[~walls, 1]], axis=1)
    np.testing.assert_allclose(d, R - 0.5 * c.overlap[~walls], rtol=1e-12)
    # nothing changed: forces again are bit-identical
    again, _ = scene.forces()
    assert np.array_equal(again, force)


def test_head_on_kelvin_voigt_contact_force_and_dashpot_power():
    k, c_damp, v = 2e3, 0.5, 0.3
    p = dk.Particles(position=[[-R * 1.001, 0, 0], [R * 1.001, 0, 0]], velocity=[[v, 0, 0], [-v, 0, 0]],
                     radius=R, mass=M)
    scene = dk.Scene(p, [dk.KelvinVoigt(k, c_damp)])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-7))
    sim.run(3e-4)
    c = scene.contacts()
    assert len(c) == 1 and tuple(c.pairs[0]) == (0, 1) and c.wall[0] == -1
    delta = 2 * R - (p.position[1, 0] - p.position[0, 0])
    rate = p.velocity[0, 0] - p.velocity[1, 0]
    assert c.overlap[0] == pytest.approx(delta, rel=1e-12)
    assert c.normal_force[0] == pytest.approx(k * delta + c_damp * rate, rel=1e-12)
    assert c.dissipation[0] == pytest.approx(c_damp * rate ** 2, rel=1e-12)
    np.testing.assert_allclose(c.normal[0], [1, 0, 0])
    assert c.sliding[0]  # frictionless contacts always slide


def test_a_skidding_sphere_slides_then_sticks_and_dissipates_coulomb_power():
    mu, v0 = 0.3, 1.0
    p = dk.Particles(position=[[0, 0, R - M * G / 2e3]], velocity=[[v0, 0, 0]], radius=R, mass=M)
    law = dk.KelvinVoigt(2e3, 0.5, friction=dk.Friction(mu))
    scene = dk.Scene(p, [law, dk.Wall((0, 0, 0), (0, 0, 1)), dk.Gravity((0, 0, -G))])
    sim = dk.Simulation(scene, dk.VelocityVerlet(2e-6))
    sim.run(0.02)
    c = scene.contacts()
    assert len(c) == 1 and c.wall[0] == 0 and c.pairs[0, 0] == -1 and c.sliding[0]
    slip = p.velocity[0, 0] - p.angular_velocity[0, 1] * (R - c.overlap[0])
    # Coulomb: |F_t| = mu F_n, against the slip; power mu F_n |slip| (+ the small normal dashpot's)
    assert c.tangential_force[0, 0] == pytest.approx(-mu * c.normal_force[0], rel=1e-12)
    assert c.dissipation[0] == pytest.approx(mu * c.normal_force[0] * slip, rel=1e-3)
    sim.run(0.3)  # rolls without slipping: sticks, spring and dashpot nearly idle
    c = scene.contacts()
    assert not c.sliding[0] and c.dissipation[0] < 1e-9


def test_vtk_writer_writes_the_contact_network(tmp_path):
    pv = pytest.importorskip("pyvista")
    law = dk.KelvinVoigt(2e3, 0.5, friction=dk.Friction(0.3))
    p, scene = settled_pile(law)
    writer = dk.VTKWriter(tmp_path / "out", every=0.01, contacts=True, trails=False)
    dk.Simulation(scene, dk.VelocityVerlet(2e-5), writers=[writer]).run(0.02)
    writer.close()
    files = sorted((tmp_path / "out").glob("particles_contacts_*.vtp"))
    assert len(files) == 3 and (tmp_path / "out" / "particles_contacts.pvd").exists()
    mesh = pv.read(files[-1])
    c = scene.contacts()
    assert mesh.n_cells == len(c)
    np.testing.assert_allclose(mesh.cell_data["force"], c.force)
    np.testing.assert_array_equal(mesh.cell_data["sliding"], c.sliding.astype(int))
    # each line joins i's centre (or the contact point on the wall) to j's: length r or R - delta
    ends = mesh.points.reshape(-1, 2, 3)
    lengths = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    walls = c.wall >= 0
    np.testing.assert_allclose(lengths[~walls], 2 * R - c.overlap[~walls], rtol=1e-12)
    np.testing.assert_allclose(lengths[walls], R - c.overlap[walls], rtol=1e-12)
    assert lengths.max() < 2 * R  # no line spans the periodic box


def test_no_contacts_is_an_empty_table_and_no_file_without_asking(tmp_path):
    p = dk.Particles(position=[[0, 0, 0], [1, 0, 0]], radius=0.1, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1.0)])
    c = scene.contacts()
    assert len(c) == 0 and c.force.shape == (0, 3)
    writer = dk.VTKWriter(tmp_path / "o", every=0.5)
    dk.Simulation(scene, dk.VelocityVerlet(0.01), writers=[writer]).run(1.0)
    assert not list((tmp_path / "o").glob("*contacts*"))
    scene_without_laws = dk.Scene(p.copy(), [dk.Gravity((0, 0, -1))])
    assert len(scene_without_laws.contacts()) == 0
    assert math.isfinite(float(c.dissipation.sum()))
