"""demkit.two_magnets.TwoMagnets: the paper's initial state, and joining consecutive runs."""
import numpy as np
import pytest

from demkit.two_magnets import analysis
import demkit as dk
from demkit.two_magnets import TwoMagnets


def test_initial_state_is_the_papers():
    setup = TwoMagnets(4.0)
    p = setup.particles()
    b = 4.0 * 6.94
    assert np.allclose(p.position, [[-150, -b / 2, 0], [150, b / 2, 0]])
    assert np.allclose(p.linear_momentum(), 0.0)               # centre of mass at rest
    assert p.angular_momentum()[2] == pytest.approx(5.78e-3 * b)  # L = m v b, counter-clockwise
    n = (p.position[1] - p.position[0]) / np.linalg.norm(p.position[1] - p.position[0])
    assert np.allclose(p.dipole, [n, n])                          # head to tail along r-hat
    anti = TwoMagnets(4.0, dipoles="anti-aligned").moments()
    assert np.allclose(anti, [n, -n])
    assert setup.initial_kinetic == pytest.approx(5.78e-3 ** 2)
    assert setup.expected_spin() == pytest.approx(5.78e-3 * b / (2.8 * 6.94 ** 2))
    assert setup.with_(b_over_R=2.0).b == pytest.approx(2 * 6.94)


@pytest.mark.parametrize("bad", [dict(b_over_R=-1.0), dict(b_over_R=1.0, model="coulomb"),
                                 dict(b_over_R=1.0, x0=5.0), dict(b_over_R=1.0, dipoles="up"),
                                 dict(b_over_R=1.0, speed=0.0)])
def test_invalid_setups_are_rejected(bad):
    with pytest.raises(ValueError):
        TwoMagnets(**bad)


def test_concatenated_runs_equal_one_continuous_run():
    setup = TwoMagnets(3.0)
    whole = setup.simulation().run(3000.0, record_every=10.0)
    sim = setup.simulation()
    parts = [sim.run(1000.0, record_every=10.0), sim.run(2000.0, record_every=10.0)]
    joined = dk.Trajectory.concatenate(parts)
    assert np.array_equal(joined.time, whole.time)
    assert np.array_equal(joined.position, whole.position)  # same steps, bit for bit
    assert np.array_equal(joined.energy["total"], whole.energy["total"])
    with pytest.raises(analysis.UndeterminedOutcome):
        analysis.outcome(joined)
    with pytest.raises(ValueError, match="not consecutive"):
        dk.Trajectory.concatenate(parts[::-1])
