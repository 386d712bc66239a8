"""Triangle-mesh walls (demkit.MeshWall): a triangulated plane against the plane wall (to round-off, on
faces, edges and corners, and rolling across many triangles), a triangulated drum converging to the
cylinder at the order of its chordal error, a vibrated mesh against the vibrated plane, a turntable that
carries a rolling sphere round at 2/7 of its rate, files, scene files, outputs and bad input."""
import math

import meshio
import numpy as np
import pytest
from scipy.spatial import Delaunay

import demkit as dk
from demkit.cli import main as demkit_main
from demkit.interactions.mesh_geometry import closest_on_triangle

R, G, L = 0.5, 10.0, 9.0


def square(points=0, seed=0, size=L, z=0.0):
    """(vertices, triangles) of the square [-size, size]^2 at height z: two triangles, or a Delaunay
    triangulation of its corners and ``points`` random points inside (an irregular mesh)."""
    corners = np.array([[-size, -size], [size, -size], [size, size], [-size, size]])
    if points == 0:
        return np.c_[corners, np.full(4, z)], np.array([[0, 1, 2], [0, 2, 3]])
    inner = np.random.default_rng(seed).uniform(-0.95 * size, 0.95 * size, size=(points, 2))
    xy = np.concatenate([corners, inner])
    return np.c_[xy, np.full(len(xy), z)], Delaunay(xy).simplices


def drum(n, radius=3.0, half=2.0):
    """A triangulated cylinder about z of ``n`` facets (two triangles each), its vertices on the circle."""
    angle = 2.0 * math.pi * np.arange(n) / n
    ring = np.c_[radius * np.cos(angle), radius * np.sin(angle)]
    vertices = np.concatenate([np.c_[ring, np.full(n, -half)], np.c_[ring, np.full(n, half)]])
    k = np.arange(n)
    triangles = np.concatenate([np.c_[k, (k + 1) % n, n + k], np.c_[(k + 1) % n, n + (k + 1) % n, n + k]])
    return vertices, triangles


def law():
    return dk.KelvinVoigt(1e4, 20.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.05),
                          twisting=dk.TwistingResistance())


def spheres_over(vertices, triangles, rng):
    """Sphere centres exactly over corners, over edges (their midpoints) and over faces (random) of the
    mesh at z = 0, at least 2.2 radii apart, each pressed into it by a random overlap."""
    edges = np.concatenate([vertices[triangles[:, [0, 1]]], vertices[triangles[:, [1, 2]]]]).mean(axis=1)
    faces = np.c_[rng.uniform(-L + 4, L - 4, size=(40, 2)), np.zeros(40)]
    kept = []
    for kind in (vertices, edges, faces):
        chosen = 0
        for x in kind[np.all(np.abs(kind[:, :2]) < L - 4, axis=1)]:
            if chosen < 10 and all(math.dist(x, y) > 2.2 * R for y in kept):
                kept.append(x)
                chosen += 1
    xy = np.array(kept)[:, :2]
    return np.c_[xy, R - rng.uniform(0.0, 0.05 * R, size=len(xy))]


def pair(mesh, position, rng, wall=(0.0, 0.0, 1.0), turn=None, **motion):
    """The same spheres (random velocities and spins) on the mesh and on the plane wall."""
    v = rng.normal(size=position.shape) * [2.0, 2.0, 0.1]
    w = rng.normal(size=position.shape) * 3.0
    if turn is not None:
        position, v, w = position @ turn.T, v @ turn.T, w @ turn.T
    scenes = []
    for effect in (dk.MeshWall(*mesh, **motion), dk.Wall((0, 0, 0), wall, **motion)):
        p = dk.Particles(position=position, velocity=v, angular_velocity=w, radius=R, mass=1.0)
        scenes.append(dk.Scene(p, [law(), effect, dk.Gravity(-G * np.asarray(wall))]))
    return scenes


def test_closest_point_of_a_triangle_against_a_dense_sampling(rng):
    """Ericson's regions against the nearest of 45 000 points spread over the triangle: never farther,
    and within the sampling's spacing (1/300 of an edge, edges up to ~5 long)."""
    u = np.linspace(0.0, 1.0, 301)
    a, b = np.meshgrid(u, u)
    keep = a + b <= 1.0
    for _ in range(25):
        corner = rng.normal(size=(3, 3))
        p = 2.0 * rng.normal(size=3)
        samples = corner[0] + a[keep, None] * (corner[1] - corner[0]) + b[keep, None] * (corner[2] - corner[0])
        sampled = np.linalg.norm(samples - p, axis=1).min()
        qx, qy, qz, inside = closest_on_triangle(*p, *corner.ravel())
        found = math.dist((qx, qy, qz), p)
        assert sampled - 0.02 <= found <= sampled + 1e-13
        normal = np.cross(corner[1] - corner[0], corner[2] - corner[0])
        if inside:  # over the face: p - q along the face's normal
            assert np.linalg.norm(np.cross(p - (qx, qy, qz), normal)) <= 1e-12 * np.linalg.norm(normal) * (1 + found)


@pytest.mark.parametrize("points", [0, 100], ids=["two triangles", "irregular"])
def test_a_triangulated_plane_is_the_plane_wall(points, rng):
    """Spheres pressed into a triangulated plane over faces, exactly over edges and over corners feel the
    plane wall's force and torque (friction, rolling, twisting), to 1e-12 of the largest (measured: the
    same bits); tilted by a random rotation too (measured 9e-14: the overlap R - (x.n - q.n) of a tilted
    plane is a difference of numbers ~1000 times larger, each rounded).
    Then they slide and roll across it under gravity for 3000 steps, most of them across several of the
    irregular mesh's triangles (~4 radii wide): the same trajectory as on the plane wall to 1e-12 (measured:
    the same bits; the face normals are the plane's exactly, an edge's or corner's to 1 ulp)."""
    mesh = square(points)
    x = spheres_over(*mesh, rng)
    on_mesh, on_wall = pair(mesh, x, np.random.default_rng(1))
    for a, b in zip(on_mesh.forces(), on_wall.forces()):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    assert len(on_mesh.contacts().overlap) == len(x)  # one contact each, over edges and corners too
    turn = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    tilted = (mesh[0] @ turn.T, mesh[1])
    on_mesh_t, on_wall_t = pair(tilted, x, np.random.default_rng(1), wall=turn[:, 2], turn=turn)
    for a, b in zip(on_mesh_t.forces(), on_wall_t.forces()):
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
    runs = [dk.Simulation(s, dk.VelocityVerlet(4e-4)).run(1.2, record_every=0.1, progress=False)
            for s in (on_mesh, on_wall)]
    travelled = np.linalg.norm(runs[0].position[-1] - runs[0].position[0], axis=1)
    assert np.median(travelled) > 1.0 and np.abs(runs[0].position[:, :, :2]).max() < L - R  # (still over it)
    for name in ("position", "velocity", "angular_velocity"):
        a, b = getattr(runs[0], name), getattr(runs[1], name)
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), name


def test_a_triangulated_drum_converges_to_the_cylinder_at_second_order(rng):
    """Spheres at random places inside a drum of n facets: their overlaps with it differ from the
    cylinder's by at most its chordal error R_c (1 - cos(pi / n)) (a facet's middle lies that far inside
    the circle; the corners on it), and the largest error over 200 spheres is within 1 % of it; from
    n = 24 to 48 the error falls by 2^1.99 (order 2, 1/n^2). The contacts' normal forces follow."""
    rc = 3.0
    angle = rng.uniform(0, 2 * math.pi, 200)
    arm = rc - R + rng.uniform(0.001, 0.05, 200)  # pressed into the wall
    x = np.c_[arm * np.cos(angle), arm * np.sin(angle), rng.uniform(-1.0, 1.0, 200)]
    cylinder = dk.Cylinder((0, 0, 0), (0, 0, 1), rc)
    errors = []
    for n in (24, 48):
        wall = dk.MeshWall(*drum(n, rc), reach=R)
        error = np.abs(wall.heights(x) - cylinder.heights(x))
        chord = rc * (1.0 - math.cos(math.pi / n))
        assert error.max() <= chord * (1 + 1e-9) and error.max() >= 0.99 * chord
        errors.append(error.max())
    assert math.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.02)
    p = dk.Particles(position=x[:3], radius=R, mass=1.0)
    forces = [dk.Scene(p, [dk.KelvinVoigt(1e4, 0.0), wall]).contacts().normal_force
              for wall in (dk.MeshWall(*drum(48, rc)), cylinder)]
    assert np.abs(forces[0] - forces[1]).max() <= 1e4 * chord * (1 + 1e-9)


def test_an_elastic_sphere_bouncing_in_a_drum_mesh_keeps_its_energy():
    """No damping, no friction: a sphere bouncing around inside a drum of 12 facets (over their faces,
    edges and the creases between them, where the nearer face takes over) keeps its energy to the
    integrator's second order: the largest deviation falls ~4x when the step is halved (measured 3.4 and,
    halved again, 3.8), 7.5e-4 of the energy at 50 steps per contact (a cylinder's: 9.5e-4)."""
    k = 1e4
    contact_time = math.pi / math.sqrt(k)
    deviations = []
    for steps in (50, 100):
        p = dk.Particles(position=[[0.5, 0.2, 0.0]], velocity=[[3.0, 1.7, 0.4]], radius=R, mass=1.0)
        scene = dk.Scene(p, [dk.KelvinVoigt(k, 0.0), dk.MeshWall(*drum(12, 2.0, 3.0))])
        traj = dk.Simulation(scene, dk.VelocityVerlet(contact_time / steps)).run(6.0, record_every=0.01,
                                                                                 progress=False)
        e = traj.energy["total"]
        deviations.append(np.max(np.abs(e - e[0])) / e[0])
        assert np.max(traj.energy["wall"]) > 0.3 * e[0]  # it did bounce
        assert np.max(np.hypot(traj.position[:, 0, 0], traj.position[:, 0, 1])) < 2.0 - R + 0.05
    assert deviations[0] < 2e-3 and 3.0 < deviations[0] / deviations[1] < 5.0


def test_a_vibrated_and_travelling_mesh_is_the_moving_plane_wall():
    """A sphere on a floor vibrated at Gamma = a w^2 / g = 3 (it takes off and lands again) and one on a
    conveyor sliding under it: on the triangulated floor the trajectory of the plane wall's, to 1e-12."""
    mesh = square(0)
    for motion in (dict(amplitude=(0, 0, 0.02), frequency=0.5 / math.pi * math.sqrt(3 * G / 0.02)),
                   dict(velocity=(0.7, 0.2, 0.0))):
        x = np.array([[0.3, -0.2, R - 0.01]])
        scenes = pair(mesh, x, np.random.default_rng(2), **motion)
        runs = [dk.Simulation(s, dk.VelocityVerlet(2e-4)).run(0.5, progress=False) for s in scenes]
        a, b = runs[0].position, runs[1].position
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()
        assert np.ptp(b[:, 0, 2]) > 0.01 if "amplitude" in motion else np.abs(b[-1, 0, :2] - b[0, 0, :2]).max() > 0.1


def test_a_moving_mesh_is_where_its_motion_takes_it_and_its_surface_moves_rigidly(rng):
    """A bumpy sheet turning about an oblique axis while it travels and vibrates: at each time the planes
    it presents are those of a mesh at rest made of its corners where the motion has taken them (to
    1e-14: the same nearest points, found in its own frame), and the surface velocity at the contact
    point q is the rigid body's, D'(t) + omega a x (q - c - D(t))."""
    vertices, triangles = square(30, seed=2, size=3.0)
    vertices[:, 2] = 0.3 * np.sin(vertices[:, 0]) * np.cos(vertices[:, 1])
    axis = np.array([0.3, -0.5, 1.0]) / math.sqrt(1.34)
    wall = dk.MeshWall(vertices, triangles, point=(0.5, -0.2, 0.1), axis=axis, angular_velocity=0.8,
                       velocity=(0.1, 0.2, -0.05), amplitude=(0.0, 0.05, 0.02), frequency=1.3, reach=R)
    x = rng.uniform(-2, 2, size=(300, 3)) * [1, 1, 0.3]
    for t in (0.0, 0.7, 2.3):
        corners = wall.corners_at(t).reshape(-1, 3)
        still = dk.MeshWall(corners, np.arange(len(corners)).reshape(-1, 3), reach=R)
        moving, held = wall.planes(x, t), still.planes(x)
        near = moving[:, 0] > -1e200  # (a plane FAR away: no triangle within reach)
        assert np.array_equal(near, held[:, 0] > -1e200) and 50 < near.sum() < len(x)
        assert np.abs(wall.heights(x, t)[near] - still.heights(x)[near]).max() <= 1e-14
        assert np.abs(moving[near, 1:4] - held[near, 1:4]).max() <= 1e-14
        q = x - wall.heights(x, t)[:, None] * moving[:, 1:4]
        shift, speed = wall.displacement(t)
        rigid = speed + 0.8 * np.cross(axis, q - wall.point - shift)
        assert np.abs(moving[near, 4:7] - rigid[near]).max() <= 1e-14


def test_a_turntable_carries_a_rolling_sphere_round_at_two_sevenths_of_its_rate():
    """A sphere let go at rest on a disc mesh turning at Omega: friction drags it until it rolls without
    slipping, its contact point moving with the disc's surface (Omega z x (q - c), to 1e-3 of the speed
    there: the tangential spring's creep); then its centre circles at 2 Omega / 7 (a solid sphere rolling
    on a turntable: Omega I / (I + m R^2)), measured from the turn of its velocity to 0.5 % (2.9e-4
    measured). The time-step guards take the disc's rim speed as a wall's."""
    omega, segments = 1.0, 48
    angle = 2 * math.pi * np.arange(segments) / segments
    vertices = np.concatenate([[[0.0, 0.0, 0.0]], np.c_[5 * np.cos(angle), 5 * np.sin(angle), np.zeros(segments)]])
    k = np.arange(segments)
    disc = dk.MeshWall(vertices, np.c_[np.zeros(segments, dtype=int), 1 + k, 1 + (k + 1) % segments],
                       point=(0.0, 0.0, 0.0), axis=(0, 0, 1), angular_velocity=omega)
    p = dk.Particles(position=[[1.0, 0.0, R - G / 1e5]], radius=R, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1e5, 100.0, friction=dk.Friction(0.8)), disc, dk.Gravity((0, 0, -G))])
    assert disc.surface_speed() == pytest.approx(5.0 * omega)  # its rim: the guards' wall speed
    speed, why = dk.guards.fastest_impact(scene)
    assert speed >= 5.0 * omega and "moving wall" in why
    sim = dk.Simulation(scene, dk.VelocityVerlet(5e-4))
    sim.run(1.0, progress=False)
    run = sim.run(4.0, record_every=0.05, progress=False)
    c = scene.contacts()
    q, n = c.point[0], c.normal[0]
    slip = p.velocity[0] + np.cross(p.angular_velocity[0], -R * n) - omega * np.cross([0, 0, 1], q)
    assert np.linalg.norm(slip) <= 1e-3 * omega * np.linalg.norm(q[:2])
    u = disc.parameters_at(p.position)[0, 4:7]
    assert np.allclose(u, omega * np.cross([0, 0, 1], q), atol=1e-9)
    heading = np.unwrap(np.arctan2(run.velocity[:, 0, 1], run.velocity[:, 0, 0]))
    rate = np.polyfit(run.time, heading, 1)[0]
    assert rate == pytest.approx(2 * omega / 7, rel=5e-3)


def test_a_sphere_turning_with_a_turntable_mesh_feels_no_rolling_or_twisting_torque():
    """Rolling and twisting resistance act on the sphere's spin relative to the mesh's own, omega a: a
    sphere resting on a turning disc mesh (no gravity, pressed by nothing: touching it), moving and
    spinning with it as one rigid body (v = omega a x x, w = omega a, a along the normal: a spin the
    twisting spring would resist against a wall taken at rest), feels no friction, rolling or twisting
    torque, to round-off; one not spinning is twisted back (its torque along the normal 6e-4 after 20
    steps, against 1e-12)."""
    omega, segments = 1.5, 24
    angle = 2 * math.pi * np.arange(segments) / segments
    vertices = np.concatenate([[[0.0, 0.0, 0.0]], np.c_[5 * np.cos(angle), 5 * np.sin(angle), np.zeros(segments)]])
    k = np.arange(segments)
    triangles = np.c_[np.zeros(segments, dtype=int), 1 + k, 1 + (k + 1) % segments]
    contact = dk.KelvinVoigt(1e4, 20.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.1),
                             twisting=dk.TwistingResistance())
    x = np.array([1.0, 0.5, R - 1e-4])
    for spin, still in ((omega * np.array([0.0, 0.0, 1.0]), True), (np.zeros(3), False)):
        disc = dk.MeshWall(vertices, triangles, axis=(0, 0, 1), angular_velocity=omega)
        p = dk.Particles(position=[x], velocity=[omega * np.cross([0, 0, 1], x)], angular_velocity=[spin],
                         radius=R, mass=1.0)
        scene = dk.Scene(p, [contact, disc])
        if still:
            c = scene.contacts()
            assert len(c.overlap) == 1 and np.linalg.norm(c.torque_j[0]) < 1e-12
            assert np.linalg.norm(c.tangential_force[0]) < 1e-12
        else:
            dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(0.002, progress=False)
            assert abs(scene.contacts().torque_j[0][2]) > 1e-4  # (6e-4 measured after 20 steps)


def test_mesh_files_scene_files_outputs_and_restarts(tmp_path, capsys):
    """An STL written by meshio reads back as the same triangles; a scene file's [[interactions.mesh]]
    finds it beside the file; the cost and demkit info count its queries; the VTK series draws the triangles where the
    turning mesh stands at each frame (to 1e-12); a run resumed from a checkpoint gives the bits of one
    run; the LAMMPS export refuses it."""
    vertices, triangles = square(20, seed=3, size=3.0)
    meshio.write(tmp_path / "floor.stl", meshio.Mesh(vertices, [("triangle", triangles)]))
    wall = dk.MeshWall(file=tmp_path / "floor.stl", reach=R)
    assert np.allclose(wall.corners, vertices[triangles], atol=1e-6)  # (STL keeps float32)
    text = f"""
[particles]
position = [[0.0, 0.0, 0.6], [1.0, 0.5, 0.9]]
radius = {R}
mass = 1.0
[interactions.kelvin_voigt]
stiffness = 1e4
damping = 10.0
[interactions.friction]
coefficient = 0.5
[interactions.gravity]
acceleration = [0.0, 0.0, -10.0]
[[interactions.mesh]]
file = "floor.stl"
angular_velocity = 0.5
[integrator]
method = "VelocityVerlet"
dt = 1e-3
[run]
duration = 0.2
"""
    (tmp_path / "scene.toml").write_text(text)
    loaded = dk.load_scene(tmp_path / "scene.toml")
    mesh = next(e for e in loaded.scene.effects if isinstance(e, dk.MeshWall))
    assert mesh.triangle_count == len(triangles) and mesh.angular_velocity == 0.5
    estimate = dk.cost.estimate(loaded.scene, loaded.integrator, 0.2)
    assert estimate.parts["mesh walls"] > 0.0
    try:
        demkit_main(["info", str(tmp_path / "scene.toml")])
    except SystemExit as done:
        assert not done.code
    said = capsys.readouterr().out
    assert f"mesh          {len(triangles)} triangles, a grid of" in said and "mesh walls" in said

    def fresh():
        return dk.load_scene(tmp_path / "scene.toml").scene

    one = fresh()
    dk.Simulation(one, dk.VelocityVerlet(1e-3), writers=[dk.VTKWriter(tmp_path / "vtk", every=0.1)]).run(
        0.2, progress=False)
    first = fresh()
    dk.Simulation(first, dk.VelocityVerlet(1e-3), checkpoint=dk.Checkpoint(tmp_path / "c.npz")).run(0.1, progress=False)
    again = fresh()
    dk.Simulation(again, dk.VelocityVerlet(1e-3)).resume(tmp_path / "c.npz").run(0.1, progress=False)
    assert again.particles.position.tobytes() == one.particles.position.tobytes()
    assert again.particles.angular_velocity.tobytes() == one.particles.angular_velocity.tobytes()
    series = dk.read_series(tmp_path / "vtk")
    assert len(series.walls) == 3
    last = pytest.importorskip("pyvista").read(series.walls[-1])
    drawn = np.asarray(last.points)[np.asarray(last.faces).reshape(-1, 4)[:, 1:]]  # each triangle's corners
    assert last.n_cells == len(triangles) and last.n_points == len(vertices)  # (its vertices shared)
    assert np.abs(drawn - mesh.corners_at(0.2)).max() <= 1e-12
    with pytest.raises(ValueError, match="LAMMPS has no triangle-mesh walls"):
        dk.export_lammps(one, dk.VelocityVerlet(1e-3), tmp_path / "lmp")


def test_bad_meshes_are_refused_with_the_reason(tmp_path):
    vertices, triangles = square(0)
    with pytest.raises(ValueError, match="has no triangles"):
        dk.MeshWall(vertices, np.zeros((0, 3), dtype=int))
    bad = vertices.copy()
    bad[2, 1] = math.nan
    with pytest.raises(ValueError, match="vertex 2 is not finite"):
        dk.MeshWall(bad, triangles)
    with pytest.raises(ValueError, match="triangle 1 .* is degenerate"):
        dk.MeshWall(np.concatenate([vertices, [[0.0, 0.0, 0.0]]]), [[0, 1, 2], [0, 4, 2]])
    with pytest.raises(ValueError, match="names vertex"):
        dk.MeshWall(vertices, [[0, 1, 7]])
    (tmp_path / "junk.stl").write_text("solid junk\n this is not a facet\n")
    with pytest.raises(ValueError, match="meshio cannot read the mesh file"):
        dk.MeshWall(file=tmp_path / "junk.stl")
    meshio.write(tmp_path / "quads.vtk", meshio.Mesh(vertices, [("quad", [[0, 1, 2, 3]])]))
    with pytest.raises(ValueError, match="holds quad cells: a mesh wall takes triangles only"):
        dk.MeshWall(file=tmp_path / "quads.vtk")
    with pytest.raises(ValueError, match="does not exist"):
        dk.MeshWall(file=tmp_path / "none.stl")
    p = dk.Particles(position=[[0.0, 0.0, 0.45]], radius=R, mass=1.0)
    with pytest.raises(ValueError, match="larger than the reach its grid was built for"):
        dk.Scene(p, [dk.KelvinVoigt(1e4, 1.0), dk.MeshWall(vertices, triangles, reach=0.4)])
    with pytest.raises(ValueError, match="periodic axis x"):
        dk.Scene(p, [dk.KelvinVoigt(1e4, 1.0), dk.MeshWall(vertices, triangles)],
                 box=dk.Box([20, 20, 20], [True, False, False]))
    p.position[0, 2] = 0.1
    with pytest.raises(ValueError, match="deep inside the mesh of 2 triangles"):
        dk.Scene(p, [dk.KelvinVoigt(1e4, 1.0), dk.MeshWall(vertices, triangles)])


def test_the_hopper_example_pours_spheres_through_its_outlet_and_none_through_its_wall(tmp_path):
    """examples/mesh_hopper in its --quick form, in this process, without its picture: the hopper read
    back from the STL it wrote, spheres through its outlet by the end and none through its wall."""
    import importlib.util
    from pathlib import Path
    script = Path(__file__).resolve().parents[1] / "examples" / "mesh_hopper" / "run.py"
    spec = importlib.util.spec_from_file_location("mesh_hopper_example", script)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    out = example.main(["--quick", "--no-picture", "--output", str(tmp_path)])
    assert out["hopper"].triangle_count == 2 * 2 * example.FACETS and (tmp_path / "hopper.stl").is_file()
    assert out["leaks"] == 0 and out["below"][0] == 0 and out["below"][-1] > 20  # 58 of 120 measured
