"""dk.compare_dipole_sums: errors of cut-off, Ewald, P3M, exact and FMM dipole sums against a converged
sum, their time per evaluation, the cheapest meeting an accuracy, and clear refusals of bad input."""
import numpy as np
import pytest

import demkit as dk
from demkit.dipole_sums import default_candidates

N = 150


def gas(periodic=True, seed=3):
    """N spheres of diameter 1 at volume fraction 0.2 (periodic cube, side 7.2) or 0.15 (open), unit moments."""
    box = dk.build.box_for(N, 0.5, 0.2 if periodic else 0.15, periodic=periodic)
    pos = dk.build.random_packing(N, 0.5, box, seed=seed)
    dip = dk.build.random_directions(N, seed=seed + 1)
    return dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip), box


ACCURACIES = (1e-3, 1e-4, 1e-5, 1e-6)


@pytest.fixture(scope="module")
def periodic_report():
    p, box = gas()
    # (each kind of sum compiles its own kernels, ~10 s when not cached: few kinds here)
    candidates = [dk.Dipole(1.0, cutoff=3.0)] + [dk.Ewald(a) for a in ACCURACIES] + [dk.P3M(1e-4)]
    return dk.compare_dipole_sums(p, box, 1.0, candidates, repeats=2)


def row(report, label):
    return next(r for r in report.rows if r.label == label)


def test_ewald_errors_fall_with_the_accuracy_asked_and_stay_within_it(periodic_report):
    errors = [row(periodic_report, f"Ewald {a:.0e}".replace("e-0", "e-")).force_error for a in ACCURACIES]
    assert all(b < a / 3 for a, b in zip(errors, errors[1:]))
    assert all(e <= a for e, a in zip(errors, ACCURACIES))
    assert all(e > a / 100 for e, a in zip(errors, ACCURACIES))  # errors measured, not a reference compared to itself
    assert row(periodic_report, "P3M 1e-4").force_error <= 1e-4
    assert periodic_report.reference["label"] == "Ewald 1e-10 (metallic)"
    assert periodic_report.pull == pytest.approx(6.0) and periodic_report.diameter == pytest.approx(1.0)


def test_a_cutoff_is_worse_than_ewald_and_cheapest_meets_the_target(periodic_report):
    ewald = row(periodic_report, "Ewald 1e-6")
    cut = row(periodic_report, "cutoff 3 d")
    assert cut.force_error > 100 * ewald.force_error and cut.torque_error > 100 * ewald.torque_error
    assert cut.tuning_seconds == 0.0 and cut.tuned == ""
    assert ewald.tuning_seconds > 0 and ewald.tuned.startswith("TunedEwald(")
    assert all(r.seconds > 0 for r in periodic_report.rows)
    best = periodic_report.cheapest(1e-4)
    assert best.force_error <= 1e-4
    assert best.seconds == min(r.seconds for r in periodic_report.rows if r.force_error <= 1e-4)
    assert periodic_report.cheapest(1e-12) is None
    both = periodic_report.cheapest(1e-2, torque=1e-5)
    assert both.force_error <= 1e-2 and both.torque_error <= 1e-5 and both.label.startswith(("Ewald", "P3M"))
    assert periodic_report.cheapest(1.0).seconds == min(r.seconds for r in periodic_report.rows)
    # the row's Dipole goes straight into a scene
    p, box = gas()
    assert dk.Scene(p, [best.dipole], box=box).forces()[0].shape == (N, 3)


def test_table_plot_and_json(periodic_report, tmp_path):
    text = periodic_report.table()
    assert "Ewald 1e-6" in text and "cutoff 3 d" in text and "against Ewald 1e-10" in text
    assert "touching pull" in text and "1 thread" in text
    path = periodic_report.plot(tmp_path / "sums.png")
    assert path.stat().st_size > 10000
    import json
    data = json.loads(periodic_report.to_json(tmp_path / "sums.json"))
    assert len(data["rows"]) == len(periodic_report.rows) and data["periodic"] is True
    assert json.loads((tmp_path / "sums.json").read_text()) == data


def test_default_candidates():
    p, box = gas()  # side 7.2: cutoffs 2 and 3 fit in half the box, 4 does not
    labels = [repr(c) for c in default_candidates(1.0, p, box)]
    assert "Dipole(prefactor=1.0, cutoff=3.0)" in labels and "Dipole(prefactor=1.0, cutoff=4.0)" not in labels
    assert "Dipole(prefactor=1.0, cutoff=3.0, switch_width=0.75)" in labels
    assert sum("Ewald(accuracy" in s for s in labels) == 4 and sum("P3M(accuracy" in s for s in labels) == 4
    open_labels = [repr(c) for c in default_candidates(1.0, p, None)]
    assert "Dipole(prefactor=1.0, cutoff=6.0)" in open_labels and "Dipole(prefactor=1.0)" in open_labels
    assert not any("Ewald" in s or "P3M" in s for s in open_labels)
    try:
        import fmm3dpy  # noqa: F401
        assert sum("exact_below=0" in s for s in open_labels) == 3  # the FMM itself, whatever N
    except ImportError:
        assert not any("FMM" in s for s in open_labels)


def test_open_space_against_the_exact_sum():
    p, _ = gas(periodic=False)
    candidates = [dk.Dipole(1.0, cutoff=3.0), dk.Dipole(1.0)]
    try:
        import fmm3dpy  # noqa: F401
        candidates.append(dk.FMM(1e-6))
    except ImportError:
        pass
    report = dk.compare_dipole_sums(p, None, 1.0, candidates, repeats=1)
    assert report.reference["label"] == "exact (all pairs)" and not report.periodic
    assert row(report, "cutoff 3 d").force_error > 1e-3
    exact = row(report, "exact (all pairs)")
    assert exact.force_error < 1e-14 and exact.torque_error < 1e-14
    if len(candidates) == 3:  # 150 spheres: below its crossover the FMM keeps the exact sum, and says so
        fmm = row(report, "FMM 1e-6 (kept the exact sum)")
        assert fmm.force_error < 1e-14 and "exact all-pairs sum" in fmm.tuned


def test_bad_input_is_refused_with_a_message():
    p, box = gas()
    bare = dk.Particles(position=p.position, radius=0.5)
    with pytest.raises(ValueError, match="needs particles with dipole moments.*they have none"):
        dk.compare_dipole_sums(bare, box, 1.0)
    zero = dk.Particles(position=p.position, radius=0.5, dipole=np.zeros((N, 3)))
    with pytest.raises(ValueError, match="every moment is zero"):
        dk.compare_dipole_sums(zero, box, 1.0)
    for bad in ("cutoff 4", 4.0, dk.PowerLawDipole(1.0, cutoff=3.0), dk.KelvinVoigt(1.0, 0.1)):
        with pytest.raises(ValueError, match="a candidate must be a dk.Dipole"):
            dk.compare_dipole_sums(p, box, 1.0, [bad])
    with pytest.raises(ValueError, match="prefactor 2.0, the comparison 1.0"):
        dk.compare_dipole_sums(p, box, 1.0, [dk.Dipole(2.0, cutoff=3.0)])
    with pytest.raises(ValueError, match="no cutoff, which a periodic box cannot hold"):
        dk.compare_dipole_sums(p, box, 1.0, [dk.Dipole(1.0)])
    with pytest.raises(ValueError, match="periodic along x, y and z or along two of them .a slab., or open space"):
        dk.compare_dipole_sums(p, dk.Box(box.size, periodic=(True, False, False)), 1.0)
    with pytest.raises(ValueError, match="in 'vacuum' surroundings, the comparison in 'metallic' ones"):
        dk.compare_dipole_sums(p, box, 1.0, [dk.Ewald(1e-3, surface="vacuum")])
    with pytest.raises(ValueError, match="at least one candidate"):
        dk.compare_dipole_sums(p, box, 1.0, [])
    with pytest.raises(ValueError, match="repeats"):
        dk.compare_dipole_sums(p, box, 1.0, repeats=0)
