"""Dipolar Ewald sums (dk.Dipole(long_range=dk.Ewald(...))) against independent truths: lattice sums
known to ten digits, the direct sum over a large sphere of images, finite differences of the energy,
a converged reference for the tuned accuracy, energy conservation in a run, and bad input.

All scenes here share one kernel module (a periodic box, a Dipole with an Ewald sum, elastic
contacts), so the file compiles once."""
import math

import numpy as np
import pytest

import demkit as dk
from conftest import same_bits_on_two_threads_and_one
from demkit.interactions.ewald import real_space_error, reciprocal_error


def lattice(m, pattern="aligned", a=1.0):
    """m^3 simple-cubic lattice of unit moments along z in a periodic cube of side m a:
    ``aligned`` all up, ``columns`` up and down in alternate columns (sign (-1)^(ix + iy))."""
    idx = np.stack(np.meshgrid(np.arange(m), np.arange(m), np.arange(m), indexing="ij"), -1).reshape(-1, 3)
    pos = (idx + 0.5) * a
    dip = np.zeros((len(pos), 3))
    dip[:, 2] = 1.0 if pattern == "aligned" else (-1.0) ** (idx[:, 0] + idx[:, 1])
    return pos, dip


def ewald_scene(pos, dip, side, accuracy=1e-8, surface="metallic", cutoff=None, alpha=None, radius=0.3, **kw):
    p = dk.Particles(position=pos, radius=radius, mass=1.0, dipole=dip, **kw)
    dipole = dk.Dipole(prefactor=1.0, cutoff=cutoff, long_range=dk.Ewald(accuracy, surface=surface, alpha=alpha))
    # elastic contacts in every scene (inert where no spheres touch): one kernel module for the file
    return dk.Scene(p, [dipole, dk.KelvinVoigt(stiffness=1000.0, damping=0.0)], box=dk.Box(side, periodic=True))


def random_gas(n=40, side=6.0, seed=3):
    rng = np.random.default_rng(seed)
    pos = dk.build.random_packing(n, 0.4, dk.Box(side, periodic=True), seed=seed)
    dip = rng.normal(size=(n, 3))
    return pos, dip / np.linalg.norm(dip, axis=1)[:, None] * rng.uniform(0.5, 1.5, (n, 1))


@pytest.mark.parametrize("surface, truth", [("metallic", -2.0 * math.pi / 3.0), ("vacuum", 0.0)])
def test_aligned_simple_cubic_lattice(surface, truth):
    # the Lorentz field (4 pi / 3) M of a cubic lattice: -(2 pi / 3) n mu^2 per dipole with metallic
    # surroundings; the demagnetising field of a sphere in vacuum cancels it: 0. Tuned to 1e-8.
    pos, dip = lattice(4)
    scene = ewald_scene(pos, dip, 4.0, surface=surface)
    per_dipole = scene.energy()["magnetic"] / len(pos)
    assert per_dipole == pytest.approx(truth, abs=5e-8)


@pytest.mark.parametrize("surface", ["metallic", "vacuum"])
def test_luttinger_tisza_antiparallel_columns(surface):
    # zero net moment: no surface term; Luttinger & Tisza's constant -2.67678868438 n mu^2
    pos, dip = lattice(4, "columns")
    scene = ewald_scene(pos, dip, 4.0, surface=surface)
    assert scene.energy()["magnetic"] / len(pos) == pytest.approx(-2.67678868438, abs=5e-8)


def test_vacuum_sum_is_the_direct_sum_over_a_large_sphere_of_images():
    # the plain dipole pair summed over every image box whose centre lies within R of the origin's
    # (a sphere of boxes in vacuum) tends to the Ewald sum with the vacuum surface term; the shell
    # of partly included boxes leaves an error ~ (L/R)^2 of the surface energy: R = 24 L -> 1e-3 here
    pos, dip = random_gas(n=6, side=4.0, seed=5)
    scene = ewald_scene(pos, dip, 4.0, surface="vacuum", radius=0.4)
    ewald = scene.energy()["magnetic"]
    side, reach = 4.0, 24
    g = np.arange(-reach, reach + 1)
    shifts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    shifts = shifts[(shifts ** 2).sum(1) <= reach ** 2] * side
    total = 0.0
    for i in range(len(pos)):
        d = pos[None, :, :] - pos[i] + shifts[:, None, :]          # (images, j, 3)
        r2 = (d ** 2).sum(-1)
        r2[r2 == 0.0] = np.inf                                     # no self term
        r = np.sqrt(r2)
        ad = d @ dip[i]
        bd = (d * dip[None, :, :]).sum(-1)
        ab = dip @ dip[i]
        total += 0.5 * ((ab[None, :] - 3.0 * ad * bd / r2) / r ** 3).sum()
    assert total == pytest.approx(ewald, rel=2e-3, abs=2e-3)


def assert_forces_are_energy_gradients(scene, spheres, h=1e-5, atol=2e-7):
    """Central differences of the magnetic energy in position and in the moment: force = -dU/dx,
    torque = m x (-dU/dm); with h = 1e-5 truncation and round-off are ~1e-10."""
    force, torque = scene.forces()
    x, m = scene.particles.position, scene.particles.dipole
    for i in spheres:
        grad, field = np.zeros(3), np.zeros(3)
        for a in range(3):
            for arr, out in ((x, grad), (m, field)):
                arr[i, a] += h
                up = scene.energy()["magnetic"]
                arr[i, a] -= 2 * h
                down = scene.energy()["magnetic"]
                arr[i, a] += h
                out[a] = (up - down) / (2 * h)
        np.testing.assert_allclose(force[i], -grad, atol=atol)
        np.testing.assert_allclose(torque[i], np.cross(m[i], -field), atol=atol)


def test_force_and_torque_are_minus_the_energy_gradients():
    # the total energy: real-space pairs, wave vectors and the self term
    pos, dip = random_gas()
    assert_forces_are_energy_gradients(ewald_scene(pos, dip, 6.0, accuracy=1e-10, radius=0.4), (0, 7, 21))


@pytest.mark.parametrize("accuracy", [1e-3, 1e-5])
def test_tuned_accuracy_holds_against_a_converged_sum(accuracy):
    # RMS force error against the same gas at accuracy 1e-12, relative to the touching pull
    # 6 A m_rms^2 / d^4: the Wang-Holm estimates are statistical (random moments), within a factor 3
    pos, dip = random_gas(n=60, side=7.0, seed=8)
    reference = ewald_scene(pos, dip, 7.0, accuracy=1e-12, radius=0.4).forces()
    scene = ewald_scene(pos, dip, 7.0, accuracy=accuracy, radius=0.4)
    force, torque = scene.forces()
    pull = 6.0 * np.mean((dip ** 2).sum(1)) / 0.8 ** 4
    error = np.sqrt(np.mean(((force - reference[0]) ** 2).sum(1))) / pull
    assert error < 3.0 * accuracy
    assert error > accuracy / 100.0  # the tuning does not waste orders of magnitude
    assert np.sqrt(np.mean(((torque - reference[1]) ** 2).sum(1))) / pull < 3.0 * accuracy


def test_energy_does_not_depend_on_the_splitting():
    # the same sum split at two cutoffs (the tuning picks alpha for each): equal to 1e-9 relative
    pos, dip = random_gas()
    a = ewald_scene(pos, dip, 6.0, accuracy=1e-11, cutoff=2.0, radius=0.4)
    b = ewald_scene(pos, dip, 6.0, accuracy=1e-11, cutoff=2.9, radius=0.4)
    assert a.long_range[0].alpha != pytest.approx(b.long_range[0].alpha, rel=0.1)
    assert a.energy()["magnetic"] == pytest.approx(b.energy()["magnetic"], rel=1e-9)
    np.testing.assert_allclose(a.forces()[0], b.forces()[0], atol=1e-8)


def test_a_run_conserves_energy_to_the_integrators_order():
    # velocity Verlet runs of a magnetic gas with elastic contacts, free rotation and an Ewald sum:
    # the total energy's swings are the integrator's, O(dt^2): halving dt divides them by 4 (measured
    # 3.83; forces that were not the energy's gradient would leave a part that does not shrink)
    swings = []
    for dt in (1e-3, 5e-4):
        pos, dip = random_gas(n=40, side=6.0, seed=11)
        scene = ewald_scene(pos, 0.3 * dip, 6.0, accuracy=1e-7, radius=0.4,
                            velocity=np.random.default_rng(2).normal(size=(40, 3)), angular_velocity=np.zeros((40, 3)))
        energy = dk.Simulation(scene, dk.VelocityVerlet(dt)).run(duration=2.0, record_every=0.2, progress=False).energy
        assert np.ptp(energy["magnetic"]) > 0.02 * energy["kinetic"].mean()  # the dipoles do work
        swings.append(np.ptp(energy["total"]))
    assert swings[0] < 1e-4 * energy["kinetic"].mean()
    assert 3.5 < swings[0] / swings[1] < 4.5


def test_bad_input_is_refused():
    pos, dip = lattice(3)
    p = dk.Particles(position=pos, radius=0.3, mass=1.0, dipole=dip)
    with pytest.raises(ValueError, match="periodic along x, y and z"):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald())], box=dk.Box(3.0, periodic=(True, False, False)))
    with pytest.raises(ValueError, match="periodic along x, y and z"):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald())])
    for bad in (0.0, -1e-6, 1.0, float("nan")):
        with pytest.raises(ValueError, match="accuracy"):
            dk.Ewald(accuracy=bad)
    with pytest.raises(ValueError, match="surface"):
        dk.Ewald(surface="tinfoil")
    with pytest.raises(ValueError, match="power law"):
        dk.PowerLawDipole(1.0, long_range=dk.Ewald())
    with pytest.raises(ValueError, match="switch_width"):
        dk.Dipole(1.0, cutoff=1.4, switch_width=0.2, long_range=dk.Ewald())
    with pytest.raises(ValueError, match="demkit.Ewald"):
        dk.Dipole(1.0, long_range="ewald")
    zero = dk.Particles(position=pos, radius=0.3, mass=1.0, dipole=np.zeros_like(dip))
    with pytest.raises(ValueError, match="every moment is zero"):
        dk.Scene(zero, [dk.Dipole(1.0, long_range=dk.Ewald())], box=dk.Box(3.0, periodic=True))


def test_error_estimates_fall_with_their_parameters():
    # the tuning relies on both estimates decreasing in the direction it moves them
    args = (1.0, 100.0, 100, 1000.0)
    assert real_space_error(*args, 1.0, 3.0) < real_space_error(*args, 1.0, 2.0)
    assert reciprocal_error(*args, 1.0, 8, 10.0) < reciprocal_error(*args, 1.0, 6, 10.0)


def test_local_field_gives_the_torques_and_the_energy():
    # dk.measure.local_field with an Ewald sum: m_i x B_i is the torque the run applies, and the
    # magnetic energy is -1/2 sum_i m_i.B_i (the self correction included), both to round-off
    pos, dip = random_gas(n=30, side=6.0, seed=4)
    scene = ewald_scene(pos, dip, 6.0, accuracy=1e-9, surface="vacuum", radius=0.4)
    field = dk.measure.local_field(scene)
    _, torque = scene.forces()
    np.testing.assert_allclose(np.cross(dip, field), torque, atol=1e-10)
    energy = -0.5 * np.einsum("ij,ij->", dip, field)
    assert energy == pytest.approx(scene.energy()["magnetic"], rel=1e-10)
    # the stress has the sum's reciprocal virial (tests/test_measure.py): the trace of the Dipole's
    # virial is 3 U, the converged energy being of homogeneous degree -3 in the lengths (Euler: tr W =
    # -dU/d ln L); the tuned sum's energy is that to its accuracy (measured 2.4e-6 relative here: the
    # energy sums many terms that cancel, its relative error exceeds the forces')
    virial = dk.measure.stress(scene).virial["Dipole"]
    assert np.trace(virial) == pytest.approx(3 * energy, rel=1e-5)


def test_the_lammps_export_refuses_an_ewald_sum(tmp_path):
    pos, dip = lattice(3)
    scene = ewald_scene(pos, dip, 3.0, accuracy=1e-4)
    with pytest.raises(ValueError, match="ewald/dipole"):
        dk.export_lammps(scene, dk.VelocityVerlet(1e-3), tmp_path / "deck", duration=1.0)


def test_a_scene_file_asks_for_an_ewald_sum(tmp_path):
    pos, dip = lattice(4, "columns")  # an even side: the columns alternate across the faces
    text = f"""
[particles]
position = {pos.tolist()}
dipole = {dip.tolist()}
radius = 0.3
[box]
size = 4.0
periodic = true
[interactions.dipole]
prefactor = 1.0
[interactions.dipole.ewald]
accuracy = 1e-8
surface = "vacuum"
[interactions.kelvin_voigt]
stiffness = 1e5
[integrator]
dt = 0.0005
[run]
duration = 0.01
"""
    loaded = dk.parse_scene(text)
    tuned = loaded.scene.long_range[0]
    assert tuned.settings.surface == "vacuum" and tuned.estimated_error < 1e-8
    assert loaded.scene.energy()["magnetic"] / len(pos) == pytest.approx(-2.67678868438, abs=5e-8)
    with pytest.raises(dk.SceneFileError, match="interactions.dipole.ewald.surface"):
        dk.parse_scene(text.replace('"vacuum"', '"foil"'))
    with pytest.raises(dk.SceneFileError, match="switch_width: cannot be given together with ewald"):
        dk.parse_scene(text.replace("prefactor = 1.0", "prefactor = 1.0\ncutoff = 1.4\nswitch_width = 0.2"))


def test_multiple_time_stepping_puts_the_whole_sum_on_the_slow_step():
    # MultipleTimeStep with one inner step is velocity Verlet with the forces split in two: equal to
    # round-off only if the reciprocal sum is among the slow forces and nowhere else
    pos, dip = random_gas(n=30, side=6.0, seed=9)
    ends = []
    for integrator in (dk.VelocityVerlet(1e-3), dk.MultipleTimeStep(1e-3, inner=1)):
        scene = ewald_scene(pos, 0.3 * dip, 6.0, accuracy=1e-6, radius=0.4,
                            velocity=np.random.default_rng(3).normal(size=(30, 3)), angular_velocity=np.zeros((30, 3)))
        dk.Simulation(scene, integrator).run(duration=0.5, progress=False)
        ends.append((scene.particles.position.copy(), scene.particles.angular_velocity.copy()))
    np.testing.assert_allclose(ends[0][0], ends[1][0], atol=1e-11)
    np.testing.assert_allclose(ends[0][1], ends[1][1], atol=1e-10)


def test_cost_estimate_and_wave_vectors():
    # demkit info's estimate names the two parts of the sum; the count of wave vectors is the
    # brute-force count of the half-space vectors with 0 < |k| <= kcut
    pos, dip = random_gas(n=40, side=6.0, seed=2)
    scene = ewald_scene(pos, dip, 6.0, accuracy=1e-6, radius=0.4)
    tuned = scene.long_range[0]
    g = np.arange(-20, 21)
    k = 2 * np.pi / 6.0 * np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    k2 = (k ** 2).sum(1)
    assert tuned.wave_vectors == np.count_nonzero((k2 > 0) & (k2 <= tuned.kcut ** 2 * (1 + 1e-9))) // 2
    parts = dk.cost.estimate(scene, dk.VelocityVerlet(1e-3), 1.0).parts
    assert parts["reciprocal sum"] == pytest.approx(40 * tuned.wave_vectors * dk.cost.RECIPROCAL_VECTOR)
    assert parts["listed Ewald pairs"] > 0


def test_one_dipole_object_in_two_boxes():
    # the scene tunes a copy: the same Dipole joins scenes of different boxes, each keeps its own sum
    # (a single dipole in a cube of side L is the aligned lattice: -(2 pi / 3) mu^2 / L^3, metallic)
    dipole = dk.Dipole(1.0, long_range=dk.Ewald(1e-10))  # (the energy's error is of the force error's order)
    scenes = []
    for side in (2.0, 3.0):
        p = dk.Particles(position=[[0.5, 0.5, 0.5]], radius=0.4, mass=1.0, dipole=[[0.0, 0.0, 1.0]])
        scenes.append(dk.Scene(p, [dipole, dk.KelvinVoigt(stiffness=1000.0, damping=0.0)],
                               box=dk.Box(side, periodic=True)))
    assert dipole.tuned is None and scenes[0].long_range[0] is not scenes[1].long_range[0]
    for side, scene in zip((2.0, 3.0), scenes):
        assert scene.energy()["magnetic"] == pytest.approx(-2.0 * math.pi / 3.0 / side ** 3, abs=1e-8)
        np.testing.assert_allclose(dk.measure.local_field(scene), [[0.0, 0.0, 4.0 * math.pi / 3.0 / side ** 3]],
                                   atol=1e-8)
    assert len(scenes[0].candidate_pairs(dipole)) == 0  # the user's object finds its tuned copy
    with pytest.raises(ValueError, match="wave vectors"):
        two = dk.Particles(position=[[0.5, 0.5, 0.5], [1.5, 0.5, 0.5]], radius=0.4, mass=1.0,
                           dipole=[[0, 0, 1.0], [0, 0, 1.0]])
        dk.Scene(two, [dk.Dipole(1.0, cutoff=0.05, long_range=dk.Ewald(1e-6))], box=dk.Box(3.0, periodic=True))


def test_a_scene_built_again_is_not_tuned_again(monkeypatch):
    """The tuning reads the moments, radii, count, box and settings, not the positions: the same spheres
    moved, in a second scene, reuse the first tuning; other moments or another box tune again."""
    from demkit.interactions import ewald
    calls = []
    tune = ewald.Ewald.tune
    monkeypatch.setattr(ewald.Ewald, "tune", lambda self, *a: calls.append(1) or tune(self, *a))
    pos, dip = random_gas(n=20, side=5.0, seed=11)
    first = ewald_scene(pos, dip, 5.0, accuracy=3e-5)
    again = ewald_scene(np.roll(pos, 1, axis=0), dip, 5.0, accuracy=3e-5)
    assert len(calls) == 1 and again.long_range[0] is first.long_range[0]
    ewald_scene(pos, 1.1 * dip, 5.0, accuracy=3e-5)
    ewald_scene(pos, dip, 5.5, accuracy=3e-5)
    ewald_scene(pos, dip, 5.0, accuracy=1e-5)
    assert len(calls) == 4
    # the tuning reused is the tuning the scene would get: the same energy as a freshly tuned one's
    from demkit.interactions import dipole
    dipole._TUNINGS.clear()
    fresh = ewald_scene(np.roll(pos, 1, axis=0), dip, 5.0, accuracy=3e-5)
    assert len(calls) == 5 and fresh.energy()["magnetic"] == again.energy()["magnetic"]


def test_an_ewald_run_on_two_threads_gives_the_bits_of_one_thread():
    """The real-space pairs in fixed chunks on numba's threads, the reciprocal sum on one (a split of it
    over threads measured slower on one thread, docs/long_range.md): forces and a run on two threads
    give the bits of one thread, and the run gives numba's thread setting back."""
    def make():
        pos, dip = random_gas(n=120, side=12.0, seed=7)
        velocity = np.random.default_rng(4).normal(size=(120, 3))
        return ewald_scene(pos, dip, 12.0, accuracy=1e-5, radius=0.4, velocity=velocity)

    same_bits_on_two_threads_and_one(make, 0.03)
