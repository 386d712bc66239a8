"""MagnetField in scene files: magpylib sources declared in TOML, the same scene as in Python."""
import math
import sys
import textwrap

import numpy as np
import pytest

import demkit as dk

magpylib = pytest.importorskip("magpylib")
from scipy.spatial.transform import Rotation  # noqa: E402

R = 0.0015
VOLUME = 4 / 3 * math.pi * R ** 3
MASS = 7500 * VOLUME
MOMENT = 1.2 * VOLUME / dk.units.MU0

FILE = textwrap.dedent(f"""\
    [particles]
    position = [[-0.018, 0.002, 0.016]]
    velocity = [[6.0, 0.0, 0.0]]
    radius = {R!r}
    mass = {MASS!r}
    dipole = [[0.0, 0.0, {MOMENT!r}]]
    angular_velocity = [[0.0, 50.0, 0.0]]

    [[interactions.magnet_field]]
    region = [[-0.02, -0.02, 0.005], [0.02, 0.02, 0.02]]
    spacing = 0.002

    [[interactions.magnet_field.source]]
    kind = "cylinder"
    polarization = [0.0, 0.0, 1.2]
    dimension = [0.01, 0.005]

    [[interactions.magnet_field.source]]
    kind = "cuboid"
    magnetization = [8e5, 0.0, 0.0]
    dimension = [0.004, 0.006, 0.002]
    position = [0.0, 0.0, -0.01]
    rotation_vector = [0.0, 0.0, 0.3]

    [[interactions.magnet_field.source]]
    kind = "sphere"
    polarization = [0.0, 1.0, 0.0]
    diameter = 0.004
    position = [0.03, 0.0, 0.01]
    axis = [1.0, 1.0, 0.0]
    angle = 30.0

    [[interactions.magnet_field.source]]
    kind = "circle"
    current = 200.0
    diameter = 0.03
    position = [0.0, 0.0, 0.025]

    [integrator]
    dt = 1e-5

    [run]
    duration = 0.002
    record_every = 5e-4
    """)


def in_python():
    sources = [
        magpylib.magnet.Cylinder(polarization=(0, 0, 1.2), dimension=(0.01, 0.005)),
        magpylib.magnet.Cuboid(magnetization=(8e5, 0, 0), dimension=(0.004, 0.006, 0.002), position=(0, 0, -0.01),
                               orientation=Rotation.from_rotvec([0, 0, 0.3])),
        magpylib.magnet.Sphere(polarization=(0, 1.0, 0), diameter=0.004, position=(0.03, 0, 0.01),
                               orientation=Rotation.from_rotvec(math.radians(30.0) * np.array([1, 1, 0]) / math.sqrt(2))),
        magpylib.current.Circle(current=200.0, diameter=0.03, position=(0, 0, 0.025))]
    field = dk.MagnetField(sources, region=((-0.02, -0.02, 0.005), (0.02, 0.02, 0.02)), spacing=0.002)
    p = dk.Particles(position=[[-0.018, 0.002, 0.016]], velocity=[[6.0, 0, 0]], radius=R, mass=MASS,
                     dipole=[[0, 0, MOMENT]], angular_velocity=[[0, 50.0, 0]])
    return dk.Scene(p, [field]), sources


def test_a_magnet_field_file_is_the_python_scene_bit_for_bit():
    loaded = dk.parse_scene(FILE)
    field = loaded.scene.effects[0]
    assert isinstance(field, dk.MagnetField) and field.cells.tolist() == [20, 20, 8]
    scene, sources = in_python()
    assert np.array_equal(field.table_values(), scene.effects[0].table_values())
    points = np.random.default_rng(1).uniform(*field.region, size=(50, 3))
    exact = sum(s.getB(points) for s in sources)
    assert np.abs(field.field(points) - exact).max() < 0.01 * np.abs(exact).max()  # the table is of these sources
    a = dk.Simulation(loaded.scene, loaded.integrator).run(duration=0.002, record_every=5e-4)
    b = dk.Simulation(scene, dk.VelocityVerlet(dt=1e-5)).run(duration=0.002, record_every=5e-4)
    for name in ("time", "position", "velocity", "angular_velocity", "dipole"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.array_equal(a.energy["field"], b.energy["field"]) and np.ptp(a.energy["field"]) > 0


def test_si_scene_takes_its_field_units_from_the_scales():
    text = 'units = "si"\n[scales]\nmass = 1e-3\nradius = 1.5e-3\nstiffness = 1e4\ndipole_moment = 0.01\n' + FILE
    loaded = dk.parse_scene(text)
    units, field = loaded.units, loaded.scene.effects[0]
    assert field.length_unit == pytest.approx(units.length, rel=1e-14)
    assert field.region[0, 2] == pytest.approx(0.005 / units.length, rel=1e-12)
    point = np.array([0.001, 0.002, 0.01])  # metres: the scene's field there, in tesla, is magpylib's
    exact = sum(s.getB(point) for s in in_python()[1])
    assert field.field(point / units.length) * field.field_unit == pytest.approx(exact, rel=1e-3, abs=1e-4)
    with pytest.raises(dk.SceneFileError, match=r"magnet_field\[0\].length_unit: is set from \[scales\]"):
        dk.parse_scene(text.replace("spacing = 0.002", "spacing = 0.002\nlength_unit = 1.0"))


@pytest.mark.parametrize("change, message", [
    (('kind = "cuboid"', 'kind = "cubiod"'),
     "m.toml:19: interactions.magnet_field[0].source[1].kind: must be one of 'cuboid', 'cylinder', 'sphere', 'circle', "
     "'dipole', got 'cubiod'; did you mean 'cuboid'?"),
    (('kind = "circle"', 'kind = "coil"'), "m.toml:34: interactions.magnet_field[0].source[3].kind: must be one of "
                                           "'cuboid', 'cylinder', 'sphere', 'circle', 'dipole', got 'coil'; did you "
                                           "mean 'circle'?"),
    (("dimension = [0.01, 0.005]", "dimension = [0.01, 0.005, 0.002]"),
     "m.toml:16: interactions.magnet_field[0].source[0].dimension: must be a list of 2 numbers"),
    (("polarization = [0.0, 0.0, 1.2]", "polarization = [0.0, 0.0, 1.2]\nmagnetization = [0.0, 0.0, 1e6]"),
     "m.toml:16: interactions.magnet_field[0].source[0].magnetization: give only one of polarization, magnetization"),
    (("angle = 30.0", ""), "m.toml:25: interactions.magnet_field[0].source[2].angle: missing: an orientation by axis and angle"),
    (("polarization = [0.0, 1.0, 0.0]", "polarisation = [0.0, 1.0, 0.0]"),
     "m.toml:27: interactions.magnet_field[0].source[2].polarisation: unknown key; did you mean 'polarization'?"),
    (("spacing = 0.002", "spacing = 0"), "m.toml:11: interactions.magnet_field[0].spacing: must be positive"),
    (("[0.02, 0.02, 0.02]]", "[0.02, 0.02, 0.02], [0.0, 0.0, 0.0]]"),
     "m.toml:10: interactions.magnet_field[0].region: must be two corners"),
    (("0.005], [0.02", "-0.02], [0.02"), "m.toml:10: interactions.magnet_field[0].region: MagnetField region [[-0.02, -0.02, -0.02], [0.02, 0.02, 0.02]] contains magnet material"),
])
def test_bad_magnet_fields_are_one_error_at_their_key(change, message):
    with pytest.raises(dk.SceneFileError) as err:
        dk.parse_scene(FILE.replace(*change), source="m.toml")
    assert str(err.value).startswith(message), str(err.value)


def test_without_magpylib_the_file_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "magpylib", None)  # import magpylib raises ImportError
    with pytest.raises(dk.SceneFileError, match=r'm.toml:9: interactions.magnet_field\[0\]: needs magpylib, an '
                                                r'optional extra: pip install "demkit\[magnets\]"'):
        dk.parse_scene(FILE, source="m.toml")
