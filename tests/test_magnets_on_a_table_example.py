"""The magnets-on-a-table example (examples/magnets_on_a_table/run.py) in its --quick form: 12 NdFeB
balls dropped on a table, three animation frames. It renders, so it runs in a child process without
DISPLAY (as the other rendering tests do: a broken OpenGL stack could crash the interpreter)."""
import math
from pathlib import Path

import numpy as np
from PIL import Image

import demkit as dk
from conftest import run_example_quick

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "magnets_on_a_table" / "run.py"



def test_quick_run_writes_everything_and_the_balls_settle_into_chains_on_the_table(tmp_path):
    pv = __import__("pytest").importorskip("pyvista")
    done, result = run_example_quick(SCRIPT, tmp_path, timeout=300)
    assert "steps/s" in done.stdout and "plain rings" in done.stdout and "sliding" in done.stdout
    n, duration = 12, 0.4

    # the files: a VTK series that ends at the end of the run, its contact network, the pictures
    series = dk.read_series(tmp_path / "vtk" / "particles.pvd")
    assert len(series) == 101 and np.isclose(series.time[-1], duration) and series.dipole is not None
    assert series.position.shape == (101, n, 3)
    contact_frames = sorted((tmp_path / "vtk").glob("particles_contacts_*.vtp"))
    assert len(contact_frames) == 101 and (tmp_path / "vtk" / "particles_contacts.pvd").exists()
    network = pv.read(contact_frames[-1])
    c = result["contacts"]
    assert network.n_cells == c["ball_ball"] + c["ball_table"]  # the last frame: every contact, one line each
    assert {"force_magnitude", "sliding", "normal_force", "wall"} <= set(network.cell_data.keys())
    assert network.cell_data["force_magnitude"].max() > 1.0  # magnets squeeze with newtons (weight 5 mN)
    gif = Image.open(tmp_path / "table.gif")
    assert gif.n_frames == 3
    for name in ("final.png", "energy.png"):
        rgb = np.asarray(Image.open(tmp_path / name).convert("RGB"), dtype=int)
        assert np.mean(np.abs(rgb - 255).sum(axis=2) > 30) > 0.01, name  # not blank

    # Nobody goes through the table: the deepest a ball pressed into it over the run. A Hertz impact
    # at 7.7 m/s, the fastest a snap can give, squeezes two balls by 29 um; balls that only fall a
    # few millimetres and roll press the rigid table by under a micrometre (measured 0.1 um).
    assert result["lowest"] > -5e-6
    # Energy balance: |total + dissipated - initial| / dissipated. It closes to first order in dt
    # (the dashpots see the half-step velocities; friction's and rolling's work is booked exactly):
    # measured 0.98 % at the example's 40 steps per fastest impact (2.02 % at 20, 0.48 % at 80;
    # 1.82 % when friction's work was booked as dt x power)
    assert result["closure"] < 0.0125
    # The magnets pulled together: each head-to-tail contact releases about 2 (mu0/4pi) m^2/d^3
    # = 7.3 mJ, and most balls end in chains.
    pair = 2e-7 * (1.3 * 4 / 3 * math.pi * 2.5e-3**3 / dk.units.MU0) ** 2 / 5e-3**3
    assert result["magnetic"][1] < result["magnetic"][0] - 0.5 * (n / 2) * pair
    assert result["end"]["largest"] >= 4 and result["end"]["contacts"] >= n / 2
    assert result["start"]["contacts"] == 0 and result["end"]["linked"] >= n / 2
    # ... and settled on the table: slow (median speed measured 0.03 mm/s; a lone ball may still roll
    # away, spinning), resting at height R: most bottoms within 10 um of the table (a ball of a chain
    # may still rock by tens of um: measured 8 and 7 of the 12 balls within 10 um, in two arithmetics
    # of the same run), none on top of another ball.
    assert result["final_speed"][0] < 0.005  # median speed, m/s
    final = series.position[-1, :, 2] - 2.5e-3
    assert np.mean(np.abs(final) < 1e-5) > 1 / 2 and final.max() < 2.5e-3
