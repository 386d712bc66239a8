"""Measurements (demkit.measure): the pressure tensor against finite differences of the energy under
a box strain and the ideal gas law, pair forces against the compiled kernels' forces, the local
field against the kernels' torques and the field of a dipole, coordination against a brute-force
count."""
import numpy as np
import pytest

import demkit as dk
from demkit import measure

R = 0.5


def squeezed_magnets(n=300, squeeze=0.97, seed=3, velocity=None):
    """A periodic random packing squeezed so that neighbours overlap, random unit moments; dipoles
    cut at 3 d and Kelvin-Voigt contacts (the scenes of the N-body tests: nothing new to compile)."""
    box = dk.build.box_for(n, R, 0.3)
    pos = dk.build.random_packing(n, R, box, seed=seed) * squeeze
    small = dk.Box(box.size * squeeze, periodic=True)
    dipole = dk.build.random_directions(n, seed=seed + 1)
    p = dk.Particles(position=pos, radius=R, mass=1.0, dipole=dipole, velocity=velocity)
    return dk.Scene(p, [dk.Dipole(prefactor=0.8, cutoff=3.0), dk.KelvinVoigt(stiffness=500.0, damping=1.0)],
                    box=small)


def potential(scene):
    e = scene.energy()
    return {"magnetic": e["magnetic"], "contact": e["contact"]}


def strained(scene, axis, eps):
    """The scene stretched by (1 + eps) along one axis: positions and box alike (affine)."""
    p = scene.particles
    scale = np.ones(3)
    scale[axis] += eps
    q = dk.Particles(position=p.position * scale, radius=R, mass=1.0, dipole=p.dipole)
    return dk.Scene(q, list(scene.interactions), box=dk.Box(scene.box.size * scale, periodic=True))


def test_the_virial_is_minus_the_energy_derivative_under_a_box_strain():
    # P_aa = -(1/V) dU/d eps_aa for an affine stretch along a, at rest (no kinetic part); checked
    # for each interaction's own virial against its own energy. Central differences with eps = 1e-6:
    # truncation ~eps^2 and round-off ~1e-16 / eps of the energy, so 1e-6 relative is generous.
    scene = squeezed_magnets()
    d = scene.separations(scene.candidate_pairs(scene.interactions[0]))
    r = np.linalg.norm(d, axis=1)
    # no pair crosses the dipoles' cutoff under the strain (h = 1e-6 moves a pair at r = 3 by 3e-6)
    assert np.min(np.abs(r - 3.0)) > 1e-5
    s = measure.stress(scene)
    volume = np.prod(scene.box.size)
    assert s.volume == pytest.approx(volume) and np.all(s.kinetic == 0.0)
    h = 1e-6
    for axis in range(3):
        up, down = potential(strained(scene, axis, h)), potential(strained(scene, axis, -h))
        for kind, name in (("magnetic", "Dipole"), ("contact", "KelvinVoigt")):
            derivative = (up[kind] - down[kind]) / (2 * h)
            assert s.virial[name][axis, axis] / volume == pytest.approx(-derivative / volume, rel=1e-6), (axis, kind)
    # both parts matter here: the contacts push (positive pressure), the dipoles' sign is the packing's
    assert s.virial["KelvinVoigt"].trace() > 0.0 and abs(s.virial["Dipole"].trace()) > 0.0
    assert s.per_sphere.sum(axis=0) == pytest.approx(volume * s.pressure_tensor, rel=1e-12, abs=1e-12)
    assert s.stress == pytest.approx(-s.pressure_tensor)


def test_pair_forces_add_up_to_the_kernels_forces_and_the_field_gives_their_torques():
    scene = squeezed_magnets(n=400, seed=5)
    force, torque = scene.forces()
    total = np.zeros_like(force)
    x = scene.particles.position
    for inter, pairs, d, f in scene.pair_forces():
        np.add.at(total, pairs[:, 1], f)
        np.add.at(total, pairs[:, 0], -f)
        # pairs across the periodic faces are there, by their minimum image
        assert np.any(np.abs(d - (x[pairs[:, 1]] - x[pairs[:, 0]])) > 1.0)
    scale = np.abs(force).max()
    assert np.abs(total - force).max() < 1e-10 * scale
    # the torque on each moment is m x B (Kelvin-Voigt without friction exerts none)
    field = measure.local_field(scene)
    expected = np.cross(scene.particles.dipole, field)
    assert np.abs(expected - torque).max() < 1e-10 * np.abs(torque).max()


def test_the_field_of_a_dipole_on_its_axis_and_beside_it():
    # B = A (3 (m.n) n - m) / r^3: 2 A m / r^3 on the axis, -A m / r^3 beside it
    A, m, r = 0.3, 2.0, 2.5
    p = dk.Particles(position=[[0, 0, 0], [r, 0, 0], [0, r, 0]], radius=R, mass=1.0,
                     dipole=[[m, 0, 0], [0, 0, 0], [0, 0, 0]])
    field = measure.local_field(dk.Scene(p, [dk.Dipole(prefactor=A)]))
    assert field[1] == pytest.approx([2 * A * m / r**3, 0, 0], abs=1e-15)
    assert field[2] == pytest.approx([-A * m / r**3, 0, 0], abs=1e-15)
    with_field = dk.Scene(p.copy(), [dk.Dipole(prefactor=A), dk.UniformField((0.0, 0.0, 0.25))])
    assert measure.local_field(with_field)[2] == pytest.approx([-A * m / r**3, 0, 0.25], abs=1e-15)
    assert measure.local_field(with_field, applied=False)[2] == pytest.approx([-A * m / r**3, 0, 0], abs=1e-15)


def test_an_ideal_gas_has_pressure_n_kT():
    # the kinetic part of P for Maxwell-Boltzmann velocities: p = N kT / V up to the sampling error
    # of sum m v^2 (relative standard deviation sqrt(2 / (3 N)) = 1.3 % for N = 4000): 5 of them
    n, kT = 4000, 1.3
    box = dk.build.box_for(n, R, 0.05)
    p = dk.Particles(position=dk.build.random_packing(n, R, box, seed=1), radius=R, mass=2.0,
                     velocity=dk.build.thermal_velocities(n, kT=kT, mass=2.0, seed=2))
    scene = dk.Scene(p, [dk.KelvinVoigt(stiffness=1000.0, damping=1.0)], box=box)
    s = measure.stress(scene)
    ideal = n * kT / np.prod(box.size)
    assert s.pressure == pytest.approx(ideal, rel=5 * np.sqrt(2 / (3 * n)))
    assert s.virial["KelvinVoigt"] == pytest.approx(np.zeros((3, 3)))  # nothing touches
    off = s.pressure_tensor[~np.eye(3, dtype=bool)]
    assert np.all(np.abs(off) < 5 * ideal / np.sqrt(n))  # <m vx vy> = 0, sd kT / sqrt(N) per sphere


def test_coordination_counts_the_spheres_each_touches():
    scene = squeezed_magnets(n=300, seed=7)
    pairs = scene.candidate_pairs(scene.interactions[1])
    d = scene.separations(pairs)
    touching = pairs[np.einsum("ij,ij->i", d, d) < (2 * R) ** 2]
    brute = np.bincount(touching.ravel(), minlength=300)
    z = measure.coordination(scene)
    assert z.sum() > 0 and np.array_equal(z, brute)


def test_magnetisation_and_bad_requests():
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=R, mass=1.0, dipole=[[0, 0, 2.0], [0, 0, 2.0]])
    open_scene = dk.Scene(p, [dk.Dipole(prefactor=1.0)])
    assert measure.magnetisation(open_scene, volume=8.0) == pytest.approx([0, 0, 0.5])
    with pytest.raises(ValueError, match="no box, so no volume"):
        measure.stress(open_scene)
    with pytest.raises(ValueError, match="volume must be a positive number"):
        measure.magnetisation(open_scene, volume=-1.0)
    plain = dk.Scene(dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=R, mass=1.0),
                     [dk.KelvinVoigt(stiffness=10.0)])
    with pytest.raises(ValueError, match="no dipole moments"):
        measure.local_field(plain)
    power_law = dk.Scene(p.copy(), [dk.PowerLawDipole(prefactor=1.0)])
    with pytest.raises(ValueError, match="no torque"):
        measure.local_field(power_law)


def test_sweep_observables_measure_the_scene_at_the_end():
    import sys
    from types import SimpleNamespace
    sweep = sys.modules["demkit.sweep"]  # dk.sweep is the function
    scene = squeezed_magnets(n=300, seed=7)
    out = sweep.observe(["pressure", "pressure_tensor", "coordination", "magnetisation"],
                        SimpleNamespace(scene=scene), None)
    s = measure.stress(scene)
    assert out["pressure"] == pytest.approx(s.pressure, rel=1e-12)
    assert out["pressure_tensor_xy"] == pytest.approx(s.pressure_tensor[0, 1], rel=1e-12)
    assert out["pressure_tensor_zz"] == pytest.approx(s.pressure_tensor[2, 2], rel=1e-12)
    assert out["coordination"] == pytest.approx(np.mean(measure.coordination(scene)))
    m = scene.particles.dipole.sum(axis=0) / np.prod(scene.box.size)
    assert [out["magnetisation_x"], out["magnetisation_y"], out["magnetisation_z"]] == pytest.approx(m)
    # an open scene has no volume: the observable records why, the others are measured
    p = dk.Particles(position=[[0, 0, 0], [3, 0, 0]], radius=R, mass=1.0, dipole=[[0, 0, 1.0], [0, 0, 1.0]])
    out = sweep.observe(["pressure", "coordination"], SimpleNamespace(scene=dk.Scene(p, [dk.Dipole()])), None)
    assert isinstance(out["pressure"], ValueError) and out["coordination"] == 0.0


def test_clusters_of_touching_spheres():
    # two touching pairs (one across the periodic x faces), a chain of three at gaps of 0.05, a lone sphere
    box = dk.Box([20.0, 20.0, 20.0], periodic=True)
    x = [[0.2, 5, 5], [19.3, 5, 5], [5, 5, 5], [5, 5.98, 5], [10, 10, 10], [11.05, 10, 10], [12.1, 10, 10],
         [15, 15, 15]]
    scene = dk.Scene(dk.Particles(position=x, radius=R, mass=1.0), [dk.KelvinVoigt(stiffness=10.0)], box=box)
    touching = measure.clusters(scene)
    assert touching.sizes.tolist() == [2, 2, 1, 1, 1, 1] and touching.count == 6 and touching.largest == 2
    assert touching.labels[0] == touching.labels[1] and touching.labels[2] == touching.labels[3]
    near = measure.clusters(scene, gap=0.06)  # the chain's gaps of 0.05 now connect it
    assert near.sizes.tolist() == [3, 2, 2, 1]
    assert near.mean_size == pytest.approx((9 + 4 + 4 + 1) / 8)
    with pytest.raises(ValueError, match="gap must be a non-negative length"):
        measure.clusters(scene, gap=-1.0)


def test_vtk_frames_carry_the_per_sphere_measurements(tmp_path):
    scene = squeezed_magnets(n=300, seed=7)
    writer = dk.VTKWriter(tmp_path / "vtk", every=1e-3, measures=["pressure", "coordination", "field"])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[writer])
    sim.run(duration=2e-3)
    from demkit.io.frames import read_frame
    frames = sorted((tmp_path / "vtk").glob("particles_*.vtu"))
    assert len(frames) == 3
    _, data = read_frame(frames[-1])
    expected = measure.sphere_arrays(sim.scene, ["pressure", "coordination", "field"])
    order = np.argsort(data["id"])
    for name in ("pressure_volume", "coordination", "local_field"):
        assert np.allclose(np.asarray(data[name])[order], expected[name], rtol=1e-12, atol=1e-12), name
    # the shares add up to p V
    s = measure.stress(sim.scene)
    assert expected["pressure_volume"].sum() == pytest.approx(s.pressure * s.volume, rel=1e-10)
    with pytest.raises(ValueError, match="unknown measures"):
        dk.VTKWriter(tmp_path / "other", every=1.0, measures=["stress"])


def ewald_gas(method, n=40, side=5.0, seed=7, scale=1.0, stiffness=1000.0):
    """A periodic magnetic gas with elastic contacts, its dipoles summed by ``method`` (a settings
    object): the spheres and box stretched by ``scale`` (a number or three); ``stiffness``: of the
    contacts (a run needs 2e4 to hold the touching pairs)."""
    rng = np.random.default_rng(seed)
    box = dk.Box(side, periodic=True)
    pos = dk.build.random_packing(n, 0.4, box, seed=seed)
    dip = rng.normal(size=(n, 3))
    stretch = np.broadcast_to(np.asarray(scale, dtype=float), (3,))
    p = dk.Particles(position=pos * stretch, radius=0.4, mass=1.0, dipole=dip)
    return dk.Scene(p, [dk.Dipole(prefactor=0.5, cutoff=2.4, long_range=method), dk.KelvinVoigt(stiffness)],
                    box=dk.Box(side * stretch, periodic=True))


def test_the_stress_of_an_ewald_sum_is_minus_the_energy_derivative_under_a_strain():
    """With a fixed splitting (alpha, cutoff), the magnetic virial (real-space pairs + reciprocal and
    surface terms) against central differences of the scene's magnetic energy under a stretch of each
    axis; the reciprocal part's whole tensor (shears too) against differences of its energy under any
    strain, that energy being the compiled sum's (to round-off) unstrained."""
    from reference_forces import reciprocal_energy_strained

    from demkit.interactions.ewald_virial import reciprocal_virial
    for surface in ("metallic", "vacuum"):
        method = dk.Ewald(1e-6, surface=surface, alpha=1.8)
        scene = ewald_gas(method)
        s = measure.stress(scene)
        h = 1e-6
        for axis in range(3):
            up, down = (ewald_gas(method, scale=np.where(np.arange(3) == axis, 1 + e, 1.0)).energy()["magnetic"]
                        for e in (h, -h))
            # central differences: truncation ~h^2, round-off ~1e-16 / h of an energy of order 1
            assert s.virial["Dipole"][axis, axis] == pytest.approx(-(up - down) / (2 * h), rel=1e-6, abs=1e-8), axis
        tuned = scene.long_range[0]
        p = scene.particles
        args = (p.position, p.dipole, scene.box.size, tuned.prefactor, tuned.alpha, surface == "vacuum", tuned.kmax,
                tuned.kcut)
        w, shares = reciprocal_virial(*args)
        derivative = np.zeros((3, 3))
        for a in range(3):
            for b in range(3):
                strain = np.zeros((3, 3))
                strain[a, b] = h
                derivative[a, b] = (reciprocal_energy_strained(*args, strain)
                                    - reciprocal_energy_strained(*args, -strain)) / (2 * h)
        np.testing.assert_allclose(w, -derivative.T, rtol=0, atol=1e-6 * np.abs(w).max())
        assert np.abs(w - w.T).max() > 1e-3 * np.abs(w).max()  # not symmetric: the moments are not strained
        np.testing.assert_allclose(shares.sum(axis=0), w, rtol=1e-12, atol=1e-12)
        from demkit.interactions.ewald import reciprocal_sum
        table = tuned.table_values()
        compiled = reciprocal_sum(p.position, p.dipole, scene.box.size, table, 0, np.zeros((40, 3)),
                                  np.zeros((40, 3)), False, np.zeros(4, dtype=np.int64))
        self_term = -tuned.prefactor * 2 * tuned.alpha ** 3 / (3 * np.sqrt(np.pi)) * np.sum(p.dipole ** 2)
        assert reciprocal_energy_strained(*args, np.zeros((3, 3))) + self_term == pytest.approx(compiled, rel=1e-12)
        assert s.per_sphere.sum(axis=0) == pytest.approx(s.volume * s.pressure_tensor, rel=1e-10, abs=1e-10)


def test_the_stress_of_a_p3m_sum_is_the_ewald_sums_to_its_accuracy():
    """The same spheres summed by P3M at 1e-5 and by Ewald at 1e-9: the magnetic virials agree to
    the P3M accuracy (relative to the virial's scale, the touching pull times a diameter per sphere)."""
    ewald, p3m = (measure.stress(ewald_gas(method)) for method in (dk.Ewald(1e-9), dk.P3M(1e-5)))
    scale = np.abs(ewald.virial["Dipole"]).max()
    assert np.abs(p3m.virial["Dipole"] - ewald.virial["Dipole"]).max() < 1e-3 * scale
    np.testing.assert_allclose(p3m.virial["KelvinVoigt"], ewald.virial["KelvinVoigt"], rtol=1e-12, atol=1e-12)


def test_the_stress_of_an_fmm_sum_is_the_exact_sums_and_its_trace_three_times_the_energy():
    """An open cluster of 300 touching magnets: the Dipole's virial by FMM3D (forced: exact_below=0;
    from its forces, sum_i (x_i - mean x) F_i) against the exact all-pairs sum's pair virial, within
    the FMM's accuracy (1e-10 asked, a virial of 300 terms: bound 1e-8 of its largest component;
    measured 5e-15); and Euler's theorem for a dipole energy, homogeneous of degree -3 in the
    positions: tr W = 3 U (measured 1e-15)."""
    pytest.importorskip("fmm3dpy")
    rng = np.random.default_rng(21)
    n, R = 300, 0.5
    x = dk.build.random_packing(n, R, dk.Box(9.0), seed=4)  # volume fraction 0.22, many contacts
    d = rng.normal(size=(n, 3))
    p = dk.Particles(position=x, radius=R, mass=1.0, velocity=0.1 * rng.normal(size=(n, 3)),
                     dipole=d / np.linalg.norm(d, axis=1)[:, None])
    contact = dk.KelvinVoigt(500.0, 1.0, friction=dk.Friction(0.5))
    exact, fmm = (measure.stress(dk.Scene(p.copy(), [dk.Dipole(0.2, long_range=method), contact]), volume=729.0)
                  for method in (None, dk.FMM(1e-10, exact_below=0)))
    w = exact.virial["Dipole"]
    np.testing.assert_allclose(fmm.virial["Dipole"], w, rtol=0, atol=1e-8 * np.abs(w).max())
    np.testing.assert_allclose(fmm.virial["KelvinVoigt"], exact.virial["KelvinVoigt"], rtol=1e-12, atol=1e-12)
    assert np.abs(w - w.T).max() > 1e-3 * np.abs(w).max()  # dipole forces are not central
    energy = dk.Scene(p.copy(), [dk.Dipole(0.2, long_range=dk.FMM(1e-10, exact_below=0))]).energy()["magnetic"]
    assert np.trace(fmm.virial["Dipole"]) == pytest.approx(3 * energy, rel=1e-8)
    assert fmm.per_sphere.sum(axis=0) == pytest.approx(fmm.volume * fmm.pressure_tensor, rel=1e-10, abs=1e-10)


@pytest.mark.parametrize("method", [None, dk.FMM(1e-10, exact_below=0)], ids=["exact", "FMM"])
def test_the_stress_of_an_open_sum_is_minus_the_energy_derivative_under_any_strain(method):
    """The convention (module docstring of demkit.measure): W_ab = sum over pairs d_a F_b, d = x_j - x_i
    and F the force on j, that is sum_i x_ia F_ib. Under a homogeneous strain x -> (I + eps) x of the
    positions, the moments held fixed, dU/d eps_ab = -sum_i F_ia x_ib, so W = -(dU/d eps)^T: all nine
    components, the six of the symmetric part and the three of the antisymmetric one, which this
    convention keeps (dipole forces are not central and the moments do not turn with the strain).
    Checked on 300 magnets in open space, summed exactly (Dipole without cutoff: all pairs) and by
    FMM3D, against central differences of the scene's own magnetic energy (h = 1e-5: truncation
    ~h^2 and round-off ~1e-16 U / h, both ~1e-10 of the largest component; measured 3e-10 exact and
    1.5e-10 FMM), bound 1e-7 of the largest component: the antisymmetric part is 5 % of it. And a
    truth of its own for the antisymmetric part: turning positions and moments together changes
    nothing, so W_ab - W_ba = -e_abc T_c, T the total torque on the moments (measured 4e-15)."""
    if method is not None:
        pytest.importorskip("fmm3dpy")
    rng = np.random.default_rng(21)
    n = 300
    x = dk.build.random_packing(n, R, dk.Box(9.0), seed=4)
    d = rng.normal(size=(n, 3))
    p = dk.Particles(position=x, radius=R, mass=1.0, dipole=d / np.linalg.norm(d, axis=1)[:, None])
    scene = dk.Scene(p, [dk.Dipole(0.2, long_range=method)])
    w = measure.stress(scene, volume=729.0).virial["Dipole"]
    start = p.position.copy()
    h = 1e-5
    derivative = np.zeros((3, 3))
    for a in range(3):
        for b in range(3):
            strain = np.zeros((3, 3))
            strain[a, b] = h
            energies = []
            for sign in (1, -1):
                p.position[...] = start @ (np.eye(3) + sign * strain).T
                energies.append(scene.energy()["magnetic"])
            derivative[a, b] = (energies[0] - energies[1]) / (2 * h)
    p.position[...] = start
    scale = np.abs(w).max()
    np.testing.assert_allclose(w, -derivative.T, rtol=0, atol=1e-7 * scale)
    antisymmetric = w - w.T
    assert np.abs(antisymmetric).max() > 1e-2 * scale  # what a symmetric convention would lose
    torque = scene.forces()[1].sum(axis=0)
    levi_civita = np.zeros((3, 3, 3))
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        levi_civita[a, b, c], levi_civita[b, a, c] = 1.0, -1.0
    np.testing.assert_allclose(antisymmetric, -np.einsum("abc,c->ab", levi_civita, torque), rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("surface", ["metallic", "vacuum"])
def test_the_stress_of_a_p3m_sum_is_minus_its_own_energy_derivative_to_its_accuracy(surface):
    """The diagonal of the P3M Dipole virial (real-space pairs + the mesh part + the surface term)
    against central differences of the P3M scene's own magnetic energy when the box and the spheres
    are stretched along one axis (h = 1e-5). The sum's parameters are held fixed: alpha, mesh and
    order passed explicitly (the tuned ones of P3M(1e-5)), the real-space cutoff the Dipole's; the
    mesh keeps its points and stretches with the box. The mesh part's virial is the Ewald reciprocal
    virial at the same alpha (demkit.interactions.ewald_virial), not the derivative of the mesh
    energy, so the two agree to the sum's accuracy, not to round-off: that accuracy bounds the RMS
    force error per sphere, accuracy x pull, and the virial sums N such errors times lever arms up
    to L/2, sqrt(N) accuracy pull L/2 if uncorrelated. Bound: twice that (2.1e-4 of the largest
    component here). Measured: 0.41 of sqrt(N) accuracy pull L/2 with either surface, 0.52 at
    accuracy 1e-4 (the gap falls with the accuracy asked). The mesh and surface terms' own virial is 0.2 (metallic) and
    0.4 (vacuum) of the largest component: leaving either out would miss by about a thousand bounds."""
    from demkit.interactions.ewald import scales
    accuracy = 1e-5
    tuned = ewald_gas(dk.P3M(accuracy, surface=surface)).long_range[0]
    method = dk.P3M(accuracy, surface=surface, alpha=tuned.alpha, mesh=tuned.mesh, order=tuned.order)
    scene = ewald_gas(method)
    fixed = scene.long_range[0]
    assert (fixed.alpha, fixed.mesh, fixed.order, fixed.cutoff) == (tuned.alpha, tuned.mesh, tuned.order, 2.4)
    w = measure.stress(scene).virial["Dipole"]
    h = 1e-5
    derivative = np.zeros(3)
    for axis in range(3):
        up, down = (ewald_gas(method, scale=np.where(np.arange(3) == axis, 1 + e, 1.0)) for e in (h, -h))
        assert up.long_range[0].mesh == fixed.mesh and up.long_range[0].alpha == fixed.alpha
        derivative[axis] = (up.energy()["magnetic"] - down.energy()["magnetic"]) / (2 * h)
    n, _, _, pull, _, _ = scales("a P3M sum", 0.5, scene.particles, scene.box, "")
    bound = 2 * np.sqrt(n) * accuracy * pull * scene.box.size[0] / 2
    np.testing.assert_allclose(np.diag(w), -derivative, rtol=0, atol=bound)
    mesh_part = fixed.virial(scene.particles, scene.box)[0]
    assert np.abs(np.diag(mesh_part)).max() > 100 * bound


def test_the_contact_stress_of_an_ewald_scene_keeps_the_friction_history_of_its_run():
    """40 magnets with frictional contacts (mu = 0.3) in a periodic box, their dipoles summed by Ewald,
    run for 300 steps: contacts slide and others stick, their friction springs hold history. The
    contact part of dk.measure.stress (the compiled pair loops) equals the virial built by hand from
    scene.contacts() (each law evaluated in Python on the stored history): sum over contacts of the
    branch vector n (R_i + R_j - overlap), from i to j, times the force on j, friction included; all
    nine components to 1e-12 of the largest (the same law in two evaluations: round-off; measured
    2e-16). The friction part is no small correction: the normal forces alone miss by 16 % of the
    largest component and the tensor is not symmetric. Rebuilding the scene from its spheres, the
    workaround once suggested, starts the friction springs from nothing and misses too."""
    n = 40
    box = dk.build.box_for(n, R, 0.3)
    rng = np.random.default_rng(5)
    x = dk.build.random_packing(n, R, box, seed=rng)
    v = dk.build.thermal_velocities(n, 2.0, 1.0, seed=rng)
    moments = dk.build.random_directions(n, seed=rng)
    p = dk.Particles(position=x, velocity=v, radius=R, mass=1.0, dipole=moments, angular_velocity=np.zeros((n, 3)))
    contact = dk.KelvinVoigt(2000.0, 3.0, friction=dk.Friction(0.3))
    scene = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald(1e-4)), contact], box=box)
    dk.Simulation(scene, dk.VelocityVerlet(2e-3)).run(duration=0.6, progress=False)
    c = scene.contacts()
    friction = np.linalg.norm(c.tangential_force, axis=1)
    assert np.all(c.wall < 0) and c.sliding.any() and np.any(~c.sliding & (friction > 0)), "contacts slide and stick"
    branch = c.normal * (p.radius[c.pairs[:, 0]] + p.radius[c.pairs[:, 1]] - c.overlap)[:, None]
    by_hand = np.einsum("ca,cb->ab", branch, c.force)
    s = measure.stress(scene)
    scale = np.abs(by_hand).max()
    np.testing.assert_allclose(s.virial["KelvinVoigt"], by_hand, rtol=0, atol=1e-12 * scale)
    normal_only = np.einsum("ca,cb->ab", branch, c.normal_force[:, None] * c.normal)
    assert np.abs(normal_only - by_hand).max() > 0.05 * scale
    assert np.abs(by_hand - by_hand.T).max() > 0.05 * scale
    off = ~np.eye(3, dtype=bool)
    assert np.all(np.abs(by_hand[off]) > 0.05 * scale)  # the shears are measured, not zeros
    # the magnetic part is there (the Ewald sum's), and the shares add up
    assert set(s.virial) == {"Dipole", "KelvinVoigt"} and np.abs(s.virial["Dipole"]).max() > 0
    assert s.per_sphere.sum(axis=0) == pytest.approx(s.volume * s.pressure_tensor, rel=1e-10, abs=1e-10)
    rebuilt = dk.Scene(p.copy(), [dk.Dipole(1.0, long_range=dk.Ewald(1e-4)), contact], box=box)
    assert np.abs(measure.stress(rebuilt).virial["KelvinVoigt"] - by_hand).max() > 0.05 * scale


def test_sweep_observables_measure_a_p3m_scene_file_at_the_end(tmp_path):
    """A scene file of 40 magnets in a periodic box, their dipoles by P3M: run as a sweep point runs
    it, its observables are dk.measure's of the scene it ended in (the same evaluation: to 1e-12),
    the pressure tensor's nine columns with the mesh part's virial in them (it moves the pressure
    by about 9 % here, asserted > 1 %: an observable that left it out would fail by 1e10 tolerances)."""
    import sys
    sweep = sys.modules["demkit.sweep"]  # dk.sweep is the function
    start = ewald_gas(None)
    p = start.particles
    velocity = np.random.default_rng(8).normal(size=(len(p), 3))
    text = f"""
[particles]
position = {p.position.tolist()}
dipole = {p.dipole.tolist()}
velocity = {velocity.tolist()}
radius = 0.4
[box]
size = 5.0
periodic = true
[interactions.dipole]
prefactor = 0.5
cutoff = 2.4
[interactions.dipole.p3m]
accuracy = 1e-3
[interactions.kelvin_voigt]
stiffness = 20000.0
[integrator]
dt = 0.001
[run]
duration = 0.005
"""
    loaded = dk.parse_scene(text)
    loaded.outputs = {}
    trajectory = loaded.run(progress=False, out_dir=tmp_path)
    names = ["pressure", "pressure_tensor", "magnetisation", "coordination"]
    out = sweep.observe(names, loaded, trajectory)
    scene = loaded.scene
    assert scene.long_range and type(scene.long_range[0]).__name__ == "TunedP3M" and scene.time == pytest.approx(0.005)
    s = measure.stress(scene)
    assert out["pressure"] == pytest.approx(s.pressure, rel=1e-12)
    for i, a in enumerate("xyz"):
        for k, b in enumerate("xyz"):
            assert out[f"pressure_tensor_{a}{b}"] == pytest.approx(s.pressure_tensor[i, k], rel=1e-12, abs=1e-14), a + b
    mesh = scene.long_range[0].virial(scene.particles, scene.box)[0]
    assert abs(np.trace(mesh) / (3 * s.volume)) > 1e-2 * abs(s.pressure)
    m = scene.particles.dipole.sum(axis=0) / s.volume
    assert [out[f"magnetisation_{a}"] for a in "xyz"] == pytest.approx(m, rel=1e-12)
    assert out["coordination"] == pytest.approx(np.mean(measure.coordination(scene)))


def test_vtk_frames_of_an_ewald_scene_carry_its_per_sphere_measurements(tmp_path):
    """VTK frames of an Ewald scene's run carry each sphere's share of the pressure (its reciprocal
    and real-space virial with the contacts', trace / 3) and its local field (every image): those of
    dk.measure on the state the run ended in (1e-12: the same evaluation written and read back); the
    shares add up to p V (1e-10), and the field is the one whose torques the kernels exert, m x B
    (1e-10 of the largest: two evaluations of the same Ewald sum, round-off; measured 3e-16). The
    reciprocal sum's own shares are 0.6 of the largest share: frames without them would fail."""
    scene = ewald_gas(dk.Ewald(1e-5), stiffness=2e4)
    writer = dk.VTKWriter(tmp_path / "vtk", every=1e-3, measures=["pressure", "coordination", "field"])
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-3), writers=[writer])
    sim.run(duration=2e-3, progress=False)
    from demkit.io.frames import read_frame
    frames = sorted((tmp_path / "vtk").glob("particles_*.vtu"))
    assert len(frames) == 3
    _, data = read_frame(frames[-1])
    order = np.argsort(data["id"])
    s = measure.stress(sim.scene)
    shares = np.trace(s.per_sphere, axis1=1, axis2=2) / 3.0
    np.testing.assert_allclose(np.asarray(data["pressure_volume"])[order], shares, rtol=1e-12, atol=1e-12)
    assert shares.sum() == pytest.approx(s.pressure * s.volume, rel=1e-10)
    reciprocal = np.trace(sim.scene.long_range[0].virial(sim.scene.particles, sim.scene.box)[1], axis1=1, axis2=2) / 3
    assert np.abs(reciprocal).max() > 1e-2 * np.abs(shares).max()  # the sum's own shares are in them
    field = np.asarray(data["local_field"])[order]
    np.testing.assert_allclose(field, measure.local_field(sim.scene), rtol=1e-12, atol=1e-12)
    torque = sim.scene.forces()[1]
    np.testing.assert_allclose(np.cross(sim.scene.particles.dipole, field), torque, rtol=0,
                               atol=1e-10 * np.abs(torque).max())
    assert np.array_equal(np.asarray(data["coordination"])[order], measure.coordination(sim.scene))
