"""The field of real magnets and coils, from magpylib (optional: ``pip install "demkit[magnets]"``).

``MagnetField`` samples B once, at construction, from the sources' ``getB`` on a regular grid over
a box ``region`` and fits each component with a tricubic B-spline (uniform knots at the grid
nodes; it passes through the samples at the n + 3 sites 0, h/2, h, 2h, ..., L - h/2, L of each
axis). The spline B_s is twice continuously differentiable and converges as h^4 (its gradient
as h^3). A sphere with moment m at x feels

    U = -m.B_s(x),   F = grad(m.B_s)(x),   tau = m x B_s(x)

so F is the exact gradient of U: kinetic + rotational + field energy is conserved to the
integrator's order, not only to the interpolation error, and the force does not jump when a sphere
crosses a cell. Outside its sources a magnetostatic field is curl-free, so grad(m.B) = (m.grad)B:
the region must hold no magnet material and no current (it is refused when a sample point lies in
magnet material; wires cannot be detected: keep them out, B is singular on them).

Units: magpylib works in SI. A scene length x is x * ``length_unit`` metres and a scene field is
B[T] / ``field_unit``; energies are moment x field in the scene's units (an SI scene keeps the
defaults: moments in A m^2, fields in T, energies in J, forces in N).

Outside the region the field is unknown: force, torque and energy are NaN there, which stops a run
with a message saying the sphere left the region (:class:`demkit.SimulationError`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS

from .base import positive, real_array
from .sphere import SphereInteraction

#: largest number of grid nodes a MagnetField tabulates (3 floats each)
MAX_NODES = 2**24


@njit(**KERNEL_OPTIONS)
def bspline_weights(t):
    """The four uniform cubic B-splines that are non-zero in a cell, at t in [0, 1] of the cell,
    and their derivatives d/dt."""
    s = 1.0 - t
    t2 = t * t
    t3 = t2 * t
    weights = (s * s * s / 6.0, (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0, (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
               t3 / 6.0)
    slopes = (-0.5 * s * s, 1.5 * t2 - 2.0 * t, -1.5 * t2 + t + 0.5, 0.5 * t2)
    return weights, slopes


@njit(**KERNEL_OPTIONS)
def spline_field(x, y, z, mx, my, mz, params, start, x0, y0, z0, x1, y1, z1, sx, sy, sz, nx, ny, nz):
    """(B, grad(m.B)) of the spline whose coefficients c[i, j, k, :] (i < nx + 3, ...) are stored
    from params[start] in C order, over the region (x0, y0, z0)-(x1, y1, z1); (sx, sy, sz):
    1 / grid spacing; (nx, ny, nz): cells per axis. All six are NaN outside the region (or at a NaN
    position)."""
    if not (x0 <= x <= x1 and y0 <= y <= y1 and z0 <= z <= z1):
        return math.nan, math.nan, math.nan, math.nan, math.nan, math.nan
    u = (x - x0) * sx
    v = (y - y0) * sy
    w = (z - z0) * sz
    i = min(int(u), int(nx) - 1)
    j = min(int(v), int(ny) - 1)
    k = min(int(w), int(nz) - 1)
    wx, dx = bspline_weights(u - i)
    wy, dy = bspline_weights(v - j)
    wz, dz = bspline_weights(w - k)
    rows = int(ny) + 3
    depth = int(nz) + 3
    bx = by = bz = gx = gy = gz = 0.0
    for a in range(4):
        for b in range(4):
            base = start + (((i + a) * rows + j + b) * depth + k) * 3
            wab, dab, adb = wx[a] * wy[b], dx[a] * wy[b], wx[a] * dy[b]
            for c in range(4):
                q = base + 3 * c
                cx, cy, cz = params[q], params[q + 1], params[q + 2]
                weight = wab * wz[c]
                bx += weight * cx
                by += weight * cy
                bz += weight * cz
                mc = mx * cx + my * cy + mz * cz
                gx += dab * wz[c] * mc
                gy += adb * wz[c] * mc
                gz += wab * dz[c] * mc
    return bx, by, bz, gx * sx, gy * sy, gz * sz


@njit(**KERNEL_OPTIONS)
def magnet_force(i, x, y, z, dipole, params, start, x0, y0, z0, x1, y1, z1, sx, sy, sz, nx, ny, nz):
    mx, my, mz = dipole[i, 0], dipole[i, 1], dipole[i, 2]
    bx, by, bz, fx, fy, fz = spline_field(x, y, z, mx, my, mz, params, start, x0, y0, z0, x1, y1, z1, sx, sy, sz,
                                          nx, ny, nz)
    return fx, fy, fz, my * bz - mz * by, mz * bx - mx * bz, mx * by - my * bx


@njit(**KERNEL_OPTIONS)
def magnet_energy(i, x, y, z, dipole, params, start, x0, y0, z0, x1, y1, z1, sx, sy, sz, nx, ny, nz):
    mx, my, mz = dipole[i, 0], dipole[i, 1], dipole[i, 2]
    bx, by, bz, _, _, _ = spline_field(x, y, z, 0.0, 0.0, 0.0, params, start, x0, y0, z0, x1, y1, z1, sx, sy, sz,
                                       nx, ny, nz)
    return -(mx * bx + my * by + mz * bz)


@njit(cache=True)
def _field_at(points, table, x0, y0, z0, x1, y1, z1, sx, sy, sz, nx, ny, nz, out):
    for p in range(points.shape[0]):
        out[p, 0], out[p, 1], out[p, 2], _, _, _ = spline_field(
            points[p, 0], points[p, 1], points[p, 2], 0.0, 0.0, 0.0, table, 0, x0, y0, z0, x1, y1, z1, sx, sy, sz,
            nx, ny, nz)


def collocation_sites(n):
    """The n + 3 sites (in cells) where the spline of n cells matches the samples."""
    return np.concatenate([[0.0, 0.5], np.arange(1.0, n), [n - 0.5, n]])


def collocation_matrix(n):
    """(n + 3, n + 3): the n + 3 uniform cubic B-splines of n cells at the collocation sites."""
    u = collocation_sites(n)
    cell = np.minimum(np.floor(u).astype(np.int64), n - 1)
    t = u - cell
    weights = np.stack([(1 - t) ** 3, 3 * t ** 3 - 6 * t ** 2 + 4, -3 * t ** 3 + 3 * t ** 2 + 3 * t + 1, t ** 3]) / 6
    matrix = np.zeros((n + 3, n + 3))
    for a in range(4):
        matrix[np.arange(n + 3), cell + a] = weights[a]
    return matrix


def _require_magpylib():
    try:
        import magpylib  # noqa: F401
    except ImportError:
        raise ImportError("MagnetField needs magpylib: pip install 'demkit[magnets]'") from None


class MagnetField(SphereInteraction):
    """The field of magpylib sources, tabulated over a box (see the module docstring).

    sources : a magpylib source or Collection (anything with ``getB``), or a list of them (summed)
    region : ((x0, y0, z0), (x1, y1, z1)), the box the spheres stay in (scene lengths); it must
        hold no magnet material and no current
    spacing : largest grid spacing (scene length); each axis of length L gets ceil(L / spacing)
        cells (at least 2). B's error falls as spacing^4 (docs/fields.md)
    length_unit : metres per scene length unit; field_unit : tesla per scene field unit
    """

    reads = ("dipole",)
    torque = True
    energy_kind = "field"
    repeatable = True  # fields superpose: a coarse table of a far magnet, a fine one of a near one
    parameters = ("x0", "y0", "z0", "x1", "y1", "z1", "sx", "sy", "sz", "nx", "ny", "nz")
    force_function = magnet_force
    energy_function = magnet_energy

    def __init__(self, sources, region, spacing, length_unit=1.0, field_unit=1.0):
        _require_magpylib()
        self.sources = sources
        for source in sources if isinstance(sources, (list, tuple)) else [sources]:
            if not callable(getattr(source, "getB", None)):
                raise TypeError(f"MagnetField sources must be magpylib sources or Collections (objects with getB), "
                                f"got {type(source).__name__}")
        region = real_array("MagnetField region", region)
        if region.shape != (2, 3):
            raise ValueError(f"MagnetField region must be two corners ((x0, y0, z0), (x1, y1, z1)), each a "
                             f"3-vector: got shape {region.shape}")
        if not np.isfinite(region).all() or not (region[0] < region[1]).all():
            raise ValueError(f"MagnetField region must be finite with x0 < x1, y0 < y1, z0 < z1, got "
                             f"{region.tolist()}")
        self.region = region
        spacing = positive("MagnetField spacing", spacing)
        self.length_unit = positive("MagnetField length_unit", length_unit)
        self.field_unit = positive("MagnetField field_unit", field_unit)
        length = region[1] - region[0]
        self.cells = np.maximum(2, np.ceil(length / spacing * (1 - 1e-12))).astype(np.int64)
        if np.prod(self.cells + 1.0) > MAX_NODES:
            raise ValueError(f"MagnetField spacing {spacing:.6g} gives {self.cells.tolist()} cells over the region "
                             f"{region.tolist()}: more than {MAX_NODES} grid nodes; use a larger spacing")
        self.spacing = length / self.cells
        self.x0, self.y0, self.z0 = (float(c) for c in region[0])
        self.x1, self.y1, self.z1 = (float(c) for c in region[1])
        self.sx, self.sy, self.sz = (float(c) for c in 1.0 / self.spacing)
        self.nx, self.ny, self.nz = (float(c) for c in self.cells)
        self._table = self._tabulate()

    def _tabulate(self):
        """Sample B at the collocation sites and solve for the spline coefficients, axis by axis."""
        axes = [self.region[0, a] + collocation_sites(n) * self.spacing[a] for a, n in enumerate(self.cells)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        metres = points * self.length_unit
        sources = self.sources if isinstance(self.sources, (list, tuple)) else [self.sources]
        field = np.zeros_like(points)
        for source in sources:
            getJ = getattr(source, "getJ", None)
            if callable(getJ):  # magnet material in the region: the field there is not curl-free
                inside = np.flatnonzero(np.any(np.asarray(getJ(metres)).reshape(-1, 3) != 0, axis=1))
                if len(inside):
                    raise ValueError(f"MagnetField region {self.region.tolist()} contains magnet material (at "
                                     f"{points[inside[0]].tolist()}, scene units): tabulate only outside the "
                                     f"sources, where the field is curl-free")
            values = np.asarray(source.getB(metres), dtype=np.float64)
            if values.shape != points.shape:
                raise ValueError(f"MagnetField: getB gave an array of shape {values.shape} for {len(points)} points; "
                                 f"expected ({len(points)}, 3), one 3-vector per point (static sources only)")
            field += values
        bad = np.flatnonzero(~np.isfinite(field).all(axis=1))
        if len(bad):
            raise ValueError(f"MagnetField: the field is not finite at {points[bad[0]].tolist()} (scene units), "
                             f"inside the region")
        coefficients = (field / self.field_unit).reshape(*(self.cells + 3), 3)
        for a, n in enumerate(self.cells):
            moved = np.moveaxis(coefficients, a, 0)
            solved = np.linalg.solve(collocation_matrix(n), moved.reshape(n + 3, -1)).reshape(moved.shape)
            coefficients = np.moveaxis(solved, 0, a)
        return np.ascontiguousarray(coefficients).ravel()

    def table_values(self):
        return self._table

    def field(self, points):
        """The tabulated field (scene field units) at points (..., 3) in scene lengths; NaN outside
        the region."""
        points = np.asarray(points, dtype=np.float64)
        flat = np.ascontiguousarray(points.reshape(-1, 3))
        out = np.empty_like(flat)
        _field_at(flat, self._table, self.x0, self.y0, self.z0, self.x1, self.y1, self.z1, self.sx, self.sy,
                  self.sz, self.nx, self.ny, self.nz, out)
        return out.reshape(points.shape)

    def inside(self, position):
        """Which positions (N, 3) lie in the region (boundary included)."""
        position = np.asarray(position, dtype=np.float64).reshape(-1, 3)
        return ((position >= self.region[0]) & (position <= self.region[1])).all(axis=1)

    def check(self, particles):
        super().check(particles)
        outside = np.flatnonzero(~self.inside(particles.position))
        if len(outside):
            k = int(outside[0])
            raise ValueError(f"particle {particles.ids[k]} at {particles.position[k].tolist()} is outside the "
                             f"region of MagnetField ({self._box()}), where the field is tabulated "
                             f"({len(outside)} particles are)")

    def _box(self):
        return ", ".join(f"{axis} in [{lo:.6g}, {hi:.6g}]" for axis, lo, hi in zip("xyz", *self.region))

    def stop_hint(self, position):
        if position is None:
            return (f"became non-finite (NaN or inf). If it left the region of MagnetField ({self._box()}), where "
                    f"the field is tabulated (outside it the force is NaN), enlarge the region; otherwise a "
                    f"smaller time step may help.")
        if self.inside(position)[0]:
            return None
        at = ", ".join(f"{c:.6g}" for c in position)
        return (f"left the region of MagnetField ({self._box()}), where the field is tabulated: it is at "
                f"({at}), where its force is NaN. Enlarge the region (keeping magnets and currents out of it) "
                f"or keep the spheres inside it.")

    def __repr__(self):
        return (f"MagnetField({type(self.sources).__name__}, region={self.region.tolist()}, "
                f"cells={self.cells.tolist()})")
