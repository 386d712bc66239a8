"""A periodic box deforming at set strain rates (``dk.Box(..., deform=dk.Deform(x=...))``) in the compiled loops.

Each deforming axis a has the length L_a(t) = L_a0 (1 + rate_a (t - t0)), from the scene's clock (never
accumulated: a restart gives the same bits); t0 = 0 and L_a0 the box's size unless a servo on the box
(:class:`demkit.PressureServo`) has set new rates at t0, from the lengths L_a0 the box had then. After every step (``end_step``, as LAMMPS' ``fix deform``
at the end of its step) the box takes its length at the clock and the positions are remapped affinely,
x_a -> x_a L_a(t) / L_a(before), with the neighbour lists' reference positions (``remap x``: the velocities
are left alone, so they are the spheres' velocities relative to the affine flow (Ldot_a / L_a) x_a).

The scene keeps a block of :data:`DEFORM_VALUES` numbers in ``params`` (the program's ``H_DEFORM`` column
holds its slot, -1 in a box that does not deform): the three rates, the three lengths at t0, the
lengths at the lists' last build, the reach of the longest list (its cutoff plus the skin), and t0.

The skin: with the reference positions remapped too, a sphere's displacement from its reference is its
motion relative to the flow alone; a pair of separation d at the build is at least s d apart by the
remap, s the smallest L_a(t) / L_a(build) below 1 (:func:`squeeze_since_build`). A pair outside the
list's reach r_l at the build comes within a cutoff r_l - skin only once
2 max|displacement| + (1 - s) r_l passes the skin: the lists are rebuilt before.
"""
from __future__ import annotations

from numba import njit

#: the deform block in params: rates (3), lengths at t0 (3), lengths at the lists' build (3), longest list reach, t0
DF_RATE, DF_SIZE0, DF_BUILT, DF_REACH, DF_START = 0, 3, 6, 9, 10
DEFORM_VALUES = 11

#: no fastmath: L_a0 (1 + rate (t - t0)) must give the bits Python's arithmetic gives (demkit.box.Deform.size_at)
OPTIONS = dict(cache=True, _nrt=False, error_model="numpy")


@njit(**OPTIONS)
def deform_step(position, reference, box, params, q, t):
    """The box at time t (L_a0 (1 + rate_a (t - t0)) along each deforming axis), the positions and the
    lists' references remapped affinely from the box they were in."""
    for a in range(3):
        rate = params[q + DF_RATE + a]
        if rate == 0.0:
            continue
        length = params[q + DF_SIZE0 + a] * (1.0 + rate * (t - params[q + DF_START]))
        f = length / box[a]
        if f == 1.0:
            continue
        for i in range(position.shape[0]):
            position[i, a] *= f
        for i in range(reference.shape[0]):
            reference[i, a] *= f
        box[a] = length


@njit(**OPTIONS)
def squeeze_since_build(params, q, box):
    """(1 - s) r_l: how much closer than at the lists' build the remap alone has brought a pair at
    the lists' reach r_l (s: the smallest L_a / L_a(build) below 1)."""
    s = 1.0
    for a in range(3):
        ratio = box[a] / params[q + DF_BUILT + a]
        if ratio < s:
            s = ratio
    return (1.0 - s) * params[q + DF_REACH]


@njit(**OPTIONS)
def mark_built(params, q, box):
    """Note the box the lists were built in (no-op when q < 0: the box does not deform)."""
    if q < 0:
        return
    for a in range(3):
        params[q + DF_BUILT + a] = box[a]
