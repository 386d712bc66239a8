"""Fast multipole dipole sums (dk.Dipole(long_range=dk.FMM(...)), FMM3D) against the exact pair sum.

Every scene has elastic contacts beside the dipoles (inert where nothing touches), so the file
compiles two kernel modules: a small open scene (no lists) and a cluster (a contact list)."""
import sys

import numpy as np
import pytest

import demkit as dk

pytest.importorskip("fmm3dpy")  # installed with the test extras (pyproject.toml): the tests run in CI


def cluster(n, seed=1):
    rng = np.random.default_rng(seed)
    box = dk.build.box_for(n, 0.5, 0.15)
    pos = dk.build.random_packing(n, 0.5, box, seed=seed)
    dip = rng.normal(size=(n, 3))
    return pos, dip / np.linalg.norm(dip, axis=1)[:, None] * rng.uniform(0.5, 1.5, (n, 1))


def scene_of(pos, dip, long_range, **kw):
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip, **kw)
    return dk.Scene(p, [dk.Dipole(1.0, long_range=long_range), dk.KelvinVoigt(stiffness=1e4, damping=0.0)])


def test_two_dipoles_match_the_exact_pair():
    # pins FMM3D's conventions (the 1/4 pi of its kernel, the sign of its dipole term, the order of
    # its Hessian: xx yy zz xy xz yz): energy, forces and torques of the exact pair to 1e-12 relative
    pos = np.array([[0.0, 0.0, 0.0], [1.3, 0.4, -0.2]])
    dip = np.array([[0.3, -0.5, 0.8], [0.6, 0.7, -0.1]])
    fmm = scene_of(pos, dip, dk.FMM(1e-14, exact_below=0))
    exact = scene_of(pos, dip, None)
    assert fmm.energy()["magnetic"] == pytest.approx(exact.energy()["magnetic"], rel=1e-12)
    for a, b in zip(fmm.forces(), exact.forces()):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-13)
    # the Dipole alone (a small scene compiled without reference counting, but for the sum's arrays)
    alone = dk.Scene(dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip),
                     [dk.Dipole(1.0, long_range=dk.FMM(1e-14, exact_below=0))])
    for a, b in zip(alone.forces(), exact.forces()):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-13)


@pytest.mark.parametrize("accuracy", [1e-6, 1e-9])
def test_a_cluster_matches_the_exact_sum_to_the_precision_asked(accuracy):
    # 400 dipoles: RMS force and torque errors against the exact all-pairs sum, relative to the RMS
    # force, below 10 eps (FMM3D's eps bounds the error relative to the sums' size); energy likewise
    pos, dip = cluster(400)
    fmm = scene_of(pos, dip, dk.FMM(accuracy, exact_below=0))
    exact = scene_of(pos, dip, None)
    (f, t), (f0, t0) = fmm.forces(), exact.forces()
    scale_f = np.sqrt(np.mean((f0 ** 2).sum(1)))
    scale_t = np.sqrt(np.mean((t0 ** 2).sum(1)))
    assert np.sqrt(np.mean(((f - f0) ** 2).sum(1))) < 10 * accuracy * scale_f
    assert np.sqrt(np.mean(((t - t0) ** 2).sum(1))) < 10 * accuracy * scale_t
    e, e0 = fmm.energy()["magnetic"], exact.energy()["magnetic"]
    assert abs(e - e0) < 10 * accuracy * abs(e0)
    assert fmm.plan.groups[0].members[0][1].__class__.__name__ == "KelvinVoigt"  # no dipole pair loop


def test_a_run_with_contacts_follows_the_exact_one():
    # 0.2 time units of a magnetic cluster with elastic contacts: positions equal the exact sum's run
    # to 1e-8 (eps 1e-12; the two differ by round-off growing over the run)
    pos, dip = cluster(150, seed=3)
    ends = []
    for long_range in (dk.FMM(1e-12, exact_below=0), None):
        scene = scene_of(pos, 0.5 * dip, long_range, velocity=np.zeros((150, 3)), angular_velocity=np.zeros((150, 3)))
        dk.Simulation(scene, dk.VelocityVerlet(1e-3)).run(duration=0.2, progress=False)
        ends.append(scene.particles.position.copy())
    np.testing.assert_allclose(ends[0], ends[1], atol=1e-8)
    assert np.abs(ends[0] - pos).max() > 1e-4  # the dipoles moved the spheres


def test_multiple_time_stepping_takes_the_sum_as_a_slow_force():
    # MultipleTimeStep(dt, inner=1) is velocity Verlet with the kicks split in two: the same path to
    # round-off. (It passes rows of its stage array to the sum, which once reached FMM3D as the
    # whole stage array.)
    pos, dip = cluster(100, seed=4)
    ends = []
    for integrator in (dk.VelocityVerlet(1e-3), dk.MultipleTimeStep(1e-3, inner=1)):
        scene = scene_of(pos, 0.5 * dip, dk.FMM(1e-12, exact_below=0), velocity=np.zeros((100, 3)),
                         angular_velocity=np.zeros((100, 3)))
        dk.Simulation(scene, integrator).run(duration=0.05, progress=False)
        ends.append(scene.particles.position.copy())
    np.testing.assert_allclose(ends[1], ends[0], atol=1e-12)
    assert np.abs(ends[0] - pos).max() > 1e-6


def test_local_field_gives_the_torques_and_the_energy():
    pos, dip = cluster(120, seed=5)
    scene = scene_of(pos, dip, dk.FMM(1e-12, exact_below=0))
    field = dk.measure.local_field(scene)
    _, torque = scene.forces()
    np.testing.assert_allclose(np.cross(dip, field), torque, atol=1e-9)
    assert -0.5 * np.einsum("ij,ij->", dip, field) == pytest.approx(scene.energy()["magnetic"], rel=1e-10)
    parts = dk.cost.estimate(scene, dk.VelocityVerlet(1e-3), 1.0).parts
    assert parts["fast multipole sum"] == pytest.approx(120 * (dk.cost.FMM_SPHERE + 9 * dk.cost.FMM_SPHERE_PER_DIGIT))


def test_bad_input_is_refused(monkeypatch):
    pos, dip = cluster(10)
    p = dk.Particles(position=pos, radius=0.5, mass=1.0, dipole=dip)
    with pytest.raises(ValueError, match="open space.*periodic along xyz.*Ewald"):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.FMM())], box=dk.Box(20.0, periodic=True))
    with pytest.raises(ValueError, match="takes no cutoff"):
        dk.Scene(p, [dk.Dipole(1.0, cutoff=3.0, long_range=dk.FMM())])
    for bad in (0.0, 1.0, -1e-3, 1e-16, float("nan")):
        with pytest.raises(ValueError, match="FMM accuracy"):
            dk.FMM(bad)
    for bad in (-1, 2.5, True, "always", float("nan")):
        with pytest.raises(ValueError, match="exact_below"):
            dk.FMM(exact_below=bad)
    monkeypatch.setitem(sys.modules, "fmm3dpy", None)  # as if not installed
    with pytest.raises(ImportError, match=r'pip install "demkit\[fmm\]"'):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.FMM(exact_below=0))])
    # below the crossover the exact sum needs no fmm3dpy
    assert dk.Scene(p, [dk.Dipole(1.0, long_range=dk.FMM())]).long_range == ()


def test_below_its_crossover_a_scene_keeps_the_exact_sum_and_says_so(capsys):
    # the crossover N* = 2 c_FMM / c_pair grows with the digits asked (benchmarks/results/fmm.json
    # measures ~3500, 1e4 and 1.5e4 at eps 1e-3, 1e-6, 1e-9: the model within 30 %)
    crossings = [dk.FMM(eps).crossover() for eps in (1e-3, 1e-6, 1e-9)]
    assert crossings == sorted(crossings) and 2500 < crossings[0] < 4500 and 7000 < crossings[1] < 13000
    assert 10000 < crossings[2] < 20000
    pos, dip = cluster(120, seed=5)
    auto = scene_of(pos, dip, dk.FMM(1e-6))
    exact = scene_of(pos, dip, None)
    assert auto.long_range == () and auto.interactions[0].pair_loop
    assert "exact all-pairs sum of 120 spheres (below the crossover" in auto.interactions[0].long_range_note
    for a, b in zip(auto.forces(), exact.forces()):
        np.testing.assert_array_equal(a, b)  # the same loop: the same bits
    forced = scene_of(pos, dip, dk.FMM(1e-6, exact_below=100))
    assert forced.long_range and "fast multipole sum of 120 spheres" in forced.interactions[0].long_range_note
    assert scene_of(pos, dip, dk.FMM(1e-6, exact_below=121)).long_range == ()


def test_a_scene_file_asks_for_a_fast_multipole_sum():
    pos, dip = cluster(80, seed=2)
    text = f"""
[particles]
position = {pos.tolist()}
dipole = {(0.3 * dip).tolist()}
radius = 0.5
[interactions.dipole]
prefactor = 1.0
[interactions.dipole.fmm]
accuracy = 1e-10
exact_below = 0
[interactions.kelvin_voigt]
stiffness = 1e4
[integrator]
dt = 0.001
[run]
duration = 0.01
"""
    scene = dk.parse_scene(text).scene
    assert repr(scene.long_range[0]) == "TunedFMM(accuracy=1e-10)"
    assert dk.parse_scene(text.replace("exact_below = 0", "")).scene.long_range == ()  # 80 < the crossover
    exact = scene_of(pos, 0.3 * dip, None)
    assert scene.energy()["magnetic"] == pytest.approx(exact.energy()["magnetic"], rel=1e-9)
    with pytest.raises(dk.SceneFileError, match="give only one of ewald, p3m, fmm"):
        dk.parse_scene(text + "[interactions.dipole.ewald]\naccuracy = 1e-6\n")
    with pytest.raises(dk.SceneFileError, match="cutoff: cannot be given together with fmm"):
        dk.parse_scene(text.replace("prefactor = 1.0", "prefactor = 1.0\ncutoff = 3.0"))
