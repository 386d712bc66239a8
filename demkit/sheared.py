"""Scenes in a sheared box (``dk.Box(..., shear=dk.Shear(rate, flow, gradient))``): what the Lees-Edwards
images cover, the rest refused by name, and the shear's block of parameters for the compiled loops
(:mod:`demkit.engine.shear`)."""
from __future__ import annotations

import numpy as np

from .engine.shear import SH_BUILT, SH_FLOW, SH_GRADIENT, SH_JUMP, SH_MARGIN, SHEAR_VALUES


def shear_block(box, list_reach, skin):
    """The params block of a sheared box: [a, b, gammadot L_b, offset at the lists' last build (0 for now),
    the margin: the longest list's reach (cutoff + skin) plus twice the skin]."""
    a, b = box.shear.axes
    block = np.zeros(SHEAR_VALUES)
    block[SH_FLOW], block[SH_GRADIENT], block[SH_JUMP], block[SH_BUILT] = a, b, box.shear.jump(box.size), 0.0
    block[SH_MARGIN] = list_reach + 2.0 * skin
    return block


def check_scene(box, interactions, effects):
    """Raise ValueError for what a sheared box does not do yet (each named, with the reason)."""
    shear = box.shear
    for inter in interactions:
        if getattr(inter, "long_range", None) is not None:
            raise ValueError(f"{type(inter).__name__} with long_range={type(inter.long_range).__name__}: Ewald, "
                             f"P3M and FMM sums are not done in a sheared box (they need the sheared "
                             f"reciprocal lattice); give the dipoles a cutoff instead")
        if "velocity" in inter.reads and not type(inter).__module__.startswith("demkit."):
            raise ValueError(f"{type(inter).__name__} reads velocities: a function of your own would see v_j - v_i "
                             f"without the sliding image's velocity (gammadot L_b along the flow) across the "
                             f"boundary; a sheared box runs shipped velocity-reading laws only")
    a, b = shear.axes
    for effect in effects:
        name = type(effect).__name__
        if getattr(effect, "plane_contact", False):
            normal = getattr(effect, "normal", None)
            flat = getattr(effect, "flat", True) and name == "Wall"
            if not flat or normal is None or abs(normal[a]) > 0.0 or abs(normal[b]) > 0.0:
                raise ValueError(f"{name} in a box sheared along {shear.flow} with gradient {shear.gradient}: only "
                                 f"plane walls across the third axis are supported (a wall along the gradient or "
                                 f"the flow would cut the sliding images)")
