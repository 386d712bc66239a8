"""The oedometer example (examples/oedometer/run.py) in its --quick form: 3 x 3 x 4 magnetic spheres
pressed by a piston to 2 % strain, without and with a vertical field. It renders its final picture,
so it runs in a child process without DISPLAY (conftest.run_example_quick)."""
import csv
from pathlib import Path

import numpy as np

import demkit as dk
from conftest import run_example_quick

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "oedometer" / "run.py"


def test_quick_run_balances_the_forces_and_writes_the_curves_and_the_walls(tmp_path):
    done, result = run_example_quick(SCRIPT, tmp_path)
    runs = result["results"]
    assert set(runs) == {"0.0", "10.0"}
    for run in runs.values():
        weight = run["weight"]
        # statics before the piston touches: the floor carries the spheres' weight (the magnetic forces are
        # internal), settled and again as the piston arrives (the pile settled anew: a few tenths of a
        # percent of rocking are left)
        assert abs(run["floor_settled"] - weight) < 0.02 * weight
        assert abs(run["floor_before"] - weight) < 0.02 * weight
        # pressed slowly (inertia number ~ 0.01), the floor carries the weight and the piston's push; the
        # rest is the pile's acceleration as it gives way in steps (a few percent of the weight)
        assert abs(run["balance"] - 1.0) < 0.1
        assert 0.3 < run["volume_fraction"] < 0.65
    # the curves, as a table and a figure
    with open(result["table"]) as fh:
        rows = list(csv.DictReader(fh))
    assert {row["field"] for row in rows} == {"0.0", "10.0"}
    strain = np.array([float(row["strain"]) for row in rows])
    assert strain.min() == 0.0 and 0.02 <= strain.max() < 0.03
    assert Path(result["figure"]).stat().st_size > 10_000
    # each run's series has its walls; the piston stands in its last frame where the run says it was
    series = dk.read_series(tmp_path / "vtk_field_10" / "particles.pvd")
    assert series.walls is not None and all(path is not None for path in series.walls)
    assert "field 10:" in done.stdout and "floor carries" in done.stdout
