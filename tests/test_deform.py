"""Homogeneous deformation of a periodic box (dk.Deform, demkit.engine.deform): an affinely compressed
lattice against the stress of its bonds computed by hand, a free sphere's path against the affine flow's
exact solution, the lists against brute force while the box squeezes, exact restarts, LAMMPS' fix deform
(tests/test_lammps_export.py) and what a deforming box refuses."""
import math

import numpy as np
import pytest

import demkit as dk
from restart_scenes import assert_dipole_pairs_by_brute_force, assert_identical, state_of


def fcc(cells, spacing):
    """Sites of an fcc lattice of ``cells``^3 cubic cells of side ``spacing`` (4 a cell), inside [0, L)."""
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]]) + 0.25
    grid = np.array([(i, j, k) for i in range(cells) for j in range(cells) for k in range(cells)], float)
    return ((grid[:, None, :] + basis[None, :, :]).reshape(-1, 3)) * spacing


def bonds_stress(k, radius, cube):
    """The pressure tensor of an fcc crystal of Kelvin-Voigt spheres at rest, by hand: each sphere's six
    bonds r = (+-c_x, +-c_y, 0) / 2 ... (c: the deformed cubic cell's sides), each pressed by
    F = k (2 R - |r|) along r when shorter than 2 R, over the volume per sphere c_x c_y c_z / 4:
    P = (4 / (c_x c_y c_z)) sum over the six bonds of k (2 R - |r|) r r^T / |r|."""
    P = np.zeros((3, 3))
    for a, b in ((0, 1), (0, 2), (1, 2)):
        for sign in (1.0, -1.0):
            r = np.zeros(3)
            r[a], r[b] = 0.5 * cube[a], sign * 0.5 * cube[b]
            d = np.linalg.norm(r)
            if d < 2.0 * radius:
                P += k * (2.0 * radius - d) * np.outer(r, r) / d
    return 4.0 * P / np.prod(cube)


def test_an_affinely_compressed_fcc_crystal_has_the_stress_of_its_bonds():
    """108 spheres on an fcc lattice (bonds 0.1 % shorter than touching), the box compressed along x at
    1 %/s and drawn out along z at 0.5 %/s for 2 s: by symmetry every sphere stays on its (remapped)
    site, so the crystal deforms affinely and the StressSeries' pressure tensor at each sample is the
    bonds' by hand (bonds_stress) to round-off (1e-12 relative: each sample is a sum of 648 bond
    forces), the shear components zero; P_yy grows through the bonds in the xy plane (C_12 of the
    crystal), less than P_xx, more than P_zz. The spheres stay at rest (to round-off, 1e-8)."""
    R, k, cells = 0.5, 1000.0, 3
    spacing = 2.0 * R * math.sqrt(2.0) * 0.999
    pos = fcc(cells, spacing)
    p = dk.Particles(position=pos, velocity=np.zeros_like(pos), radius=R, mass=1.0)
    deform = dk.Deform(x=-0.01, z=0.005)
    box = dk.Box(cells * spacing, periodic=True, deform=deform)
    series = dk.StressSeries(every=0.25)
    sim = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(k, 2.0)], box=box), dk.VelocityVerlet(2e-3), writers=[series])
    sim.run(2.0, progress=False)
    assert len(series.time) == 9
    for t, P in zip(series.time, series.pressure_tensor):
        cube = box.size_at(t) / cells
        truth = bonds_stress(k, R, cube)
        assert np.abs(P - truth).max() < 1e-12 * np.abs(truth).max()
    first, last = bonds_stress(k, R, box.size / cells), bonds_stress(k, R, box.size_at(2.0) / cells)
    assert last[0, 0] > 5 * first[0, 0] and last[0, 0] > last[1, 1] > last[2, 2]  # pressed along x, drawn out along z
    assert np.abs(sim.scene.particles.velocity).max() < 1e-8  # (round-off of forces ~20: 3e-10 measured)
    assert sim.scene.arrays["box"][0] == box.size_at(2.0)[0]  # the same bits as Python's L0 (1 + rate t)


def test_a_free_sphere_follows_the_affine_flow():
    """Two spheres that never meet in a box compressed along x and stretched along y at rates +-0.2 for
    4 s, crossing the box faces: each step drifts x by v dt and remaps by L(t + dt) / L(t), so the
    unwrapped path is X_n = (X_{n-1} + v dt) (1 + r t_n) / (1 + r t_{n-1}) (to 1e-12), within O(dt) of the
    flow's exact solution X(t) = (1 + r t) (X0 + v ln(1 + r t) / r); its velocity (unwrapped_velocity)
    is v + r X / (1 + r t), the velocity in the state staying v (relative to the flow)."""
    rates = np.array([-0.2, 0.2, 0.0])
    x0 = np.array([[1.0, 2.0, 3.0], [6.0, 7.0, 8.0]])
    v = np.array([[-3.1, 2.3, 0.4], [2.9, -2.7, -0.3]])
    p = dk.Particles(position=x0, velocity=v, radius=0.3, mass=1.0)
    box = dk.Box(10.0, periodic=True, deform=dk.Deform(*rates))
    dt, steps = 1e-3, 4000
    traj = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(100.0, 0.0)], box=box), dk.VelocityVerlet(dt)).run(
        steps * dt, record_every=0.5, progress=False)
    X = traj.unwrapped()
    assert np.abs(traj.image[-1]).max() >= 1  # the spheres crossed the faces
    path = x0.copy()
    for n in range(1, steps + 1):
        path = (path + v * dt) * (1.0 + rates * n * dt) / (1.0 + rates * (n - 1) * dt)
    assert np.abs(X[-1] - path).max() < 1e-12 * 10
    t = traj.time[:, None, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        exact = np.where(rates != 0, (1 + rates * t) * (x0 + v * np.log1p(rates * t) / np.where(rates, rates, 1)),
                         x0 + v * t)
    assert np.abs(X - exact).max() < 5 * dt * np.abs(v).max()
    np.testing.assert_array_equal(traj.velocity[-1], v)
    np.testing.assert_allclose(traj.unwrapped_velocity()[-1], v + rates / (1 + rates * 4.0) * X[-1], rtol=1e-14)


def squeezed_gas(tier=None, n=120, rate=-0.3, skin=None, sort_every=40):
    """A frictional magnetic gas (restart_scenes' spheres) compressed fast along x, drawn out along z."""
    rng = np.random.default_rng(3)
    box = dk.build.box_for(n, 0.5, 0.2)
    x = dk.build.random_packing(n, 0.5, box, seed=rng)
    p = dk.Particles(position=x, velocity=dk.build.thermal_velocities(n, 4.0, 1.0, seed=rng), radius=0.5, mass=1.0,
                     dipole=0.7 * dk.build.random_directions(n, seed=rng), angular_velocity=np.zeros((n, 3)))
    contact = dk.KelvinVoigt(2000.0, 3.0, friction=dk.Friction(0.4))
    box = dk.Box(box.size, periodic=True, deform=dk.Deform(x=rate, z=0.5))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0), contact], box=box, skin=skin, sort_every=sort_every,
                    tier=tier)


def test_the_lists_hold_every_pair_while_the_box_squeezes():
    """Compressed by 1 %/0.01 s with a thin skin (0.05), the pairs the dipole loop acts on are exactly
    those within its cutoff by brute force over all pairs at the box's lengths now (1e-9 of the cutoff
    left for rounding at the edge), their separations the brute force's to round-off; the remap's
    squeeze counts against the skin, so the lists were rebuilt as the box shrank."""
    scene = squeezed_gas(rate=-1.0, skin=0.05, sort_every=None)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    for _ in range(5):
        sim.run(duration=0.02, progress=False)
        assert_dipole_pairs_by_brute_force(scene, 3.0)
    assert scene.box.size_at(scene.time)[0] < 0.91 * scene.box.size[0]
    assert scene.counters[0] >= 10, "the lists were rebuilt as the box squeezed"


def test_a_stopped_and_resumed_deforming_run_is_bit_identical(tmp_path):
    """The box lengths come from the clock and the lengths of the lists' last build are saved with the
    state: a run stopped twice and resumed in new scenes gives the uninterrupted run's bits (re-sorting
    every 40 steps, friction history, wraps, the box itself)."""
    until = 0.3
    scene = squeezed_gas()
    dk.Simulation(scene, dk.VelocityVerlet(2e-3)).run(until=until, progress=False)
    truth = state_of(scene)
    path = tmp_path / "deform.ckpt"
    for k, end in enumerate([0.062, 0.2, until]):
        again = squeezed_gas()
        vtk = dk.VTKWriter(tmp_path / "vtk", every=0.02, trails=False, resume=k > 0)
        sim = dk.Simulation(again, dk.VelocityVerlet(2e-3), checkpoint=dk.Checkpoint(path), writers=[vtk])
        if k:
            sim.resume()
        sim.run(until=end, progress=False)
    assert truth["image"].any(), "spheres crossed the faces"
    assert_identical(state_of(again), truth)
    assert again.arrays["box"].tobytes() == scene.arrays["box"].tobytes()
    # the box's outline at every frame (particles_box.pvd, demkit.io.box_outline), continued by the resumed runs
    # as the spheres' series is: one outline per frame, each the box of its frame's time
    import pyvista as pv
    read = dk.read_series(tmp_path / "vtk")
    outlines = pv.get_reader(str(tmp_path / "vtk" / "particles_box.pvd"))
    # (16 frames every 0.02 and the end of the first run, 0.062)
    assert np.allclose(outlines.time_values, read.time, rtol=0, atol=1e-12) and len(read.time) == 17
    for t in read.time:
        outlines.set_active_time_value(t)
        mesh = outlines.read()[0]
        size = again.box.size_at(t)
        assert np.array_equal(mesh.field_data["box_size"], size) and mesh.n_cells == 12
        assert np.allclose(mesh.bounds, [0, size[0], 0, size[1], 0, size[2]], rtol=0, atol=1e-12)
        assert np.array_equal(np.bincount(mesh.cell_data["axis"]), [4, 4, 4])
    assert again.box.size_at(read.time[-1])[0] < 0.95 * again.box.size_at(0.0)[0]  # (the outline moved)


def test_setting_the_time_remaps_the_spheres_into_the_box_of_that_time():
    """scene.time = t puts the kernels' box at L(t) and the spheres at the same fractions of it (what
    checkpoints and the LAMMPS export rely on); measurements divide by that box's volume."""
    scene = squeezed_gas(sort_every=None)
    x = scene.particles.position.copy()
    scene.time = 0.2
    L = scene.box.size_at(0.2)
    assert np.array_equal(scene.arrays["box"], L)
    np.testing.assert_allclose(scene.particles.position, x * L / scene.box.size, rtol=1e-15)
    assert dk.measure.stress(scene).volume == pytest.approx(np.prod(L), rel=1e-15)


def test_bad_deformation_is_refused():
    with pytest.raises(ValueError, match="at least one axis"):
        dk.Deform()
    with pytest.raises(ValueError, match="rate x must be finite"):
        dk.Deform(x=float("nan"))
    with pytest.raises(ValueError, match="rate y must be a number"):
        dk.Deform(y="fast")
    with pytest.raises(ValueError, match="axis z deforms but is not periodic"):
        dk.Box(10.0, periodic=(True, True, False), deform=dk.Deform(z=0.1))
    with pytest.raises(ValueError, match="shear and deform together"):
        dk.Box(10.0, periodic=True, shear=dk.Shear(1.0), deform=dk.Deform(z=0.1))
    with pytest.raises(ValueError, match="demkit.Deform"):
        dk.Box(10.0, periodic=True, deform=0.1)
    with pytest.raises(ValueError, match="need the time"):
        dk.Box(10.0, periodic=True, deform=dk.Deform(x=0.1)).minimum_image(np.ones(3))
    assert repr(dk.Box(10.0, periodic=True, deform=dk.Deform(y=-0.5))).endswith("deform=Deform(y=-0.5))")


def test_what_a_deforming_box_does_not_do_is_refused():
    box = dk.Box(10.0, periodic=(True, True, False), deform=dk.Deform(x=-0.1))
    pos = np.array([[2.0, 2.0, 2.0], [5.0, 5.0, 5.0]])
    p = dk.Particles(position=pos, velocity=np.zeros((2, 3)), radius=0.5, mass=1.0, dipole=[[0, 0, 1.0]] * 2)
    cubic = dk.Box(10.0, periodic=True, deform=dk.Deform(x=-0.1))
    with pytest.raises(ValueError, match="tuned to a fixed box"):
        dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0, long_range=dk.Ewald(1e-4))], box=cubic)
    with pytest.raises(ValueError, match="Wall in a box deforming along x"):
        dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0), dk.Wall((0, 0, 0), (1, 0, 0))], box=cubic)
    # a wall across an axis that does not deform is fine: a floor under a box squeezed sideways
    scene = dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0), dk.Dipole(prefactor=1.0, cutoff=3.0),
                         dk.Wall((0, 0, 0), (0, 0, 1))], box=box)
    with pytest.raises(ValueError, match="not one the steps remap"):
        dk.Simulation(scene, dk.VelocityVerlet(1e-3, resolve_contacts=True))
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3))
    # L_x = 10 (1 - 0.1 t) reaches twice the dipoles' reach 3 at t = 4 (the run is refused before it steps)
    with pytest.raises(ValueError, match=r"not longer than twice the reach 3 \(reached at t = 4\)"):
        sim.run(5.0, progress=False)
    assert sim.step == 0
    sim.run(1.0, progress=False)
    assert scene.arrays["box"][0] == pytest.approx(9.0, rel=1e-15)


def info_of(text, folder, capsys):
    """What `demkit info` prints for the scene file ``text``."""
    from demkit.cli import main as demkit_main
    (folder / "scene.toml").write_text(text)
    try:
        demkit_main(["info", str(folder / "scene.toml")])
    except SystemExit as done:
        assert not done.code
    return capsys.readouterr().out


def test_a_scene_file_deforms_its_box_as_the_python_scene_does(tmp_path, capsys):
    """[box.deform] builds dk.Deform: the file's scene steps to the bits of the Python scene, a bad rate is
    refused naming the key; a saved trajectory and a VTK series keep the deformation, so their unwrapped
    paths (position + image L(t)) are the run's and clusters read back take each frame's box; demkit info
    says what the run does to the box."""
    rows = lambda a: "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in a) + "]"  # noqa: E731
    pos = np.array([[1.0, 2.0, 3.0], [1.9, 2.1, 3.0], [6.0, 7.0, 8.0]])
    vel = np.array([[-3.1, 2.3, 0.4], [-3.0, 2.2, 0.5], [2.9, -2.7, -0.3]])
    text = f"""
[particles]
position = {rows(pos)}
velocity = {rows(vel)}
radius = 0.5
mass = 1.0
[box]
size = 10.0
periodic = true
[box.deform]
x = -0.2
y = 0.1
[interactions.kelvin_voigt]
stiffness = 1e3
damping = 2.0
[integrator]
method = "VelocityVerlet"
dt = 0.001
[run]
duration = 2.0
"""
    loaded = dk.parse_scene(text)
    assert loaded.scene.box.deform == dk.Deform(x=-0.2, y=0.1)
    python = dk.Scene(dk.Particles(position=pos, velocity=vel, radius=0.5, mass=1.0), [dk.KelvinVoigt(1e3, 2.0)],
                      box=dk.Box(10.0, periodic=True, deform=dk.Deform(x=-0.2, y=0.1)))
    writer = dk.VTKWriter(tmp_path / "vtk", every=0.25, trails=True)
    a = dk.Simulation(loaded.scene, dk.VelocityVerlet(1e-3), writers=[writer]).run(duration=2.0, record_every=0.25,
                                                                                   progress=False)
    b = dk.Simulation(python, dk.VelocityVerlet(1e-3)).run(duration=2.0, record_every=0.25, progress=False)
    assert a.position.tobytes() == b.position.tobytes() and a.velocity.tobytes() == b.velocity.tobytes()
    assert np.abs(a.image).max() >= 1
    with pytest.raises(dk.SceneFileError, match="box.deform.x"):
        dk.parse_scene(text.replace("x = -0.2", 'x = "fast"'))
    from demkit.scenefile.running import load_trajectory, save_trajectory
    save_trajectory(a, tmp_path / "run.npz")
    again = load_trajectory(tmp_path / "run.npz")
    assert again.box == a.box and np.array_equal(again.unwrapped(), a.unwrapped())
    series = dk.read_series(tmp_path / "vtk")
    assert series.box == a.box
    np.testing.assert_allclose(series.unwrapped(), a.unwrapped(), rtol=0, atol=1e-12)
    from demkit import clustering
    for k in range(len(series.time)):
        ours = clustering.clusters(a.position[k], a.radius, a.box, gap=0.05, time=a.time[k])
        read = clustering.clusters(series.position[k], series.radius, series.box, gap=0.05, time=series.time[k])
        assert np.array_equal(ours, read)
    said = info_of(text, tmp_path, capsys)
    assert ("deform        x at -0.2, y at 0.1: the box 10 x 10 x 10 becomes 6 x 12 x 10 by t = 2 (volume x 0.72), "
            "the positions remapped affinely after each step") in said, said


def servo_packing(rate=0.03, every=0.05, pressure=50.0, n=250, friction=None):
    """250 bidisperse spheres (examples/jamming's gas) at volume fraction 0.3 in a box a PressureServo
    drives to ``pressure`` on every axis."""
    radius = np.where(np.arange(n) % 2 == 0, 0.5, 0.7)
    side = (np.sum(4.0 / 3.0 * np.pi * radius ** 3) / 0.3) ** (1.0 / 3.0)
    pos = dk.build.random_packing(n, radius, dk.Box(side, periodic=True), seed=2)
    p = dk.Particles(position=pos, velocity=np.zeros((n, 3)), radius=radius, mass=(radius / 0.5) ** 3,
                     angular_velocity=np.zeros((n, 3)))
    servo = dk.PressureServo(pressure, max_rate=rate, every=every)
    box = dk.Box(side, periodic=True, deform=dk.Deform(servo=servo))
    law = dk.KelvinVoigt(1e4, 30.0, friction=dk.Friction(0.3) if friction is None else (friction or None))
    return dk.Scene(p, [law], box=box)


def test_a_pressure_servo_brings_a_gas_to_a_packing_at_its_pressure(tmp_path):
    """From a gas at 0.3 the servo shrinks the box at its largest rate (the stress far below the target),
    the spheres jam, and the normal stresses settle on the target, 50 on each axis (within 1 % over the
    last 4 time units: the loop's gain max_rate / p * K * every ~ 0.2 for this packing's stiffness K);
    the box's history gives back the compiled box at every frame (Box.size_at, the same bits), and
    a VTK series and a saved trajectory keep that history (their unwrapped paths are the run's)."""
    scene = servo_packing()
    series = dk.StressSeries(every=0.5)
    vtk = dk.VTKWriter(tmp_path / "vtk", every=2.0, trails=False)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1.5e-3), writers=[series, vtk])
    traj = sim.run(24.0, record_every=2.0, progress=False)
    history = scene.box.deform.history
    steps = round(0.05 / 1.5e-3)  # (every, in whole steps: 33)
    assert len(history) == round(24.0 / 1.5e-3) // steps + 1 and np.all(np.diff(history[:, 0]) > 0)
    assert np.all(history[:20, 4:] < -0.0299)  # a gas: nearly full speed ahead (its pressure ~1e-3 of the target)
    late = series.time >= 20.0
    diagonal = np.diagonal(series.pressure_tensor[late], axis1=1, axis2=2)
    assert np.abs(diagonal / 50.0 - 1.0).max() < 0.01, diagonal
    fraction = np.sum(4.0 / 3.0 * np.pi * scene.particles.radius ** 3) / scene.box.volume_at(sim.time)
    assert 0.57 < fraction < 0.66  # jammed: friction 0.3 between 0.58 and 0.64 (Silbert 2010), a little compressed
    assert scene.box.size_at(sim.time).tobytes() == scene.arrays["box"].tobytes()
    sizes = scene.box.size_at(np.asarray(traj.time)[:, None])  # each frame's box: the frames wrapped into it
    assert np.all(traj.position >= 0.0) and np.all(traj.position < sizes)
    read = dk.read_series(tmp_path / "vtk")
    assert np.array_equal(read.box.size_at(read.time), scene.box.size_at(read.time))
    np.testing.assert_allclose(read.unwrapped(), traj.unwrapped(), rtol=0, atol=1e-12)
    from demkit.scenefile.running import load_trajectory, save_trajectory
    save_trajectory(traj, tmp_path / "run.npz")
    assert np.array_equal(load_trajectory(tmp_path / "run.npz").unwrapped(), traj.unwrapped())


def test_a_servo_driven_run_split_or_resumed_gives_the_same_bits(tmp_path):
    """The servo changes the rates on the step grid (every 33 steps): one run to t = 3, two runs split off
    the grid (at 1.23), and a run stopped twice and resumed from checkpoints in new scenes give the same
    bits, the box's history too."""
    def state(scene):
        return state_of(scene), scene.box.deform.history.copy(), scene.arrays["box"].copy()

    one = servo_packing(rate=0.3)
    dk.Simulation(one, dk.VelocityVerlet(1.5e-3)).run(until=3.0, progress=False)
    truth = state(one)
    two = servo_packing(rate=0.3)
    sim = dk.Simulation(two, dk.VelocityVerlet(1.5e-3))
    sim.run(until=1.23, progress=False)
    sim.run(until=3.0, progress=False)
    path = tmp_path / "servo.ckpt"
    for k, end in enumerate([0.9, 2.1, 3.0]):
        again = servo_packing(rate=0.3)
        resumed = dk.Simulation(again, dk.VelocityVerlet(1.5e-3), checkpoint=dk.Checkpoint(path))
        if k:
            resumed.resume()
        resumed.run(until=end, progress=False)
    for scene in (two, again):
        got = state(scene)
        assert_identical(got[0], truth[0])
        assert got[1].tobytes() == truth[1].tobytes() and got[2].tobytes() == truth[2].tobytes()
    assert len(truth[1]) == 61 and np.ptp(truth[1][:, 4:]) > 0  # rates changed, not only at full speed


def test_bad_servos_are_refused():
    for bad in (dict(pressure=-1.0), dict(max_rate=float("nan")), dict(every=0.0), dict(pressure="high")):
        args = dict(pressure=1.0, max_rate=0.1, every=0.1) | bad
        with pytest.raises(ValueError, match=f"PressureServo {next(iter(bad))} must be a positive finite number"):
            dk.PressureServo(**args)
    with pytest.raises(ValueError, match="axes must name each of x, y, z at most once"):
        dk.PressureServo(1.0, 0.1, 0.1, axes="xx")
    used = servo_packing()
    dk.Simulation(used, dk.VelocityVerlet(1.5e-3)).run(0.1, progress=False)
    with pytest.raises(ValueError, match="this box's servo has driven another scene"):
        dk.Scene(used.particles, list(used.interactions), box=used.box)
    with pytest.raises(ValueError, match="Deform servo must be a demkit.PressureServo"):
        dk.Deform(servo=1.0)
    with pytest.raises(ValueError, match="axis z deforms but is not periodic"):
        dk.Box(10.0, periodic=(True, True, False), deform=dk.Deform(servo=dk.PressureServo(1.0, 0.1, 0.1)))
    assert dk.Deform(servo=dk.PressureServo(1.0, 0.1, 0.1, axes="zx")).axes == [0, 2]


def test_a_scene_file_drives_its_box_to_a_pressure(tmp_path, capsys):
    """[box.deform.servo] builds dk.PressureServo (a bad value refused naming the key), and demkit info
    says what the servo does."""
    text = """
[particles]
position = [[1.0, 1.0, 1.0], [3.0, 3.0, 3.0]]
velocity = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
radius = 0.5
mass = 1.0
[box]
size = 8.0
periodic = true
[box.deform]
z = 0.01
[box.deform.servo]
pressure = 2.0
max_rate = 0.01
every = 0.1
axes = "xy"
[interactions.kelvin_voigt]
stiffness = 1e3
damping = 2.0
[integrator]
method = "VelocityVerlet"
dt = 0.001
[run]
duration = 1.0
"""
    loaded = dk.parse_scene(text)
    assert loaded.scene.box.deform == dk.Deform(z=0.01, servo=dk.PressureServo(2.0, 0.01, 0.1, axes="xy"))
    with pytest.raises(dk.SceneFileError, match="box.deform.servo.pressure: must be positive"):
        dk.parse_scene(text.replace("pressure = 2.0", "pressure = -1.0"))
    said = info_of(text, tmp_path, capsys)
    assert ("deform        a servo drives x, y to the normal stress 2: strain rates up to 0.01, set every 0.1 from "
            "the stress measured then, z at 0.01") in said, said


def test_a_servo_that_would_shrink_the_box_too_far_stops_the_run_with_a_message():
    """One sphere alone feels no pressure, so its servo shrinks the box at the full rate until the next
    stretch would bring it to twice the contact's reach: the run stops there with a ValueError naming
    the axis, the length and the pressures, the state up to then kept."""
    p = dk.Particles(position=[[2.0, 2.0, 2.0]], velocity=[[0.0, 0.0, 0.0]], radius=0.5, mass=1.0)
    box = dk.Box(4.0, periodic=True, deform=dk.Deform(servo=dk.PressureServo(1.0, max_rate=0.5, every=0.1)))
    sim = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0)], box=box), dk.VelocityVerlet(1e-3))
    with pytest.raises(ValueError, match=r"the pressure servo would shrink the box along x to .* not longer than "
                                         r"twice the reach 1: .* \(measured 0, target 1\)"):
        sim.run(10.0, progress=False)
    assert 2.0 < sim.scene.arrays["box"][0] < 2.2 and 1.0 < sim.time < 1.6  # (0.95 of the box every 0.1)


def test_pictures_frame_the_largest_box_shown_and_outline_each_frames_box():
    """A picture or animation of a deforming box is framed by the largest box over the frames shown (the
    spheres of every frame inside it) and draws each frame's box (viz.plan.Framing.outline_at)."""
    from demkit.viz.plan import Framing
    p = dk.Particles(position=[[1.0, 2.0, 3.0], [6.0, 7.0, 8.0]], velocity=[[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]],
                     radius=0.5, mass=1.0)
    box = dk.Box(10.0, periodic=True, deform=dk.Deform(x=-0.2, y=0.1))
    traj = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0)], box=box), dk.VelocityVerlet(1e-3)).run(
        2.0, record_every=0.5, progress=False)
    framing = Framing(traj, "box", None, lambda k: np.ones(2, dtype=bool), range(len(traj.time)), 0.5)
    assert framing.moving and np.array_equal(framing.size, [10.0, box.size_at(2.0)[1], 10.0])
    for k, t in enumerate(traj.time):
        assert np.array_equal(framing.outline_at(k), [0.0, box.size_at(t)[0], 0.0, box.size_at(t)[1], 0.0, 10.0])


def test_a_servo_box_is_exported_to_lammps_only_with_a_note(tmp_path):
    """LAMMPS' barostats scale the box by other laws: the export refuses a pressure servo unless told
    otherwise, and then deforms the box at the rates the servo set last, noted in the deck."""
    scene = servo_packing(friction=False)  # (frictionless: no contact history LAMMPS could not start from)
    sim = dk.Simulation(scene, dk.VelocityVerlet(1.5e-3))
    sim.run(0.3, progress=False)
    with pytest.raises(ValueError, match="pressure servo: .* has no LAMMPS counterpart"):
        dk.export_lammps(scene, dk.VelocityVerlet(1.5e-3), tmp_path, duration=0.15)
    deck = dk.export_lammps(scene, dk.VelocityVerlet(1.5e-3), tmp_path, duration=0.15, strict=False).deck.read_text()
    start, rate = scene.box.deform.history[-1, [0, 4]]  # the servo's last change: r' = r / (1 + r (t - t_k))
    assert f"x erate {rate / (1.0 + rate * (scene.time - start)):.17g} " in deck and "# NOTE: pressure servo" in deck


def test_induced_moments_in_a_deforming_box_are_those_of_the_box_of_that_time():
    """Magnetisable spheres in a field, the box compressed along x and drawn out along z: after the run
    the moments solved at the state reached (conjugate gradients to 1e-13) equal those a scene in a
    fixed box of the deformed lengths solves at the same positions (1e-11 of the largest: the two
    solves' round-off), and differ from those in the box the run started in."""
    n, R = 60, 0.5
    size = dk.build.box_for(n, R, 0.15).size
    pos = dk.build.random_packing(n, R, dk.Box(size, periodic=True), seed=4)
    chi = np.where(np.arange(n) % 3 == 0, 0.0, 4.0)  # one in three permanent
    moment = np.zeros((n, 3))
    moment[chi == 0] = [0.0, 0.0, 0.5]

    def scene_in(box, position, dipole):
        p = dk.Particles(position=position, velocity=np.zeros((n, 3)), radius=R, mass=1.0, dipole=dipole,
                         susceptibility=chi)
        return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=2.5, induction=dk.Induction(1e-13, 300)),
                            dk.KelvinVoigt(1e3, 1.0), dk.UniformField((0.0, 0.0, 0.3))], box=box)

    scene = scene_in(dk.Box(size, periodic=True, deform=dk.Deform(x=-0.15, z=0.1)), pos, moment)
    dk.Simulation(scene, dk.VelocityVerlet(1e-3)).run(1.0, progress=False)
    scene.induce()
    now = scene.box.size_at(scene.time)
    state = scene.particles.position.copy(), scene.particles.dipole.copy()  # (the permanent moments turned)
    fixed = scene_in(dk.Box(now, periodic=True), *state)
    scale = np.abs(fixed.particles.dipole).max()
    assert np.abs(scene.particles.dipole - fixed.particles.dipole).max() < 1e-11 * scale
    before = scene_in(dk.Box(size * 1.2, periodic=True), *state)
    assert np.abs(before.particles.dipole - fixed.particles.dipole).max() > 1e-4 * scale


def test_a_langevin_bath_keeps_its_temperature_in_a_squeezed_box():
    """The remap leaves the velocities (relative to the affine flow) alone, so a bath keeps a dilute gas
    compressed 10 % along each axis at kT: m <v^2> / 3 over the run's second half within 6 % of kT = 1.5
    (200 spheres, 20 frames about 10 drag times apart in all: a statistical error of about 2 %)."""
    n = 200
    size = dk.build.box_for(n, 0.5, 0.02).size
    pos = dk.build.random_packing(n, 0.5, dk.Box(size, periodic=True), seed=5)
    p = dk.Particles(position=pos, velocity=np.zeros((n, 3)), radius=0.5, mass=1.0)
    box = dk.Box(size, periodic=True, deform=dk.Deform(x=-0.01, y=-0.01, z=-0.01))
    scene = dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0), dk.Langevin(1.5, 2.0, seed=1)], box=box)
    traj = dk.Simulation(scene, dk.VelocityVerlet(2e-3)).run(10.0, record_every=0.25, progress=False)
    late = np.asarray(traj.time) >= 5.0
    assert np.mean(np.sum(traj.velocity[late] ** 2, axis=2)) / 3.0 == pytest.approx(1.5, rel=0.06)


def test_the_unwrapped_velocity_in_a_servo_driven_box_is_the_paths_rate_of_change():
    """One sphere feels no pressure, so its servo shrinks the box at its full rate, changing the rates
    every 0.05 from the lengths then (the box's first rates are 0): the unwrapped path's central
    differences over two steps equal unwrapped_velocity (velocity + the servo's Ldot/L x) to 1e-4 (the
    remap after the drift: an O(rate v dt) = 6e-5 difference; frames next to a change of rates left out,
    where the difference straddles two rates), and differ from the velocity alone by far more."""
    p = dk.Particles(position=[[2.0, 3.0, 4.0]], velocity=[[0.3, -0.2, 0.1]], radius=0.5, mass=1.0)
    box = dk.Box(20.0, periodic=True, deform=dk.Deform(servo=dk.PressureServo(1.0, max_rate=0.2, every=0.05)))
    dt = 1e-3
    traj = dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(1e3, 1.0)], box=box), dk.VelocityVerlet(dt)).run(
        0.5, record_every=dt, progress=False)
    x, v, t = traj.unwrapped()[:, 0], traj.unwrapped_velocity()[:, 0], np.asarray(traj.time)
    slope = (x[2:] - x[:-2]) / (2 * dt)
    changes = box.deform.history[:, 0]
    steady = ~np.any((changes[None, :] > t[:-2, None] + 0.5 * dt) & (changes[None, :] < t[2:, None] + 0.5 * dt), axis=1)
    assert steady.sum() > 400 and len(changes) == 11
    assert np.abs(slope - v[1:-1])[steady].max() < 1e-4
    assert np.abs(traj.velocity[1:-1, 0] - slope).max() > 0.1  # the flow: 0.2 x ~ 0.4 along x
