"""Induced dipoles (demkit.interactions.induction) against closed forms, a dense direct solve,
finite differences of the energy, conservation laws and the other dipole sums."""
import math

import numpy as np
import pytest

import demkit as dk
from demkit.interactions.dipole import switch
from demkit.interactions.induction import clausius_mossotti

A = 1e-7  # mu0 / 4 pi, SI
R = 0.005  # steel balls of 1 cm
B0 = 0.02  # tesla
ZETA3 = 1.2020569031595942


def alpha_of(chi, radius=R):
    return clausius_mossotti(chi) * radius**3 / A


def solved(positions, chi, field=(0.0, 0.0, B0), dipole=None, box=None, tolerance=1e-13, **dipole_options):
    """The moments a scene solves at its start (no kernels run: the first solve is Python's)."""
    p = dk.Particles(positions, radius=R, mass=1e-3, susceptibility=chi, dipole=dipole)
    effects = [dk.UniformField(field)] if field is not None else []
    scene = dk.Scene(p, [dk.Dipole(A, induction=dk.Induction(tolerance), **dipole_options)] + effects, box=box)
    return scene, p.dipole.copy()


@pytest.mark.parametrize("beta", [0.2, 0.999])
@pytest.mark.parametrize("gap", [2.02, 3.0])
def test_two_spheres_along_and_across_the_field_match_mutual_induction(beta, gap):
    """m = alpha B0 / (1 - 2 A alpha / r^3) along the field, alpha B0 / (1 + A alpha / r^3) across it:
    the field of one point dipole at the other's centre (2 A m / r^3 on the axis, -A m / r^3 beside
    it). Two spheres are solved exactly by conjugate gradients (one direction by symmetry): to round-off."""
    chi = 3.0 * beta / (1.0 - beta)
    alpha = alpha_of(chi)
    r = gap * R
    _, along = solved([[0, 0, 0], [0, 0, r]], chi)
    _, across = solved([[0, 0, 0], [r, 0, 0]], chi)
    np.testing.assert_allclose(along[:, 2], alpha * B0 / (1.0 - 2.0 * A * alpha / r**3), rtol=1e-12)
    np.testing.assert_allclose(across[:, 2], alpha * B0 / (1.0 + A * alpha / r**3), rtol=1e-12)
    assert np.all(along[:, :2] == 0.0) and np.all(across[:, :2] == 0.0)


@pytest.mark.parametrize("axis, coupling", [(2, 4.0), (0, -2.0)])
def test_middle_of_a_long_chain_carries_the_infinite_chain_moment(axis, coupling):
    """Touching soft-iron spheres (beta = 0.999) in a straight chain of 401 along (across) the field:
    each feels 2 zeta(3) times the field of one neighbour from each side, so
    m = alpha B0 / (1 - c zeta(3) A alpha / d^3) with c = 4 (along) or -2 (across). The middle sphere
    misses the neighbours beyond 200 d: sum_(k>200) 2/k^3 ~ 1/200^2 = 2.5e-5 of zeta(3), times the
    coupling 0.6 / (1 - 0.6): below 1e-4."""
    chi = 3.0 * 0.999 / 0.001
    d = 2.0 * R
    n = 401
    positions = np.zeros((n, 3))
    positions[:, axis] = (np.arange(n) - n // 2) * d
    _, m = solved(positions, chi, tolerance=1e-12)
    alpha = alpha_of(chi)
    expected = alpha * B0 / (1.0 - coupling * ZETA3 * A * alpha / d**3)
    assert m[n // 2, 2] == pytest.approx(expected, rel=1e-4)
    assert m[0, 2] < m[n // 2, 2] if coupling > 0 else m[0, 2] > m[n // 2, 2]  # the ends feel less (more)


def test_a_soft_sphere_beside_a_magnet_carries_the_magnet_field_and_the_magnet_keeps_its_moment():
    """No applied field: the soft sphere on the magnet's axis at r feels 2 A m0 / r^3 and carries
    alpha times it (a permanent moment does not respond to it); to round-off."""
    chi, m0, r = 5000.0, 0.05, 2.5 * R
    p = dk.Particles([[0, 0, 0], [0, 0, r]], radius=R, mass=1e-3, dipole=[[0, 0, m0], [0, 0, 0]],
                     susceptibility=[0.0, chi])
    dk.Scene(p, [dk.Dipole(A, induction=dk.Induction(1e-14))])
    assert p.dipole[0].tolist() == [0.0, 0.0, m0]
    assert p.dipole[1, 2] == pytest.approx(alpha_of(chi) * 2.0 * A * m0 / r**3, rel=1e-12)


def _dense_solve(positions, chi, box, cutoff, width):
    """The induced moments by a dense linear solve: T from the minimum image and the switch S(r)."""
    n = len(positions)
    alpha = alpha_of(np.asarray(chi))
    t = np.zeros((3 * n, 3 * n))
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            d = positions[j] - positions[i]
            d -= box * np.round(d / box)
            r = np.linalg.norm(d)
            if r >= cutoff:
                continue
            u = d / r
            s = switch(r, cutoff, width)[0]
            t[3 * i:3 * i + 3, 3 * j:3 * j + 3] = s * A * (3.0 * np.outer(u, u) - np.eye(3)) / r**3
    a = np.repeat(alpha, 3)
    b0 = np.tile([0.3 * B0, 0.0, B0], n)
    return np.linalg.solve(np.eye(3 * n) - a[:, None] * t, a * b0).reshape(n, 3)


def test_cutoff_switch_and_minimum_image_agree_with_a_dense_solve():
    """A periodic box of 80 spheres of two susceptibilities with a switched cutoff (neighbour lists):
    the same linear system solved densely by numpy. Conjugate gradients stop at 1e-13 of the right-hand
    side; the condition number is below 10: agreement to 1e-11."""
    rng = np.random.default_rng(4)
    size = 20.0 * R
    box = dk.Box([size] * 3, periodic=True)
    positions = _spread(rng, 80, size)
    chi = np.where(np.arange(80) % 2 == 0, 2000.0, 0.5)
    _, m = solved(positions, chi, field=(0.3 * B0, 0.0, B0), box=box, cutoff=6.0 * R, switch_width=2.0 * R)
    truth = _dense_solve(np.asarray(positions), chi, np.full(3, size), 6.0 * R, 2.0 * R)
    np.testing.assert_allclose(m, truth, rtol=0, atol=1e-11 * np.abs(truth).max())


def _spread(rng, n, size, gap=2.05 * R):
    """n random centres in a periodic cube at least ``gap`` apart (minimum image)."""
    out = []
    while len(out) < n:
        x = rng.uniform(0, size, 3)
        d = np.asarray(out) - x if out else np.zeros((0, 3))
        d -= size * np.round(d / size)
        if not len(d) or np.min(np.linalg.norm(d, axis=1)) > gap:
            out.append(x)
    return np.array(out)


def test_ewald_and_p3m_solve_the_same_moments_and_fmm_the_exact_ones():
    """Periodic: 120 soft spheres at volume fraction 0.06 solved with Ewald(1e-9) and P3M(1e-5);
    the field error of a sum is its force error's order (both come from the same screened
    pairs): the moments agree within 10x the P3M accuracy relative to the largest.
    Open space: FMM(1e-10) forced against the exact all-pairs sum, agreement within 1e-8."""
    rng = np.random.default_rng(7)
    size = 24.0 * R
    box = dk.Box([size] * 3, periodic=True)
    positions = _spread(rng, 120, size)
    _, ewald = solved(positions, 1000.0, box=box, long_range=dk.Ewald(1e-9), tolerance=1e-12)
    _, p3m = solved(positions, 1000.0, box=box, long_range=dk.P3M(1e-5), tolerance=1e-12)
    scale = np.abs(ewald).max()
    assert np.abs(p3m - ewald).max() < 1e-4 * scale
    lone = alpha_of(1000.0) * B0
    assert np.abs(ewald[:, 2] - lone).max() > 1e-2 * lone  # the spheres do polarise each other
    cluster = _spread(rng, 70, 12.0 * R)
    _, exact = solved(cluster, 1000.0, tolerance=1e-13)
    _, fmm = solved(cluster, 1000.0, long_range=dk.FMM(1e-10, exact_below=0), tolerance=1e-13)
    assert np.abs(fmm - exact).max() < 1e-8 * np.abs(exact).max()


def test_long_range_sums_solve_and_step_the_induced_moments_in_compiled_code():
    """The compiled path (forces(), energy(), runs with velocity Verlet and multiple time stepping),
    not only the first solve made in Python: 27 magnetisable spheres near a lattice in a periodic
    box, summed by P3M(1e-5) against Ewald(1e-9). The moments (solved to 1e-12) and the energy agree
    within the P3M accuracy (measured 1.2e-7 and 1.3e-7), the largest force within 10x it (the
    accuracy bounds an RMS error; measured 5.7e-5). The P3M table once ended where the induction's
    began: its mesh was read from the whole tail and every compiled call failed."""
    g = (np.arange(3) * 4.0 / 3 + 0.5) * R
    positions = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    positions += np.random.default_rng(3).uniform(-0.05, 0.05, positions.shape) * R
    box = dk.Box([4.0 * R] * 3, periodic=True)
    results = []
    for method in (dk.Ewald(1e-9), dk.P3M(1e-5)):
        p = dk.Particles(positions, radius=0.4 * R, mass=1e-3, susceptibility=10.0)
        scene = dk.Scene(p, [dk.Dipole(A, long_range=method, induction=dk.Induction(1e-12)),
                             dk.UniformField((0.0, 0.3 * B0, B0))], box=box)
        p.dipole[:] = 0.0  # re-solved from nothing by the compiled code
        force, torque = scene.forces()
        results.append((force, p.dipole.copy(), scene.energy()["magnetic"]))
    (f_ewald, m_ewald, u_ewald), (f_p3m, m_p3m, u_p3m) = results
    assert np.abs(m_ewald).max() > 0 and np.abs(f_ewald).max() > 0
    assert np.abs(m_p3m - m_ewald).max() < 1e-5 * np.abs(m_ewald).max()
    assert np.abs(f_p3m - f_ewald).max() < 1e-4 * np.abs(f_ewald).max()
    assert u_p3m == pytest.approx(u_ewald, rel=1e-5)
    for integrator in (dk.VelocityVerlet(1e-3), dk.MultipleTimeStep(2e-3, inner=2)):
        p = dk.Particles(positions, radius=0.4 * R, mass=1e-3, susceptibility=10.0)
        scene = dk.Scene(p, [dk.Dipole(A, long_range=dk.P3M(1e-5), induction=dk.Induction(1e-12)),
                             dk.UniformField((0.0, 0.3 * B0, B0))], box=box)
        traj = dk.Simulation(scene, integrator).run(duration=0.006, record_every=0.002, progress=False)
        assert np.all(np.isfinite(traj.position)) and np.all(np.isfinite(traj.dipole))
        assert np.abs(traj.dipole[-1] - m_p3m).max() < 1e-2 * np.abs(m_p3m).max()  # barely moved


@pytest.fixture(scope="module")
def cluster_scene():
    """Four soft spheres and a magnet with contacts, in a field: one compiled kernel for the tests below."""
    positions = np.array([[0, 0, 0], [0.3, 0.1, 2.3], [2.2, 0.4, 0.5], [2.4, -0.2, 3.0], [-2.5, 0.3, 1.2]]) * R
    p = dk.Particles(positions, radius=R, mass=4e-3, dipole=[[0, 0, 0]] * 4 + [[0.02, 0.0, 0.01]],
                     susceptibility=[1000.0, 1000.0, 10.0, 1000.0, 0.0])
    scene = dk.Scene(p, [dk.Dipole(A, induction=dk.Induction(1e-13)), dk.KelvinVoigt(4e4, 0.0),
                         dk.UniformField((0.2 * B0, 0.0, B0))])
    return scene


def test_forces_are_minus_the_gradient_of_the_energy_with_moments_re_solved(cluster_scene):
    """U = U_dipole + U_field + sum |m|^2 / 2 alpha, re-solved at each displaced position, against the
    forces of fixed moments: central differences with h = 1e-6 R have an O(h^2) error ~1e-12 of
    the force scale and round-off ~1e-16 U / h ~ 1e-9 of it: agreement within 1e-6."""
    scene = cluster_scene
    p = scene.particles
    start = p.position.copy()
    force, torque = scene.forces()
    h = 1e-6 * R
    for i in range(len(p)):
        for a in range(3):
            values = []
            for sign in (1, -1):
                p.position[...] = start
                p.position[i, a] += sign * h
                values.append(scene.energy()["total"])
            assert -(values[0] - values[1]) / (2 * h) == pytest.approx(force[i, a], abs=1e-6 * np.abs(force).max())
    p.position[...] = start
    scene.induce()
    # the torque on a magnetisable sphere, alpha B x B, vanishes; the magnet's does not
    assert np.abs(torque[:4]).max() < 1e-10 * np.abs(torque[4]).max()
    # U = -1/2 sum m.B0 over the soft spheres when alone: checked on the soft spheres' share
    e = scene.energy()
    assert e["induction"] > 0.0


def test_a_run_of_colliding_soft_spheres_conserves_energy_and_momentum(cluster_scene):
    """Velocity Verlet with the moments re-solved every step, elastic contacts: the total energy
    stays within 1e-6 of the magnetic energy scale (dt^2 error of the 40 us contacts at dt = 1 us)
    and the momenta are conserved to round-off (pair forces, a uniform field pulls nothing)."""
    scene = cluster_scene
    p = scene.particles
    sim = dk.Simulation(scene, dk.VelocityVerlet(1e-6))
    traj = sim.run(0.01, record_every=0.0005)
    e = traj.energy
    scale = np.abs(e["magnetic"]).max()
    assert e["kinetic"].max() > 1e-3 * scale, "the spheres moved"
    assert np.ptp(e["total"]) < 1e-6 * scale
    assert np.abs(scene.linear_momentum()).max() < 1e-12
    assert scene.induction.solves >= 10000 and scene.induction.mean_iterations < 10


def test_a_solve_that_stops_converging_stops_the_run_and_keeps_the_frames(cluster_scene):
    scene = cluster_scene
    scene.induction.settings = dk.Induction(1e-15, 1)
    try:
        with pytest.raises(dk.SimulationError, match="did not converge in 1 iterations") as stop:
            dk.Simulation(scene, dk.VelocityVerlet(1e-6)).run(1e-3, record_every=1e-4)
    finally:
        scene.induction.settings = dk.Induction(1e-13)
    assert stop.value.trajectory is not None


def test_an_unused_susceptibility_costs_nothing():
    """chi = 0 everywhere: the same kernel source as without susceptibility, no induction energy."""
    positions = [[0, 0, 0], [0, 0, 3 * R]]
    plain = dk.Scene(dk.Particles(positions, radius=R, dipole=[[0, 0, 1e-3]] * 2), [dk.Dipole(A)])
    zero = dk.Scene(dk.Particles(positions, radius=R, dipole=[[0, 0, 1e-3]] * 2, susceptibility=0.0), [dk.Dipole(A)])
    assert zero.induction is None and zero.fused_source() == plain.fused_source()
    assert "induction" not in zero.energy_kinds


@pytest.mark.parametrize("bad, match", [(-1.0, "susceptibility must be >= 0"), (math.nan, "NaN"),
                                        ([1.0, 2.0, 3.0], "shape")])
def test_bad_susceptibilities_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        dk.Particles([[0, 0, 0], [0, 0, 3 * R]], radius=R, susceptibility=bad)


def test_scenes_that_cannot_induce_are_refused():
    p = dk.Particles([[0, 0, 0], [0, 0, 3 * R]], radius=R, susceptibility=100.0)
    with pytest.raises(ValueError, match="nothing to magnetise them"):
        dk.Scene(p, [dk.Dipole(A)])
    with pytest.raises(ValueError, match="need a dk.Dipole"):
        dk.Scene(p, [dk.UniformField((0, 0, B0))])
    with pytest.raises(ValueError, match="central power law"):
        dk.Scene(p, [dk.PowerLawDipole(A), dk.UniformField((0, 0, B0))])
    with pytest.raises(ValueError, match="did not converge"):
        far = dk.Particles([[0, 0, 0], [0, 0, 2.2 * R], [0.5 * R, 2.2 * R, 0]], radius=R, susceptibility=100.0)
        dk.Scene(far, [dk.Dipole(A, induction=dk.Induction(1e-15, 1)), dk.UniformField((0, 0, B0))])
    for bad in (0.0, 1.0, math.nan):
        with pytest.raises(ValueError, match="tolerance"):
            dk.Induction(tolerance=bad)
    with pytest.raises(ValueError, match="max_iterations"):
        dk.Induction(max_iterations=0.5)
    with pytest.raises(ValueError, match="must be a demkit.Induction"):
        dk.Dipole(A, induction=1e-8)


def test_a_checkpointed_run_resumes_bit_identical(tmp_path, cluster_scene):
    """The solve starts from the moments in the state, which the checkpoint keeps: a run stopped and
    resumed in a new scene ends on the same bits as the uninterrupted one."""
    start = cluster_scene.particles.copy()

    def fresh():
        p = start.copy()
        return dk.Scene(p, [dk.Dipole(A, induction=dk.Induction(1e-13)), dk.KelvinVoigt(4e4, 0.0),
                            dk.UniformField((0.2 * B0, 0.0, B0))])

    whole = fresh()
    dk.Simulation(whole, dk.VelocityVerlet(1e-6)).run(until=2e-3)
    path = tmp_path / "run.ckpt"
    first = fresh()
    dk.Simulation(first, dk.VelocityVerlet(1e-6), checkpoint=dk.Checkpoint(path)).run(until=1e-3)
    second = fresh()
    sim = dk.Simulation(second, dk.VelocityVerlet(1e-6), checkpoint=dk.Checkpoint(path))
    sim.resume()
    sim.run(until=2e-3)
    for name in ("position", "velocity", "dipole"):
        assert np.array_equal(getattr(second.particles, name), getattr(whole.particles, name)), name


def test_scene_files_make_magnetisable_spheres_and_check_the_keys():
    text = """
units = "plain"
[particles]
position = [[0, 0, 0], [0, 0, 0.002]]
radius = 0.001
mass = 3.3e-5
susceptibility = 1000
[interactions.dipole]
prefactor = 1e-7
[interactions.dipole.induction]
tolerance = 1e-12
[interactions.uniform_field]
field = [0, 0, 0.02]
[integrator]
method = "VelocityVerlet"
dt = 1e-6
[run]
duration = 1e-4
"""
    loaded = dk.parse_scene(text)
    alpha = clausius_mossotti(1000.0) * 1e-9 / 1e-7
    expected = alpha * 0.02 / (1.0 - 2.0 * 1e-7 * alpha / 0.002**3)
    np.testing.assert_allclose(loaded.scene.particles.dipole[:, 2], expected, rtol=1e-12)
    assert loaded.scene.induction.settings.tolerance == 1e-12
    with pytest.raises(dk.SceneFileError, match="particles.susceptibility: must be zero or positive"):
        dk.parse_scene(text.replace("susceptibility = 1000", "susceptibility = -1"))
    with pytest.raises(dk.SceneFileError, match="induction.maxiter: unknown key"):
        dk.parse_scene(text.replace("tolerance = 1e-12", "maxiter = 3"))


def test_docs_page_example_prints_what_it_says():
    """docs/induced_dipoles.md: its printed numbers, recomputed."""
    import re
    from pathlib import Path
    page = Path(__file__).resolve().parents[1] / "docs" / "induced_dipoles.md"
    ns = {}
    for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S):
        exec(compile(block, str(page), "exec"), ns)
    p, force = ns["p"], ns["force"]
    assert p.dipole[0, 2] == pytest.approx(0.0002656, rel=1e-4)
    assert force[1, 2] == pytest.approx(-0.002645, rel=1e-3)
    assert force[1, 2] == pytest.approx(-6 * 1e-7 * p.dipole[0, 2] ** 2 / 0.002**4, rel=1e-12)
    assert ns["scene"].energy()["total"] == pytest.approx(-0.5 * p.dipole[:, 2].sum() * 0.02, rel=1e-12)


def test_lammps_export_refuses_magnetisable_spheres(tmp_path):
    scene, _ = solved([[0, 0, 0], [0, 0, 3 * R]], 100.0)
    with pytest.raises(ValueError, match="LAMMPS has no induced dipoles"):
        dk.export_lammps(scene, dk.VelocityVerlet(1e-6), tmp_path)


def test_long_range_sums_bound_the_field_error_of_magnetisable_spheres():
    """Induced moments follow the field: Ewald and P3M sums tuned for magnetisable spheres bound the
    RMS error of the field at the spheres (relative to a touching neighbour's field, 2 A m/d^3) by the
    accuracy asked, as they bound the forces' (relative to the touching pull). A lone sphere feels no
    force from its images (the force error said nothing: 1e-19 before) but their field."""
    accuracy = 1e-4
    for method in (dk.Ewald(accuracy), dk.P3M(accuracy)):
        scenes = []
        for settings in (method, dk.Ewald(1e-10)):
            p = dk.Particles([[1.0, 1.0, 1.0]], radius=0.4, mass=1.0, susceptibility=10.0)
            scenes.append(dk.Scene(p, [dk.Dipole(1.0, long_range=settings), dk.UniformField([0, 0, 1.0])],
                                   box=dk.Box(4.0, periodic=True)))
        tuned = scenes[0].long_range[0]
        moment = np.linalg.norm(scenes[0].particles.dipole[0])
        field, exact = (dk.measure.local_field(scene)[0] for scene in scenes)
        error = np.linalg.norm(field - exact) / (2 * moment / 0.8 ** 3)
        # the estimate is the error measured at random places: the Ewald sum's error at a lone sphere is
        # the same everywhere, the mesh's depends on where the sphere sits between mesh points
        spread = 0.3 if isinstance(method, dk.P3M) else 0.05
        assert 1e-7 < error < accuracy and error == pytest.approx(tuned.estimated_error, rel=spread), (method, error)


@pytest.mark.parametrize("make_sum", [lambda: dk.Ewald(1e-6), lambda: dk.P3M(1e-3)], ids=["Ewald", "P3M"])
def test_magnetisable_spheres_with_a_long_range_sum_on_two_threads_give_the_bits_of_one(make_sum):
    """27 magnetisable spheres near a lattice in a field, in a periodic box, their moments solved
    every step through an Ewald or P3M sum (the real-space pairs in fixed chunks on the threads, the
    mesh's planes too): the forces, and a run's positions, spins and induced moments, on two of
    numba's threads are the bits of one thread (equality: the truth is the one-thread run). P3M at
    1e-3: a 15^3 mesh (1e-5 takes 64^3, four times the test's time, for nothing more to see)."""
    from conftest import same_bits_on_two_threads_and_one
    g = (np.arange(3) * 4.0 / 3 + 0.5) * R
    positions = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    positions += np.random.default_rng(3).uniform(-0.05, 0.05, positions.shape) * R

    def make():
        p = dk.Particles(positions, radius=0.4 * R, mass=1e-3, susceptibility=10.0, angular_velocity=np.zeros((27, 3)))
        return dk.Scene(p, [dk.Dipole(A, long_range=make_sum(), induction=dk.Induction(1e-12)),
                            dk.UniformField((0.0, 0.3 * B0, B0))], box=dk.Box([4.0 * R] * 3, periodic=True))

    scene = make()
    assert scene.induction is not None and scene.effects and scene.long_range
    same_bits_on_two_threads_and_one(make, 0.004)
