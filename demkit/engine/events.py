"""Contact events: when, within a step, a pair of spheres starts or stops touching.

A dashpot's force jumps when a contact opens or closes (F = k delta + c d(delta)/dt switches on at
delta = 0 with d(delta)/dt != 0). A fixed-step method that steps across such a jump makes an
error of the order of the jump times the step, which caps it at first order. Locating the crossing
and ending a sub-step there keeps every sub-step smooth (``VelocityVerlet(dt, resolve_contacts=True)``).

Over a velocity-Verlet sub-step of length tau from (x, v) with acceleration a = F/m, a centre
moves along x + tau v + tau^2/2 a exactly. A pair (i, j) touches while
s(tau) = |d(tau)|^2 - (R_i + R_j)^2 < 0, d = x_j - x_i (minimum image along periodic axes). The
earliest sign change of s on (0, H] is found by bisection to round-off.
"""
from __future__ import annotations

import math

from numba import njit

from .motion import KERNEL_OPTIONS

#: bisection steps: the bracket shrinks below 2^-60 of H (round-off)
BISECTIONS = 60


@njit(**KERNEL_OPTIONS)
def _path_gap(dx, dy, dz, ux, uy, uz, ax, ay, az, reach2, tau):
    """|d(tau)|^2 - reach^2 along d + tau u + tau^2/2 a."""
    half = 0.5 * tau * tau
    x = dx + tau * ux + half * ax
    y = dy + tau * uy + half * ay
    z = dz + tau * uz + half * az
    return x * x + y * y + z * z - reach2


@njit(**KERNEL_OPTIONS)
def pair_crossing(i, j, position, velocity, force, mass, radius, box, periodic, horizon):
    """Earliest tau in (0, horizon] at which pair (i, j) starts or stops touching along the
    velocity-Verlet path, or math.inf if its state at the horizon is that of now (a grazing
    pass that touches and leaves within one step is not seen)."""
    dx = position[j, 0] - position[i, 0]
    dy = position[j, 1] - position[i, 1]
    dz = position[j, 2] - position[i, 2]
    if periodic[0]:
        dx -= box[0] * math.floor(dx / box[0] + 0.5)
    if periodic[1]:
        dy -= box[1] * math.floor(dy / box[1] + 0.5)
    if periodic[2]:
        dz -= box[2] * math.floor(dz / box[2] + 0.5)
    ux = velocity[j, 0] - velocity[i, 0]
    uy = velocity[j, 1] - velocity[i, 1]
    uz = velocity[j, 2] - velocity[i, 2]
    ai = 1.0 / mass[i]
    aj = 1.0 / mass[j]
    ax = force[j, 0] * aj - force[i, 0] * ai
    ay = force[j, 1] * aj - force[i, 1] * ai
    az = force[j, 2] * aj - force[i, 2] * ai
    reach = radius[i] + radius[j]
    # too far to reach contact within the horizon
    speed = math.sqrt(ux * ux + uy * uy + uz * uz) + 0.5 * horizon * math.sqrt(ax * ax + ay * ay + az * az)
    distance = math.sqrt(dx * dx + dy * dy + dz * dz)
    if distance - reach > horizon * speed:
        return math.inf
    reach2 = reach * reach
    now = _path_gap(dx, dy, dz, ux, uy, uz, ax, ay, az, reach2, 0.0) < 0.0
    if (_path_gap(dx, dy, dz, ux, uy, uz, ax, ay, az, reach2, horizon) < 0.0) == now:
        return math.inf
    low, high = 0.0, horizon  # the state at low is now's, at high the other
    for _ in range(BISECTIONS):
        middle = 0.5 * (low + high)
        if middle <= low or middle >= high:
            break
        if (_path_gap(dx, dy, dz, ux, uy, uz, ax, ay, az, reach2, middle) < 0.0) == now:
            low = middle
        else:
            high = middle
    return high


@njit(**KERNEL_OPTIONS)
def earliest_crossing(position, velocity, force, mass, radius, box, periodic, start, end, partner, is_list,
                      horizon):
    """Earliest contact event within ``horizon`` (math.inf if none) of the pairs of a neighbour list
    (``is_list``: the partners of i are partner[start[i]:end[i]]) or of all pairs i < j. One loop for both:
    its pair test is inlined once into what calls it."""
    n = position.shape[0]
    earliest = math.inf
    for i in range(n):
        for p in range(start[i] if is_list else i + 1, end[i] if is_list else n):
            tau = pair_crossing(i, partner[p] if is_list else p, position, velocity, force, mass, radius, box,
                                periodic, horizon)
            if tau < earliest:
                earliest = tau
    return earliest


@njit(**KERNEL_OPTIONS)
def earliest_wall_crossing(position, velocity, force, mass, radius, plane, nx, ny, nz, horizon):
    """Earliest time in (0, horizon] at which a sphere starts or stops touching the wall
    x.n = plane (its height (x.n - plane) passes R along the Verlet path), or math.inf."""
    earliest = math.inf
    for i in range(position.shape[0]):
        h = position[i, 0] * nx + position[i, 1] * ny + position[i, 2] * nz - plane - radius[i]
        u = velocity[i, 0] * nx + velocity[i, 1] * ny + velocity[i, 2] * nz
        a = (force[i, 0] * nx + force[i, 1] * ny + force[i, 2] * nz) / mass[i]
        if h - horizon * (abs(u) + 0.5 * horizon * abs(a)) > 0.0:
            continue  # cannot reach the wall within the horizon
        now = h < 0.0
        if (h + horizon * u + 0.5 * horizon * horizon * a < 0.0) == now:
            continue
        low, high = 0.0, min(horizon, earliest)
        if (h + high * u + 0.5 * high * high * a < 0.0) == now:
            continue  # crosses, but after an event already found
        for _ in range(BISECTIONS):
            middle = 0.5 * (low + high)
            if middle <= low or middle >= high:
                break
            if (h + middle * u + 0.5 * middle * middle * a < 0.0) == now:
                low = middle
            else:
                high = middle
        earliest = high
    return earliest
