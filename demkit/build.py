"""Builders for the scenes simulations start from: packings, lattices, chains, rings, random states.

Every function returns plain numpy arrays (float64, C-contiguous) that go straight into
:class:`demkit.Particles`; the functions that decide a box also return the :class:`demkit.Box`.
Lengths are in whatever unit the radii are given in; velocities in length/time and spins in
rad/time for the ``kT`` and masses (moments of inertia) given, in consistent units
(k_B T in energy units, m v^2 has the same unit). Dipole moments have the magnitude ``moment``
in its own unit (a scene's dipole prefactor turns them into energies).

Positions refer to boxes with their lower corner at the origin (see :mod:`demkit.box`):
coordinates along a periodic axis lie in [0, L); along an open axis whole spheres lie inside
[0, L] (centres in [r, L - r]).

Randomness: ``seed`` is anything :func:`numpy.random.default_rng` takes (None, an int, a
``SeedSequence`` or a ``Generator``). The same int gives the same arrays; one ``Generator`` passed
to several builders draws from one stream (see ``benchmarks/reference_scene.py``).
"""
from __future__ import annotations

import math
import numbers

import numpy as np
from numba import njit

from . import checks, memory
from .box import Box

__all__ = ["RSA_LIMIT", "box_for", "random_packing", "spatial_order", "lattice", "chain", "ring",
           "random_directions", "thermal_velocities", "thermal_spins"]

#: Highest volume fraction :func:`random_packing` accepts. Random sequential addition of equal
#: spheres saturates ("jams") at 0.3841; close to it every new sphere needs ever more attempts.
RSA_LIMIT = 0.38
#: at most this many grid cells per sphere (very dilute packings get wider cells)
_MAX_CELLS_PER_SPHERE = 4
#: candidate positions drawn per batch (at most; each batch is 3 doubles per candidate)
_BATCH = 1 << 20


# ----------------------------------------------------------------------------- checks

def _count(n, what="n"):
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise ValueError(f"{what} must be an integer, got {n!r}")
    if n < 1:
        raise ValueError(f"{what} must be at least 1, got {n}")
    return int(n)


def _spheres(n, what=None):
    """``n`` checked as a count of spheres (:func:`_count`) that a scene can hold: refused (ValueError)
    when even the arrays of a scene of them (:func:`demkit.memory.estimate`, no neighbour lists
    nor record) exceed the memory available, before anything is allocated."""
    n = _count(n)
    arrays = memory.estimate(n)["arrays"]
    memory.refuse_above(arrays, f"{what or f'n = {n:,}'}: {n:,} spheres need", f"fewer spheres (a smaller "
                        f"{'shape' if what else 'n'})", parts="the arrays of a scene of them alone")
    return n


def _positive(value, what):
    return checks.positive(what, value)


def _radii(n, radius):
    """(radii (n,), scalar?) with every radius positive and finite."""
    r = checks.real_array("radius", radius)
    if r.ndim == 0:
        _positive(r, "radius")
        return np.full(n, float(r)), True
    if r.shape != (n,):
        raise ValueError(f"radius must be a scalar or have shape ({n},), got shape {r.shape}")
    bad = ~np.isfinite(r) | (r <= 0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"radius must be positive and finite; sphere {k} has radius {r[k]}")
    return np.ascontiguousarray(r), False


def _unit(vector, what):
    v = checks.real_array(what, vector)
    if v.shape != (3,):
        raise ValueError(f"{what} must be three numbers (x, y, z), got {vector!r}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be finite, got {vector!r}")
    norm = float(np.linalg.norm(v))
    if norm == 0.0:
        raise ValueError(f"{what} must not be the zero vector")
    return v / norm


def _point(point, what):
    p = checks.real_array(what, point)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"{what} must be three finite numbers (x, y, z), got {point!r}")
    return p


def _gap(gap):
    return checks.non_negative("gap", gap)


def _fraction(volume_fraction):
    phi = checks.number("volume_fraction", volume_fraction)
    if not math.isfinite(phi) or phi <= 0:
        raise ValueError(f"volume_fraction must be in (0, {RSA_LIMIT}], got {volume_fraction!r}")
    if phi > RSA_LIMIT * (1 + 1e-12):  # slack: the fraction of box_for(..., RSA_LIMIT) rounds either way
        raise ValueError(
            f"volume fraction {phi:.4g} is beyond what random sequential addition reaches: it saturates "
            f"at 0.384 for equal spheres and needs ever more attempts long before, so random_packing "
            f"accepts at most {RSA_LIMIT}; start denser packings from a lattice or compress a random one")
    return phi


def _sphere_volume(r):
    return 4.0 / 3.0 * math.pi * float(np.sum(np.asarray(r, dtype=np.float64) ** 3))


# ----------------------------------------------------------------------------- random packing

def box_for(n, radius, volume_fraction, periodic=True):
    """The cube that n spheres of ``radius`` fill at ``volume_fraction``.

    radius : scalar or (n,) array (same units as the returned side).
    volume_fraction : sum of sphere volumes / box volume, in (0, RSA_LIMIT].
    periodic : as for :class:`demkit.Box` (True, False, or three booleans).

    Returns a :class:`demkit.Box` with side L = (sum 4/3 pi r^3 / volume_fraction)^(1/3).
    """
    n = _spheres(n)
    r, _ = _radii(n, radius)
    phi = _fraction(volume_fraction)
    return Box((_sphere_volume(r) / phi) ** (1.0 / 3.0), periodic=periodic)


def _grid(size, width_min, n):
    """Cells at least ``width_min`` wide, at most about _MAX_CELLS_PER_SPHERE per sphere."""
    checks.resolvable("the box", size, 0.5 * width_min, "half the narrowest cell")  # (cells of a diameter)
    width = width_min
    while True:
        ncell = np.maximum(1, np.floor(size / width)).astype(np.int64)
        if int(np.prod(ncell)) <= _MAX_CELLS_PER_SPHERE * n + 27:
            return ncell, size / ncell
        width *= 1.25


@njit(cache=True, inline="always")
def _cell_coordinate(x, width, ncell):
    k = int(x / width)
    if k < 0:
        return 0
    if k >= ncell:
        return ncell - 1
    return k


@njit(cache=True, inline="always")
def _cell_range(k, ncell):
    """(first offset, last offset) of the neighbouring cells along one axis: all cells when there
    are fewer than three (so no cell is visited twice), else k-1..k+1 (folded or clipped later)."""
    if ncell < 3:
        return -k, ncell - 1 - k
    return -1, 1


@njit(cache=True)
def _rsa_place(candidates, k, radius, position, span, size, periodic, ncell, width, head, link):
    """Random sequential addition of spheres k, k+1, ... (radius[k], ...) from candidate points.

    candidates : (m, 3) uniform numbers in [0, 1); sphere k's trial centre is u L along periodic axes
    and r + u span[a, k] along open ones (span = L - 2r).
    Accepted spheres go into ``position`` and the cell lists (head[cell] -> first sphere,
    link[sphere] -> next sphere of the same cell, -1 ends). The candidate's own cell is searched
    first (most rejections are found there), then its neighbours.
    Returns (spheres placed so far, candidates used).
    """
    n = radius.shape[0]
    used = 0
    m = candidates.shape[0]
    x = np.empty(3)
    c = np.empty(3, dtype=np.int64)
    while used < m and k < n:
        r = radius[k]
        for a in range(3):
            if periodic[a]:
                xa = candidates[used, a] * size[a]
                if xa >= size[a]:
                    xa -= size[a]
            else:
                xa = r + candidates[used, a] * span[a, k]
            x[a] = xa
            c[a] = _cell_coordinate(xa, width[a], ncell[a])
        used += 1
        ok = True
        lo0, hi0 = _cell_range(c[0], ncell[0])
        lo1, hi1 = _cell_range(c[1], ncell[1])
        lo2, hi2 = _cell_range(c[2], ncell[2])
        for stage in range(2):  # the own cell first (most rejections are found there), then the others
            a0, b0 = (0, 0) if stage == 0 else (lo0, hi0)
            a1, b1 = (0, 0) if stage == 0 else (lo1, hi1)
            a2, b2 = (0, 0) if stage == 0 else (lo2, hi2)
            for o0 in range(a0, b0 + 1):
                c0 = c[0] + o0
                if c0 < 0 or c0 >= ncell[0]:
                    if not periodic[0]:
                        continue
                    c0 %= ncell[0]
                for o1 in range(a1, b1 + 1):
                    c1 = c[1] + o1
                    if c1 < 0 or c1 >= ncell[1]:
                        if not periodic[1]:
                            continue
                        c1 %= ncell[1]
                    for o2 in range(a2, b2 + 1):
                        c2 = c[2] + o2
                        if c2 < 0 or c2 >= ncell[2]:
                            if not periodic[2]:
                                continue
                            c2 %= ncell[2]
                        if stage == 1 and o0 == 0 and o1 == 0 and o2 == 0:
                            continue
                        j = head[(c0 * ncell[1] + c1) * ncell[2] + c2]
                        while j >= 0:
                            d2 = 0.0
                            for a in range(3):
                                d = x[a] - position[j, a]
                                if periodic[a]:
                                    if d > 0.5 * size[a]:
                                        d -= size[a]
                                    elif d < -0.5 * size[a]:
                                        d += size[a]
                                d2 += d * d
                            reach = r + radius[j]
                            if d2 < reach * reach:
                                ok = False
                                break
                            j = link[j]
                        if not ok:
                            break
                    if not ok:
                        break
                if not ok:
                    break
            if not ok:
                break
        if ok:
            for a in range(3):
                position[k, a] = x[a]
            cell = (c[0] * ncell[1] + c[1]) * ncell[2] + c[2]
            link[k] = head[cell]
            head[cell] = k
            k += 1
    return k, used


@njit(cache=True)
def _cell_index(position, width, ncell):
    out = np.empty(position.shape[0], dtype=np.int64)
    for i in range(position.shape[0]):
        c0 = _cell_coordinate(position[i, 0], width[0], ncell[0])
        c1 = _cell_coordinate(position[i, 1], width[1], ncell[1])
        c2 = _cell_coordinate(position[i, 2], width[2], ncell[2])
        out[i] = (c0 * ncell[1] + c1) * ncell[2] + c2
    return out


def spatial_order(position, box, width):
    """Permutation that sorts ``position`` by grid cell (cells about ``width`` wide, x slowest,
    z fastest; inside a cell the input order is kept), so spheres close in space are close in memory.

    Use it to reorder polydisperse packings together with their radii::

        order = dk.build.spatial_order(x, box, width=2 * r.max())
        x, r = x[order], r[order]
    """
    if not isinstance(box, Box):
        raise ValueError(f"box must be a demkit.Box, got {type(box).__name__}")
    position = np.ascontiguousarray(position, dtype=np.float64)
    if position.ndim != 2 or position.shape[1] != 3:
        raise ValueError(f"position must have shape (n, 3), got {position.shape}")
    ncell, cell_width = _grid(box.size, _positive(width, "width"), max(1, len(position)))
    wrapped, _ = box.wrap(position)
    return np.argsort(_cell_index(np.ascontiguousarray(wrapped), cell_width, ncell), kind="stable")


def random_packing(n, radius, box, seed=None, max_attempts=None):
    """Random non-overlapping spheres filling ``box`` (random sequential addition).

    Spheres are tried one at a time at uniformly random centres and kept when they overlap no sphere
    placed before (distance >= r_i + r_j; minimum image along periodic axes). Along open axes whole
    spheres stay inside the box (centres in [r, L - r]); along periodic axes centres lie in [0, L).
    Overlaps are found with a cell grid in compiled code: 10^6 spheres at volume fraction 0.2 take a
    few seconds (the first call also compiles, about a second, cached afterwards).

    n : number of spheres.
    radius : scalar, or (n,) array for a polydisperse packing (the largest spheres are placed first).
    box : :class:`demkit.Box`; the volume fraction is sum(4/3 pi r^3) / box.volume. To ask for a
        volume fraction instead, make the box with :func:`box_for`::

            box = dk.build.box_for(n, r, volume_fraction=0.2)
            x = dk.build.random_packing(n, r, box, seed=1)

    seed : see the module docstring.
    max_attempts : give up after this many trial centres (default 1000 n + 10^6).

    Returns positions (n, 3). Order: with a scalar radius (all spheres alike) the rows are sorted by
    grid cell (cells about one diameter wide; x slowest, z fastest) so that neighbours in space are
    near in memory. With an array radius row i is the sphere of radius[i] (so the radii need no
    reordering); sort both with :func:`spatial_order` if memory order matters.

    Raises ValueError for bad input, a box side shorter than a diameter, a volume fraction above
    RSA_LIMIT = 0.38 (random sequential addition saturates at 0.384), or when max_attempts run out
    (the message says how far it got).
    """
    n = _spheres(n)
    r, same = _radii(n, radius)
    if not isinstance(box, Box):
        raise ValueError(f"box must be a demkit.Box (make one with dk.build.box_for(n, radius, "
                         f"volume_fraction)), got {type(box).__name__}")
    size = np.array(box.size, dtype=np.float64)
    periodic = np.array(box.periodic, dtype=np.bool_)
    rmax = float(r.max())
    for a in range(3):
        if size[a] < 2 * rmax:
            raise ValueError(f"the box side {'xyz'[a]} = {size[a]:.6g} is shorter than the largest sphere's "
                             f"diameter {2 * rmax:.6g}")
    phi = _sphere_volume(r) / box.volume
    _fraction(phi)  # raises above RSA_LIMIT, with the explanation
    if max_attempts is None:
        max_attempts = 1000 * n + 1_000_000
    max_attempts = _count(max_attempts, "max_attempts")

    order = np.argsort(-r, kind="stable")  # largest first
    rs = np.ascontiguousarray(r[order])
    span = np.ascontiguousarray((size[:, None] - 2 * rs[None, :]))  # (3, n), used along open axes
    ncell, width = _grid(size, 2 * rmax, n)
    head = np.full(int(np.prod(ncell)), -1, dtype=np.int64)
    link = np.full(n, -1, dtype=np.int64)
    placed = np.zeros((n, 3))
    rng = np.random.default_rng(seed)
    k = 0
    attempts = 0
    while k < n:
        if attempts >= max_attempts:
            got = _sphere_volume(rs[:k]) / box.volume
            raise ValueError(
                f"random sequential addition placed only {k} of {n} spheres (volume fraction {got:.4g} of the "
                f"requested {phi:.4g}) in {attempts} attempts: the packing is too dense for it (it saturates "
                f"at 0.384 for equal spheres and slows down well before); use a lower volume fraction, a "
                f"bigger box, or a larger max_attempts")
        batch = int(min(_BATCH, max(1024, 4 * (n - k)), max_attempts - attempts))
        k, used = _rsa_place(rng.random((batch, 3)), k, rs, placed, span, size, periodic,
                             ncell, width, head, link)
        attempts += used

    if same:
        cells = _cell_index(placed, width, ncell)
        return np.ascontiguousarray(placed[np.argsort(cells, kind="stable")])
    out = np.empty_like(placed)
    out[order] = placed
    return out


# ----------------------------------------------------------------------------- lattices

_SQ3 = math.sqrt(3.0)
#: kind -> (cell edges in units of the nearest-neighbour distance, basis in units of the cell edges,
#: nearest-neighbour count)
_LATTICES = {
    "sc": ((1.0, 1.0, 1.0), [(0, 0, 0)], 6),
    "bcc": ((2 / _SQ3,) * 3, [(0, 0, 0), (0.5, 0.5, 0.5)], 8),
    "fcc": ((math.sqrt(2.0),) * 3, [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)], 12),
    # hexagonal close packing in an orthorhombic cell a x a sqrt(3) x c, c = a sqrt(8/3), layers A B
    "hcp": ((1.0, _SQ3, math.sqrt(8.0 / 3.0)),
            [(0, 0, 0), (0.5, 0.5, 0), (0.5, 1 / 6, 0.5), (0, 2 / 3, 0.5)], 12),
}


def lattice(kind, shape, spacing=None, radius=None, periodic=True):
    """Spheres on a crystal lattice, and the box that tiles it.

    kind : "sc" (simple cubic), "bcc", "fcc" or "hcp" (hexagonal close packed, A-B layers along z).
    shape : number of unit cells (nx, ny, nz), or one int for all three. Unit cells hold 1 (sc),
        2 (bcc), 4 (fcc) or 4 (hcp; orthorhombic cell a x a sqrt(3) x a sqrt(8/3)) spheres.
    spacing : nearest-neighbour centre distance; or give ``radius`` instead (spacing = 2 radius,
        touching spheres). Cubic lattice constants: sc a = s, bcc a = 2 s / sqrt(3), fcc a = s sqrt(2).
    periodic : as for :class:`demkit.Box`. Along a periodic axis the box side is the cells' length, so
        the lattice continues through the boundary with the same spacing; along an open axis the box
        is the extent of the centres plus one spacing, with the centres shifted in by spacing/2 (spheres
        of radius spacing/2 lie inside).

    Returns (positions (n, 3), Box); n = cells x basis, rows in cell order (x slowest), each cell's basis together.
    Nearest neighbours: sc 6, bcc 8, fcc 12, hcp 12.
    """
    if kind not in _LATTICES:
        raise ValueError(f"unknown lattice kind {kind!r}; known: {', '.join(_LATTICES)}")
    cells = np.array(shape)
    if cells.ndim == 0:
        cells = np.full(3, cells)
    if (cells.shape != (3,) or not all(isinstance(c, numbers.Integral) and not isinstance(c, bool)
                                         for c in cells.tolist()) or np.any(cells < 1)):
        raise ValueError(f"shape must be a positive integer or three positive integers (cells along x, y, z), "
                         f"got {shape!r}")
    if (spacing is None) == (radius is None):
        raise ValueError("give exactly one of spacing (nearest-neighbour distance) and radius (touching spheres)")
    count = math.prod(int(c) for c in cells.tolist()) * len(_LATTICES[kind][1])
    _spheres(count, f"shape = {' x '.join(str(int(c)) for c in cells.tolist())} cells of {len(_LATTICES[kind][1])} "
                    f"({kind})")
    s = _positive(spacing, "spacing") if spacing is not None else 2 * _positive(radius, "radius")
    edges, basis, _ = _LATTICES[kind]
    edge = np.array(edges) * s
    flags = np.array(Box(1.0, periodic).periodic)  # validates periodic
    ijk = np.stack(np.meshgrid(*(np.arange(c) for c in cells), indexing="ij"), axis=-1).reshape(-1, 1, 3)
    x = ((ijk + np.array(basis, dtype=np.float64)[None]) * edge).reshape(-1, 3)
    size = cells * edge
    for a in np.flatnonzero(~flags):
        x[:, a] += 0.5 * s - x[:, a].min()
        size[a] = x[:, a].max() + 0.5 * s
    return np.ascontiguousarray(x), Box(size, periodic=periodic)


# ----------------------------------------------------------------------------- chains and rings

def chain(n, radius, start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), gap=0.0, moment=1.0):
    """A straight chain of n spheres with head-to-tail dipoles.

    Centres start + k (2 radius + gap) u, k = 0..n-1, u = direction / |direction| (gap = 0: touching).
    Every dipole is moment * u. Returns (positions (n, 3), dipoles (n, 3)).
    """
    n = _spheres(n)
    r = _positive(radius, "radius")
    u = _unit(direction, "direction")
    p0 = _point(start, "start")
    step = 2 * r + _gap(gap)
    m = _moment(moment)
    x = p0 + step * np.arange(n)[:, None] * u
    return np.ascontiguousarray(x), np.ascontiguousarray(np.tile(m * u, (n, 1)))


def _moment(moment):
    return checks.finite("moment", moment)


def _frame(normal):
    """Two unit vectors e1, e2 with (e1, e2, normal) right-handed."""
    w = _unit(normal, "normal")
    helper = np.eye(3)[int(np.argmin(np.abs(w)))]
    e1 = np.cross(helper, w)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(w, e1)


def ring(n, radius, centre=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), gap=0.0, moment=1.0):
    """n spheres on a circle with tangent dipoles circulating one way (a flux-closure ring).

    Neighbouring centres are 2 radius + gap apart (a chord), so the circle through the centres has
    radius (2 radius + gap) / (2 sin(pi / n)); n >= 3. The circle lies in the plane through ``centre``
    perpendicular to ``normal``; sphere k sits at angle 2 pi k / n from a fixed in-plane axis and its
    dipole is moment times the unit tangent, counter-clockwise seen from the tip of ``normal``
    (right-handed about it). Returns (positions (n, 3), dipoles (n, 3)).
    """
    n = _spheres(n)
    if n < 3:
        raise ValueError(f"a ring needs at least 3 spheres, got n = {n}")
    r = _positive(radius, "radius")
    c = _point(centre, "centre")
    e1, e2 = _frame(normal)
    m = _moment(moment)
    big = (2 * r + _gap(gap)) / (2 * math.sin(math.pi / n))
    theta = 2 * math.pi * np.arange(n) / n
    cos, sin = np.cos(theta)[:, None], np.sin(theta)[:, None]
    x = c + big * (cos * e1 + sin * e2)
    mu = m * (-sin * e1 + cos * e2)
    return np.ascontiguousarray(x), np.ascontiguousarray(mu)


# ----------------------------------------------------------------------------- random states

def random_directions(n, seed=None):
    """n unit vectors uniformly distributed on the sphere, shape (n, 3)."""
    n = _spheres(n)
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(n, 3))
    norm = np.linalg.norm(u, axis=1)
    while np.any(norm == 0.0):  # probability zero, but cheap to exclude
        bad = norm == 0.0
        u[bad] = rng.normal(size=(int(bad.sum()), 3))
        norm = np.linalg.norm(u, axis=1)
    return u / norm[:, None]


def _per_sphere(n, value, what):
    a = checks.real_array(what, value)
    if a.ndim == 0:
        _positive(a, what)
        return np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{what} must be a scalar or have shape ({n},), got shape {a.shape}")
    bad = ~np.isfinite(a) | (a <= 0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what} must be positive and finite; sphere {k} has {what} {a[k]}")
    return a


def _kT(kT):
    return checks.non_negative("kT", kT)


def thermal_velocities(n, kT, mass, seed=None):
    """Maxwell-Boltzmann velocities at temperature kT (energy units) with zero total momentum.

    Each component is normal with variance kT / m_i; then the centre-of-mass velocity
    sum(m v) / sum(m) is subtracted, so sum_i m_i v_i = 0 (to round-off) and the expected kinetic
    energy is 3/2 (n - 1) kT. mass : scalar or (n,). Returns (n, 3).
    """
    n = _spheres(n)
    t = _kT(kT)
    m = _per_sphere(n, mass, "mass")
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3)) * np.sqrt(t / m)[:, None]
    v -= (m[:, None] * v).sum(axis=0) / m.sum()
    return v


def thermal_spins(n, kT, inertia, seed=None):
    """Angular velocities at temperature kT: each component normal with variance kT / I_i (rad/time).

    inertia : scalar or (n,) moments of inertia (2/5 m r^2 for solid spheres). Returns (n, 3).
    Total angular momentum is not removed (spins exchange it with orbits through friction and torques).
    """
    n = _spheres(n)
    t = _kT(kT)
    inertia = _per_sphere(n, inertia, "inertia")
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, 3)) * np.sqrt(t / inertia)[:, None]
