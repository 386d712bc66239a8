"""Bad input stops before stepping with a ValueError naming the problem."""
import numpy as np
import pytest

import demkit as dk


@pytest.mark.parametrize("kwargs, message", [
    (dict(position=[[0, 0], [1, 1]]), r"position must have shape \(N, 3\)"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], velocity=[[0, 0, 0]]), r"velocity must have shape \(2, 3\)"),
    (dict(position=[[0, 0, np.nan], [3, 0, 0]]), "position contains NaN"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], velocity=[[0, np.inf, 0], [0, 0, 0]]), "velocity contains NaN or inf"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], radius=-1.0), "radius must be positive"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], radius=[1.0, 0.0]), "radius must be positive; particle 1"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], mass=0.0), "mass must be positive"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], mass=[1.0, 2.0, 3.0]), r"mass must be a scalar or have shape \(2,\)"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], dipole=[[0, 0, 1]] * 3), r"dipole must have shape \(2, 3\)"),
    (dict(position=[[0, 0, 0], [3, 0, 0]], ids=[4, 4]), "unique"),
])
def test_bad_particles(kwargs, message):
    with pytest.raises(ValueError, match=message):
        dk.Particles(**kwargs)


def test_dipole_without_moments():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]])
    with pytest.raises(ValueError, match="Dipole needs particle dipole moments"):
        dk.Scene(p, [dk.Dipole(1.0)])


@pytest.mark.parametrize("make", [lambda: dk.Dipole(prefactor=-1.0), lambda: dk.Dipole(1.0, cutoff=0.0),
                                  lambda: dk.KelvinVoigt(stiffness=0.0),
                                  lambda: dk.KelvinVoigt(stiffness=1.0, damping=-0.1),
                                  lambda: dk.KelvinVoigt(stiffness=np.nan)])
def test_bad_interaction_parameters(make):
    with pytest.raises(ValueError, match="must be a"):
        make()


def test_coincident_spheres():
    p = dk.Particles(position=[[1, 2, 3], [5, 5, 5], [1, 2, 3]])
    with pytest.raises(ValueError, match="particles 0 and 2 are coincident"):
        dk.Scene(p, [dk.KelvinVoigt(1.0)])


def test_deeply_overlapping_spheres():
    p = dk.Particles(position=[[0, 0, 0], [0.8, 0, 0]], radius=1.0)
    with pytest.raises(ValueError, match="overlap deeply"):
        dk.Scene(p, [dk.KelvinVoigt(1.0)])
    # a shallow overlap is a legitimate start (e.g. a settled packing)
    dk.Scene(dk.Particles(position=[[0, 0, 0], [1.9, 0, 0]], radius=1.0), [dk.KelvinVoigt(1.0)])


def test_time_step_too_large_names_the_largest_safe_value():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=1.0, mass=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=1.0, damping=0.1)])
    safe = scene.max_time_step()
    assert 0.2 < safe < 0.25  # contact of two unit masses with k = 1 lasts ~2.22
    with pytest.raises(ValueError, match=f"largest safe value is {safe:.6g}"):
        dk.Simulation(scene, dk.EulerCromer(dt=0.3))
    dk.Simulation(scene, dk.EulerCromer(dt=safe))  # the limit itself is accepted


def test_nan_set_after_construction_is_caught_before_stepping():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=1.0)
    scene = dk.Scene(p, [dk.KelvinVoigt(1.0)])
    sim = dk.Simulation(scene, dk.VelocityVerlet(0.01))
    p.velocity[1, 2] = np.nan
    with pytest.raises(ValueError, match="velocity contains NaN or inf .particle 1"):
        sim.run(duration=1.0)
    assert sim.step == 0


def test_not_an_interaction():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]])
    with pytest.raises(TypeError, match="PairInteraction"):
        dk.Scene(p, ["gravity"])
