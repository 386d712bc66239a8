"""The Brownian-colloid example (examples/brownian_colloid/run.py) in its --quick form: 100 spheres
at xi = 2 for lambda = 1 and 4. It renders, so it runs in a child process without DISPLAY (as the
other rendering tests do: a broken OpenGL stack could crash the interpreter)."""
import json
from pathlib import Path

from PIL import Image

from conftest import run_example_quick

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "brownian_colloid" / "run.py"


def test_quick_run_follows_the_langevin_law_at_weak_coupling_and_exceeds_it_when_chained(tmp_path):
    done, result = run_example_quick(SCRIPT, tmp_path)
    weak, strong = result["rows"]
    assert (weak["lambda"], strong["lambda"]) == (1.0, 4.0) and weak["xi"] == strong["xi"] == 2.0
    # lambda = 1 at volume fraction 0.03: the moments' mutual field shifts xi by about 8 phi lambda L = 0.13
    # at most (+5 % in m), and the estimate's standard error is ~0.01: within 0.06 of L(2) = 0.537
    assert abs(weak["m"] - weak["langevin"]) < 0.06, weak
    # lambda = 4: chains magnetise more easily than independent moments, by far more than the errors
    assert strong["m"] > strong["langevin"] + 3 * strong["error"], strong
    assert result["chains_at_lambda_4_xi_2"]["largest"] >= 4
    assert json.loads((tmp_path / "magnetisation.json").read_text())["rows"] == result["rows"]
    assert Image.open(tmp_path / "magnetisation.png").size[0] > 300
    chains = tmp_path / "chains.png"
    if "chains.png not drawn" not in done.stderr:
        assert Image.open(chains).size == (800, 700)
