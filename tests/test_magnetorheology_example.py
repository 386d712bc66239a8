"""The magnetorheology example (examples/magnetorheology/run.py) in its --quick form: 100 spheres, rates
0.2 and 1, strain 4. It renders, so it runs in a child process without DISPLAY (as the other
rendering tests do: a broken OpenGL stack could crash the interpreter)."""
import csv
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from conftest import headless_env

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "magnetorheology" / "run.py"

CHILD = """
    import json, runpy
    main = runpy.run_path({script!r})["main"]
    result = main(["--quick", "--output", {out!r}])
    print("RESULT" + json.dumps({{"ratio": result["ratio"]}}))
"""


def test_quick_run_finds_the_field_induced_stress_and_writes_the_curve_and_the_chains(tmp_path):
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(CHILD.format(script=str(SCRIPT), out=str(tmp_path)))],
                          capture_output=True, text=True, env=headless_env(), timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    result = json.loads(next(line for line in done.stdout.splitlines() if line.startswith("RESULT"))[6:])
    with open(tmp_path / "flow_curve.csv") as f:
        rows = list(csv.DictReader(f))
    assert [(float(r["rate"]), r["field"]) for r in rows] == [(0.2, "True"), (0.2, "False"), (1.0, "True"),
                                                             (1.0, "False")]
    sigma = {(float(r["rate"]), r["field"] == "True"): float(r["shear_stress"]) for r in rows}
    # the chains resist the flow: at the slower rate the field raises the shear stress (measured 13.8x
    # here, 147x at rate 0.03 in the full run); the stress rises with the rate in both cases
    assert result["ratio"] == sigma[0.2, True] / sigma[0.2, False] and result["ratio"] > 5
    assert sigma[1.0, False] > sigma[0.2, False] > 0 and sigma[1.0, True] > sigma[0.2, True] > 0
    for r in rows:  # a viscosity and errors for every point
        assert float(r["viscosity"]) == pytest.approx(float(r["shear_stress"]) / float(r["rate"]), rel=1e-12)
        assert np.isfinite(float(r["shear_stress_error"])) and float(r["shear_stress_error"]) > 0
    for name in ("flow_curve.png", "chains.png"):
        image = np.asarray(Image.open(tmp_path / name).convert("RGB"), dtype=float)
        assert image.std() > 20  # a drawing, not a blank
