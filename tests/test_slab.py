"""Slab sums (demkit.interactions.slab): Ewald and P3M in a box periodic along two axes, checked against
closed-form lattice layers and a direct sum over the layer's in-plane copies (tests/slab_reference.py)."""
import numpy as np
import pytest

import demkit as dk
from slab_reference import layer_energy, square_lattice_sum

METHODS = [pytest.param(dk.Ewald, 1e-6, id="ewald"), pytest.param(dk.P3M, 1e-5, id="p3m")]


def lattice_layer(moment, side=4, thickness=1.0, height=0.5):
    """A square monolayer of unit spacing, ``side`` x ``side`` spheres in the periodic cell, every moment
    ``moment``, at ``height`` in a box of this thickness."""
    g = np.arange(side) + 0.5
    xy = np.stack(np.meshgrid(g, g, indexing="ij"), -1).reshape(-1, 2)
    position = np.column_stack([xy, np.full(len(xy), height)])
    p = dk.Particles(position, radius=0.2, mass=1.0, dipole=np.tile(np.asarray(moment, dtype=float), (len(xy), 1)))
    return p, dk.Box([side, side, thickness], periodic=[True, True, False])


@pytest.mark.parametrize("method, accuracy", METHODS)
def test_square_lattice_layers_have_their_closed_form_energies(method, accuracy):
    """A square layer of parallel unit dipoles (spacing a = 1, A = 1) has the energy per dipole
    (1/2) sum_n' [1 - 3 cos^2] / |n|^3 with S = sum_n' |n|^-3 = 4 zeta(3/2) beta(3/2) = 9.0336:
    S/2 for moments across the layer, -S/4 along it, and S/2 - (3/4) sin^2(t) S tilted by t. The
    sums are tuned to a force error: the energy per dipole is within that error over a diameter,
    accuracy x pull x d (measured: Ewald at 1e-6 within 1.7e-6 and 4.8e-6 of the energy, 0.08 and 0.12
    of the bound; P3M at 1e-5 within 1.0e-4 of it along the layer, 0.24 of the bound)."""
    s = square_lattice_sum()
    for tilt in (0.0, np.pi / 2, np.arcsin(0.6)):  # the angle from the normal
        p, box = lattice_layer((np.sin(tilt), 0.0, np.cos(tilt)))
        scene = dk.Scene(p, [dk.Dipole(1.0, long_range=method(accuracy))], box=box)
        per_dipole = scene.energy()["magnetic"] / len(p)
        pull = 6.0 / 0.4 ** 4
        assert per_dipole == pytest.approx(s / 2 - 0.75 * np.sin(tilt) ** 2 * s, abs=accuracy * pull * 0.4), tilt
        # no forces; the torque about y is -dE/dtilt = (3/2) S sin cos (6.504 at sin = 0.6); each within
        # 3 x accuracy of the touching pull 6 A m^2 / d^4 (times d for torques): measured 1e-5 of it
        force, torque = scene.forces()
        assert np.abs(force).max() < 3 * accuracy * pull
        np.testing.assert_allclose(torque, np.tile([0.0, 1.5 * s * np.sin(tilt) * np.cos(tilt), 0.0], (len(p), 1)),
                                   atol=3 * accuracy * pull * 0.4)


def test_a_layer_does_not_depend_on_the_thickness_of_its_box():
    """The same monolayer in boxes 1 and 3 thick (drawn out to different lengths, with other wave
    vectors) has the same energy and fields: the copies across the gap are summed away."""
    energies = []
    for thickness in (1.0, 3.0):
        p, box = lattice_layer((0.6, 0.0, 0.8), thickness=thickness, height=0.5)
        scene = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald(1e-6))], box=box)
        energies.append(scene.energy()["magnetic"])
        assert scene.long_range[0].layer.thickness == thickness
    assert energies[0] == pytest.approx(energies[1], rel=1e-5)


@pytest.fixture(scope="module")
def random_layer():
    """12 spheres with random moments in a 4 x 4 x 2 slab, and the reference energy of the layer."""
    rng = np.random.default_rng(7)
    n, side, thickness = 12, 4.0, 2.0
    box = dk.Box([side, side, thickness], periodic=[True, True, False])
    position = dk.build.random_packing(n, 0.35, box, seed=3)
    dipole = rng.normal(size=(n, 3))
    return position, dipole, box, layer_energy(position, dipole, [side, 0, 0], [0, side, 0])


@pytest.mark.parametrize("method, accuracy", METHODS)
def test_energy_forces_and_torques_agree_with_the_direct_sum_over_the_copies(random_layer, method, accuracy):
    """Against the direct sum over in-plane copies: the energy within accuracy x pull x diameter per
    sphere (the force error over a diameter; measured 4.5e-6 and 1e-8 of it per sphere), and the
    forces and fields (torques) of two spheres, by central differences of the direct sum, within
    3 x accuracy of the touching pull (the RMS force error the sums are tuned to)."""
    position, dipole, box, reference = random_layer
    p = dk.Particles(position, radius=0.35, mass=1.0, dipole=dipole)
    scene = dk.Scene(p, [dk.Dipole(1.0, long_range=method(accuracy))], box=box)
    n, d = len(p), 0.7
    pull = 6.0 * np.mean(np.sum(dipole ** 2, axis=1)) / d ** 4
    assert abs(scene.energy()["magnetic"] - reference) < n * accuracy * pull * d
    force, torque = scene.forces()
    side = box.size[0]
    h = 1e-4
    for i in (2, 9):
        for axis in range(3):
            plus, minus = position.copy(), position.copy()
            plus[i, axis] += h
            minus[i, axis] -= h
            fd = -(layer_energy(plus, dipole, [side, 0, 0], [0, side, 0])
                   - layer_energy(minus, dipole, [side, 0, 0], [0, side, 0])) / (2 * h)
            assert abs(force[i, axis] - fd) < 3 * accuracy * pull, (i, axis)
    i = 4
    field = np.empty(3)
    for axis in range(3):
        plus, minus = dipole.copy(), dipole.copy()
        plus[i, axis] += h
        minus[i, axis] -= h
        field[axis] = -(layer_energy(position, plus, [side, 0, 0], [0, side, 0])
                        - layer_energy(position, minus, [side, 0, 0], [0, side, 0])) / (2 * h)
    np.testing.assert_allclose(torque[i], np.cross(dipole[i], field), atol=3 * accuracy * pull * d)


def test_the_stress_of_a_slab_is_minus_the_energy_derivative_of_the_direct_sum(random_layer):
    """W_ab = -dU/d eps_ba under x -> (1 + eps) x (the layer's lattice vectors strained with it) for the
    seven components that keep the layer flat (eps_zx = eps_zy = 0), the energy by the direct sum over
    the copies: within 1e-4 of the largest component (the sum's accuracy 1e-7; central differences
    of 1e-5)."""
    position, dipole, box, _ = random_layer
    p = dk.Particles(position, radius=0.35, mass=1.0, dipole=dipole)
    scene = dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald(1e-7))], box=box)
    stress = dk.measure.stress(scene)
    w = stress.virial["Dipole"]
    side = box.size[0]
    h = 1e-5
    worst = np.abs(w).max()
    for a, b in [(0, 0), (1, 1), (2, 2), (0, 1), (1, 0), (0, 2), (1, 2)]:
        energies = []
        for e in (h, -h):
            strain = np.eye(3)
            strain[a, b] += e
            energies.append(layer_energy(position @ strain.T, dipole, strain @ [side, 0, 0], strain @ [0, side, 0]))
        assert w[b, a] == pytest.approx(-(energies[0] - energies[1]) / (2 * h), abs=1e-4 * worst), (a, b)
    assert stress.volume == pytest.approx(box.volume)


@pytest.mark.parametrize("method", [dk.Ewald, dk.P3M])
def test_a_run_between_plates_conserves_energy(method):
    """A magnetic gas between two plates in a slab, stepped in compiled code: total energy within
    2e-3 of the magnetic energy's scale over 2000 steps (velocity Verlet at this step: measured
    6e-4 and 2e-4 of it)."""
    rng = np.random.default_rng(3)
    n, side, thickness = 40, 6.0, 2.0
    box = dk.Box([side, side, thickness], periodic=[True, True, False])
    d = rng.normal(size=(n, 3))
    p = dk.Particles(dk.build.random_packing(n, 0.3, box, seed=2), velocity=0.1 * rng.normal(size=(n, 3)), radius=0.3,
                     mass=1.0, dipole=d / np.linalg.norm(d, axis=1)[:, None], angular_velocity=np.zeros((n, 3)))
    scene = dk.Scene(p, [dk.Dipole(0.05, long_range=method(1e-4)), dk.KelvinVoigt(2000.0, 0.0),
                         dk.Wall((0, 0, 0), (0, 0, 1)), dk.Wall((0, 0, thickness), (0, 0, -1))], box=box)
    traj = dk.Simulation(scene, dk.VelocityVerlet(2e-3)).run(duration=4.0, record_every=0.5, progress=False)
    magnetic = traj.energy["magnetic"]
    assert magnetic[-1] < magnetic[0] - 2.0  # the moments found each other
    total = traj.energy["total"]
    assert np.abs(total - total[0]).max() < 2e-3 * np.abs(magnetic).max()


def test_a_sphere_leaving_the_layer_stops_the_run_and_diagnostics_refuse():
    n, side, thickness = 20, 6.0, 2.0
    box = dk.Box([side, side, thickness], periodic=[True, True, False])
    rng = np.random.default_rng(1)
    velocity = np.zeros((n, 3))
    velocity[5, 2] = 3.0
    p = dk.Particles(dk.build.random_packing(n, 0.3, box, seed=2), velocity=velocity, radius=0.3, mass=1.0,
                     dipole=rng.normal(size=(n, 3)))
    scene = dk.Scene(p, [dk.Dipole(0.05, long_range=dk.P3M(1e-3)), dk.KelvinVoigt(2000.0, 0.0)], box=box)
    sim = dk.Simulation(scene, dk.VelocityVerlet(2e-3))
    with pytest.raises(dk.SimulationError, match=r"particle id 5 left the layer the slab sum was tuned for.*"
                                                 r"length 2 along z") as stop:
        sim.run(duration=4.0, record_every=0.1, progress=False)
    assert stop.value.particle == 5 and len(stop.value.trajectory.time) >= 4  # the frames before it kept
    span = np.ptp(scene.particles.position[:, 2])
    assert thickness < span < thickness + 3.0 * 2e-3 * 1.01  # stopped at the first step beyond
    with pytest.raises(ValueError, match="particle id 5 left the layer"):
        scene.forces()


def test_boxes_a_slab_sum_refuses():
    p, _ = lattice_layer((0, 0, 1))
    for periodic in ([True, False, False], [False, False, False]):
        with pytest.raises(ValueError, match="periodic along x, y and z, or along two of them"):
            dk.Scene(p, [dk.Dipole(1.0, long_range=dk.Ewald(1e-4))], box=dk.Box([4, 4, 1], periodic=periodic))
    with pytest.raises(ValueError, match="surface='vacuum' is for boxes periodic along x, y and z"):
        dk.Scene(p, [dk.Dipole(1.0, long_range=dk.P3M(1e-4, surface="vacuum"))],
                 box=dk.Box([4, 4, 1], periodic=[True, True, False]))


def test_a_scene_file_sums_a_slab_and_compare_dipole_sums_measures_one(random_layer):
    """The square layer from a scene file (box periodic along x and y) has its closed-form energy;
    compare_dipole_sums on a slab measures Ewald and P3M within their accuracy of its converged slab
    sum, a cutoff far from it."""
    p, _ = lattice_layer((0.0, 0.0, 1.0))
    text = f"""
[particles]
position = {p.position.tolist()}
dipole = {p.dipole.tolist()}
radius = 0.2
[box]
size = [4.0, 4.0, 1.0]
periodic = [true, true, false]
[interactions.dipole]
prefactor = 1.0
[interactions.dipole.p3m]
accuracy = 1e-5
[integrator]
dt = 0.001
[run]
duration = 0.01
"""
    loaded = dk.parse_scene(text)
    assert loaded.scene.long_range[0].layer.axis == 2
    assert loaded.scene.energy()["magnetic"] / len(p) == pytest.approx(square_lattice_sum() / 2, rel=1e-4)
    position, dipole, box, _ = random_layer
    report = dk.compare_dipole_sums(dk.Particles(position, radius=0.35, mass=1.0, dipole=dipole), box, 1.0,
                                    [dk.Ewald(1e-4), dk.P3M(1e-4), dk.Dipole(1.0, cutoff=1.9)], repeats=1)
    assert report.space == "slab open along z" and "slab open along z" in report.table()
    ewald, p3m, cutoff = report.rows
    assert ewald.force_error < 2e-4 and p3m.force_error < 2e-4 and cutoff.force_error > 1e-2


def test_induced_moments_in_a_slab_match_a_dense_solve_over_the_copies():
    """Magnetisable steel balls between two plates (examples/steel_columns/run.py's cell, 40 balls):
    the moments solved with slab Ewald and P3M sums at 1e-4 against the example's dense solve over
    every periodic copy of the cell (its own code: copies within 12 cell widths, the rest as a sheet),
    within 1e-3 of the largest (the sums bound the field's error too; measured 2.0e-5 and 3.0e-5); and a
    compiled run of the P3M slab keeps solving them (its moments at the end are a fresh solve's)."""
    import runpy
    from pathlib import Path
    example = runpy.run_path(str(Path(__file__).resolve().parents[1] / "examples" / "steel_columns" / "run.py"))
    particles, box = example["build"](40, 0.05, 8.0, 1)
    exact = example["solve_moments"](example["slab_tensor"](particles.position, box.size, images=12))
    for method in (dk.Ewald, dk.P3M):
        p = dk.Particles(position=particles.position, radius=example["R"], mass=example["MASS"],
                         susceptibility=example["CHI"])
        dipole = dk.Dipole(example["PREFACTOR"], long_range=method(1e-4), induction=dk.Induction(tolerance=1e-8))
        scene = dk.Scene(p, [dipole, example["contact_law"](), dk.UniformField((0, 0, example["B0"])),
                             dk.Wall((0, 0, 0), (0, 0, 1)),
                             dk.Wall((0, 0, box.size[2]), (0, 0, -1)), dk.Gravity((0, 0, -9.81))], box=box)
        scene.induce()
        assert np.abs(p.dipole - exact).max() < 1e-3 * np.abs(exact).max(), method
    dk.Simulation(scene, dk.VelocityVerlet(3e-6)).run(duration=6e-5, progress=False)
    moved = p.dipole.copy()
    scene.induce()
    assert np.abs(p.dipole - moved).max() < 1e-6 * np.abs(moved).max()
    assert not np.allclose(p.position, particles.position)  # the balls moved: a new solve each step
