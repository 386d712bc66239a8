"""Scenes in a deforming box (``dk.Box(..., deform=dk.Deform(x=rate))``): what the affine remap covers, the
rest refused by name, the deformation's block of parameters for the compiled loops
(:mod:`demkit.engine.deform`), and the check that a run leaves the box long enough."""
from __future__ import annotations

import numpy as np

from .box import AXES
from .engine.deform import DEFORM_VALUES, DF_BUILT, DF_RATE, DF_REACH, DF_SIZE0, DF_START


def deform_block(box, time, list_reach):
    """The params block: [rates (3), lengths at t0 = 0 (3), lengths at ``time`` (the lists' build), the
    longest list reach, t0]."""
    block = np.zeros(DEFORM_VALUES)
    block[DF_RATE:DF_RATE + 3] = box.deform.rates
    block[DF_SIZE0:DF_SIZE0 + 3] = box.size
    block[DF_BUILT:DF_BUILT + 3] = box.size_at(float(time))
    block[DF_REACH] = list_reach
    return block


def change_rates(scene, rates):
    """A servo's new rates from now on: the box's lengths now and the time into the scene's block (the
    compiled step reads them) and into the box's history (what Box.size_at reads)."""
    q, lengths, now = scene.deform_slot, scene.arrays["box"].copy(), scene.time
    scene.params[q + DF_RATE:q + DF_RATE + 3] = rates
    scene.params[q + DF_SIZE0:q + DF_SIZE0 + 3] = lengths
    scene.params[q + DF_START] = now
    scene.box.deform.change(now, lengths, rates)



def check_scene(box, interactions, effects):
    """Raise ValueError for what a deforming box does not do (each named, with the reason)."""
    for inter in interactions:
        if getattr(inter, "long_range", None) is not None:
            raise ValueError(f"{type(inter).__name__} with long_range={type(inter.long_range).__name__}: Ewald, "
                             f"P3M and FMM sums are tuned to a fixed box and not done in a deforming one; give the "
                             f"dipoles a cutoff instead")
    axes = box.deform.axes
    for effect in effects:
        if getattr(effect, "plane_contact", False):
            normal = getattr(effect, "normal", None)
            if normal is None or any(abs(normal[a]) > 0.0 for a in axes):
                raise ValueError(f"{type(effect).__name__} in a box deforming along "
                                 f"{', '.join(AXES[a] for a in axes)}: only plane walls across an axis that does "
                                 f"not deform are supported (the wall would not move with the box)")


def check_run(box, reach, start, end):
    """Raise ValueError if the box, deforming from time ``start`` to ``end``, would come to a periodic
    length not longer than twice ``reach`` (the minimum image would miss pairs), naming when."""
    deform = box.deform
    driven = deform.servo.axes if deform.servo is not None else ()
    for a in deform.axes:
        rate = deform.rates[a]
        if rate >= 0.0 or a in driven:  # (a servo keeps its axes long enough itself)
            continue
        length = box.size_at(float(end))[a]
        if length <= 2.0 * reach:
            when = (2.0 * reach / box.size[a] - 1.0) / rate  # L_a0 (1 + rate t) = 2 reach
            raise ValueError(f"the box deforming along {AXES[a]} at the rate {rate:g} would be {length:.6g} long at "
                             f"t = {end:.6g}, not longer than twice the reach {reach:.6g} (reached at t = "
                             f"{when:.6g}): the minimum image would miss interactions; end the run before t = "
                             f"{when:.6g} (it starts at t = {start:.6g}) or shorten the reach")


def remap(arrays, box, time):
    """The kernels' box at ``time`` and their positions (and the lists' references) remapped affinely
    into it; returns whether anything changed (the same arithmetic as the compiled step)."""
    size, changed = box.size_at(float(time)), False
    for a in range(3):
        f = size[a] / arrays["box"][a]
        if f != 1.0:
            arrays["position"][:, a] *= f
            arrays["reference"][:, a] *= f
            arrays["box"][a], changed = size[a], True
    return changed
