"""dk.build: packings without overlaps at the asked volume fraction, lattices, chains, rings, random states."""
import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import demkit as dk
from demkit import build

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs" / "builders.md"
BENCHMARKS = ROOT / "benchmarks"
TOL = 1e-9  # relative slack for "touching" in the overlap checks


def closest_pair_gap(x, radius, box=None):
    """min over pairs of |x_i - x_j| - (r_i + r_j), checked independently with a k-d tree
    (periodic axes through boxsize)."""
    r = np.broadcast_to(np.asarray(radius, dtype=float), (len(x),))
    reach = 2 * r.max()
    if box is not None and box.any_periodic:
        size = np.where(box.periodic, box.size, np.inf)  # inf: open along that axis
        tree = cKDTree(np.where(box.periodic, np.mod(x, box.size), x), boxsize=size)
    else:
        tree = cKDTree(x)
    pairs = tree.query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        return np.inf
    d = x[pairs[:, 1]] - x[pairs[:, 0]]
    if box is not None:
        d = box.minimum_image(d)
    return float(np.min(np.linalg.norm(d, axis=1) - r[pairs[:, 0]] - r[pairs[:, 1]]))


# ----------------------------------------------------------------------------- random packing

@pytest.mark.parametrize("phi", [0.05, 0.2, 0.3])
def test_periodic_packing_has_no_overlaps_and_the_asked_fraction(phi):
    n, r = 3000, 0.5
    box = build.box_for(n, r, phi)
    assert box.periodic.all()
    x = build.random_packing(n, r, box, seed=3)
    assert x.shape == (n, 3) and x.dtype == np.float64 and x.flags.c_contiguous
    assert np.all((x >= 0) & (x < box.size))
    assert closest_pair_gap(x, r, box) >= -TOL
    assert n * 4 / 3 * math.pi * r**3 / box.volume == pytest.approx(phi, rel=1e-12)


def test_periodic_packing_uses_the_minimum_image():
    """Spheres near opposite faces of a dense small periodic box are kept apart through the boundary."""
    n, r = 400, 0.5
    box = build.box_for(n, r, 0.3)
    x = build.random_packing(n, r, box, seed=0)
    assert closest_pair_gap(x, r, box) >= -TOL
    # without the periodic images some pairs across faces would be missed: check there are some close ones
    d = box.minimum_image(x[:, None] - x[None]).reshape(-1, 3)
    raw = (x[:, None] - x[None]).reshape(-1, 3)
    across = (np.linalg.norm(d, axis=1) < 1.2) & (np.linalg.norm(raw, axis=1) > box.size[0] / 2)
    assert across.any()


def test_open_and_mixed_boxes_keep_spheres_inside_the_open_axes():
    r = 0.5
    for periodic in (False, (True, True, False)):
        box = dk.Box((12.0, 10.0, 8.0), periodic=periodic)
        n = int(0.25 * box.volume / (4 / 3 * math.pi * r**3))
        x = build.random_packing(n, r, box, seed=7)
        flags = np.array(box.periodic)
        assert np.all(x[:, ~flags] >= r) and np.all(x[:, ~flags] <= box.size[~flags] - r)
        assert np.all(x[:, flags] >= 0) and np.all(x[:, flags] < box.size[flags])
        assert closest_pair_gap(x, r, box) >= -TOL
        assert len(box.outside(x)) == 0


def test_polydisperse_packing_keeps_the_radius_order():
    rng = np.random.default_rng(1)
    n = 2000
    r = rng.uniform(0.3, 0.9, n)
    box = build.box_for(n, r, 0.25)
    x = build.random_packing(n, r, box, seed=5)
    assert closest_pair_gap(x, r, box) >= -TOL
    assert np.sum(4 / 3 * math.pi * r**3) / box.volume == pytest.approx(0.25, rel=1e-12)
    # row i has radius r[i]: the smallest gap of the big spheres is measured with their own radii
    big = r > 0.8
    assert closest_pair_gap(x[big], r[big], box) >= -TOL
    order = build.spatial_order(x, box, width=2 * r.max())
    assert sorted(order) == list(range(n))


def test_packing_rows_are_in_cell_order():
    n, r = 5000, 0.5
    box = build.box_for(n, r, 0.2)
    x = build.random_packing(n, r, box, seed=2)
    ncell = np.floor(box.size / (2 * r)).astype(int)
    c = np.minimum((x / (box.size / ncell)).astype(int), ncell - 1)
    index = (c[:, 0] * ncell[1] + c[:, 1]) * ncell[2] + c[:, 2]
    assert np.all(np.diff(index) >= 0)
    np.testing.assert_array_equal(build.spatial_order(x, box, 2 * r), np.arange(n))


def test_packing_seed_reproduces():
    box = build.box_for(500, 0.5, 0.2)
    a = build.random_packing(500, 0.5, box, seed=11)
    np.testing.assert_array_equal(a, build.random_packing(500, 0.5, box, seed=11))
    assert not np.array_equal(a, build.random_packing(500, 0.5, box, seed=12))


def test_small_periodic_box_with_fewer_than_three_cells():
    box = dk.Box((2.5, 2.5, 30.0), periodic=True)
    x = build.random_packing(12, 0.5, box, seed=4)
    assert closest_pair_gap(x, 0.5, box) >= -TOL


def test_single_sphere_and_dilute_packing():
    x = build.random_packing(1, 0.5, dk.Box(3.0), seed=0)
    assert x.shape == (1, 3) and np.all((x >= 0.5) & (x <= 2.5))
    box = build.box_for(200, 0.5, 0.001)  # very dilute: wider cells, still exact
    assert closest_pair_gap(build.random_packing(200, 0.5, box, seed=0), 0.5, box) >= -TOL


@pytest.mark.parametrize("args, match", [
    ((0, 0.5, 0.2), "at least 1"),
    ((2.5, 0.5, 0.2), "integer"),
    ((10, 0.0, 0.2), "radius"),
    ((10, float("nan"), 0.2), "radius"),
    ((10, -1.0, 0.2), "radius"),
    ((10, np.ones(9), 0.2), r"shape \(10,\)"),
    ((10, 0.5, 0.0), "volume_fraction"),
    ((10, 0.5, -0.1), "volume_fraction"),
    ((10, 0.5, 0.45), "random sequential addition"),
    ((10, 0.5, float("nan")), "volume_fraction"),
])
def test_box_for_rejects_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        build.box_for(*args)


def test_random_packing_rejects_bad_input():
    with pytest.raises(ValueError, match="demkit.Box"):
        build.random_packing(10, 0.5, 10.0)
    with pytest.raises(ValueError, match="shorter than the largest sphere's diameter"):
        build.random_packing(2, 0.5, dk.Box((0.9, 5, 5)))
    with pytest.raises(ValueError, match="0.384"):
        build.random_packing(100, 0.5, dk.Box(4.0, periodic=True))  # phi = 0.82
    with pytest.raises(ValueError, match=r"placed only \d+ of 1000 spheres"):
        build.random_packing(1000, 0.5, build.box_for(1000, 0.5, 0.37), seed=0, max_attempts=20000)


# ----------------------------------------------------------------------------- lattices

@pytest.mark.parametrize("kind, per_cell, neighbours", [("sc", 1, 6), ("bcc", 2, 8), ("fcc", 4, 12), ("hcp", 4, 12)])
def test_lattice_spacing_count_and_periodic_tiling(kind, per_cell, neighbours):
    s = 1.3
    x, box = build.lattice(kind, (4, 3, 4), spacing=s)
    assert x.shape == (4 * 3 * 4 * per_cell, 3)
    assert box.periodic.all() and np.all((x >= 0) & (x < box.size))
    d = np.linalg.norm(box.minimum_image(x[:, None] - x[None]), axis=-1)
    np.fill_diagonal(d, np.inf)
    assert d.min() == pytest.approx(s, rel=1e-12)
    # every sphere, including those at the faces, has the lattice's number of nearest neighbours
    counts = np.sum(np.abs(d - s) < 1e-9 * s, axis=1)
    assert np.all(counts == neighbours)


def test_lattice_radius_means_touching_and_open_box_holds_the_spheres():
    x, box = build.lattice("fcc", 3, radius=0.5, periodic=False)
    assert len(x) == 4 * 27
    assert closest_pair_gap(x, 0.5) == pytest.approx(0.0, abs=1e-12)
    assert np.all(x >= 0.5 - 1e-12) and np.all(x <= box.size - 0.5 + 1e-12)
    assert len(box.outside(x)) == 0


def test_lattice_volume_fraction_of_close_packing():
    for kind in ("fcc", "hcp"):
        x, box = build.lattice(kind, 2, radius=0.5)
        assert len(x) * math.pi / 6 / box.volume == pytest.approx(math.pi / math.sqrt(18), rel=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    (dict(kind="diamond", shape=2, spacing=1.0), "unknown lattice kind"),
    (dict(kind="sc", shape=0, spacing=1.0), "shape"),
    (dict(kind="sc", shape=(2, 2), spacing=1.0), "shape"),
    (dict(kind="sc", shape=2.5, spacing=1.0), "shape"),
    (dict(kind="sc", shape=2), "exactly one"),
    (dict(kind="sc", shape=2, spacing=1.0, radius=0.5), "exactly one"),
    (dict(kind="sc", shape=2, spacing=-1.0), "spacing"),
    (dict(kind="sc", shape=2, radius=float("nan")), "radius"),
])
def test_lattice_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        build.lattice(**kwargs)


# ----------------------------------------------------------------------------- chains and rings

def test_chain_touches_head_to_tail():
    x, mu = build.chain(6, 0.5, start=(1, 2, 3), direction=(0, 3, 4), moment=2.0)
    u = np.array([0, 0.6, 0.8])
    np.testing.assert_allclose(x[0], [1, 2, 3])
    np.testing.assert_allclose(np.diff(x, axis=0), np.tile(u, (5, 1)), atol=1e-15)
    np.testing.assert_allclose(mu, np.tile(2.0 * u, (6, 1)))
    assert closest_pair_gap(x, 0.5) == pytest.approx(0.0, abs=1e-12)


def test_chain_gap():
    x, _ = build.chain(3, 1.0, gap=0.25)
    np.testing.assert_allclose(x[:, 0], [0.0, 2.25, 4.5])


@pytest.mark.parametrize("n", [3, 4, 7, 20])
def test_ring_touches_with_tangent_dipoles_circulating_one_way(n):
    r, centre, normal = 0.5, np.array([1.0, -2.0, 0.5]), np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    x, mu = build.ring(n, r, centre=centre, normal=3 * normal, moment=1.5)
    rel = x - centre
    np.testing.assert_allclose(rel @ normal, 0, atol=1e-12)  # in the plane
    radii = np.linalg.norm(rel, axis=1)
    np.testing.assert_allclose(radii, radii[0], rtol=1e-12)  # on a circle
    nxt = np.roll(x, -1, axis=0)
    np.testing.assert_allclose(np.linalg.norm(nxt - x, axis=1), 2 * r, rtol=1e-12)  # neighbours touch
    assert closest_pair_gap(x, r) == pytest.approx(0.0, abs=1e-12)  # and nobody overlaps
    np.testing.assert_allclose(np.linalg.norm(mu, axis=1), 1.5)
    np.testing.assert_allclose(np.sum(mu * rel, axis=1), 0, atol=1e-12)  # tangent
    circulation = np.cross(rel, mu) @ normal  # right-handed about the normal, for every sphere
    np.testing.assert_allclose(circulation, 1.5 * radii, rtol=1e-12)
    np.testing.assert_allclose(mu.sum(axis=0), 0, atol=1e-12)  # flux closure: no net moment


def test_ring_gap():
    x, _ = build.ring(5, 0.5, gap=0.1)
    np.testing.assert_allclose(np.linalg.norm(np.roll(x, -1, axis=0) - x, axis=1), 1.1, rtol=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda: build.chain(0, 0.5), "at least 1"),
    (lambda: build.chain(3, 0.0), "radius"),
    (lambda: build.chain(3, 0.5, direction=(0, 0, 0)), "direction must not be the zero vector"),
    (lambda: build.chain(3, 0.5, direction=(1, 0)), "direction"),
    (lambda: build.chain(3, 0.5, start=(0, 0, np.nan)), "start"),
    (lambda: build.chain(3, 0.5, gap=-0.1), "gap"),
    (lambda: build.chain(3, 0.5, moment=np.inf), "moment"),
    (lambda: build.ring(2, 0.5), "at least 3"),
    (lambda: build.ring(5, -0.5), "radius"),
    (lambda: build.ring(5, 0.5, normal=(0, 0, 0)), "normal must not be the zero vector"),
    (lambda: build.ring(5, 0.5, centre=(0, 0)), "centre"),
])
def test_chain_and_ring_reject_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ----------------------------------------------------------------------------- random states

def test_random_directions_are_uniform_unit_vectors():
    u = build.random_directions(20000, seed=1)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, rtol=1e-14)
    assert np.all(np.abs(u.mean(axis=0)) < 0.03)  # 4 sigma: sigma = 1/sqrt(3 n)
    np.testing.assert_allclose(np.cov(u.T), np.eye(3) / 3, atol=0.02)
    np.testing.assert_array_equal(u, build.random_directions(20000, seed=1))


def test_thermal_velocities_have_zero_momentum_and_the_temperature():
    n, kT = 20000, 2.5
    m = np.random.default_rng(0).uniform(0.5, 2.0, n)
    v = build.thermal_velocities(n, kT, m, seed=2)
    np.testing.assert_allclose((m[:, None] * v).sum(axis=0), 0, atol=1e-9)
    ke = 0.5 * np.sum(m[:, None] * v**2)
    assert ke / (1.5 * (n - 1) * kT) == pytest.approx(1.0, abs=0.03)
    np.testing.assert_array_equal(v, build.thermal_velocities(n, kT, m, seed=2))
    assert np.all(build.thermal_velocities(3, 0.0, 1.0, seed=0) == 0)


def test_thermal_spins_equipartition():
    n, kT, inertia = 20000, 1.0, 0.1
    w = build.thermal_spins(n, kT, inertia, seed=3)
    assert 0.5 * inertia * np.sum(w**2) / (1.5 * n * kT) == pytest.approx(1.0, abs=0.03)


@pytest.mark.parametrize("call, match", [
    (lambda: build.random_directions(0), "at least 1"),
    (lambda: build.thermal_velocities(10, -1.0, 1.0), "kT"),
    (lambda: build.thermal_velocities(10, 1.0, 0.0), "mass"),
    (lambda: build.thermal_velocities(10, 1.0, np.ones(3)), r"shape \(10,\)"),
    (lambda: build.thermal_spins(10, 1.0, -0.4), "inertia"),
])
def test_random_states_reject_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_the_examples_in_docs_builders_run():
    ns = {}
    for block in re.findall(r"```python\n(.*?)```", DOCS.read_text(), flags=re.S):
        exec(compile(block, str(DOCS), "exec"), ns)
    scene, box = ns["scene"], ns["box"]
    assert scene.box == box and len(scene.particles) == 1000
    force, torque = scene.forces()
    assert np.all(np.isfinite(force)) and np.all(np.isfinite(torque))
    np.testing.assert_allclose(force.sum(axis=0), 0, atol=1e-9 * np.abs(force).max())
    assert scene.energy()["contact"] == 0.0  # no overlaps in the packing
    assert len(ns["chain_and_ring"]) == 20 and len(ns["x_fcc"]) == 864
    assert np.all((ns["x_slab"][:, 2] >= 0.5) & (ns["x_slab"][:, 2] <= 5.5))


# ----------------------------------------------------------------------------- the benchmarks' reference scene

def test_reference_scene_files_and_lammps_deck(tmp_path):
    sys.path.insert(0, str(BENCHMARKS))
    try:
        from lammps_run import lammps_available, run_deck
        from reference_scene import load_reference_scene, particles_and_box
    finally:
        sys.path.remove(str(BENCHMARKS))
    scene = load_reference_scene(500, tmp_path)  # writes the files
    assert set(scene) == {"L", "x", "v", "omega", "mu", "d", "m", "phi", "seed"}
    again = load_reference_scene(500, tmp_path, create=False)
    for key in ("x", "v", "mu"):
        np.testing.assert_array_equal(scene[key], again[key])
    particles, box = particles_and_box(again)
    assert box.size[0] ** 3 * 0.2 == pytest.approx(500 * math.pi / 6, rel=1e-12)
    assert closest_pair_gap(particles.position, 0.5, box) >= -TOL
    np.testing.assert_allclose(np.linalg.norm(scene["mu"], axis=1), 2.0)
    np.testing.assert_allclose(scene["v"].sum(axis=0), 0, atol=1e-12)
    # the LAMMPS data file holds the same state
    text = (tmp_path / "scene_N500.data").read_text()
    atoms = text.split("Atoms # hybrid")[1].split("Velocities")[0].split()
    rows = np.array(atoms, dtype=float).reshape(500, 11)  # id type x y z diameter density q mux muy muz
    np.testing.assert_array_equal(rows[:, 2:5], scene["x"])
    np.testing.assert_array_equal(rows[:, 8:11], scene["mu"])
    np.testing.assert_allclose(rows[:, 6] * math.pi / 6, 1.0)  # mass 1
    if not lammps_available():
        pytest.skip("lmp is not installed")
    deck = BENCHMARKS / "lammps" / "in.reference"
    for model in ("full", "nodip_nofric"):
        out = run_deck(deck, {"data": tmp_path / "scene_N500.data", "model": model, "nsteps": 20})
        assert out["steps"] == 20 and out["atoms"] == 500 and out["atom_steps_per_s"] > 0
        assert re.search(r"Step\s+v_contacts\s+v_pairs\s*\n\s*0\s+0\s", out["log"])  # no initial contacts
    with pytest.raises(RuntimeError, match="unknown model"):
        run_deck(deck, {"data": tmp_path / "scene_N500.data", "model": "bogus"})
