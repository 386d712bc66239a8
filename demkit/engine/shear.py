"""Lees-Edwards sliding images in the compiled loops (simple shear of a periodic box, ``dk.Shear``).

Flow axis a, gradient axis b, shear rate gammadot. The image of sphere j one period up b, at
x_j + L_b e_b, sits at x_j + L_b e_b + delta e_a and moves at v_j + u e_a, where u = gammadot L_b (the
*jump*) and delta(t) = u t - L_a floor(u t / L_a) in [0, L_a), computed from the scene's clock at each use
(never accumulated: a restart gives the same bits).

The scene keeps a block of :data:`SHEAR_VALUES` numbers in ``params`` (the program's ``H_SHEAR``
column holds its slot, -1 in a box that does not shear): the axes a and b, the jump u and the offset at
which the neighbour lists were last built (the skin watches its change).

Pair geometry (:func:`sheared_image`, the same function on both tiers): along b the minimum image
d_b + k L_b (k = -1, 0, +1 for coordinates within one period of each other), then d_a + k delta
reduced to the nearest image along a, then the third axis as in any periodic box. A law reading
velocities is given the shift s = -k u e_a, which it subtracts from v_j - v_i (written so because
x - 0.0 is x to the bit: an unsheared call gives the bits it gave before).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .motion import KERNEL_OPTIONS, fold
from .neighbours import LOOP_OPTIONS, wrap

#: the shear block in params: flow axis a, gradient axis b, jump u = gammadot L_b, offset at the last build,
#: and the margin: an owner farther than it from both faces across b has no listed partner through the
#: sliding boundary (the longest list's reach plus twice the skin: positions lie within a skin of the box)
SH_FLOW, SH_GRADIENT, SH_JUMP, SH_BUILT, SH_MARGIN = range(5)
SHEAR_VALUES = 5
#: the lists take the pairs across the sliding boundary that come within reach while delta slides on by
#: this many skins (at most L_a / 4) in the flow's direction: the sliding then uses up the skin that
#: many times more slowly, for a few per cent more pairs (see slide_since_build)
SLIDE_AHEAD = 3.0


@njit(**LOOP_OPTIONS)
def slide_ahead(params, sh, box, skin):
    """The signed sliding the lists cover ahead, SLIDE_AHEAD skins (at most L_a / 4) in the direction of u."""
    ahead = min(SLIDE_AHEAD * skin, 0.25 * box[int(params[sh + SH_FLOW])])
    return ahead if params[sh + SH_JUMP] >= 0.0 else -ahead


@njit(**KERNEL_OPTIONS)
def offset_turns(params, sh, box, t):
    """(delta(t) = u t mod L_a in [0, L_a), the whole turns floor(u t / L_a)) (u: the block's jump)."""
    la = box[int(params[sh + SH_FLOW])]
    d = params[sh + SH_JUMP] * t
    turns = math.floor(d / la)
    return d - la * turns, turns


@njit(**KERNEL_OPTIONS)
def shear_offset(params, sh, box, t):
    """delta(t) = u t mod L_a in [0, L_a) (:func:`offset_turns`)."""
    return offset_turns(params, sh, box, t)[0]


@njit(**KERNEL_OPTIONS)
def sheared_image(dx, dy, dz, a, b, la, lb, delta, u, pc, lc):
    """(dx, dy, dz, sx, sy, sz): the separation x_j - x_i to j's nearest Lees-Edwards image (a, b: the
    flow and gradient axes, la, lb their lengths; pc, lc: whether the third axis is periodic, its
    length) and the velocity shift s = -k u e_a of that image (subtracted from v_j - v_i by the laws)."""
    db = dx if b == 0 else (dy if b == 1 else dz)
    da = dx if a == 0 else (dy if a == 1 else dz)
    c = 3 - a - b
    dc = dx if c == 0 else (dy if c == 1 else dz)
    k = 0.0
    if db > 0.5 * lb:
        db -= lb
        k = -1.0
    elif db < -0.5 * lb:
        db += lb
        k = 1.0
    da += k * delta
    da -= la * math.floor(da / la + 0.5)
    if pc:
        if dc > 0.5 * lc:
            dc -= lc
        elif dc < -0.5 * lc:
            dc += lc
    s = -k * u
    rx = da if a == 0 else (db if b == 0 else dc)
    ry = da if a == 1 else (db if b == 1 else dc)
    rz = da if a == 2 else (db if b == 2 else dc)
    return rx, ry, rz, (s if a == 0 else 0.0), (s if a == 1 else 0.0), (s if a == 2 else 0.0)


@njit(cache=True)
def list_frame(params, sh, box, t, skin):
    """The list builder's view of the shear: [a, b, delta(t), the sliding covered ahead
    (:func:`slide_ahead`; 0 for a skin of 0)], or an empty array (sh < 0: no shear)."""
    if sh < 0:
        return np.zeros(0)
    out = np.empty(4)
    out[0] = params[sh + SH_FLOW]
    out[1] = params[sh + SH_GRADIENT]
    out[2] = shear_offset(params, sh, box, t)
    out[3] = slide_ahead(params, sh, box, skin)
    return out


@njit(**LOOP_OPTIONS)
def slide_since_build(params, sh, box, t, skin):
    """How far a pair across the sliding boundary has moved along a by the sliding alone beyond what the
    lists cover (:func:`slide_ahead`): the change of delta since the build, reduced to the nearest
    image along a, less the sliding covered ahead when it goes that way."""
    la = box[int(params[sh + SH_FLOW])]
    dd = shear_offset(params, sh, box, t) - params[sh + SH_BUILT]
    dd -= la * math.floor(dd / la + 0.5)
    ahead = slide_ahead(params, sh, box, skin)
    forward = dd / ahead if ahead != 0.0 else -1.0  # the fraction of the covered sliding used up
    if 0.0 <= forward <= 1.0:
        return 0.0
    return abs(dd) - abs(ahead) if forward > 1.0 else abs(dd)


@njit(**LOOP_OPTIONS)
def wrap_sheared(position, velocity, reference, image, box, periodic, params, sh, t):
    """Wrap periodic coordinates as :func:`demkit.engine.neighbours.wrap`, a sphere crossing the
    gradient axis k periods moved by -k delta along a and its velocity along a by -k u. Image counts
    keep the unwrapped path continuous: unwrapped x_a = x_a + n_a L_a + n_b u t (as LAMMPS' image
    flags with the current tilt), so n_a also takes -k floor(u t / L_a)."""
    a = int(params[sh + SH_FLOW])
    b = int(params[sh + SH_GRADIENT])
    lb = box[b]
    delta, turns = offset_turns(params, sh, box, t)
    u = params[sh + SH_JUMP]
    for i in range(position.shape[0]):
        y = position[i, b]
        if y < 0.0 or y >= lb:
            folded, k = fold(y, lb)
            position[i, b] = folded
            image[i, b] += k
            position[i, a] -= k * delta
            velocity[i, a] -= k * u
            image[i, a] -= k * int(turns)
            if reference.shape[0] > 0:
                reference[i, b] -= k * lb
                reference[i, a] -= k * delta
    wrap(position, reference, image, box, periodic)


@njit(**LOOP_OPTIONS)
def frame_sheared(k, position, velocity, image, tag, box, periodic, params, sh, t, rec_position, rec_velocity,
                  rec_image):
    """Frame k's positions, velocities and image counts folded with the sliding images (after
    :func:`demkit.engine.motion.store_frame`, which folds each axis on its own): what
    :func:`wrap_sheared` would make of the state, without touching it."""
    a = int(params[sh + SH_FLOW])
    b = int(params[sh + SH_GRADIENT])
    lb = box[b]
    delta, turns = offset_turns(params, sh, box, t)
    u = params[sh + SH_JUMP]
    for i in range(position.shape[0]):
        row = tag[i]
        yb, nb = fold(position[i, b], lb)
        x = position[i, a] - nb * delta
        na = image[i, a] - nb * int(turns)
        xa, shift = fold(x, box[a])
        rec_position[k, row, b] = yb
        rec_image[k, row, b] = image[i, b] + nb
        rec_position[k, row, a] = xa
        rec_image[k, row, a] = na + shift
        rec_velocity[k, row, a] = velocity[i, a] - nb * u
