"""Dipolar particle-mesh sums (dk.Dipole(long_range=dk.P3M(...))) against the Ewald sum of
test_ewald.py (itself checked against lattice sums and the direct sum over images), against
energy derivatives, and in a run. Every scene shares one kernel module (periodic box, P3M dipole,
elastic contacts)."""
import math

import numpy as np
import pytest

import demkit as dk
from conftest import same_bits_on_two_threads_and_one
from test_ewald import assert_forces_are_energy_gradients, lattice, random_gas


def scene_of(pos, dip, side, long_range, radius=0.4, **kw):
    p = dk.Particles(position=pos, radius=radius, mass=1.0, dipole=dip, **kw)
    return dk.Scene(p, [dk.Dipole(prefactor=1.0, long_range=long_range), dk.KelvinVoigt(stiffness=1000.0, damping=0.0)],
                    box=dk.Box(side, periodic=True))


@pytest.mark.parametrize("accuracy", [1e-3, 1e-5])
def test_forces_and_torques_reach_the_accuracy_asked(accuracy):
    # 200 random dipoles: RMS force error against an Ewald sum converged to 1e-12, relative to the
    # touching pull; the mesh error is measured on a sample while tuning, so within a factor 3
    pos, dip = random_gas(n=200, side=9.0, seed=3)
    f0, t0 = scene_of(pos, dip, 9.0, dk.Ewald(1e-12)).forces()
    scene = scene_of(pos, dip, 9.0, dk.P3M(accuracy))
    f, t = scene.forces()
    pull = 6.0 * np.mean((dip ** 2).sum(1)) / 0.8 ** 4
    error = np.sqrt(np.mean(((f - f0) ** 2).sum(1))) / pull
    assert accuracy / 100 < error < 3 * accuracy
    assert np.sqrt(np.mean(((t - t0) ** 2).sum(1))) / pull < 3 * accuracy
    tuned = scene.long_range[0]
    assert tuned.estimated_error == pytest.approx(error, rel=1.0)  # the tuning's own estimate


@pytest.mark.parametrize("pattern, surface, truth", [("aligned", "metallic", -2 * math.pi / 3), ("aligned", "vacuum", 0.0),
                                                     ("columns", "vacuum", -2.67678868438)])
def test_lattice_sums(pattern, surface, truth):
    pos, dip = lattice(4, pattern)
    scene = scene_of(pos, dip, 4.0, dk.P3M(1e-6, surface=surface), radius=0.3)
    assert scene.energy()["magnetic"] / len(pos) == pytest.approx(truth, abs=2e-5)


def test_force_and_torque_are_minus_the_energy_gradients():
    # the mesh forces are the exact derivatives of the mesh energy
    pos, dip = random_gas(n=40, side=6.0, seed=6)
    assert_forces_are_energy_gradients(scene_of(pos, dip, 6.0, dk.P3M(1e-4)), (0, 13, 31))


def test_a_run_conserves_energy_to_the_integrators_order():
    # as for the Ewald sum: halving dt divides the total energy's swings by 4
    swings = []
    for dt in (1e-3, 5e-4):
        pos, dip = random_gas(n=40, side=6.0, seed=11)
        scene = scene_of(pos, 0.3 * dip, 6.0, dk.P3M(1e-5),
                         velocity=np.random.default_rng(2).normal(size=(40, 3)), angular_velocity=np.zeros((40, 3)))
        energy = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=1.0, record_every=0.05, progress=False).energy
        swings.append(np.ptp(energy["total"]))
    assert 3.5 < swings[0] / swings[1] < 4.5


def test_local_field_and_scene_file():
    pos, dip = random_gas(n=30, side=6.0, seed=4)
    scene = scene_of(pos, dip, 6.0, dk.P3M(1e-6, surface="vacuum", order=7))
    field = dk.measure.local_field(scene)
    np.testing.assert_allclose(np.cross(dip, field), scene.forces()[1], atol=1e-10)
    assert -0.5 * np.einsum("ij,ij->", dip, field) == pytest.approx(scene.energy()["magnetic"], rel=1e-9)
    text = f"""
[particles]
position = {pos.tolist()}
dipole = {dip.tolist()}
radius = 0.4
[box]
size = 6.0
periodic = true
[interactions.dipole]
prefactor = 1.0
[interactions.dipole.p3m]
accuracy = 1e-6
surface = "vacuum"
order = 7
[interactions.kelvin_voigt]
stiffness = 1e5
[integrator]
dt = 0.0005
[run]
duration = 0.01
"""
    loaded = dk.parse_scene(text).scene
    assert loaded.long_range[0].order == 7
    assert loaded.energy()["magnetic"] == pytest.approx(scene.energy()["magnetic"], abs=1e-4)


def test_bad_input_is_refused():
    pos, dip = lattice(3)
    p = dk.Particles(position=pos, radius=0.3, mass=1.0, dipole=dip)
    with pytest.raises(ValueError, match="periodic along x, y and z"):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.P3M())], box=dk.Box(3.0, periodic=(False, False, True)))
    for order in (3, 8, 4.5, True):
        with pytest.raises(ValueError, match="order"):
            dk.P3M(order=order)
    for mesh in (5, (16, 16), 12.5):
        with pytest.raises(ValueError, match="mesh"):
            dk.P3M(mesh=mesh)
    with pytest.raises(ValueError, match="accuracy"):
        dk.P3M(accuracy=2.0)
    # a mesh that does not fit in memory: 4096^3 points x 32 B = 2.2 TB, refused before anything is allocated
    with pytest.raises(ValueError, match=r"a P3M mesh of \(4096, 4096, 4096\) points needs about 2.2e\+03 GB.*"
                                         r"more than this machine has available.*smaller mesh"):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.P3M(mesh=4096))], box=dk.Box(3.0, periodic=True))


def test_cost_estimate_prices_the_mesh():
    from demkit.interactions.p3m import _fft_seconds
    pos, dip = random_gas(n=40, side=6.0, seed=2)
    scene = scene_of(pos, dip, 6.0, dk.P3M(1e-4))
    tuned = scene.long_range[0]
    parts = dk.cost.estimate(scene, dk.VelocityVerlet(1e-3), 1.0).parts
    assert parts["mesh sum"] == pytest.approx(dk.cost.MESH_CALL + 40 * tuned.order ** 3 * dk.cost.MESH_POINT
                                              + _fft_seconds(tuned.mesh))
    assert "reciprocal sum" not in parts and "fast multipole sum" not in parts


def test_the_mesh_on_threads_gives_the_bits_of_one_thread():
    """The mesh's weights, spreading, FFTs and gathering run on numba's threads (each mesh plane and
    each sphere summed in one order): a run on two threads gives the bits of the same run on one,
    the forces outside a run too, and a run gives numba's thread setting back when it ends."""
    def make():
        pos, dip = random_gas(n=160, side=15.0, seed=5)
        return scene_of(pos, 0.3 * dip, 15.0, dk.P3M(1e-4), velocity=np.random.default_rng(3).normal(size=(160, 3)),
                        angular_velocity=np.zeros((160, 3)))

    same_bits_on_two_threads_and_one(make, 0.05)


def test_tuning_runs_on_one_thread_and_gives_the_tuning_of_two():
    """A tuning's trial sums are small: they run on one of numba's threads (the count given back after), and
    give what the same tuning gives on two threads (its trial sums' bits do not depend on the count)."""
    import numba

    from demkit.interactions import dipole
    pos, dip = random_gas(n=160, side=15.0, seed=5)
    p = dk.Particles(position=pos, radius=0.4, mass=1.0, dipole=0.3 * dip)
    box = dk.Box(15.0, periodic=True)
    seen = []
    tune = dk.P3M(1e-4).tune

    def watched(*args):
        seen.append(numba.get_num_threads())
        return tune(*args)

    before = numba.get_num_threads()
    numba.set_num_threads(2)
    try:
        one = dipole._on_one_thread(watched, 1.0, p, box, None)
        assert seen == [1] and numba.get_num_threads() == 2
        two = tune(1.0, p, box, None)  # (on two threads)
    finally:
        numba.set_num_threads(before)
    assert (one.mesh, one.cutoff, one.alpha, one.estimated_error) == (two.mesh, two.cutoff, two.alpha, two.estimated_error)
