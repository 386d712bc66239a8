"""The walls in the VTK series and in pictures (demkit.io.walls): each frame's surfaces where the wall's
motion has taken it, the spheres' push on each wall, and a folder that reads as its particles' series."""
import math

import numpy as np
import pytest

import demkit as dk
from demkit.io import read_pvd, read_series
from demkit.io.walls import FACETS, WallSurfaces


def walled_scene():
    """27 spheres under gravity on a vibrated floor, a piston coming down on them, all in a turning drum."""
    k = np.arange(27)
    pos = np.stack([0.5 + 1.1 * (k % 3), 0.5 + 1.1 * ((k // 3) % 3), 0.6 + 1.1 * (k // 9)], axis=1)
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, velocity=np.zeros((27, 3)))
    law = dk.KelvinVoigt(2000.0, 2.0, friction=dk.Friction(0.5))
    floor = dk.Wall((0, 0, 0), (0, 0, 1), amplitude=(0, 0, 0.05), frequency=2.0)
    piston = dk.Wall((0, 0, 4.0), (0, 0, -1), velocity=(0, 0, -0.5))
    drum = dk.Cylinder((1.6, 1.6, 0), (0, 0, 1), 2.6, angular_velocity=1.0)
    return dk.Scene(p, [law, dk.Gravity((0, 0, -1.0)), floor, piston, drum]), floor, piston, drum


def cells_of(mesh, number):
    """The points of the polygons of wall ``number`` (a pyvista mesh of a walls frame)."""
    return mesh.extract_cells(np.flatnonzero(mesh.cell_data["wall"] == number)).points


def test_each_frame_shows_the_walls_where_their_motion_has_taken_them(tmp_path):
    pv = pytest.importorskip("pyvista")
    scene, floor, piston, drum = walled_scene()
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[dk.VTKWriter(tmp_path, every=0.25)])
    sim.run(1.0, progress=False)
    frames = read_pvd(tmp_path / "particles_walls.pvd")
    assert [t for t, _ in frames] == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    number = {w: scene.effects.index(w) for w in (floor, piston, drum)}
    for t, path in frames:
        mesh = pv.read(path)
        assert mesh.n_cells == 1 + 1 + FACETS
        # planes: every corner on the plane where it stands at t (the floor's A (1 - cos 2 pi f t), the piston's V t)
        lift = 0.05 * (1 - math.cos(2 * math.pi * 2.0 * t))
        np.testing.assert_allclose(cells_of(mesh, number[floor])[:, 2], lift, atol=1e-12)
        np.testing.assert_allclose(cells_of(mesh, number[piston])[:, 2], 4.0 - 0.5 * t, atol=1e-12)
        # the drum: its points at its radius from the axis, the first turned by omega t
        ring = cells_of(mesh, number[drum])[:, :2] - 1.6
        np.testing.assert_allclose(np.hypot(*ring.T), 2.6, rtol=1e-12)
        angles = np.sort(np.mod(np.arctan2(ring[:, 1], ring[:, 0]) - 1.0 * t, 2 * math.pi / FACETS))
        assert min(angles[0], 2 * math.pi / FACETS - angles[-1]) < 1e-9  # facets turned by omega t exactly
    # the plane's rectangle covers the spheres' region and the drum their height (two radii beyond), both
    # rounded out to whole multiples of four radii
    first = pv.read(frames[0][1])
    floor_points = cells_of(first, number[floor])
    assert floor_points[:, 0].min() == -2.0 and floor_points[:, 0].max() == 4.0
    drum_z = cells_of(first, number[drum])[:, 2]
    assert drum_z.min() == pytest.approx(-2.0) and drum_z.max() == pytest.approx(4.0)


def test_the_force_on_each_wall_is_the_spheres_push_and_a_resting_sphere_weighs_on_the_floor(tmp_path):
    pv = pytest.importorskip("pyvista")
    p = dk.Particles(position=[[0.0, 0.0, 0.5]], radius=0.5, mass=2.0, velocity=np.zeros((1, 3)))
    floor = dk.Wall((0, 0, 0), (0, 0, 1))
    side = dk.Wall((-3.0, 0, 0), (1, 0, 0))  # touching nothing
    scene = dk.Scene(p, [dk.KelvinVoigt(1e4, 50.0), dk.Gravity((0, 0, -9.81)), floor, side])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-4), writers=[dk.VTKWriter(tmp_path, every=1.0)])
    sim.run(2.0, progress=False)  # settled: damped in ~0.01 s
    mesh = pv.read(read_pvd(tmp_path / "particles_walls.pvd")[-1][1])
    force = {int(w): f for w, f in zip(mesh.cell_data["wall"], mesh.cell_data["force"])}
    # statics: the floor carries the sphere's weight m g (the spring's rest overlap holds it; the
    # dashpot has nothing left to do: relative error ~1e-12 after 2 s of damping)
    np.testing.assert_allclose(force[scene.effects.index(floor)], [0.0, 0.0, -2.0 * 9.81], rtol=1e-9, atol=1e-12)
    assert np.array_equal(force[scene.effects.index(side)], np.zeros(3))
    # and it is the negative of the wall's contacts in Scene.contacts()
    contacts = scene.contacts()
    on_floor = contacts.force[contacts.wall == scene.effects.index(floor)].sum(axis=0)
    np.testing.assert_allclose(force[scene.effects.index(floor)], -on_floor, rtol=1e-12)


def test_a_servo_lid_is_drawn_where_its_servo_stands(tmp_path):
    pv = pytest.importorskip("pyvista")
    k = np.arange(8)
    pos = np.stack([0.5 + 1.0 * (k % 2), 0.5 + 1.0 * ((k // 2) % 2), 0.5 + 1.0 * (k // 4)], axis=1)
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, velocity=np.zeros((8, 3)))
    lid = dk.Wall((0, 0, 2.2), (0, 0, -1), servo=dk.Servo(force=5.0, max_speed=1.0))
    scene = dk.Scene(p, [dk.KelvinVoigt(1e3, 5.0), dk.Wall((0, 0, 0), (0, 0, 1)), lid])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[dk.VTKWriter(tmp_path, every=0.5)])
    sim.run(1.0, progress=False)
    offset = lid.servo_state()[0]
    assert offset > 0.05  # it has come down onto the spheres
    mesh = pv.read(read_pvd(tmp_path / "particles_walls.pvd")[-1][1])
    np.testing.assert_allclose(cells_of(mesh, scene.effects.index(lid))[:, 2], 2.2 - offset, atol=1e-12)


def test_a_scene_without_walls_writes_no_walls_series_and_a_folder_reads_as_its_particles(tmp_path):
    p = dk.Particles(position=[[0.0, 0, 0], [3.0, 0, 0]], radius=0.5, mass=1.0, velocity=np.zeros((2, 3)))
    sim = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(100.0, 1.0)]), dk.VelocityVerlet(1e-3),
                        writers=[dk.VTKWriter(tmp_path / "open", every=0.5)])
    sim.run(1.0, progress=False)
    assert not list((tmp_path / "open").glob("*walls*"))
    assert read_series(tmp_path / "open").walls is None
    # walls and contacts beside the particles: the folder still names the particles' series
    scene, *_ = walled_scene()
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[dk.VTKWriter(tmp_path / "walled", every=0.5,
                                                                               contacts=True)])
    sim.run(1.0, progress=False)
    series = read_series(tmp_path / "walled")
    assert series.pvd.name == "particles.pvd" and len(series.walls) == len(series.time) == 3
    assert [path.name for path in series.walls] == [f"particles_walls_{k:06d}.vtp" for k in range(3)]
    # asked not to, the writer writes no walls
    sim = dk.Simulation(walled_scene()[0], dk.VelocityVerlet(1e-3),
                        writers=[dk.VTKWriter(tmp_path / "none", every=0.5, walls=False)])
    sim.run(0.5, progress=False)
    assert not list((tmp_path / "none").glob("*walls*"))


def test_a_resumed_run_continues_the_walls_series(tmp_path):
    def run(folder, resume_at=None):
        sim = dk.Simulation(walled_scene()[0], dk.VelocityVerlet(1e-3))
        writer = dk.VTKWriter(folder, every=0.25, resume=resume_at is not None)
        if resume_at is None:
            writer.open(sim)
            writer.write(sim)
        else:
            while sim.time < resume_at - 1e-9:
                sim.run(0.25, progress=False)
            assert writer.resume(sim) is False
        while sim.time < 1.0 - 1e-9:
            sim.run(0.25, progress=False)
            writer.write(sim)
        writer.close()

    run(tmp_path / "whole")
    run(tmp_path / "resumed")
    (tmp_path / "resumed" / "particles_walls_000009.vtp").write_bytes(b"a frame of a killed run")
    run(tmp_path / "resumed", resume_at=0.5)
    whole = {p.name: p.read_bytes() for p in (tmp_path / "whole").glob("particles_walls*")}
    resumed = {p.name: p.read_bytes() for p in (tmp_path / "resumed").glob("particles_walls*")}
    assert resumed == whole and len(whole) == 6  # five frames and the .pvd, byte for byte


def test_surfaces_of_a_periodic_box_span_it_along_its_periodic_axes():
    p = dk.Particles(position=[[1.0, 1.0, 0.6], [3.0, 2.0, 0.6]], radius=0.5, mass=1.0)
    floor = dk.Wall((0, 0, 0), (0, 0, 1))
    scene = dk.Scene(p, [dk.KelvinVoigt(100.0, 1.0), floor], box=dk.Box([4.0, 5.0, 3.0], periodic=[True, True, False]))
    points, connectivity, offsets, cells = WallSurfaces(scene).at(0.0)
    assert offsets.tolist() == [4] and cells["wall"].tolist() == [scene.effects.index(floor)]
    np.testing.assert_allclose(np.sort(points[:, 0]), [0.0, 0.0, 4.0, 4.0], atol=1e-12)
    np.testing.assert_allclose(np.sort(points[:, 1]), [0.0, 0.0, 5.0, 5.0], atol=1e-12)
    np.testing.assert_allclose(points[:, 2], 0.0, atol=1e-12)


def test_a_trajectory_written_after_the_run_has_the_walls_the_writer_wrote(tmp_path):
    pv = pytest.importorskip("pyvista")
    scene, floor, piston, drum = walled_scene()
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[dk.VTKWriter(tmp_path / "live", every=0.25)])
    traj = sim.run(1.0, record_every=0.25, progress=False)
    assert [w for _, w in traj.walls] == [floor, piston, drum]
    dk.write_series(traj, tmp_path / "after")
    live, after = read_series(tmp_path / "live"), read_series(tmp_path / "after")
    assert np.allclose(live.time, after.time) and len(after.walls) == 5
    for a, b in zip(live.walls, after.walls):
        a, b = pv.read(a), pv.read(b)
        np.testing.assert_allclose(b.points, a.points, atol=1e-12)  # where the run's writer drew them
        assert np.array_equal(a.cell_data["wall"], b.cell_data["wall"]) and "force" not in b.cell_data
