"""The demkit command: `demkit accuracy scene.py` prints a work-precision table and writes its figure."""
import textwrap

import pytest
from conftest import demkit_in_process

from demkit.cli import parse_method

SCENE = textwrap.dedent("""
    import demkit as dk
    p = dk.Particles(position=[[0, 0, 0], [1.0137, 0, 0]], velocity=[[0.5, 0, 0], [-0.5, 0, 0]], radius=0.5)
    scene = dk.Scene(p, [dk.KelvinVoigt(1000.0, 4.0)])
    duration = 0.3
""")


def demkit(*args, cwd):
    return demkit_in_process(*args, cwd=cwd)  # conftest: the command in this process (children cost seconds)


def test_accuracy_prints_the_table_and_writes_the_figure(tmp_path):
    (tmp_path / "impact.py").write_text(SCENE)
    done = demkit("accuracy", "impact.py", "--dts", "0.004,0.002", "--methods", "VelocityVerlet,VelocityVerlet:resolve",
                  "--csv", "wp.csv", "--repeats", "1", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    rows = [line.split() for line in done.stdout.splitlines() if line.startswith("VelocityVerlet")]
    assert [(r[0], r[1]) for r in rows] == [("VelocityVerlet", "0.004"), ("VelocityVerlet", "0.002"),
                                            ("VelocityVerlet:resolve", "0.004"), ("VelocityVerlet:resolve", "0.002")]
    # resolved contacts: the energy balance (column 5) falls about 4x per halving (measured 3.9)
    assert 3.0 < float(rows[2][4]) / float(rows[3][4]) < 5.0
    assert (tmp_path / "impact_accuracy.png").stat().st_size > 10000
    assert (tmp_path / "wp.csv").read_text().count("\n") >= 5


@pytest.mark.parametrize("args, message", [
    (["--methods", "Leapfrog"], "unknown method 'Leapfrog'"),
    (["--methods", "RK4:resolve"], "RK4 cannot resolve contact events"),
    (["--methods", "MultipleTimeStep:0"], "inner must be a whole number"),
    (["--dts", "0.01,-1"], "--dts must be positive"),
])
def test_bad_options_are_one_clear_line(tmp_path, args, message):
    (tmp_path / "impact.py").write_text(SCENE)
    done = demkit("accuracy", "impact.py", *args, cwd=tmp_path)
    assert done.returncode == 2 and message in done.stderr and "Traceback" not in done.stderr


def test_a_file_without_a_scene_or_a_duration_is_refused(tmp_path):
    (tmp_path / "empty.py").write_text("x = 1\n")
    done = demkit("accuracy", "empty.py", cwd=tmp_path)
    assert done.returncode == 2 and "must define `scene`" in done.stderr
    (tmp_path / "nodur.py").write_text(SCENE.replace("duration = 0.3", ""))
    done = demkit("accuracy", "nodur.py", cwd=tmp_path)
    assert done.returncode == 2 and "give --duration" in done.stderr
    assert demkit("accuracy", "missing.py", cwd=tmp_path).returncode == 2


def test_method_names():
    assert parse_method("MultipleTimeStep:8:resolve")(0.01).inner == 8
    assert parse_method("MultipleTimeStep:8:resolve")(0.01).resolve_contacts
    assert parse_method("VelocityVerlet:resolve")(0.01).resolve_contacts


TOML = textwrap.dedent("""
    [particles]
    position = [[0.0, 0.0, 0.0], [1.0137, 0.0, 0.0]]
    velocity = [[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0]]
    radius = 0.5
    [interactions.kelvin_voigt]
    stiffness = 1000.0
    damping = 4.0
    [integrator]
    dt = 0.001
    [run]
    duration = 0.3
""")


def test_accuracy_of_a_scene_file_is_that_of_the_same_python_scene(tmp_path):
    """The .toml and the .py scene are the same scene: every error column agrees to the last digit printed."""
    (tmp_path / "impact.py").write_text(SCENE)
    (tmp_path / "impact.toml").write_text(TOML)
    options = ["--dts", "0.004,0.002", "--methods", "VelocityVerlet,RK4", "--no-progress", "--repeats", "1"]
    tables = []
    for name in ("impact.py", "impact.toml"):
        done = demkit("accuracy", name, *options, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        rows = [line.split() for line in done.stdout.splitlines() if line.startswith(("VelocityVerlet", "RK4"))]
        tables.append([r[:5] for r in rows])  # method, dt, position, velocity and energy errors (not the time)
    assert len(tables[0]) == 4 and tables[0] == tables[1]
    done = demkit("accuracy", "impact.toml", "--duration", "0.001", "--dts", "0.004", cwd=tmp_path)
    assert done.returncode == 2 and "duration 0.001 is shorter than the largest time step 0.004" in done.stderr
