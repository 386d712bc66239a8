"""dk.StressSeries: the stress measured while a run goes on (with the contact history of the moment),
its file, its restart, its means and a sheared sample's rheology."""
import math

import numpy as np
import pytest

import demkit as dk
from demkit.stress_series import BLOCKS, block_mean, rheology


def frictional_gas(n=64):
    """A small periodic gas of frictional magnets (the friction springs are the history a frame lacks)."""
    R = 0.5
    box = dk.build.box_for(n, R, 0.2)
    rng = np.random.default_rng(8)
    p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=3), velocity=rng.normal(size=(n, 3)),
                     radius=R, mass=1.0, dipole=0.5 * rng.normal(size=(n, 3)))
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, cutoff=2.5), dk.KelvinVoigt(2000.0, 3.0, friction=dk.Friction(0.5))],
                    box=box)


def test_the_samples_are_the_stress_of_the_state_at_their_times(tmp_path):
    """Every sample is dk.measure.stress of the run's state at that time, to the bit (a run cut into
    pieces of `every` and measured by hand between them steps to the same bits), friction included;
    the file holds the same numbers, with each interaction's part, and the parts add up to P."""
    series = dk.StressSeries(every=0.01, path=tmp_path / "stress.csv")
    scene = frictional_gas()
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[series])
    sim.run(0.05, progress=False)
    sim.close()
    by_hand = frictional_gas()
    hand_sim = dk.Simulation(by_hand, dk.VelocityVerlet(1e-3))
    expected = [dk.measure.stress(by_hand).pressure_tensor]
    for _ in range(5):
        hand_sim.run(0.01, progress=False)
        expected.append(dk.measure.stress(by_hand).pressure_tensor)
    assert np.allclose(series.time, np.arange(6) * 0.01, rtol=1e-12, atol=1e-15)
    assert series.pressure_tensor.tobytes() == np.array(expected).tobytes()
    assert len(scene.history(scene.interactions[1])[0]) > 0  # springs were held while it measured
    parts = series.parts
    assert set(parts) == {"Dipole", "KelvinVoigt"}
    assert np.allclose(series.kinetic + parts["Dipole"] + parts["KelvinVoigt"], series.pressure_tensor,
                       rtol=1e-13, atol=1e-13)
    table = np.loadtxt(tmp_path / "stress.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "stress.csv").read_text().splitlines()[0].split(",")
    assert header[:2] == ["time", "P_xx"] and header[19] == "Dipole_xx" and len(header) == 1 + 4 * 9
    assert table[:, 1:10].tobytes() == series.pressure_tensor.reshape(-1, 9).tobytes()  # repr: exact


def test_a_runs_statistics_give_the_mean_stress_of_its_own_samples():
    """sim.statistics["stress"] of each run is the block mean of the samples taken from its start (the
    first run's 21 samples, the second's 11: its start state was the first's end sample) to the bit; a
    sheared run adds its rheology; a run without a StressSeries has no such entry."""
    series = dk.StressSeries(every=0.005)
    sim = dk.Simulation(frictional_gas(), dk.VelocityVerlet(1e-3), writers=[series])
    sim.run(0.1, progress=False)
    first = sim.statistics["stress"]
    assert first["samples"] == 21 and first["rheology"] is None
    mean, error = block_mean(series.pressure_tensor)
    assert np.array(first["pressure_tensor"]).tobytes() == mean.tobytes()
    assert np.array(first["pressure_tensor_error"]).tobytes() == error.tobytes()
    assert first["pressure"] == np.trace(mean) / 3.0
    sim.run(0.05, progress=False)
    second = sim.statistics["stress"]
    assert second["samples"] == 11
    assert np.array(second["pressure_tensor"]).tobytes() == block_mean(series.pressure_tensor[20:])[0].tobytes()
    plain = dk.Simulation(frictional_gas(), dk.VelocityVerlet(1e-3))
    plain.run(0.01, progress=False)
    assert "stress" not in plain.statistics
    import test_shear
    sheared = dk.StressSeries(every=0.01)
    sim = dk.Simulation(test_shear.sheared_gas(None, n=128), dk.VelocityVerlet(1e-3), writers=[sheared])
    sim.run(0.2, progress=False)
    r = sim.statistics["stress"]["rheology"]
    assert r == sheared.rheology() and r["rate"] == 0.8 and r["shear_stress"] == -np.mean(sheared.pressure_tensor[:, 0, 1])


def test_a_resumed_run_continues_the_file_as_an_uninterrupted_one_wrote_it(tmp_path):
    """A checkpointed run stopped at t = 0.03 (after a sample at 0.035 was written: dropped) and resumed
    in a new process-like scene gives the uninterrupted run's samples, to the bit."""
    whole = dk.StressSeries(every=0.01)
    dk.Simulation(frictional_gas(), dk.VelocityVerlet(1e-3), writers=[whole]).run(0.06, progress=False)
    path, ckpt = tmp_path / "s.csv", tmp_path / "run.ckpt"
    first = dk.StressSeries(every=0.01, path=path)
    sim = dk.Simulation(frictional_gas(), dk.VelocityVerlet(1e-3), writers=[first], checkpoint=dk.Checkpoint(ckpt))
    sim.run(0.03, progress=False)
    sim.close()
    with open(path, "a") as f:  # a sample taken after the checkpoint by a run killed before its next one
        f.write(",".join(["0.035"] + ["1.0"] * 36) + "\n")
    with pytest.raises(ValueError, match="exists"):
        dk.StressSeries(every=0.01, path=path)
    again = dk.StressSeries(every=0.01, path=path, resume=True)
    sim = dk.Simulation(frictional_gas(), dk.VelocityVerlet(1e-3), writers=[again], checkpoint=dk.Checkpoint(ckpt))
    sim.resume()
    sim.run(until=0.06, progress=False)
    sim.close()
    assert np.allclose(again.time, whole.time, rtol=1e-12, atol=1e-15)
    assert again.pressure_tensor.tobytes() == whole.pressure_tensor.tobytes()
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    assert table[:, 1:10].tobytes() == whole.pressure_tensor.reshape(-1, 9).tobytes()


def test_block_mean_and_rheology_by_hand():
    """The standard error of independent samples is sigma / sqrt(n) (within the scatter of 8 blocks:
    +-60 % at 2 sigma); rheology() reads the components of a tensor as the module docstring says."""
    rng = np.random.default_rng(1)
    errors = [block_mean(rng.normal(2.0, 3.0, size=800))[1] for _ in range(50)]
    assert np.mean(errors) == pytest.approx(3.0 / math.sqrt(800), rel=0.15)
    mean, error = block_mean(np.ones((2 * BLOCKS - 1, 3, 3)))
    assert np.all(mean == 1.0) and np.all(np.isnan(error))  # too few samples for blocks of 2
    P = np.arange(9.0).reshape(3, 3)  # P_ab = 3 a + b
    r = rheology(P, dk.Shear(0.5, flow="z", gradient="x"))  # a = 2, b = 0, c = 1
    assert r == {"shear_stress": -6.0, "viscosity": -12.0, "n1": 0.0 - 8.0, "n2": 4.0 - 0.0, "pressure": 4.0}
    assert math.isnan(rheology(P, dk.Shear(0.0))["viscosity"])


def test_bad_input_is_refused(tmp_path):
    for bad in (0, -1.0, math.nan, "often"):
        with pytest.raises(ValueError, match="every"):
            dk.StressSeries(every=bad)
    with pytest.raises(ValueError, match="one of them"):
        dk.StressSeries(every=1.0, overwrite=True, resume=True)
    series = dk.StressSeries(every=0.01)
    with pytest.raises(ValueError, match="no samples"):
        series.mean()
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=0.5, mass=1.0)
    with pytest.raises(ValueError, match="volume"):  # open space, before the first step
        dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(100.0, 1.0)]), dk.VelocityVerlet(1e-3),
                      writers=[series]).run(0.01, progress=False)
    series = dk.StressSeries(every=0.01, volume=8.0)
    dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(100.0, 1.0)]), dk.VelocityVerlet(1e-3),
                  writers=[series]).run(0.02, progress=False)
    with pytest.raises(ValueError, match="sheared box"):
        series.rheology()
    with pytest.raises(ValueError, match="measured a simulation already"):  # nothing of the first run is lost
        dk.Simulation(dk.Scene(p, [dk.KelvinVoigt(100.0, 1.0)]), dk.VelocityVerlet(1e-3),
                      writers=[series]).run(0.02, progress=False)
    assert len(series.time) == 3
    with pytest.raises(ValueError, match="no sample at or after"):
        series.mean(after=1.0)
