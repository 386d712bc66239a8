"""The plane a wall presents to a sphere at the scene's clock: how the compiled loops see walls that move
or are curved.

Every plane-contact law (demkit.interactions.wall) takes the plane x.n = plane and the surface velocity u
as its first seven parameters. A steady plane wall (at rest, or sliding in itself) passes its own. Any
other wall has a geometry block in the scene's parameters (its row's E_GEOMETRY column points to it):

    shape, Vx, Vy, Vz, Ax, Ay, Az, w, <the shape's numbers>

with shape 0 a plane (the law's own plane and normal at time 0), 1 a cylinder
(demkit.interactions.cylinder.GEOMETRY), 2 a plane moved by a servo (:data:`SERVO`), 3 a cone
(demkit.interactions.cone.GEOMETRY), 4 a triangle mesh (demkit.interactions.mesh_geometry, which also turns
about an axis) and 5 a cylinder whose radius a servo moves (the cylinder's
numbers, then the servo's). A cylinder's or cone's numbers end with a flag: 1 when its contact law is
Hertz, whose moduli the wall then scales to the contact radius of its curvature
(:func:`contact_radius_factor`; the loops pass a wall law's parameters 7 and 8 through wall_plane). The wall is
carried by D(t) = V t + A (1 - cos w t) (w = 2 pi f; the vibration starts at rest, as LAMMPS'
``wiggle``): a sphere at x meets the shape as it
stood at time 0 seen from x - D(t), shifted by D(t), and the surface velocity there gains
D'(t) = V + A w sin(w t).

A servo's wall (shape 2) is moved along its normal n by its own state: the loops add to its block the
normal force F the spheres exert on it and the secant stiffness F_i / delta_i of each contact
(:func:`servo_add`, after :func:`servo_clear` at the start of each evaluation), and after each step
:func:`servo_step` moves it by gain (F - target) / K away from the spheres (towards them when it
touches nothing), at most max_speed dt. A servo whose target changes within a run holds ``points``
K > 0 pairs (time, target) after its numbers: the target at the scene's clock is the piecewise-linear
function through them, held at the first before its time and at the last after (:func:`scheduled`). A
servo cylinder (shape 5) moves its radius the same way (its
offset along the local normal: the radius R_c - side offset), and its target is a stress, the force
per unit radius held in its block times the radius it has reached (the side's area 2 pi R_c L grows
with it). These steps are quasi-static: the surface velocity the
contacts see is the wall's prescribed one only (a dashpot seeing the servo's speed would add c / dt to
the stiffness it steers by, and the loop would swing from one limit to the other).
"""
from __future__ import annotations

import math

from numba import njit

from ..engine.motion import KERNEL_OPTIONS
from .mesh_geometry import mesh_plane

#: the shape codes of the geometry block
SHAPES = {"plane": 0, "cylinder": 1, "servo": 2, "cone": 3, "mesh": 4, "servo cylinder": 5}
#: how many numbers of its shape a servo's block holds before the servo's (a servo cylinder: the
#: cylinder's nine, demkit.interactions.cylinder.GEOMETRY, and its Hertz flag)
SERVO_AFTER = {2: 0, 5: 10}
#: the motion's numbers, after the shape code
MOTION = ("vx", "vy", "vz", "ax", "ay", "az", "w")
#: a servo's numbers, after the motion (its state from "offset" on: :data:`SERVO_STATE`)
SERVO = ("force", "max_speed", "gain", "points", "offset", "speed", "pushed", "stiffness", "dt")
#: where the shape's numbers (a cylinder's, a cone's, a servo's) start in the block: after the shape code and the motion
SHAPE_AT = 1 + len(MOTION)
#: where each of a servo's numbers sits in its block
S_FORCE, S_MAX_SPEED, S_GAIN, S_POINTS, S_OFFSET, S_SPEED, S_PUSHED, S_STIFFNESS, S_DT = range(SHAPE_AT,
                                                                                         SHAPE_AT + len(SERVO))
#: where a servo's state (offset, speed, push, stiffness: what a checkpoint keeps) starts in its block
SERVO_STATE = S_OFFSET


@njit(**KERNEL_OPTIONS)
def about_axis(x, y, z, px, py, pz, ax, ay, az):
    """(h, d, dx, dy, dz, ex, ey, ez): the point (x, y, z) seen from the axis through p along the unit a:
    its height h along a, its distance d from the axis, the part (dx, dy, dz) of x - p across a and the
    radial unit e (a centre on the axis, where every radial direction is as near: one across the axis)."""
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
    return h, d, dx, dy, dz, ex, ey, ez


@njit(**KERNEL_OPTIONS)
def cylinder_plane(x, y, z, px, py, pz, ax, ay, az, rc, side, omega):
    """(plane, nx, ny, nz, ux, uy, uz): the tangent plane x.n = plane of the cylinder (axis through p
    along the unit a, radius rc, side +1 inside, -1 outside) where the sphere centred at (x, y, z)
    meets it, and the surface's velocity there (turning at omega about a)."""
    h, d, dx, dy, dz, ex, ey, ez = about_axis(x, y, z, px, py, pz, ax, ay, az)
    sx = px + h * ax + rc * ex
    sy = py + h * ay + rc * ey
    sz = pz + h * az + rc * ez
    nx = -side * ex
    ny = -side * ey
    nz = -side * ez
    speed = omega * rc
    return (sx * nx + sy * ny + sz * nz, nx, ny, nz, speed * (ay * ez - az * ey), speed * (az * ex - ax * ez),
            speed * (ax * ey - ay * ex))


@njit(**KERNEL_OPTIONS)
def cone_plane(x, y, z, px, py, pz, ax, ay, az, sn, cs, s0, s1, side, omega):
    """(plane, nx, ny, nz, ux, uy, uz): the plane the cone presents to the sphere centred at (x, y, z)
    and the surface's velocity there (demkit.interactions.cone): apex p, unit axis a, half-angle alpha
    (sn = sin alpha, cs = cos alpha), its generators running from s0 to s1 from the apex, side +1
    inside, -1 outside, turning at omega about a.

    In the meridian half-plane of the centre (its height h = r.a along the axis, distance d from it,
    r = x - p, radial unit e) the generator is the ray p + s g, g = cs a + sn e, and the nearest point
    of it is s = t = h cs + d sn. For s0 <= t <= s1 it lies on the face: the tangent plane contains the
    generator (so it passes through the apex) and its normal is side (sn a - cs e). Else the nearest
    point Q is the end of the generator (the rim circle at s0 or s1, the apex when s0 = 0 and t < 0):
    an edge or vertex contact with normal (x - Q)/|x - Q|. A centre on the axis takes one direction
    across the axis (every one is as near)."""
    h, d, dx, dy, dz, ex, ey, ez = about_axis(x, y, z, px, py, pz, ax, ay, az)
    # (a centre within rounding of the axis has a radial direction of rounding noise, not across the
    # axis: take its part across, so that the normal below is a unit vector)
    across = ex * ax + ey * ay + ez * az
    ex -= across * ax
    ey -= across * ay
    ez -= across * az
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    ex /= norm
    ey /= norm
    ez /= norm
    t = h * cs + d * sn
    nx = side * (sn * ax - cs * ex)
    ny = side * (sn * ay - cs * ey)
    nz = side * (sn * az - cs * ez)
    if t < s0 or t > s1:  # beyond the face: the nearest point is the rim (or the apex)
        s = s0 if t < s0 else s1
        qx = px + s * (cs * ax + sn * ex)
        qy = py + s * (cs * ay + sn * ey)
        qz = pz + s * (cs * az + sn * ez)
        vx = x - qx
        vy = y - qy
        vz = z - qz
        q = math.sqrt(vx * vx + vy * vy + vz * vz)
        if q > 0.0:
            nx = vx / q
            ny = vy / q
            nz = vz / q
        plane = qx * nx + qy * ny + qz * nz
    else:
        s = t
        plane = px * nx + py * ny + pz * nz
    speed = omega * s * sn  # omega times the contact point's distance from the axis
    return (plane, nx, ny, nz, speed * (ay * ez - az * ey), speed * (az * ex - ax * ez),
            speed * (ax * ey - ay * ex))


#: the planes of walls with a geometry block are computed by a function compiled once and called, not
#: copied into the IR of each wall law's call site: the cylinder's geometry typed again at each site made
#: a sphere loop of a shaken cylinder, a piston and a servo lid (tier 2) compile for 49 CPU s. Strict IEEE
#: arithmetic, as the generated modules that call it (the same bits on both tiers, inlined by LLVM or not)
PLANE_OPTIONS = dict(KERNEL_OPTIONS, inline="never", fastmath=False)


@njit(**KERNEL_OPTIONS)
def contact_radius_factor(r, curvature):
    """sqrt(R_e / R): what a Hertz law's moduli E*, G* are multiplied by on a curved wall, so that its
    E* sqrt(R delta), G* sqrt(R delta) are those of the contact radius R_e of a sphere of radius r on a
    surface of curvature ``curvature`` across (positive convex towards the sphere, 0 along): the mean of
    the relative principal curvatures, 1/R_e = 1/R + curvature/2 (LAMMPS' region walls' contact radius;
    docs/contacts.md compares it with Hertz's elliptical solution). 1 + R curvature/2 is kept >= 1/4
    (R_e <= 4 R: a sphere wrapping round a cone's axis)."""
    q = 1.0 + 0.5 * r * curvature
    if q < 0.25:
        q = 0.25
    return 1.0 / math.sqrt(q)


@njit(**KERNEL_OPTIONS)
def cone_curvature(x, y, z, px, py, pz, ax, ay, az, sn, cs, s0, s1, side):
    """The cone's curvature across its generator where the sphere centred at (x, y, z) touches its face,
    -side cos(alpha) / r (r the contact point's distance from the axis: concave inside); 0 on a rim or
    the apex (an edge: the contact radius stays the sphere's)."""
    h, d, _, _, _, _, _, _ = about_axis(x, y, z, px, py, pz, ax, ay, az)
    t = h * cs + d * sn
    if t < s0 or t > s1 or t <= 0.0:
        return 0.0
    return -side * cs / (t * sn)


@njit(**KERNEL_OPTIONS)
def wall_plane(x, y, z, r, params, g, t, plane, nx, ny, nz, ux, uy, uz, q7, q8):
    """(plane, nx, ny, nz, ux, uy, uz, q7, q8): the plane the wall presents to the sphere of radius r
    centred at (x, y, z) at time t, and its surface's velocity there, and the law's next two parameters
    (a Hertz law's E*, G*: scaled on a curved wall, :func:`contact_radius_factor`): a steady plane's own
    (``g`` < 0: a test, inlined into the loop), else :func:`geometry_plane`'s."""
    if g < 0:
        return plane, nx, ny, nz, ux, uy, uz, q7, q8
    return geometry_plane(x, y, z, r, params, g, t, plane, nx, ny, nz, q7, q8)


@njit(**PLANE_OPTIONS)
def geometry_plane(x, y, z, r, params, g, t, plane, nx, ny, nz, q7, q8):
    """The plane and surface velocity of a wall whose geometry block is at params[g] (``g`` >= 0; see the
    module docstring): a moving plane, a servo's, a cylinder's or a cone's tangent plane, or a
    mesh's plane through the point nearest to the sphere; q7, q8 as
    given, or scaled by :func:`contact_radius_factor` on a cylinder or cone whose Hertz flag is set."""
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
        return plane + (dx * nx + dy * ny + dz * nz), nx, ny, nz, vx, vy, vz, q7, q8
    if params[g] == 2.0:  # a servo's plane: moved along its normal by its offset (quasi-static steps whose
        # speed the contacts' dashpots do not see: seen, c / dt would swamp the stiffness the servo steers by)
        return plane + (dx * nx + dy * ny + dz * nz) + params[g + S_OFFSET], nx, ny, nz, vx, vy, vz, q7, q8
    k = g + SHAPE_AT  # the shape's numbers (demkit.interactions.cylinder.GEOMETRY, .cone.GEOMETRY)
    if params[g] == 4.0:  # a triangle mesh (demkit.interactions.mesh_geometry): flat, q7 and q8 as given
        c, cx, cy, cz, wx, wy, wz = mesh_plane(x, y, z, params, g, k, t, dx, dy, dz, vx, vy, vz)
        return c, cx, cy, cz, wx, wy, wz, q7, q8
    rc = params[k + 6]
    if params[g] == 5.0:  # a servo cylinder: its radius moved by the servo's offset along the normal
        rc = rc - params[k + 7] * params[g + 10 + S_OFFSET]
    elif params[g] == 3.0:
        c, cx, cy, cz, wx, wy, wz = cone_plane(x - dx, y - dy, z - dz, params[k], params[k + 1], params[k + 2],
                                               params[k + 3], params[k + 4], params[k + 5], params[k + 6],
                                               params[k + 7], params[k + 8], params[k + 9], params[k + 10],
                                               params[k + 11])
        if params[k + 12] != 0.0:  # Hertz: the contact radius of the face's curvature across
            f = contact_radius_factor(r, cone_curvature(x - dx, y - dy, z - dz, params[k], params[k + 1],
                                                        params[k + 2], params[k + 3], params[k + 4], params[k + 5],
                                                        params[k + 6], params[k + 7], params[k + 8], params[k + 9],
                                                        params[k + 10]))
            q7 = q7 * f
            q8 = q8 * f
        return c + (dx * cx + dy * cy + dz * cz), cx, cy, cz, wx + vx, wy + vy, wz + vz, q7, q8
    c, cx, cy, cz, wx, wy, wz = cylinder_plane(x - dx, y - dy, z - dz, params[k], params[k + 1], params[k + 2],
                                               params[k + 3], params[k + 4], params[k + 5], rc,
                                               params[k + 7], params[k + 8])
    if params[k + 9] != 0.0:  # Hertz: the contact radius of the curvature across, -side / R_c
        f = contact_radius_factor(r, -params[k + 7] / rc)
        q7 = q7 * f
        q8 = q8 * f
    return c + (dx * cx + dy * cy + dz * cz), cx, cy, cz, wx + vx, wy + vy, wz + vz, q7, q8


@njit(**KERNEL_OPTIONS)
def servo_base(params, g):
    """Where the servo's numbers of the block at params[g] are offset by (its S_* indices count from
    there): 0 for a servo plane, 10 for a servo cylinder; -1 for no servo (or g < 0)."""
    if g < 0:
        return -1
    if params[g] == 2.0:
        return 0
    if params[g] == 5.0:
        return 10
    return -1


@njit(**KERNEL_OPTIONS)
def servo_clear(params, g):
    """Before a force evaluation: the servo's sums of force and stiffness start at zero (g < 0 or
    another shape: nothing)."""
    b = servo_base(params, g)
    if b >= 0:
        params[g + b + S_PUSHED] = 0.0
        params[g + b + S_STIFFNESS] = 0.0


@njit(**KERNEL_OPTIONS)
def servo_add(params, g, fx, fy, fz, nx, ny, nz, overlap):
    """Add sphere i's contact with the wall to the servo's sums: the normal force (fx, fy, fz).n the wall
    exerts on it, which the sphere exerts back, and its secant stiffness (that force / overlap) when it
    pushes (a dashpot pulling as the sphere leaves has a negative secant, which would turn the servo's
    step round)."""
    b = servo_base(params, g)
    if b >= 0 and overlap > 0.0:
        push = fx * nx + fy * ny + fz * nz
        params[g + b + S_PUSHED] += push
        if push > 0.0:
            params[g + b + S_STIFFNESS] += push / overlap


@njit(**KERNEL_OPTIONS)
def scheduled(params, at, k, t):
    """The piecewise-linear function through the k points (time, value) at params[at:at + 2 k] at time t
    (the first value before the first time, the last after the last)."""
    if t <= params[at]:
        return params[at + 1]
    for m in range(k - 1):
        t1 = params[at + 2 * m + 2]
        if t < t1:
            t0 = params[at + 2 * m]
            v0 = params[at + 2 * m + 1]
            return v0 + (params[at + 2 * m + 3] - v0) * ((t - t0) / (t1 - t0))
    return params[at + 2 * k - 1]


@njit(**KERNEL_OPTIONS)
def servo_step(params, g, t):
    """After a step that has reached time t: move the servo's wall (see the module docstring); returns
    nothing."""
    b = servo_base(params, g)
    if b >= 0:
        h = g + b
        limit = params[h + S_MAX_SPEED] * params[h + S_DT]
        stiffness = params[h + S_STIFFNESS]
        points = int(params[h + S_POINTS])
        target = params[h + S_FORCE] if points == 0 else scheduled(params, h + S_DT + 1, points, t)
        if b > 0:  # a servo cylinder holds a stress: the force per unit radius times the radius now
            target *= params[g + SHAPE_AT + 6] - params[g + SHAPE_AT + 7] * params[h + S_OFFSET]
        error = params[h + S_PUSHED] - target
        move = params[h + S_GAIN] * error / stiffness if stiffness > 0.0 else -limit
        move = min(max(move, -limit), limit)  # > 0: away from the spheres
        params[h + S_OFFSET] -= move
        params[h + S_SPEED] = -move / params[h + S_DT]
