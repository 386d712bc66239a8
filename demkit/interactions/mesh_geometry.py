"""The geometry of triangle-mesh walls: the nearest point of a mesh to a sphere's centre, found through a
uniform grid, and the mesh's numbers in its geometry block (how both tiers read it).

A mesh wall (:class:`demkit.MeshWall`) presents to a sphere centred at x the plane through the point q of
the mesh nearest to x, with normal along x - q: a face's own normal (turned to the sphere's side) when q
lies inside that face, the direction from q to x when q lies on an edge or a vertex. That is the plane
wall's contact on that plane (demkit.interactions.wall), so a flat triangulated plane gives exactly the
plane wall's force whichever triangle, edge or vertex the sphere is over: one contact, no double
counting where triangles meet, no jump from one to the next. Two faces meeting at a crease are not
both felt: the nearer wins (see :mod:`demkit.interactions.mesh`).

The block (after the shape code 4 and the motion, demkit.interactions.wall_motion) holds, from its
offset k = g + SHAPE_AT (all numbers float64; counts and indices stored as floats are exact below 2^53):

    k + 0..2   c        the point the mesh turns about (at time 0)
    k + 3..5   a        the unit axis it turns about
    k + 6      omega    its rate of turning (rad per unit time, right-handed about a)
    k + 7      reach    the largest sphere radius the grid serves
    k + 8..10  lo       the grid's lower corner (in the mesh's frame)
    k + 11     h        the cells' edge
    k + 12..14 nx ny nz the number of cells along each axis
    k + 15     T        the number of triangles
    k + 16     the offset from g of the triangles' records (TRIANGLE numbers each)
    k + 17     the offset from g of the cells' starts (nx ny nz + 1 numbers)
    k + 18     the offset from g of the cells' triangle lists

A triangle's record: its corners A, B, C, its unit normal n = (B - A) x (C - A) / |...|, the centre m of
its bounding sphere (the middle of its box) and that sphere's radius. Cell (ix, iy, iz) is number
(ix ny + iy) nz + iz; it lists, in increasing order, the triangles whose box grown by ``reach`` meets
it, so a centre in the cell that is within ``reach`` of a triangle finds that triangle in its list.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..engine.motion import KERNEL_OPTIONS

#: numbers per triangle in the block: A, B, C, n, m, bounding radius
TRIANGLE = 16
#: the mesh's head in its block (from k = g + SHAPE_AT): the numbers listed in the module docstring
HEAD = 19
#: the distance a sphere with no triangle within reach is given: no contact (a finite number, so that
#: overlaps and heights stay plain arithmetic)
FAR = 1e300
#: the most cells a grid gets: at most this many per triangle (the cells' starts live in the block)
CELLS_PER_TRIANGLE = 8

#: compiled once and called (demkit.interactions.wall_motion.PLANE_OPTIONS: strict IEEE arithmetic)
MESH_OPTIONS = dict(KERNEL_OPTIONS, inline="never", fastmath=False)
_INLINE = dict(KERNEL_OPTIONS, fastmath=False)


@njit(**_INLINE)
def closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """(qx, qy, qz, inside): the point of the triangle ABC nearest to P, and whether it lies inside the
    face (True) or on an edge or a corner (False). The regions of the plane around the triangle are
    told apart by the signs of dot products of P - A, P - B, P - C with the edges (Ericson, Real-Time
    Collision Detection, 5.1.5): a corner's region, an edge's, or the face's (barycentric v, w)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:  # beyond A along both edges from it
        return ax, ay, az, False
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:  # beyond B
        return bx, by, bz, False
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:  # beside the edge AB
        v = d1 / (d1 - d3)
        return ax + v * abx, ay + v * aby, az + v * abz, False
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:  # beyond C
        return cx, cy, cz, False
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:  # beside the edge AC
        w = d2 / (d2 - d6)
        return ax + w * acx, ay + w * acy, az + w * acz, False
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:  # beside the edge BC
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + w * (cx - bx), by + w * (cy - by), bz + w * (cz - bz), False
    scale = 1.0 / (va + vb + vc)  # over the face
    v = vb * scale
    w = vc * scale
    return ax + abx * v + acx * w, ay + aby * v + acy * w, az + abz * v + acz * w, True


@njit(**_INLINE)
def _turn(vx, vy, vz, ax, ay, az, cos, sin):
    """v turned by the angle whose cosine and sine are given about the unit a (Rodrigues)."""
    dot = (ax * vx + ay * vy + az * vz) * (1.0 - cos)
    return (vx * cos + (ay * vz - az * vy) * sin + ax * dot, vy * cos + (az * vx - ax * vz) * sin + ay * dot,
            vz * cos + (ax * vy - ay * vx) * sin + az * dot)


@njit(**_INLINE)  # (inlined into mesh_plane, its one caller, which is compiled once: 30 ns a query less)
def nearest_on_mesh(px, py, pz, params, k, g):
    """(found, qx, qy, qz, nx, ny, nz): the point q of the mesh (block at params[g], its numbers from k)
    nearest to P (in the mesh's frame) among the triangles within ``reach``, and the contact normal there
    (the face's, towards P, or the unit P - q on an edge or corner); found False when no triangle lies
    within reach of P or P is outside the grid. Ties keep the triangle listed first."""
    h = params[k + 11]
    nx_, ny_, nz_ = params[k + 12], params[k + 13], params[k + 14]
    fx = (px - params[k + 8]) / h
    fy = (py - params[k + 9]) / h
    fz = (pz - params[k + 10]) / h
    if not (fx >= 0.0 and fx < nx_ and fy >= 0.0 and fy < ny_ and fz >= 0.0 and fz < nz_):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0
    cell = (int(fx) * int(ny_) + int(fy)) * int(nz_) + int(fz)
    triangles = g + int(params[k + 16])
    starts = g + int(params[k + 17])
    lists = g + int(params[k + 18])
    reach = params[k + 7]
    best = reach * reach  # squared distance of the nearest point so far
    near = reach
    found = -1
    qx = qy = qz = 0.0
    inside = False
    for j in range(int(params[starts + cell]), int(params[starts + cell + 1])):
        t = triangles + TRIANGLE * int(params[lists + j])
        # cheap rejections: the triangle's bounding sphere, then its plane, farther than the best so far
        mx, my, mz = px - params[t + 12], py - params[t + 13], pz - params[t + 14]
        bound = near + params[t + 15]
        if mx * mx + my * my + mz * mz >= bound * bound:
            continue
        side = (px - params[t]) * params[t + 9] + (py - params[t + 1]) * params[t + 10] + (
            pz - params[t + 2]) * params[t + 11]
        if side * side >= best:
            continue
        x, y, z, face = closest_on_triangle(px, py, pz, params[t], params[t + 1], params[t + 2], params[t + 3],
                                            params[t + 4], params[t + 5], params[t + 6], params[t + 7],
                                            params[t + 8])
        d2 = (px - x) * (px - x) + (py - y) * (py - y) + (pz - z) * (pz - z)
        if d2 < best:
            best, near, found = d2, math.sqrt(d2), t
            qx, qy, qz, inside = x, y, z, face
    if found < 0:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0
    ex, ey, ez = params[found + 9], params[found + 10], params[found + 11]
    dx, dy, dz = px - qx, py - qy, pz - qz
    if inside or near == 0.0:  # the face's normal, turned to P's side
        if dx * ex + dy * ey + dz * ez < 0.0:
            ex, ey, ez = -ex, -ey, -ez
    else:
        ex, ey, ez = dx / near, dy / near, dz / near
    return True, qx, qy, qz, ex, ey, ez


@njit(**MESH_OPTIONS)
def mesh_plane(x, y, z, params, g, k, t, dx, dy, dz, vx, vy, vz):
    """(plane, nx, ny, nz, ux, uy, uz): the plane the mesh (block at params[g], its numbers from k) carried
    by the translation D = (dx, dy, dz) at velocity V = (vx, vy, vz) and turned by omega t about its axis
    presents to the sphere centred at (x, y, z) at time t, and its surface's velocity at the contact point
    q: V + omega a x (q - c - D). A sphere with no triangle within reach gets a plane FAR below it."""
    omega = params[k + 6]
    px, py, pz = x - dx, y - dy, z - dz
    cx, cy, cz = params[k], params[k + 1], params[k + 2]
    ax, ay, az = params[k + 3], params[k + 4], params[k + 5]
    cos, sin = 1.0, 0.0
    if omega != 0.0:  # into the mesh's frame: turned back by omega t about the axis through c
        cos, sin = math.cos(omega * t), math.sin(omega * t)
        rx, ry, rz = _turn(px - cx, py - cy, pz - cz, ax, ay, az, cos, -sin)
        px, py, pz = cx + rx, cy + ry, cz + rz
    found, qx, qy, qz, nx, ny, nz = nearest_on_mesh(px, py, pz, params, k, g)
    if not found:
        return z - FAR, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0
    ux, uy, uz = vx, vy, vz
    if omega != 0.0:  # back into the world: turned by omega t; the surface moves at omega a x r
        rx, ry, rz = _turn(qx - cx, qy - cy, qz - cz, ax, ay, az, cos, sin)
        nx, ny, nz = _turn(nx, ny, nz, ax, ay, az, cos, sin)
        qx, qy, qz = cx + rx, cy + ry, cz + rz
        ux += omega * (ay * rz - az * ry)
        uy += omega * (az * rx - ax * rz)
        uz += omega * (ax * ry - ay * rx)
    qx += dx
    qy += dy
    qz += dz
    return qx * nx + qy * ny + qz * nz, nx, ny, nz, ux, uy, uz


# ---- the block, built once in Python -----------------------------------------------------------
def triangle_records(corners):
    """(T, TRIANGLE) records of triangles given by their corners (T, 3, 3): see the module docstring."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    lo, hi = corners.min(axis=1), corners.max(axis=1)
    m = 0.5 * (lo + hi)
    radius = np.linalg.norm(corners - m[:, None, :], axis=2).max(axis=1)
    return np.concatenate([a, b, c, n, m, radius[:, None]], axis=1)


def cell_size(corners, reach):
    """The grid's cell edge: the larger of ``reach`` and the median triangle's longest box side, grown
    until the grid has at most CELLS_PER_TRIANGLE cells per triangle (and 64 at least)."""
    lo, hi = corners.min(axis=1) - reach, corners.max(axis=1) + reach
    extent = lo.min(axis=0), hi.max(axis=0)
    span = extent[1] - extent[0]
    side = max(reach, float(np.median((corners.max(axis=1) - corners.min(axis=1)).max(axis=1))))
    most = max(64, CELLS_PER_TRIANGLE * len(corners))
    while np.prod(np.maximum(1, np.ceil(span / side))) > most:
        side *= 1.25
    return side


def grid(corners, reach, side=None):
    """(lo, side, counts, starts, listed): a uniform grid of cells of edge ``side`` (default
    :func:`cell_size`) over the triangles' boxes grown by ``reach``; cell c lists the triangles
    listed[starts[c]:starts[c + 1]], in increasing order, whose grown box meets it."""
    side = cell_size(corners, reach) if side is None else float(side)
    lo_t, hi_t = corners.min(axis=1) - reach, corners.max(axis=1) + reach
    lo = lo_t.min(axis=0)
    counts = np.maximum(1, np.ceil((hi_t.max(axis=0) - lo) / side)).astype(np.int64)
    first = np.clip(np.floor((lo_t - lo) / side).astype(np.int64), 0, counts - 1)
    last = np.clip(np.floor((hi_t - lo) / side).astype(np.int64), 0, counts - 1)
    sizes = last - first + 1
    each = sizes.prod(axis=1)
    owner = np.repeat(np.arange(len(corners)), each)
    local = np.arange(int(each.sum())) - np.repeat(np.cumsum(each) - each, each)
    sz, sy = sizes[owner, 2], sizes[owner, 1]
    ix = first[owner, 0] + local // (sy * sz)
    iy = first[owner, 1] + (local // sz) % sy
    iz = first[owner, 2] + local % sz
    cell = (ix * counts[1] + iy) * counts[2] + iz
    order = np.lexsort((owner, cell))
    starts = np.zeros(int(counts.prod()) + 1, dtype=np.int64)
    np.cumsum(np.bincount(cell, minlength=int(counts.prod())), out=starts[1:])
    return lo, side, counts, starts, owner[order]


def mesh_numbers(corners, centre, axis, omega, reach, offset, side=None):
    """The mesh's numbers in its geometry block (see the module docstring), their first at ``offset``
    from the block's start (the shape code and the motion come before them)."""
    lo, side, counts, starts, listed = grid(corners, reach, side)
    records = triangle_records(corners)
    at_triangles = offset + HEAD
    at_starts = at_triangles + records.size
    at_lists = at_starts + len(starts)
    head = np.array([*centre, *axis, omega, reach, *lo, side, *counts, len(corners), at_triangles, at_starts,
                     at_lists], dtype=np.float64)
    return np.concatenate([head, records.ravel(), starts.astype(np.float64), listed.astype(np.float64)])
