"""Conical walls (demkit.Cone): hoppers, funnels and conical posts, checked against a brute-force nearest
point of the surface, a sphere settling in a hopper at the height its geometry and contact law give,
a sphere carried round a turning cone until it rolls with the surface, energy conservation, the plane
wall's law they reuse, scene files, VTK surfaces and (where lmp is installed) LAMMPS' region cone."""
import math
import shutil
import subprocess

import numpy as np
import pytest

import demkit as dk
from demkit.interactions.wall_motion import cone_plane

R, G = 0.5, 9.81
ALPHA = math.radians(30.0)


def nearest_by_sampling(x, apex, axis, alpha, s0, s1):
    """The nearest point of the cone's surface to x and its distance by brute force: the distances to a grid
    of 241 azimuths x 121 generator lengths, then to a grid over the 8 cells about the best point, four
    times (the last spacing ~1e-8 of the first)."""
    first = np.cross(axis, np.eye(3)[int(np.argmin(np.abs(axis)))])
    first /= np.linalg.norm(first)
    second = np.cross(axis, first)
    lo_phi, hi_phi, lo_s, hi_s = 0.0, 2 * math.pi, s0, s1
    for _ in range(5):
        phi = np.linspace(lo_phi, hi_phi, 241)
        s = np.linspace(lo_s, hi_s, 121)
        e = np.cos(phi)[:, None] * first + np.sin(phi)[:, None] * second
        points = apex + s[None, :, None] * (math.cos(alpha) * axis + math.sin(alpha) * e[:, None, :])
        distance = np.linalg.norm(points - x, axis=-1)
        i, j = np.unravel_index(np.argmin(distance), distance.shape)
        dphi, ds = 4 * (phi[1] - phi[0]), 4 * (s[1] - s[0])
        lo_phi, hi_phi = phi[i] - dphi, phi[i] + dphi
        lo_s, hi_s = max(s0, s[j] - ds), min(s1, s[j] + ds)
    return points[i, j], distance[i, j]


def test_the_plane_is_the_nearest_point_of_the_surface_by_brute_force(rng):
    """cone_plane against the nearest point found by dense sampling of the surface, for centres inside and
    outside a tilted, turning cone cut at both ends (face, rim and apex contacts): the distance from the
    plane equals the distance to the nearest sample (signed: positive on the spheres' side of the face),
    the foot of the normal is that sample, the surface's velocity there is omega a x (Q - apex).
    Measured: 2e-13 in the distance, 4e-7 in the point, 1e-7 in the velocity; tolerances 1e-11, 1e-6, 1e-6
    (a distance is flat at its minimum: the sampling finds it to round-off but its point only to ~1e-7)."""
    apex, axis = np.array([0.3, -1.0, 2.0]), np.array([1.0, 2.0, 2.0]) / 3.0
    kinds = set()
    for inside, lower in ((True, 0.0), (True, 1.0), (False, 0.0)):
        cone = dk.Cone(apex, 3 * axis, ALPHA, inside=inside, lower=lower, upper=4.0, angular_velocity=-0.7)
        s0, s1 = lower / math.cos(ALPHA), 4.0 / math.cos(ALPHA)
        x = apex + rng.normal(scale=2.0, size=(20, 3)) + 2.0 * axis
        rows = cone.planes(x)
        for k in range(len(x)):
            q, distance = nearest_by_sampling(x[k], apex, axis, ALPHA, s0, s1)
            plane, n, u = rows[k, 0], rows[k, 1:4], rows[k, 4:7]
            height = x[k] @ n - plane
            assert abs(abs(height) - distance) < 1e-11 * max(1.0, distance)
            assert np.linalg.norm(x[k] - height * n - q) < 1e-6  # the foot of the normal is the nearest point
            assert np.allclose(u, -0.7 * np.cross(axis, q - apex), atol=1e-6)
            r = x[k] - apex
            t = r @ axis * math.cos(ALPHA) + np.linalg.norm(r - (r @ axis) * axis) * math.sin(ALPHA)
            face = s0 <= t <= s1
            kinds.add("face" if face else "apex" if lower == 0.0 and t < 0 else "rim")
            if face:  # on the face the height is signed: inside h sin(alpha) - d cos(alpha)
                d = np.linalg.norm(r - (r @ axis) * axis)
                assert height == pytest.approx((1 if inside else -1) * ((r @ axis) * math.sin(ALPHA)
                                                                        - d * math.cos(ALPHA)), abs=1e-12)
        assert np.allclose(cone.heights(x), np.einsum("ij,ij->i", x, rows[:, 1:4]) - rows[:, 0])
    assert kinds == {"face", "rim", "apex"}
    # a centre on the axis: every direction across is as near; some unit normal at the distance h sin(alpha)
    plane, nx, ny, nz, *_ = cone_plane(*(apex + 2 * axis), *dk.Cone(apex, axis, ALPHA).shape_values())
    assert math.hypot(nx, ny, nz) == pytest.approx(1.0)
    assert (apex + 2 * axis) @ [nx, ny, nz] - plane == pytest.approx(2 * math.sin(ALPHA))


def test_bad_cones_are_refused():
    for kwargs, match in (({"half_angle": 0.0}, "half_angle"), ({"half_angle": math.pi / 2}, "half_angle"),
                          ({"lower": -1.0}, "lower"), ({"lower": 2.0, "upper": 1.0}, "lower < upper"),
                          ({"axis": (0, 0, 0)}, "zero length"), ({"inside": "yes"}, "inside"),
                          ({"angular_velocity": math.nan}, "angular_velocity")):
        args = {"apex": (0, 0, 0), "axis": (0, 0, 1), "half_angle": ALPHA, **kwargs}
        with pytest.raises(ValueError, match=match):
            dk.Cone(**args)
    p = dk.Particles(position=[[0.0, 0.0, 2.0]], radius=R, mass=1.0)
    law = dk.KelvinVoigt(1e4, 10.0, friction=dk.Friction(0.5), rolling=dk.RollingResistance(0.1))
    with pytest.raises(ValueError, match="no upper end"):
        dk.Scene(p, [dk.KelvinVoigt(1e4, 1.0), dk.Cone((0, 0, 0), (0, 0, 1), ALPHA, angular_velocity=1.0)])
    dk.Scene(p, [law, dk.Cone((0, 0, 0), (0, 0, 1), ALPHA, upper=3.0, angular_velocity=1.0)])  # (rolling: fine)
    with pytest.raises(ValueError, match="behind"):  # a sphere outside a hopper
        dk.Scene(dk.Particles(position=[[3.0, 0.0, 1.0]], radius=R, mass=1.0),
                 [dk.KelvinVoigt(1e4, 1.0), dk.Cone((0, 0, 0), (0, 0, 1), ALPHA)])
    box = dk.Box(10.0, periodic=[True, True, False])
    p = dk.Particles(position=[[5.0, 5.0, 2.0]], radius=R, mass=1.0)
    dk.Scene(p, [dk.KelvinVoigt(1e4, 1.0), dk.Cone((5, 5, 0), (0, 0, 1), ALPHA, upper=4.0)], box=box)
    for cone, x in ((dk.Cone((5, 5, 0), (0, 0, 1), ALPHA), 5.0), (dk.Cone((5, 5, 0), (0, 0, 1), ALPHA, upper=9.0), 5.0),
                    (dk.Cone((5, 5, 0), (0, 0, 1), ALPHA, upper=4.0, inside=False), 1.0)):
        with pytest.raises(ValueError, match="periodic axis x"):
            dk.Scene(dk.Particles(position=[[x, x, 2.0]], radius=R, mass=1.0), [dk.KelvinVoigt(1e4, 1.0), cone], box=box)


def hopper(k=1e5, position=(0.01, 0.0, 1.2), friction=None, omega=0.0, velocity=(0.0, 0.0, 0.0), gravity=G,
           upper=None):
    """One sphere of radius R, mass 1, in a hopper: apex at the origin, axis +z, half-angle 30 degrees,
    gravity -z, a critically damped Kelvin-Voigt contact."""
    p = dk.Particles(position=[position], velocity=[velocity], radius=R, mass=1.0)
    law = dk.KelvinVoigt(k, 2.0 * math.sqrt(k), friction=friction)
    return dk.Scene(p, [law, dk.Cone((0, 0, 0), (0, 0, 1), ALPHA, angular_velocity=omega, upper=upper),
                        dk.Gravity((0, 0, -gravity))])


def test_a_sphere_settles_in_a_hopper_on_its_axis_at_the_height_its_contact_gives():
    """A sphere let go off the axis of a hopper (alpha = 30 degrees) settles on the axis. It touches the
    cone at h = R / sin(alpha) from the apex; one point contact carries it (module docstring: the ring a
    centre on the axis touches is not a point-contact law's), pressed until its axial part balances the
    weight, k delta sin(alpha) = m g: the centre at h = (R - m g / (k sin(alpha))) / sin(alpha) = 0.9996076.
    The centre crosses the axis every step (the contact's side flips; measured 3e-7 from it at dt = 1e-4,
    about g dt^2 / tan(alpha)), and the dashpot, seeing that crossing's speed, lifts it by 8.6e-6 at
    dt = 1e-4 and 4.6e-6 at dt = 5e-5: an error of order dt that vanishes with it. Checked: the height
    within 1.2e-5, the lift halving with dt (ratio 1.6 to 2.4), 1e-6 from the axis; the contact's force."""
    k = 1e5
    delta = G / (k * math.sin(ALPHA))
    lift = []
    for dt in (1e-4, 5e-5):
        scene = hopper(k)
        dk.Simulation(scene, dk.VelocityVerlet(dt)).run(1.0, progress=False)
        x = scene.particles.position[0]
        lift.append(x[2] - (R - delta) / math.sin(ALPHA))
        assert abs(lift[-1]) < 1.2e-5 and math.hypot(x[0], x[1]) < 1e-6
    assert 1.6 < lift[0] / lift[1] < 2.4
    c = scene.contacts()
    assert len(c.overlap) == 1 and c.overlap[0] == pytest.approx(delta, rel=0.03)
    assert c.normal_force[0] * math.sin(ALPHA) == pytest.approx(G, rel=0.03)


def test_a_turning_cone_carries_a_sphere_round_rolling_with_its_surface():
    """A sphere on the face of a hopper turning at omega = 2.5 (6 above the apex, where friction holds it
    against gravity and its centrifugal force), carried round at the surface's speed but not spinning:
    friction spins it up until it rolls on the cone without slipping, the sphere's point touching the cone
    moving with the cone's surface there, v + w x (-R n) = omega a x Q (Q the contact point; a wrong
    surface velocity would keep it sliding). Measured after 4 s: 9e-5 of the surface speed (the tangential
    spring's creep); tolerance 2e-4; the contact not sliding; dissipation nearly stopped (the rolling
    sphere still wobbles round the cone slowly)."""
    omega, k, h = 2.5, 1e5, 6.0
    d = h * math.tan(ALPHA) - R / math.cos(ALPHA)  # touching the face
    scene = hopper(k, position=(d, 0.0, h), velocity=omega * np.cross([0, 0, 1], [d, 0, h]),
                   friction=dk.Friction(0.5), omega=omega, upper=10.0)
    traj = dk.Simulation(scene, dk.VelocityVerlet(1e-4)).run(4.0, record_every=0.5, progress=False)
    v, w = traj.velocity[-1, 0], traj.angular_velocity[-1, 0]
    c = scene.contacts()
    assert len(c.overlap) == 1 and not c.sliding[0] and c.normal_force[0] > 0.0
    surface = omega * np.cross([0, 0, 1], c.point[0])
    assert np.linalg.norm(v + np.cross(w, -R * c.normal[0]) - surface) < 2e-4 * np.linalg.norm(surface)
    lost = traj.energy["dissipated"]
    assert lost[2] > 0.1 and lost[-1] - lost[-5] < 0.02 * lost[-1]  # (it slid first; measured 0.17, then 0.5 %)
    assert np.linalg.norm(w) > 1.0  # spun up


def test_an_elastic_sphere_bouncing_in_a_cone_keeps_its_energy():
    """No damping, no friction, gravity: a sphere bouncing in a hopper (off its face, near the apex) keeps
    its energy to the integrator's second order: the largest deviation falls about 4x when the step is
    halved (measured 3.2; bound 2.5 to 5), 3.7e-4 of the energy at 50 steps per contact (bound 1e-3)."""
    k = 1e4
    contact_time = math.pi / math.sqrt(k)
    deviations = []
    for steps in (50, 100):
        p = dk.Particles(position=[[0.3, 0.1, 1.6]], velocity=[[2.0, 1.0, -1.0]], radius=R, mass=1.0)
        scene = dk.Scene(p, [dk.KelvinVoigt(k, 0.0), dk.Cone((0, 0, 0), (0, 0, 1), ALPHA), dk.Gravity((0, 0, -G))])
        traj = dk.Simulation(scene, dk.VelocityVerlet(contact_time / steps)).run(2.0, record_every=0.01,
                                                                                 progress=False)
        e = traj.energy["total"]
        deviations.append(np.max(np.abs(e - e[0])) / e[0])
        assert np.max(traj.energy["wall"]) > 0.05 * e[0]  # it did bounce
    assert deviations[0] < 1e-3 and 2.5 < deviations[0] / deviations[1] < 5.0


def test_a_cone_acts_as_the_plane_wall_tangent_to_it_where_the_sphere_touches():
    """A sphere pressed into a turning cone (tilted, cut at both ends) feels the force and torque of the
    plane wall tangent to the cone where it touches, sliding at the surface's velocity omega a x
    (Q - apex) there (Kelvin-Voigt with friction, the sphere moving and spinning; the tangent plane by
    hand): agreement to round-off."""
    law = dk.KelvinVoigt(1e4, 3.0, friction=dk.Friction(0.4))
    apex, axis = np.array([0.2, 0.1, -0.3]), np.array([0.0, 0.6, 0.8])
    side = np.cross(axis, [1.0, 0.0, 0.0])
    e = side / np.linalg.norm(side)
    g = math.cos(ALPHA) * axis + math.sin(ALPHA) * e
    normal = math.sin(ALPHA) * axis - math.cos(ALPHA) * e
    q = apex + 2.5 * g
    x = q + (R - 0.01) * normal
    p = dk.Particles(position=[x], velocity=[[0.3, -0.2, 0.1]], angular_velocity=[[1, 2, 3]], radius=R, mass=1.0)
    curved = dk.Scene(p, [law, dk.Cone(apex, axis, ALPHA, lower=0.5, upper=4.0, angular_velocity=1.3)])
    flat = dk.Scene(p, [law, dk.Wall(q, normal, velocity=1.3 * np.cross(axis, q - apex))])
    assert curved.contacts().overlap[0] == pytest.approx(0.01, rel=1e-10)
    for a, b in zip(curved.forces(), flat.forces()):
        assert np.allclose(a, b, rtol=1e-12, atol=1e-12)


def test_a_cone_from_a_scene_file_is_the_python_cone(tmp_path):
    """[[interactions.cone]] builds the same Cone (half_angle in degrees there), refusing unknown keys."""
    text = f"""
[particles]
position = [[0.0, 0.0, 1.5]]
radius = {R}
[interactions.kelvin_voigt]
stiffness = 1e5
damping = 600.0
[interactions.gravity]
acceleration = [0.0, 0.0, {-G}]
[[interactions.cone]]
apex = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
half_angle = 30.0
lower = 0.2
upper = 5.0
angular_velocity = 1.5
[integrator]
dt = 2e-4
[run]
duration = 0.1
"""
    (tmp_path / "hopper.toml").write_text(text)
    cone = dk.load_scene(tmp_path / "hopper.toml").scene.effects[-1]
    assert isinstance(cone, dk.Cone) and cone.inside and cone.upper == 5.0
    assert np.array_equal(cone.geometry_values(), dk.Cone((0, 0, 0), (0, 0, 1), math.radians(30.0), lower=0.2,
                                                          upper=5.0, angular_velocity=1.5).geometry_values())
    (tmp_path / "bad.toml").write_text(text.replace("half_angle = 30.0", "half_angle = 95.0"))
    with pytest.raises(ValueError, match="half_angle"):
        dk.load_scene(tmp_path / "bad.toml")


def test_the_walls_series_draws_the_cone_on_its_surface(tmp_path):
    """The VTK walls of a turning hopper cut at both ends: every corner lies on the cone (its distance from
    the axis h tan(alpha)), between its ends, turned by omega t."""
    from demkit.io.walls import FACETS, surfaces
    cone = dk.Cone((1.0, 2.0, 0.0), (0, 0, 1), ALPHA, lower=0.5, upper=3.0, angular_velocity=0.5)
    points, connectivity, offsets, cells = surfaces([(4, cone)], 0.7, np.array([-5.0, -5.0, -5.0]),
                                                    np.array([5.0, 5.0, 5.0]))
    r = points - [1.0, 2.0, 0.0]
    assert np.allclose(np.hypot(r[:, 0], r[:, 1]), r[:, 2] * math.tan(ALPHA))
    assert set(np.round(r[:, 2], 12)) == {0.5, 3.0} and len(offsets) == FACETS and set(cells["wall"]) == {4}
    first = math.atan2(r[0, 1], r[0, 0]) - 0.35
    assert abs(math.remainder(first, 2 * math.pi / FACETS)) < 1e-12
    unbounded = dk.Cone((0, 0, 0), (0, 0, 1), ALPHA)  # from the apex up to the region's top: triangles
    points, connectivity, offsets, _ = surfaces([(0, unbounded)], 0.0, np.zeros(3), np.full(3, 2.0))
    assert len(offsets) == FACETS and np.diff(offsets).max() == 3 and points[:, 2].max() == pytest.approx(2.0)


needs_lammps = pytest.mark.skipif(shutil.which("lmp") is None,
                                  reason="LAMMPS (lmp, Debian package 'lammps') is not installed")


def test_the_lammps_export_writes_an_axis_aligned_cone_and_refuses_the_others(tmp_path):
    law = dk.KelvinVoigt(2000.0, 2.0)
    p = dk.Particles(position=[[0.0, 0.0, -2.0]], radius=R, mass=1.0)
    cone = dk.Cone((0, 0, 0), (0, 0, -1), ALPHA, lower=0.5, upper=3.0, angular_velocity=2.0)
    deck = dk.export_lammps(dk.Scene(p, [law, cone]), dk.VelocityVerlet(1e-3), tmp_path, duration=1e-2).deck.read_text()
    tan = math.tan(ALPHA)
    assert (f"region      cone0 cone z 0 0 {3 * tan:.17g} {0.5 * tan:.17g} -3 -0.5 side in open 1 open 2 units box "
            f"rotate v_turn0 0 0 0 0 0 -1") in deck
    rolling = dk.KelvinVoigt(2000.0, 2.0, friction=dk.Friction(0.5, slip_radius="full", sliding="lammps"),
                             rolling=dk.RollingResistance(0.1, 10.0, 1.0))
    with pytest.raises(ValueError, match="relative to the turning wall's"):  # (LAMMPS' wall rolls against w alone)
        dk.export_lammps(dk.Scene(p, [rolling, cone]), dk.VelocityVerlet(1e-3), tmp_path / "r", duration=1e-2)
    for bad, reason in ((dk.Cone((0, 0, 0), (0, 1, 1), ALPHA, upper=3.0), "runs along x, y or z"),
                        (dk.Cone((0, 0, 0), (0, 0, -1), ALPHA), "upper end"),
                        (dk.Cone((0, 0, 0), (0, 0, -1), ALPHA, upper=3.0, velocity=(0.1, 0, 0)), "carried by")):
        with pytest.raises(ValueError, match=reason):
            dk.export_lammps(dk.Scene(p, [law, bad]), dk.VelocityVerlet(1e-3), tmp_path / "x", duration=1e-2)


@needs_lammps
@pytest.mark.parametrize("friction", [False, True], ids=["frictionless", "friction"])
def test_spheres_in_a_turning_hopper_agree_with_lammps_region_cone_to_round_off(tmp_path, friction):
    """Three spheres dropped into a hopper (axis z, half-angle 30 degrees, from 0.3 to 4 above the apex)
    turning at 2 rad/s, against LAMMPS' fix wall/gran/region on a region cone with open ends turned by
    'rotate', Hooke contacts, frictionless or with friction (slip_radius="full", LAMMPS' rules), 600
    steps: to round-off (measured over every step: 2e-15 in position and 5e-14 in velocity frictionless;
    3e-15, 8e-14 and 1.2e-13 in spin with friction). None touches at step 0 (LAMMPS' turning region stands still at its first step:
    tests/test_lammps_export.py's drum) and none nears the axis or the rims (where LAMMPS' cone differs:
    no contact on the axis, and none for centres beyond the ends)."""
    pos = [[0.8, 0.0, 2.6], [-0.4, 0.75, 2.7], [-0.3, -1.0, 3.0]]
    p = dk.Particles(position=pos, radius=[0.5, 0.48, 0.5], mass=[1.0, 0.9, 1.1], velocity=[[0.1, 0, 0], [0, 0, 0.05],
                     [0, 0.02, 0]], angular_velocity=[[0, 0, 1.0], [0, 0, 0], [0.5, 0, 0]])
    f = dk.Friction(0.5, slip_radius="full", sliding="lammps") if friction else None
    scene = dk.Scene(p, [dk.KelvinVoigt(2000.0, 2.0, friction=f), dk.Cone((0, 0, 0), (0, 0, 1), ALPHA, lower=0.3,
                                                                         upper=4.0, angular_velocity=2.0),
                         dk.Gravity([0, 0, -9.81])])
    dt, steps = 1e-3, 600
    files = dk.export_lammps(scene, dk.VelocityVerlet(dt), tmp_path, duration=steps * dt, record_every=dt)
    assert files.notes == ()
    done = subprocess.run(["lmp", "-in", files.deck.name, "-screen", "none", "-log", "log.lammps", "-nocite"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    frames = dk.lammps.read_dump(tmp_path / "state.dump")
    traj = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(steps * dt, record_every=dt, progress=False)
    last = frames[steps]
    assert np.abs(traj.position[-1] - last[:, 1:4]).max() < 1e-12
    assert np.abs(traj.velocity[-1] - last[:, 4:7]).max() < 1e-12
    assert np.abs(traj.angular_velocity[-1] - last[:, 7:10]).max() < 1e-12
    touched = np.hypot(traj.position[:, :, 0], traj.position[:, :, 1]) > traj.position[:, :, 2] * math.tan(ALPHA) - \
        np.array([0.5, 0.48, 0.5]) / math.cos(ALPHA)
    assert touched.any(axis=0).all()  # each sphere reached the cone
    if friction:
        assert np.abs(traj.angular_velocity[-1, :, 2]).max() > 0.5  # carried round


def elliptical_hertz_radius(a, b):
    """The exact Hertz contact radius R_x of two bodies whose gap is A x^2 + B y^2 (A <= B): the force
    at approach delta is 4/3 E* sqrt(R_x) delta^(3/2). From Johnson's elliptical solution (Contact
    Mechanics 4.2): the eccentricity e of the contact ellipse solves B/A = (E(e)/(1 - e^2) - K(e)) /
    (K(e) - E(e)); its semi-axis a_x = sqrt(delta (K - E) / (K e^2 A)) and P = (2 pi / 3) E* delta a_x / K."""
    from scipy.optimize import brentq
    from scipy.special import ellipe, ellipk
    if b - a < 1e-12 * b:
        return 1.0 / (2.0 * a)
    m = brentq(lambda m: (ellipe(m) / (1 - m) - ellipk(m)) / (ellipk(m) - ellipe(m)) - b / a, 1e-12, 1 - 1e-12)
    k, e = ellipk(m), ellipe(m)
    return (math.pi / 2 * math.sqrt((k - e) / (k * m * a)) / k) ** 2


@pytest.mark.parametrize("ratio", [5.0, 10.0, 20.0])
def test_a_curved_wall_s_hertz_contact_radius_is_within_its_documented_error(ratio):
    """The accuracy of the contact radius a Hertz law takes on a curved wall (docs/contacts.md). A sphere
    in a tube of radius R_c (surface curvatures 0 along the axis, -1/R_c across; +1/R_c outside) has the
    exact elliptical Hertz stiffness of radius R_x. A plane's R (demkit before) is off by about
    -+R/(4 R_c) (measured at R_c = 10 R: -2.62 %, +2.39 %); Johnson's equivalent radius sqrt(R' R'')
    is within 0.03 % there; the mean curvature 1/R_e = 1/R -+ 1/(2 R_c) that demkit takes (as LAMMPS'
    region walls) within 0.1 % (0.09 %, 0.08 %; 0.41 % and 0.28 % at R_c = 5 R)."""
    for side in (-1.0, 1.0):
        a, b = sorted((0.5, 0.5 * (1.0 + side / ratio)))  # (R = 1)
        exact = elliptical_hertz_radius(a, b)
        plane = math.sqrt(1.0 / exact) - 1.0
        assert plane == pytest.approx(side / (4.0 * ratio), rel=0.15)
        assert abs(math.sqrt(math.sqrt(1.0 / (4 * a * b)) / exact) - 1.0) < 0.03 / ratio ** 2
        assert abs(math.sqrt(1.0 / (a + b) / exact) - 1.0) < 0.12 / ratio ** 2
