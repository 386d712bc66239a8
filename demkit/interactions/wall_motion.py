"""The plane a wall presents to a sphere at the scene's clock: how the compiled loops see walls that move
or are curved.

Every plane-contact law (demkit.interactions.wall) takes the plane x.n = plane and the surface velocity u
as its first seven parameters. A steady plane wall (at rest, or sliding in itself) passes its own. Any
other wall has a geometry block in the scene's parameters (its row's E_GEOMETRY column points to it):

    shape, Vx, Vy, Vz, Ax, Ay, Az, w, <the shape's numbers>

with shape 0 a plane (the law's own plane and normal at time 0), 1 a cylinder
(demkit.interactions.cylinder.GEOMETRY), 2 a plane moved by a servo (:data:`SERVO`) and 4 a triangle
mesh (demkit.interactions.mesh_geometry, which also turns about an axis). The wall is
carried by D(t) = V t + A (1 - cos w t) (w = 2 pi f; the vibration starts at rest, as LAMMPS'
``wiggle``): a sphere at x meets the shape as it
stood at time 0 seen from x - D(t), shifted by D(t), and the surface velocity there gains
D'(t) = V + A w sin(w t).

A servo's wall (shape 2) is moved along its normal n by its own state: the loops add to its block the
normal force F the spheres exert on it and the secant stiffness F_i / delta_i of each contact
(:func:`servo_add`, after :func:`servo_clear` at the start of each evaluation), and after each step
:func:`servo_step` moves it by gain (F - target) / K away from the spheres (towards them when it
touches nothing), at most max_speed dt. These steps are quasi-static: the surface velocity the
contacts see is the wall's prescribed one only (a dashpot seeing the servo's speed would add c / dt to
the stiffness it steers by, and the loop would swing from one limit to the other).
"""
from __future__ import annotations

import math

from numba import njit

from ..engine.motion import KERNEL_OPTIONS
from .mesh_geometry import mesh_plane

#: the shape codes of the geometry block
SHAPES = {"plane": 0, "cylinder": 1, "servo": 2, "mesh": 4}
#: the motion's numbers, after the shape code
MOTION = ("vx", "vy", "vz", "ax", "ay", "az", "w")
#: a servo's numbers, after the motion (its state from "offset" on: :data:`SERVO_STATE`)
SERVO = ("force", "max_speed", "gain", "offset", "speed", "pushed", "stiffness", "dt")
#: where the shape's numbers (a cylinder's, a servo's) start in the block: after the shape code and the motion
SHAPE_AT = 1 + len(MOTION)
#: where each of a servo's numbers sits in its block
S_FORCE, S_MAX_SPEED, S_GAIN, S_OFFSET, S_SPEED, S_PUSHED, S_STIFFNESS, S_DT = range(SHAPE_AT, SHAPE_AT + len(SERVO))
#: where a servo's state (offset, speed, push, stiffness: what a checkpoint keeps) starts in its block
SERVO_STATE = S_OFFSET


@njit(**KERNEL_OPTIONS)
def cylinder_plane(x, y, z, px, py, pz, ax, ay, az, rc, side, omega):
    """(plane, nx, ny, nz, ux, uy, uz): the tangent plane x.n = plane of the cylinder (axis through p
    along the unit a, radius rc, side +1 inside, -1 outside) where the sphere centred at (x, y, z)
    meets it, and the surface's velocity there (turning at omega about a)."""
    rx = x - px
    ry = y - py
    rz = z - pz
    h = rx * ax + ry * ay + rz * az
    dx = rx - h * ax
    dy = ry - h * ay
    dz = rz - h * az
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d > 0.0:
        ex = dx / d
        ey = dy / d
        ez = dz / d
    else:  # a centre on the axis: every radial direction is as near; take one across the axis
        if abs(ax) < 0.9:
            ex, ey, ez = 0.0, -az, ay
        else:
            ex, ey, ez = az, 0.0, -ax
        norm = math.sqrt(ex * ex + ey * ey + ez * ez)
        ex /= norm
        ey /= norm
        ez /= norm
    sx = px + h * ax + rc * ex
    sy = py + h * ay + rc * ey
    sz = pz + h * az + rc * ez
    nx = -side * ex
    ny = -side * ey
    nz = -side * ez
    speed = omega * rc
    return (sx * nx + sy * ny + sz * nz, nx, ny, nz, speed * (ay * ez - az * ey), speed * (az * ex - ax * ez),
            speed * (ax * ey - ay * ex))


#: the planes of walls with a geometry block are computed by a function compiled once and called, not
#: copied into the IR of each wall law's call site: the cylinder's geometry typed again at each site made
#: a sphere loop of a shaken cylinder, a piston and a servo lid (tier 2) compile for 49 CPU s. Strict IEEE
#: arithmetic, as the generated modules that call it (the same bits on both tiers, inlined by LLVM or not)
PLANE_OPTIONS = dict(KERNEL_OPTIONS, inline="never", fastmath=False)


@njit(**KERNEL_OPTIONS)
def wall_plane(x, y, z, params, g, t, plane, nx, ny, nz, ux, uy, uz):
    """(plane, nx, ny, nz, ux, uy, uz): the plane the wall presents to the sphere centred at (x, y, z) at
    time t, and its surface's velocity there: a steady plane's own (``g`` < 0: a test, inlined into the
    loop), else :func:`geometry_plane`'s."""
    if g < 0:
        return plane, nx, ny, nz, ux, uy, uz
    return geometry_plane(x, y, z, params, g, t, plane, nx, ny, nz)


@njit(**PLANE_OPTIONS)
def geometry_plane(x, y, z, params, g, t, plane, nx, ny, nz):
    """The plane and surface velocity of a wall whose geometry block is at params[g] (``g`` >= 0; see the
    module docstring): a moving plane, a servo's, a cylinder's tangent plane, or a mesh's plane through the
    point nearest to the sphere."""
    w = params[g + 7]
    swing = 1.0 - math.cos(w * t)
    rate = w * math.sin(w * t)
    dx = params[g + 1] * t + params[g + 4] * swing
    dy = params[g + 2] * t + params[g + 5] * swing
    dz = params[g + 3] * t + params[g + 6] * swing
    vx = params[g + 1] + params[g + 4] * rate
    vy = params[g + 2] + params[g + 5] * rate
    vz = params[g + 3] + params[g + 6] * rate
    if params[g] == 0.0:
        return plane + (dx * nx + dy * ny + dz * nz), nx, ny, nz, vx, vy, vz
    if params[g] == 2.0:  # a servo's plane: moved along its normal by its offset (quasi-static steps whose
        # speed the contacts' dashpots do not see: seen, c / dt would swamp the stiffness the servo steers by)
        return plane + (dx * nx + dy * ny + dz * nz) + params[g + S_OFFSET], nx, ny, nz, vx, vy, vz
    k = g + SHAPE_AT  # the shape's numbers
    if params[g] == 4.0:  # a triangle mesh (demkit.interactions.mesh_geometry)
        return mesh_plane(x, y, z, params, g, k, t, dx, dy, dz, vx, vy, vz)
    # the cylinder's numbers (demkit.interactions.cylinder.GEOMETRY)
    c, cx, cy, cz, wx, wy, wz = cylinder_plane(x - dx, y - dy, z - dz, params[k], params[k + 1], params[k + 2],
                                               params[k + 3], params[k + 4], params[k + 5], params[k + 6],
                                               params[k + 7], params[k + 8])
    return c + (dx * cx + dy * cy + dz * cz), cx, cy, cz, wx + vx, wy + vy, wz + vz


@njit(**KERNEL_OPTIONS)
def servo_clear(params, g):
    """Before a force evaluation: the servo's sums of force and stiffness start at zero (g < 0 or
    another shape: nothing)."""
    if g >= 0 and params[g] == 2.0:
        params[g + S_PUSHED] = 0.0
        params[g + S_STIFFNESS] = 0.0


@njit(**KERNEL_OPTIONS)
def servo_add(params, g, fx, fy, fz, nx, ny, nz, overlap):
    """Add sphere i's contact with the wall to the servo's sums: the normal force (fx, fy, fz).n the wall
    exerts on it, which the sphere exerts back, and its secant stiffness (that force / overlap) when it
    pushes (a dashpot pulling as the sphere leaves has a negative secant, which would turn the servo's
    step round)."""
    if g >= 0 and params[g] == 2.0 and overlap > 0.0:
        push = fx * nx + fy * ny + fz * nz
        params[g + S_PUSHED] += push
        if push > 0.0:
            params[g + S_STIFFNESS] += push / overlap


@njit(**KERNEL_OPTIONS)
def servo_step(params, g):
    """After a step: move the servo's wall (see the module docstring); returns nothing."""
    if g >= 0 and params[g] == 2.0:
        limit = params[g + S_MAX_SPEED] * params[g + S_DT]
        stiffness = params[g + S_STIFFNESS]
        error = params[g + S_PUSHED] - params[g + S_FORCE]
        move = params[g + S_GAIN] * error / stiffness if stiffness > 0.0 else -limit
        move = min(max(move, -limit), limit)  # > 0: away from the spheres
        params[g + S_OFFSET] -= move
        params[g + S_SPEED] = -move / params[g + S_DT]
