"""The code in the user guide runs, and its plug-in example is physically right."""
import re
from pathlib import Path

import numpy as np
import pytest

import demkit as dk
from conftest import energy_gradient

GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guide.md"


@pytest.fixture(scope="module")
def guide_namespace():
    ns = {"__name__": "guide_example"}  # not importable: exercises the in-memory compile path
    for block in re.findall(r"```python\n(.*?)```", GUIDE.read_text(), flags=re.S):
        exec(compile(block, str(GUIDE), "exec"), ns)
    return ns


def page_namespace(name, ns=None):
    """Run every Python block of docs/<name> in one namespace and return it."""
    page = GUIDE.parent / name
    ns = {} if ns is None else ns
    for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S):
        exec(compile(block, str(page), "exec"), ns)
    return ns


def test_guide_quick_start_runs(guide_namespace):
    traj = guide_namespace["traj"]
    assert guide_namespace["dk"].two_magnets.outcome(traj) == "stick"
    omega, _ = guide_namespace["omega"], guide_namespace["sigma"]
    assert omega > 0


def test_guide_plugin_force_is_minus_energy_gradient(guide_namespace):
    soft = guide_namespace["SoftRepulsion"](strength=3.0)
    p = dk.Particles(position=[[0, 0, 0], [1.7, 0.2, 0.1]], radius=1.0)
    scene = dk.Scene(p, [soft])
    assert "guide_example" not in scene.fused_source()  # compiled in memory, not imported
    force, _ = scene.forces()
    np.testing.assert_allclose(force[1], -energy_gradient(scene, "contact", 1, h=1e-6), rtol=1e-6)
    assert np.allclose(force[0], -force[1])


def test_nbody_page_example_runs_as_described():
    page = Path(__file__).resolve().parents[1] / "docs" / "nbody.md"
    ns = {}
    exec(compile(re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)[0], str(page), "exec"), ns)
    traj, sim, box = ns["traj"], ns["sim"], ns["box"]
    assert len(traj) == 6 and (traj.position >= 0).all() and (traj.position < box.size).all()
    assert np.array_equal(traj.unwrapped(), traj.position + traj.image * box.size)
    st = sim.statistics
    assert st["neighbour_list_builds"] >= 1 and sorted(entry["cutoff"] for entry in st["lists"]) == [1.0, 4.0]


def test_contacts_page_example_runs_as_described():
    ns = page_namespace("contacts.md", {"__name__": "contacts_page"})
    traj = ns["traj"]
    assert {"wall", "gravity", "field", "magnetic", "contact"} <= set(traj.energy)
    e = traj.energy
    balance = np.abs(e["total"] + e["dissipated"] - e["total"][0]).max()
    assert balance < 1e-3 * (abs(e["kinetic"][0]) + e["dissipated"][-1])
    assert (traj.position[:, :, 2] > 0).all()  # on the floor, not through it
    # the vibrated bed: it leaves the plate near a lone ball's phase and is thrown for two cycles
    assert abs(ns["leaves"] - np.arccos(-1 / 3.0)) < 0.05 and 0.015 < ns["gap"].max() < 0.025
    # the hopper: the grains drain through the funnel's outlet (18 of 20 by t = 2)
    assert ns["drained"] >= 15
    # the servo lid: it holds 100 (1e-6 from t = 3 on), and the floor carries that and the weight
    assert all(abs(push - 100.0) < 1e-6 * 100.0 for t, _, push in ns["history"] if t >= 3.0)
    c = ns["pile"].contacts()
    assert abs(c.normal_force[c.wall == 0].sum() - (100.0 + 48 * 9.81)) < 1e-3 * 570.9


def test_fields_page_example_runs_as_described():
    pytest.importorskip("magpylib")
    ns = page_namespace("fields.md", {"__name__": "fields_page"})
    field, traj, e = ns["field"], ns["traj"], ns["e"]
    assert np.abs(field.field(ns["points"]) - ns["exact"]).max() < 1e-3 * np.abs(ns["exact"]).max()  # 3e-4
    assert np.ptp(e["total"]) < 1e-4 * np.ptp(e["field"])  # 1.2e-5 said on the page
    assert field.inside(traj.position.reshape(-1, 3)).all() and traj.position[-1, 0, 0] > 0.015  # across


def test_rheology_page_example_runs(capsys):
    """docs/rheology.md's sheared magnetic sample: the chains along the field resist the flow (a
    positive shear stress, 0.091 printed there, of many standard errors) and the rheology's parts are
    those of the series' mean stress."""
    ns = page_namespace("rheology.md")
    r, series = ns["r"], ns["series"]
    assert r["shear_stress"] > 5 * r["shear_stress_error"] > 0 and r["rate"] == 0.1
    P = series.mean(after=series.time[-1] / 2)[0]
    assert r["shear_stress"] == pytest.approx(-P[0, 1], rel=1e-9) and r["n1"] == pytest.approx(P[1, 1] - P[0, 0], rel=1e-9)
    assert "shear stress" in capsys.readouterr().out


def test_measurements_page_example_runs_and_its_parts_add_up(capsys):
    ns = page_namespace("measurements.md")
    s = ns["s"]
    assert s.pressure == pytest.approx((np.trace(s.kinetic) + sum(np.trace(w) for w in s.virial.values()))
                                       / (3 * s.volume))
    assert set(s.virial) == {"Dipole", "KelvinVoigt"} and ns["z"].shape == (300,)
    out = capsys.readouterr().out
    assert "p = " in out
    # the Ewald sample: its reciprocal terms are in the Dipole's virial, the shares add up, and the
    # chains along the field pull it together along z (the page prints -1.011; a run of 1000 steps
    # of 40 frictional spheres need not repeat its digits on another machine: half of it is asked)
    chains, st, P = ns["chains"], ns["st"], ns["P"]
    reciprocal = chains.long_range[0].virial(chains.particles, chains.box)[0]
    assert type(chains.long_range[0]).__name__ == "TunedEwald" and np.abs(reciprocal).max() > 0.01 * np.abs(P).max()
    assert st.per_sphere.sum(axis=0) == pytest.approx(st.volume * st.pressure_tensor, rel=1e-10, abs=1e-10)
    assert P[2, 2] - (P[0, 0] + P[1, 1]) / 2 < -0.5 and "magnetic P_zz - (P_xx + P_yy) / 2 = " in out


def test_thermostat_page_example_runs_as_described(capsys):
    ns = page_namespace("thermostat.md")
    xi = ns["xi"]
    # standard errors: sqrt(var(cos theta) / 20000) = 0.003 and sqrt(2 / 3000) = 0.026; 5 of them
    assert abs(np.mean(ns["cos_theta"]) - (1 / np.tanh(xi) - 1 / xi)) < 0.015
    assert abs(ns["T"] - 1.0) < 0.13
    assert "<cos theta> = 0.5414, Langevin law 0.5373; kT from velocities 1.031" in capsys.readouterr().out


def test_long_range_page_example_runs_as_described(capsys):
    ns = page_namespace("long_range.md")
    m = ns["m"]
    assert ns["full"].energy()["magnetic"] / m**3 == pytest.approx(-2 * np.pi / 3, rel=2e-6)
    assert abs(ns["cut"].energy()["magnetic"]) < 1e-10
    out = capsys.readouterr().out
    assert "Ewald: -2.094394 per dipole" in out and "local field B_z = 4.18878" in out  # (4 pi/3 = 4.1887902)
    # "Which sum for my scene": the report's errors as printed on the page (times vary)
    report, best = ns["report"], ns["best"]
    errors = {r.label: (r.force_error, r.torque_error) for r in report.rows}
    assert errors["cutoff 4 d"][0] == pytest.approx(9.37e-3, rel=1e-3) and errors["cutoff 4 d"][1] > 0.09  # Lorentz
    assert errors["Ewald 1e-5"][0] == pytest.approx(8.85e-6, rel=5e-3)  # within the 1e-5 asked, polarised
    assert best.force_error <= 1e-3 and best.label in ("P3M 1e-3", "Ewald 1e-3")
    assert "errors against Ewald 1e-10 (metallic)" in out and "use Dipole(prefactor=1.0, long_range=" in out
