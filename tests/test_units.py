"""The paper's non-dimensionalisation from SI inputs."""
import math

import pytest

from demkit import units


def test_paper_scales():
    u = units.paper_magnets()
    # inputs of the paper: k = Y pi R^2 / (2R) = 3.1e8 N/m, mu = M V = 0.46 A m^2
    assert units.stiffness_from_young(39.5e9, 5e-3) == pytest.approx(3.1e8, rel=0.01)
    assert units.dipole_from_magnetisation(8.8e5, 5e-3) == pytest.approx(0.46, rel=0.01)
    assert u.time == pytest.approx(3.6e-6, rel=0.01)  # paper: t_c = 3.6e-6 s
    # paper: x_c = 7.2e-4 m; the exact value from its inputs is 7.29e-4 (the paper rounded down)
    assert u.length == pytest.approx(7.2e-4, rel=0.015)
    assert u.dimensionless_radius == pytest.approx(6.94, rel=0.015)
    assert 5e-3 / 7.2e-4 == pytest.approx(6.94, abs=0.005)  # ...which is how the paper got 6.94
    assert u.to_si(5.78e-3, "velocity") == pytest.approx(1.16, rel=0.015)
    assert u.from_si_value(1.16, "velocity") == pytest.approx(5.78e-3, rel=0.015)


def test_definitions_and_round_trip():
    u = units.PaperUnits.from_si(mass=2.0, radius=0.1, stiffness=8.0, dipole_moment=3.0)
    assert u.time == pytest.approx(0.5)
    assert u.length == pytest.approx((3 * units.MU0 * 9.0 / (4 * math.pi * 8.0)) ** 0.2)
    # in these units k = 1: force scale / length scale = stiffness
    assert u.scale("force") / u.scale("length") == pytest.approx(8.0)
    assert u.scale("energy") == pytest.approx(8.0 * u.length**2)
    for q in ("time", "velocity", "angular_velocity", "energy", "damping"):
        assert u.from_si_value(u.to_si(0.37, q), q) == pytest.approx(0.37)


@pytest.mark.parametrize("kwargs, message", [
    (dict(mass=-1, radius=0.1, stiffness=1, dipole_moment=1), "mass"),
    (dict(mass=1, radius=0.1, dipole_moment=1), "exactly one of stiffness"),
    (dict(mass=1, radius=0.1, stiffness=1, dipole_moment=1, magnetisation=1), "exactly one of dipole"),
])
def test_bad_inputs(kwargs, message):
    with pytest.raises(ValueError, match=message):
        units.PaperUnits.from_si(**kwargs)
    with pytest.raises(ValueError, match="unknown quantity"):
        units.paper_magnets().scale("colour")


def test_the_papers_rounded_scales():
    rounded = units.PaperUnits(mass=4e-3, length=7.2e-4, time=3.6e-6, radius=5e-3)
    assert rounded.dimensionless_radius == pytest.approx(6.944, abs=1e-3)
    assert rounded.to_si(5.78e-3, "velocity") == pytest.approx(1.156, rel=1e-9)
