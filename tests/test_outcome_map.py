"""TwoMagnets.orientation and the outcome-map task of the sweeps."""
import math

import numpy as np
import pytest

from demkit.two_magnets import TwoMagnets
from demkit.two_magnets.outcome_map import two_magnets_point


def test_orientation_turns_both_moments_in_the_plane_and_zero_changes_nothing():
    base = TwoMagnets(4.0)
    assert np.array_equal(base.with_(orientation=0.0).moments(), base.moments())  # bit for bit
    n0 = base.moments()[0]
    for dipoles, sign in (("aligned", 1.0), ("anti-aligned", -1.0)):
        m = TwoMagnets(4.0, dipoles=dipoles, orientation=90.0).moments()
        assert m[0] @ n0 == pytest.approx(0.0, abs=1e-15) and np.cross(n0, m[0])[2] == pytest.approx(1.0)
        np.testing.assert_allclose(m[1], sign * m[0])
    m = TwoMagnets(4.0, orientation=30.0).moments()
    assert m[0] @ n0 == pytest.approx(math.cos(math.radians(30))) and np.linalg.norm(m[0]) == pytest.approx(1)
    np.testing.assert_allclose(TwoMagnets(4.0, orientation=180.0).moments(), -base.moments(), atol=1e-15)
    with pytest.raises(ValueError, match="explicit"):
        TwoMagnets(4.0, dipoles=[[1, 0, 0], [1, 0, 0]], orientation=10.0)
    with pytest.raises(ValueError, match="finite"):
        TwoMagnets(4.0, orientation=math.nan)


def test_outcome_map_point():
    # fast spheres from close by: head-on they bounce, far off they miss
    near = {"speed": 2e-2, "x0": 20.0}
    hit = two_magnets_point(dict(near, b_over_R=0.5))
    assert hit["outcome"] == "bounce" and hit["closest"] <= 1 and hit["contacts"] >= 1
    miss = two_magnets_point(dict(near, b_over_R=6.0))
    assert miss["outcome"] == "miss" and miss["closest"] > 1 and miss["first_contact"] is None
    assert miss["contacts"] == 0
    with pytest.raises(ValueError, match="unknown parameter"):
        two_magnets_point({"b_over_R": 1.0, "colour": "red"})
    with pytest.raises(ValueError, match="integrator"):
        two_magnets_point({"b_over_R": 1.0, "integrator": "leapfrog"})
