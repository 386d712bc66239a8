"""TOML scene files: dk.load_scene / parse_scene, their errors, `demkit run` and `demkit info`."""
import math
import os
import random
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import demkit_in_process

import demkit as dk
from demkit.schema import key_lines

ROOT = Path(__file__).resolve().parent.parent
COLLISION = ROOT / "examples" / "two_magnets" / "collision.toml"
CLUSTER = ROOT / "examples" / "magnetic_cluster" / "cluster.toml"

SMALL = textwrap.dedent("""\
    title = "two spheres meet"

    [particles]
    position = [[0.0, 0.0, 0.0], [1.05, 0.0, 0.0]]
    velocity = [[0.1, 0.0, 0.0], [-0.1, 0.0, 0.0]]
    radius = 0.5
    mass = [1.0, 2.0]

    [interactions.kelvin_voigt]
    stiffness = 1000.0
    damping = 1.0

    [integrator]
    method = "VelocityVerlet"
    dt = 0.001

    [run]
    duration = 0.5
    record_every = 0.1
""")

GAS = textwrap.dedent("""\
    [particles.build]
    kind = "random_packing"
    n = 80
    radius = 0.5
    seed = 7
    moment = 0.8
    kT = 0.5
    spin_kT = 0.2

    [box]
    size = [12.0, 12.0, 8.0]
    periodic = [true, true, false]

    [interactions.dipole]
    prefactor = 1.0
    cutoff = 3.0

    [interactions.kelvin_voigt]
    stiffness = 2000.0
    damping = 5.0

    [interactions.friction]
    coefficient = 0.4

    [interactions.rolling_resistance]
    coefficient = 0.05

    [interactions.gravity]
    acceleration = [0.0, 0.0, -1.0]

    [[interactions.wall]]
    point = [0.0, 0.0, 0.0]
    normal = [0.0, 0.0, 1.0]

    [[interactions.wall]]
    point = [0.0, 0.0, 8.0]
    normal = [0.0, 0.0, -1.0]
    velocity = [0.1, 0.0, 0.0]

    [integrator]
    method = "VelocityVerlet"
    dt = 0.002

    [run]
    duration = 0.4
    record_every = 0.02
""")


def gas_in_python(**options):
    """The scene GAS describes, built with the Python API (``options``: dk.Scene's keywords)."""
    rng = np.random.default_rng(7)
    box = dk.Box([12.0, 12.0, 8.0], periodic=[True, True, False])
    x = dk.build.random_packing(80, 0.5, box, seed=rng)
    m = 0.8 * dk.build.random_directions(80, seed=rng)
    v = dk.build.thermal_velocities(80, kT=0.5, mass=1.0, seed=rng)
    w = dk.build.thermal_spins(80, kT=0.2, inertia=0.4 * 0.25, seed=rng)
    p = dk.Particles(position=x, velocity=v, radius=0.5, mass=1.0, dipole=m, angular_velocity=w)
    law = dk.KelvinVoigt(2000.0, 5.0, friction=dk.Friction(0.4), rolling=dk.RollingResistance(0.05))
    scene = dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=3.0), law, dk.Gravity([0, 0, -1.0]),
                         dk.Wall([0, 0, 0], [0, 0, 1]), dk.Wall([0, 0, 8.0], [0, 0, -1], velocity=[0.1, 0, 0])],
                     box=box, **options)
    return scene


def same(a, b):
    for name in ("time", "position", "velocity", "angular_velocity", "dipole", "image"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert np.array_equal(x, y), name
    for key in a.energy:
        assert np.array_equal(a.energy[key], b.energy[key]), key


def test_the_collision_file_is_the_papers_collision_bit_for_bit():
    loaded = dk.load_scene(COLLISION, overrides={"run.duration": 400.0})
    assert loaded.duration == 400.0 and loaded.record_every == 1.0
    a = dk.Simulation(loaded.scene, loaded.integrator).run(duration=400.0, record_every=1.0)
    b = dk.two_magnets.TwoMagnets(b_over_R=4.0).simulation(dt=0.01).run(duration=400.0, record_every=1.0)
    same(a, b)
    # an override reaches the builder: another impact parameter, other starting positions
    other = dk.load_scene(COLLISION, overrides={"particles.build.b_over_R": 2.0})
    assert other.scene.particles.position[1, 1] == pytest.approx(6.94)


def test_an_nbody_file_with_box_friction_walls_is_the_python_scene_bit_for_bit():
    loaded = dk.parse_scene(GAS)
    assert loaded.scene.box.periodic.tolist() == [True, True, False]
    a = dk.Simulation(loaded.scene, loaded.integrator).run(duration=0.4, record_every=0.02)
    b = dk.Simulation(gas_in_python(), dk.VelocityVerlet(dt=0.002)).run(duration=0.4, record_every=0.02)
    same(a, b)
    assert np.abs(a.angular_velocity[-1]).max() > 0 and a.image is not None


def test_the_scene_table_sets_skin_parallel_and_sorting_bit_for_bit():
    loaded = dk.parse_scene(GAS + "[scene]\nskin = 0.45\nparallel = true\nsort_every = 7\n")
    scene = loaded.scene
    assert (scene.skin, scene.parallel, scene.sort_every) == (0.45, True, 7)
    a = dk.Simulation(scene, loaded.integrator).run(duration=0.4, record_every=0.02)
    python = gas_in_python(skin=0.45, parallel=True, sort_every=7)
    b = dk.Simulation(python, dk.VelocityVerlet(dt=0.002)).run(duration=0.4, record_every=0.02)
    same(a, b)
    default = dk.parse_scene(GAS).scene  # no [scene]: dk.Scene's defaults
    assert (default.skin, default.parallel, default.sort_every) == (0.3, False, 0)


@pytest.mark.parametrize("table, message", [
    ("skin = -0.1", "gas.toml:48: scene.skin: must be positive, got -0.1"),
    ('skin = "0.3"', "gas.toml:48: scene.skin: must be a number, got a string ('0.3')"),
    ('parallel = "yes"', 'gas.toml:48: scene.parallel: must be true, false or "auto", got a string'),
    ("sort_every = 2.5", "gas.toml:48: scene.sort_every: must be a whole number, got a number (2.5)"),
    ("sort_every = -1", "gas.toml:48: scene.sort_every: must be zero or positive, got -1"),
    ("skni = 0.3", "gas.toml:48: scene.skni: unknown key; did you mean 'skin'?"),
])
def test_bad_scene_options_are_one_error_at_their_key(table, message):
    with pytest.raises(dk.SceneFileError) as err:
        dk.parse_scene(GAS + "[scene]\n" + table + "\n", source="gas.toml")
    assert str(err.value).startswith(message), str(err.value)


def test_scene_options_the_constructor_refuses_and_misplaced_ones():
    with pytest.raises(dk.SceneFileError, match=r"^s.toml:\d+: scene.sort_every: sort_every needs neighbour lists"):
        dk.parse_scene(SMALL + "[scene]\nsort_every = 10\n", source="s.toml")
    with pytest.raises(dk.SceneFileError, match=r"^s.toml:1: skin: unknown key; it belongs in \[scene\]"):
        dk.parse_scene("skin = 0.2\n" + SMALL, source="s.toml")


def test_a_dipole_without_its_prefactor_is_refused_in_plain_units():
    """Plain units take numbers as given: mu0/4pi = 1e-7 (SI's constant) is no default there."""
    text = GAS.replace("prefactor = 1.0\n", "")
    assert text != GAS
    with pytest.raises(dk.SceneFileError, match=r"^gas.toml:\d+: interactions.dipole.prefactor: is required in "
                                                r"plain units .*1/3 with unit moments"):
        dk.parse_scene(text, source="gas.toml")
    assert dk.parse_scene(GAS).scene.interactions[0].prefactor == 1.0


@pytest.mark.parametrize("text, value", [
    ("size = [12.0, 12.0, 8.0]", "size = [1e300, 12.0, 8.0]"),  # crashed the interpreter (cell counts)
    ("radius = 0.5", "radius = 1e300"), ("radius = 0.5", "radius = 1e-300"),  # OverflowError tracebacks
    ("duration = 0.4", "duration = 1e308"),
    ("[interactions.rolling_resistance]\ncoefficient = 0.05", "[interactions.rolling_resistance]\ncoefficient = 1e-300"),
])
def test_extreme_numbers_in_a_scene_file_are_one_error_or_a_scene(text, value):
    """Found by substituting 1e300, 1e-300, 1e308, inf, nan and 2^63 - 1 for every number of two scene
    files: each ends in a SceneFileError naming the key, or in a scene, never in another exception."""
    assert text in GAS
    try:
        dk.parse_scene(GAS.replace(text, value), source="gas.toml")
    except dk.SceneFileError as err:
        assert str(err).startswith("gas.toml:")
    p = dk.Particles(position=[[0.0, 0, 0], [1e300, 0, 0]], radius=0.5)
    with pytest.raises(ValueError, match="more than 1e\\+12 times the smallest radius"):
        dk.Scene(p, [dk.KelvinVoigt(1.0)])


def test_an_infinitely_heavy_sphere_or_a_vanishing_spring_sets_no_time_step():
    from demkit.interactions.contact import contact_duration
    assert contact_duration(0.0, 1.0, 1.0) == math.inf and contact_duration(1.0, 0.0, math.inf) == math.inf
    assert contact_duration(1e-300, 1.0, 1.0) > 1e149  # overdamped: over at pi / omega0
    assert contact_duration(1.0, 0.0, 1.0) == pytest.approx(math.pi)


def test_inline_particles_and_defaults():
    loaded = dk.parse_scene(SMALL)
    p = loaded.scene.particles
    assert p.mass.tolist() == [1.0, 2.0] and p.dipole is None
    assert loaded.data["integrator"]["resolve_contacts"] is False and loaded.data["box"] is None
    assert loaded.data["title"] == "two spheres meet"


def test_particles_from_csv_and_npz(tmp_path):
    (tmp_path / "s.csv").write_text("# two spheres\nx,y,z,vx,vy,vz,radius,fixed\n0,0,0,0,0,0,0.5,1\n1.05,0,0,-0.1,0,0,0.5,0\n")
    text = SMALL.replace('position = [[0.0, 0.0, 0.0], [1.05, 0.0, 0.0]]\nvelocity = [[0.1, 0.0, 0.0], [-0.1, 0.0, 0.0]]\n',
                         'file = "s.csv"\n')
    (tmp_path / "a.toml").write_text(text)
    p = dk.load_scene(tmp_path / "a.toml").scene.particles
    assert p.fixed.tolist() == [True, False] and p.velocity[1, 0] == -0.1 and p.mass.tolist() == [1.0, 2.0]
    np.savez(tmp_path / "s.npz", position=[[0, 0, 0], [1.05, 0, 0]], radius=[0.5, 0.5], dipole=np.eye(3)[:2])
    (tmp_path / "b.toml").write_text(text.replace("s.csv", "s.npz"))
    assert dk.load_scene(tmp_path / "b.toml").scene.particles.dipole[1].tolist() == [0, 1, 0]
    (tmp_path / "s.csv").write_text("x,y,z,radious\n0,0,0,1\n")
    with pytest.raises(dk.SceneFileError, match=r"a.toml:\d+: particles.file: .*unknown column 'radious'; did you mean 'radius'"):
        dk.load_scene(tmp_path / "a.toml")


def line(text, fragment):
    return 1 + text.splitlines().index(fragment)


@pytest.mark.parametrize("change, path, message", [
    (("prefactor", "prefator"), "interactions.dipole.prefator", "unknown key; did you mean 'prefactor'?"),
    (("cutoff = 3.0", 'cutoff = "3"'), "interactions.dipole.cutoff", "must be a number, got a string"),
    (("stiffness = 2000.0", "stiffness = -2000.0"), "interactions.kelvin_voigt.stiffness", "must be positive"),
    (("n = 80", "n = 80.5"), "particles.build.n", "must be a whole number"),
    (("size = [12.0, 12.0, 8.0]", "size = [12.0, 12.0]"), "box.size", "one number or three"),
    (("coefficient = 0.4", "coefficient = 1e400"), "interactions.friction.coefficient", "must be finite"),
    (('method = "VelocityVerlet"', 'method = "Leapfrog"'), "integrator.method", "unknown method 'Leapfrog'"),
    (('kind = "random_packing"', 'kind = "random_pack"'), "particles.build.kind", "did you mean 'random_packing'"),
    (("dt = 0.002", "dt = 0.5"), "integrator", "time step dt = 0.5 is too large"),
    (("normal = [0.0, 0.0, -1.0]", "normal = [0.0, 0.0, 0.0]"), "interactions.wall[1].normal", "zero length"),
])
def test_every_error_names_the_file_the_line_and_the_key(change, path, message):
    text = GAS.replace(*change)
    with pytest.raises(dk.SceneFileError) as err:
        dk.parse_scene(text, source="gas.toml")
    text_line = line(text, next(l for l in text.splitlines() if change[1] in l))
    if path == "integrator":
        text_line = line(text, "[integrator]")
    assert str(err.value).startswith(f"gas.toml:{text_line}: {path}: "), str(err.value)
    assert message in str(err.value)


def test_missing_tables_keys_and_rules():
    def error(text):
        with pytest.raises(dk.SceneFileError) as err:
            dk.parse_scene(text)
        return str(err.value)
    assert "integrator: missing: add a [integrator] table" in error(SMALL.split("[integrator]")[0] + "[run]\nduration=1.0\n")
    assert "run.duration: missing" in error(SMALL.replace("duration = 0.5", ""))
    assert "give one of position, file, build" in error(SMALL.replace("position =", "#"))
    assert "interactions.friction: needs a contact law" in error(
        SMALL.replace("[interactions.kelvin_voigt]\nstiffness = 1000.0\ndamping = 1.0", "[interactions.friction]\ncoefficient = 0.5"))
    assert "particles: radius must be positive" not in error(SMALL.replace("radius = 0.5", "radius = -0.5"))
    assert "particles.radius: must be positive, got -0.5" in error(SMALL.replace("radius = 0.5", "radius = -0.5"))
    assert "particles.velocity: velocity must have shape (2, 3)" in error(SMALL.replace("[-0.1, 0.0, 0.0]]", "]"))
    assert "overlap" in error(SMALL.replace("1.05, 0.0", "0.3, 0.0"))
    assert "<string>:2: not valid TOML" in error("x = 1\ny = = 2\n")


def test_overrides_apply_before_validation_and_unknown_ones_are_errors():
    loaded = dk.parse_scene(GAS, overrides={"interactions.dipole.prefactor": 0.5, "interactions.wall.1.velocity": [0.0, 0.2, 0.0],
                                            "integrator.dt": "auto"})
    assert loaded.scene.interactions[0].prefactor == 0.5 and loaded.scene.effects[2].velocity.tolist() == [0, 0.2, 0]
    choice = loaded.step_choice  # "auto": at most half the largest safe step (demkit.step_choice)
    assert choice.stable == 0.5 * dk.guards.largest_safe_step(loaded.scene)[0]
    assert loaded.integrator.dt == choice.dt <= choice.stable
    with pytest.raises(dk.SceneFileError, match=r"interactions.dipole.prefator: unknown key; did you mean 'prefactor'\? "
                                                r"\(set by override"):
        dk.parse_scene(GAS, overrides={"interactions.dipole.prefator": 0.5})
    with pytest.raises(dk.SceneFileError, match="no item 5"):
        dk.parse_scene(GAS, overrides={"interactions.wall.5.point": [0, 0, 0]})


def test_key_lines_finds_tables_arrays_of_tables_and_dotted_keys():
    text = 'a = 1\nlong = [\n  1,\n  2,\n]\nb.c = "x"\n[t]\nk = """\nz = 3\n"""\n[[w]]\np = 1\n[[w]]\np = 2\n[w.sub]\nq = 1\n'
    lines = key_lines(text)
    assert lines[("a",)] == 1 and lines[("long",)] == 2 and lines[("b", "c")] == 6 and lines[("t", "k")] == 8
    assert ("t", "z") not in lines  # inside a multi-line string
    assert lines[("w", 0, "p")] == 12 and lines[("w", 1, "p")] == 14 and lines[("w", 1, "sub", "q")] == 16


def test_si_input_is_the_papers_units():
    """The paper's magnets in SI with the paper's scales: the same numbers as the paper-unit file."""
    s = dk.units.PaperUnits.from_si(mass=4e-3, radius=5e-3, young_modulus=39.5e9, magnetisation=8.8e5)
    mu = dk.units.dipole_from_magnetisation(8.8e5, 5e-3)
    v = 0.01 * s.scale("velocity")
    text = textwrap.dedent(f"""\
        units = "si"
        [scales]
        mass = 4e-3
        radius = 5e-3
        young_modulus = 39.5e9
        magnetisation = 8.8e5
        [particles]
        position = [[-0.1, 0.0, 0.0], [0.1, 0.0, 0.0]]
        velocity = [[{v!r}, 0.0, 0.0], [{-v!r}, 0.0, 0.0]]
        radius = 5e-3
        mass = 4e-3
        dipole = [[{mu!r}, 0.0, 0.0], [{mu!r}, 0.0, 0.0]]
        [interactions.dipole]
        prefactor = 1e-7
        [interactions.kelvin_voigt]
        stiffness = {math.pi * 39.5e9 * 5e-3 / 2!r}
        [integrator]
        dt = {0.01 * s.time!r}
        [run]
        duration = {s.time!r}
        """)
    loaded = dk.parse_scene(text)
    p = loaded.scene.particles
    assert p.radius[0] == pytest.approx(s.dimensionless_radius, rel=1e-12)
    assert p.velocity[0, 0] == pytest.approx(0.01, rel=1e-12) and p.mass[0] == pytest.approx(1.0, rel=1e-12)
    assert np.linalg.norm(p.dipole[0]) == pytest.approx(1.0, rel=1e-12)
    assert loaded.scene.interactions[0].prefactor == pytest.approx(1 / 3, rel=1e-9)  # mu0/4pi -> 1/3
    assert loaded.scene.interactions[1].stiffness == pytest.approx(1.0, rel=1e-12)
    assert loaded.integrator.dt == pytest.approx(0.01, rel=1e-12) and loaded.duration == pytest.approx(1.0)
    with pytest.raises(dk.SceneFileError, match="scales: give one of stiffness, young_modulus"):
        dk.parse_scene(text.replace("young_modulus = 39.5e9\n", ""))
    # a refusal quotes converted numbers, and says they are in the paper's units (10 time units here)
    with pytest.raises(dk.SceneFileError, match=rf"dt = 10 is too large.*\[numbers in the paper's units, converted from "
                                                rf"SI: length {s.length:.4g} m, time {s.time:.4g} s"):
        dk.parse_scene(text.replace(f"dt = {0.01 * s.time!r}", f"dt = {10 * s.time!r}"))


AT_REST = """\
[particles]
position = [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0]]
dipole = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
[interactions.dipole]
prefactor = 1.0
[interactions.hertz]
young = 1000.0
poisson = 0.3
[integrator]
dt = "auto"
[run]
duration = 1.0
"""


def test_auto_time_step_resolves_magnets_snapping_together_from_rest_and_says_when_nothing_limits_it():
    """Touching magnets at rest: Hertz' own limit is infinite (no speed), the checks before a run use
    the speed of the magnets snapping together; "auto" is half of what they accept, and passes them."""
    loaded = dk.parse_scene(AT_REST)
    limit, why = dk.guards.largest_safe_step(loaded.scene)
    assert loaded.scene.max_time_step() == math.inf and math.isfinite(limit) and "snapping together" in why
    assert loaded.step_choice.stable == 0.5 * limit and loaded.integrator.dt <= 0.5 * limit
    dk.guards.before_stepping(loaded.scene, loaded.integrator)  # raises if refused
    alone = AT_REST.replace("[[0.0, 0.0, 1.0], [2.0, 0.0, 1.0]]", "[[0.0, 0.0, 1.0]]").replace(
        "[[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]", "[[1.0, 0.0, 0.0]]")
    with pytest.raises(dk.SceneFileError, match=r'integrator.dt: dt = "auto" found no largest safe step \(the stiffest '
                                                r'contact .* every sphere is at rest.*give dt as a number'):
        dk.parse_scene(alone)


# ---- fuzz ------------------------------------------------------------------------------------------
def mutate(text, rng):
    lines = text.splitlines()
    how = rng.randrange(8)
    k = rng.randrange(len(lines))
    if how == 0:  # delete a line
        del lines[k]
    elif how == 1:  # swap a value's type
        if "=" in lines[k]:
            key = lines[k].split("=")[0]
            lines[k] = key + "= " + rng.choice(['"text"', "true", "[1, 2]", "{a = 1}", "-3", "0", "1e400", "-1e400",
                                                "nan", "inf", "[[1, 2, 3]]", "2000-01-01", "9" * 30])
    elif how == 2:  # garbage characters
        junk = "".join(rng.choice("[]{}=\"'#.\\\n\x00\x07é€ ") for _ in range(rng.randrange(1, 12)))
        pos = rng.randrange(len(lines[k]) + 1)
        lines[k] = lines[k][:pos] + junk + lines[k][pos:]
    elif how == 3:  # huge numbers
        lines.insert(k, rng.choice(["x = 1e400", "n = 99999999999999999999", "radius = 1e308"]))
    elif how == 4:  # deep nesting
        depth = rng.choice([50, 1000, 100000])
        lines.append("deep = " + "[" * depth + "]" * depth)
    elif how == 5:  # a long string (10 MB in test_a_10_MB_string: 0.7 s to parse)
        lines.insert(k, f'title = "{"x" * 100_000}"')
    elif how == 6:  # duplicate a line
        lines.insert(k, lines[k])
    else:  # a deeply nested table
        lines.append("[" + ".".join(["t"] * rng.choice([10, 500])) + "]")
    return "\n".join(lines) + "\n"


def test_fuzz_every_outcome_is_a_scene_or_a_scene_file_error_a_line_a_problem():
    rng = random.Random(11)
    outcomes = {"ok": 0, "error": 0, "several": 0}
    for case in range(300):
        text = mutate(SMALL if case % 2 else GAS.replace("n = 80", "n = 20"), rng)
        if rng.random() < 0.2:
            text = mutate(text, rng)
        try:
            loaded = dk.parse_scene(text, source="fuzz.toml")
        except dk.SceneFileError as err:
            lines = str(err).strip().split("\n")
            assert len(lines) == len(err.errors) and all(line.startswith("fuzz.toml") and len(line) < 2000
                                                         for line in lines), str(err)
            outcomes["error"] += 1
            outcomes["several"] += len(lines) > 1
        else:
            assert isinstance(loaded, dk.LoadedScene)
            outcomes["ok"] += 1
    assert outcomes["ok"] > 20 and outcomes["error"] > 100 and outcomes["several"] > 5, outcomes


def test_a_10_MB_string_is_a_title_or_one_short_error():
    assert dk.parse_scene(f'title = "{"x" * 10_000_000}"\n' + SMALL.replace('title = "two spheres meet"', ""))
    with pytest.raises(dk.SceneFileError, match="run.title: unknown key") as err:
        dk.parse_scene(SMALL + f'title = "{"x" * 10_000_000}"\n')
    assert len(str(err.value)) < 300


def test_bytes_that_are_not_utf8_and_missing_files(tmp_path):
    (tmp_path / "bad.toml").write_bytes(b"title = 'a'\nx = '\xff\xfe'\n")
    with pytest.raises(dk.SceneFileError, match=r"bad.toml:2: is not UTF-8"):
        dk.load_scene(tmp_path / "bad.toml")
    with pytest.raises(dk.SceneFileError, match="cannot be read"):
        dk.load_scene(tmp_path / "missing.toml")


# ---- running and the command line ------------------------------------------------------------------
def test_run_writes_outputs_and_a_rerun_resumes_from_the_checkpoint(tmp_path):
    text = SMALL + textwrap.dedent("""\
        [outputs]
        trajectory = "out/traj.npz"
        [outputs.vtk]
        folder = "out/vtk"
        every = 0.1
        [outputs.checkpoint]
        path = "out/run.ckpt"
        """)
    (tmp_path / "s.toml").write_text(text)
    first = dk.load_scene(tmp_path / "s.toml", overrides={"run.duration": 0.3}).run()
    assert first.time[-1] == pytest.approx(0.3)
    saved = np.load(tmp_path / "out" / "traj.npz")
    assert np.array_equal(saved["position"], first.position) and "energy_total" in saved.files
    resumed = dk.load_scene(tmp_path / "s.toml").run()  # continues from t = 0.3: the file holds t = 0 .. 0.5
    assert resumed.time[0] == 0.0 and resumed.time[-1] == pytest.approx(0.5) and len(resumed) == 6
    straight = dk.Simulation(dk.parse_scene(SMALL).scene, dk.VelocityVerlet(0.001)).run(duration=0.5, record_every=0.1)
    same(resumed, straight)
    assert len(dk.read_series(tmp_path / "out" / "vtk" / "particles.pvd").time) == 6


def test_rerunning_a_finished_run_says_it_is_complete_and_changes_nothing(tmp_path, capsys):
    from demkit.cli import main
    (tmp_path / "s.toml").write_text(SMALL + RESUMABLE)
    assert main(["run", str(tmp_path / "s.toml"), "--no-progress"]) == 0
    first = capsys.readouterr().out
    assert "done in" in first and "resuming" not in first
    before = {f: f.read_bytes() for f in (tmp_path / "out").rglob("*") if f.is_file()}
    assert main(["run", str(tmp_path / "s.toml"), "--no-progress"]) == 0
    again = capsys.readouterr().out
    assert "already complete" in again and "nothing ran" in again and "kept trajectory" in again
    assert "resuming" not in again and "done in" not in again and "wrote" not in again
    assert {f: f.read_bytes() for f in (tmp_path / "out").rglob("*") if f.is_file()} == before  # byte for byte


def test_a_rerun_without_a_checkpoint_says_it_replaces_the_earlier_outputs(tmp_path, capsys):
    from demkit.cli import main
    (tmp_path / "s.toml").write_text(SMALL + '[outputs]\ntrajectory = "out/traj.npz"\n')
    assert main(["run", str(tmp_path / "s.toml"), "--no-progress"]) == 0
    assert "replacing" not in capsys.readouterr().out
    assert main(["run", str(tmp_path / "s.toml"), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "replacing the outputs of an earlier run: " in out and "traj.npz" in out and "done in" in out


RESUMABLE = textwrap.dedent("""\
    [outputs]
    trajectory = "out/traj.npz"
    [outputs.vtk]
    folder = "out/vtk"
    every = 0.05
    [outputs.checkpoint]
    path = "out/run.ckpt"
    """)


def saved_arrays(path):
    with np.load(path) as z:
        return {name: z[name] for name in z.files}


@pytest.mark.parametrize("record", ["record_every = 0.1", "record_every = 0.07", ""])
def test_a_run_stopped_by_ctrl_c_and_resumed_writes_the_npz_of_the_whole_run(tmp_path, monkeypatch, record):
    import signal
    text = SMALL.replace("record_every = 0.1", record) + RESUMABLE
    for name in ("straight", "stopped"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "s.toml").write_text(text)
    dk.load_scene(tmp_path / "straight" / "s.toml").run(progress=False)
    write = dk.io.VTKWriter.write

    def ctrl_c_at_t_015(writer, sim):  # Ctrl-C at t = 0.15, off the record grid
        write(writer, sim)
        if sim.step == 150:
            signal.raise_signal(signal.SIGINT)
    monkeypatch.setattr(dk.io.VTKWriter, "write", ctrl_c_at_t_015)
    with pytest.raises(KeyboardInterrupt):
        dk.load_scene(tmp_path / "stopped" / "s.toml").run(progress=False)
    stopped = saved_arrays(tmp_path / "stopped" / "out" / "traj.npz")
    assert stopped["time"][-1] == pytest.approx(0.15)  # the frames so far and where it stopped
    monkeypatch.setattr(dk.io.VTKWriter, "write", write)
    dk.load_scene(tmp_path / "stopped" / "s.toml").run(progress=False)
    whole, straight = (saved_arrays(tmp_path / name / "out" / "traj.npz") for name in ("stopped", "straight"))
    assert sorted(whole) == sorted(straight)
    for name in straight:
        assert np.array_equal(whole[name], straight[name]), name
    assert whole["time"][0] == 0.0 and whole["time"][-1] == pytest.approx(0.5)


def test_a_resume_without_the_earlier_frames_says_which_times_the_file_holds(tmp_path, capsys):
    (tmp_path / "s.toml").write_text(SMALL + RESUMABLE)
    dk.load_scene(tmp_path / "s.toml", overrides={"run.duration": 0.25}).run(progress=False)
    (tmp_path / "out" / "traj.npz").unlink()  # as if killed after a checkpoint, before writing the frames
    dk.load_scene(tmp_path / "s.toml").run(progress=False)
    assert "frames before t = 0.25 (the resume) are not kept: there is none; the file will hold t = 0.25 .. 0.5" \
        in capsys.readouterr().err
    assert np.allclose(np.load(tmp_path / "out" / "traj.npz")["time"], [0.25, 0.3, 0.4, 0.5])


def demkit(*args, cwd):
    return demkit_in_process(*args, cwd=cwd)  # conftest: the command in this process (children cost seconds)


def test_ctrl_c_in_demkit_run_says_what_is_kept_and_the_same_command_resumes(tmp_path):
    import signal
    (tmp_path / "s.toml").write_text(SMALL + RESUMABLE)
    command = [sys.executable, "-m", "demkit", "run", "s.toml", "--set", "run.duration=1e5", "--set",
               "run.record_every=100", "--set", "outputs.vtk.every=1000"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    for attempt in range(2):
        mark = time.time_ns()
        child = subprocess.Popen(command, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                 text=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        try:
            series = tmp_path / "out" / "vtk" / "particles.pvd"
            for _ in range(1200):  # stepping once the series gets a frame from this process (compiled)
                if (series.exists() and series.stat().st_mtime_ns > mark) or child.poll() is not None:
                    break
                time.sleep(0.05)
            time.sleep(0.3)
            child.send_signal(signal.SIGINT)
            out, err = child.communicate(timeout=120)
        finally:
            child.kill()
        assert child.returncode == 130, err
        assert ("resuming from" in out) == (attempt == 1), out
        line = err.strip().splitlines()[-1]
        assert line.startswith("demkit run: interrupted; kept: trajectory ") and "checkpoint " in line, err
        assert line.endswith("run the same command to resume") and "Traceback" not in err
        assert (tmp_path / "out" / "run.ckpt").exists() and (tmp_path / "out" / "traj.npz").exists()
    assert np.load(tmp_path / "out" / "traj.npz")["time"][0] == 0.0  # the file holds the whole run


def test_demkit_run_the_examples(tmp_path):
    done = demkit("run", str(COLLISION), "--duration", "300", "--out", str(tmp_path / "c"), cwd=ROOT)
    assert done.returncode == 0, done.stderr
    traj = np.load(tmp_path / "c" / "output" / "collision.npz")
    assert traj["time"][-1] == 300.0 and traj["position"].shape == (301, 2, 3)
    done = demkit("run", str(CLUSTER), "--duration", "0.06", "--set", "particles.build.n=60", "--set",
                  "outputs.animation.max_frames=2", "--set", "outputs.vtk.every=0.03", "--out", str(tmp_path / "k"),
                  cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert np.load(tmp_path / "k" / "output" / "cluster.npz")["position"].shape == (2, 60, 3)
    assert (tmp_path / "k" / "output" / "cluster_vtk" / "particles.pvd").is_file()
    # a finished run whose animation was not made (Ctrl-C while it was rendered): the rerun makes it
    options = ["--duration", "0.06", "--set", "particles.build.n=60", "--set", "outputs.animation.max_frames=2",
               "--set", "outputs.vtk.every=0.03", "--set", "outputs.checkpoint.path=ck.npz", "--out", str(tmp_path / "a")]
    assert demkit("run", str(CLUSTER), *options, cwd=ROOT).returncode == 0
    animation = next((tmp_path / "a").rglob("*.gif"))
    animation.unlink()
    done = demkit("run", str(CLUSTER), *options, cwd=ROOT)
    assert done.returncode == 0 and "already complete" in done.stdout, done.stdout + done.stderr
    assert f"wrote animation (the finished run's, not made before): {animation}" in done.stdout and animation.is_file()


def test_demkit_run_without_outputs_says_so_and_set_adds_one(tmp_path):
    (tmp_path / "s.toml").write_text(SMALL)
    done = demkit("run", "s.toml", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "no outputs requested: this run saves nothing" in done.stdout and "wrote" not in done.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]
    done = demkit("run", "s.toml", "--set", "outputs.trajectory=traj.npz", cwd=tmp_path)
    assert done.returncode == 0 and "no outputs" not in done.stdout and "wrote trajectory" in done.stdout
    assert np.load(tmp_path / "traj.npz")["position"].shape == (6, 2, 3)


def test_demkit_info_and_errors(tmp_path):
    done = demkit("info", str(COLLISION), cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "spheres       2" in done.stdout and "largest safe step 0.2227" in done.stdout
    assert "for the run: stepping" in done.stdout and "touching pairs" in done.stdout
    (tmp_path / "bad.toml").write_text(SMALL.replace("stiffness", "stifness"))
    done = demkit("run", "bad.toml", cwd=tmp_path)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.startswith("demkit run: error: bad.toml:10: interactions.kelvin_voigt.stifness: unknown key; "
                                  "did you mean 'stiffness'?"), done.stderr
    done = demkit("run", str(COLLISION), "--set", "nonsense", cwd=tmp_path)
    assert done.returncode == 2 and "--set needs key.path=value" in done.stderr


def test_the_docs_reference_is_generated_from_the_schema():
    text = (ROOT / "docs" / "scene_files.md").read_text()
    assert text.rstrip().endswith(dk.scenefile.reference().rstrip())


def test_si_input_of_magnetisable_spheres_takes_its_scales_from_the_inducing_field():
    """Steel balls have no moment of their own: [scales] gives the field and susceptibility instead, and
    the reference moment is the one the field induces in a lone ball, 4 pi R^3 chi/(chi + 3) B / mu0."""
    chi, radius, field = 1000.0, 2e-3, 0.02
    text = textwrap.dedent(f"""\
        units = "si"
        [scales]
        mass = 3.3e-4
        radius = {radius}
        young_modulus = 2e11
        field = {field}
        susceptibility = {chi}
        [particles]
        position = [[0.0, 0.0, 0.0], [0.05, 0.0, 0.0]]
        radius = {radius}
        mass = 3.3e-4
        susceptibility = {chi}
        [interactions.dipole]
        prefactor = 1e-7
        [interactions.hertz]
        young = 2e11
        poisson = 0.28
        restitution = 0.5
        [interactions.uniform_field]
        field = [0.0, 0.0, {field}]
        [integrator]
        dt = 1e-7
        [run]
        duration = 1e-6
        """)
    loaded = dk.parse_scene(text)
    scene = loaded.scene
    lone = dk.units.induced_dipole(chi, radius, field)
    assert lone == pytest.approx(4 * math.pi * radius ** 3 * chi / (chi + 3) * field / dk.units.MU0, rel=1e-15)
    # the reference moment is one unit; the two spheres, side by side across the field, weaken each other:
    # m = 1 / (1 + beta (R/r)^3) units (mutual induction of two point dipoles), beta = chi/(chi + 3)
    moments = np.linalg.norm(scene.particles.dipole, axis=1)
    beta = chi / (chi + 3)
    np.testing.assert_allclose(moments, 1.0 / (1.0 + beta * (radius / 0.05) ** 3), rtol=1e-6)  # the solve's tolerance
    sim = dk.Simulation(scene, loaded.integrator)
    sim.run(loaded.duration)  # runs in the paper's units (the prefactor 1e-7 became 1/3)
    assert scene.interactions[0].prefactor == pytest.approx(1 / 3, rel=1e-9)
    for wrong, message in ((f"susceptibility = {chi}\n[particles]", "[particles]"),
                           (f"field = {field}\nsusceptibility", "magnetisation = 1e5\nsusceptibility")):
        bad = text.replace(wrong, message, 1)
        with pytest.raises(dk.SceneFileError, match="scales.(field: needs susceptibility|susceptibility: goes with "
                                                    "field)"):
            dk.parse_scene(bad)


def test_every_problem_of_the_keys_is_reported_in_one_pass():
    """A file with several mistakes gets them all at once, a line each in the file's order (a key
    misspelt is not also reported missing); the problems between tables come once the keys are right."""
    text = SMALL.replace("radius = 0.5", "radius = -0.5\nmas = 1.0").replace("stiffness = 1000.0", "stifness = 1000.0")
    text = text.replace("dt = 0.001", 'dt = "fast"')
    with pytest.raises(dk.SceneFileError) as info:
        dk.parse_scene(text, source="s.toml")
    lines = str(info.value).split("\n")
    assert lines == ["s.toml:6: particles.radius: must be positive, got -0.5",
                     "s.toml:7: particles.mas: unknown key; did you mean 'mass'?",
                     "s.toml:11: interactions.kelvin_voigt.stifness: unknown key; did you mean 'stiffness'?",
                     "s.toml:16: integrator.dt: must be a number or \"auto\", got a string ('fast')"]
    assert [e.line for e in info.value.errors] == [6, 7, 11, 16] and info.value.line == 6
    # one problem: one line, as before
    with pytest.raises(dk.SceneFileError, match=r"^s.toml:6: particles.radius: must be positive, got -0.5$"):
        dk.parse_scene(SMALL.replace("radius = 0.5", "radius = -0.5"), source="s.toml")


def test_demkit_info_measure_times_the_tier_a_long_run_uses(shipped_tiers, monkeypatch):
    """A run long enough to go over to the scene's own code (tier 2) is timed there: the paper's
    collision steps several times faster on its fused module than on the generic one, and a
    timing of tier 1 put `demkit info --measure` at 2.5 times the run. A short run stays on tier 1."""
    # 40 million steps: about 20 s on tier 1, which compiles tier 2 (or loads it) for the run
    done = demkit("info", str(COLLISION), "--measure", "--set", "run.duration=400000.0", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "steps now on tier 2" in done.stdout, done.stdout
    # a new process (the long run's tier 2 is cached now, but a short run does not even load it)
    monkeypatch.setattr(dk.engine.tiers, "_SPENT", {})
    monkeypatch.setattr(dk.engine.tiers, "_READY", set())
    done = demkit("info", str(COLLISION), "--measure", "--set", "run.duration=2.0", cwd=ROOT)
    assert done.returncode == 0 and "steps now" in done.stdout and "tier 2" not in done.stdout.split("cost")[1]


def test_demkit_info_measure_after_earlier_runs_of_the_combination(shipped_tiers, monkeypatch):
    """Earlier runs of the combination in the process count towards compiling tier 2, so a process
    that ran the collision long before switches during the timing itself; the timing still says (and
    times) the tier the run uses. (A test worker that had run it before printed no tier: CI failed.)"""

    class LongBefore(dict):
        def get(self, key, default=None):
            return 1e3  # seconds every combination ran on tier 1 before, in this process

    monkeypatch.setattr(dk.engine.tiers, "_SPENT", LongBefore())
    done = demkit("info", str(COLLISION), "--measure", "--set", "run.duration=400000.0", cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "steps now on tier 2" in done.stdout, done.stdout
