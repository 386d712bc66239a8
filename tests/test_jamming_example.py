"""The jamming example (examples/jamming/run.py) in its --quick form: 250 bidisperse spheres compressed in
a deforming periodic box until they jam, without and with friction. It renders its picture, so it runs in
a child process without DISPLAY (conftest.run_example_quick)."""
import csv
from pathlib import Path

from conftest import run_example_quick

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "jamming" / "run.py"


def test_quick_run_jams_near_random_close_packing_and_lower_with_friction(tmp_path):
    done, result = run_example_quick(SCRIPT, tmp_path)
    runs = result["results"]
    frictionless, frictional = runs["0.0"], runs["0.5"]
    # O'Hern et al. 2003: 0.639 quasi-statically; 250 spheres compressed at 0.01 jam at 0.62 (the finite rate and
    # size shift it by a few per cent: 0.60-0.66 accepted); friction 0.5 jams looser (Silbert 2010: 0.58-0.59)
    assert 0.60 < frictionless["phi_J"] < 0.66
    assert 0.54 < frictional["phi_J"] < frictionless["phi_J"] - 0.03
    for run in runs.values():  # each stopped once rigid, beyond its jamming point
        assert run["final_fraction"] > run["phi_J"] and run["final_pressure"] > 0.02 * 1e4
    with open(result["table"]) as fh:
        rows = list(csv.DictReader(fh))
    fractions = [float(row["volume_fraction"]) for row in rows if row["friction"] == "0.0"]
    assert abs(fractions[0] - 0.3) < 1e-12 and fractions == sorted(fractions)  # the box only shrinks
    assert Path(result["figure"]).stat().st_size > 10_000
    assert Path(result["picture"]).stat().st_size > 10_000
    assert "jams at phi_J" in done.stdout
