"""Faster compilation: numba's variable liveness computed on bit sets, not on sets of names.

numba (0.59 to 0.68 at least) recomputes which variables are live at the entry of each block after most
of its IR rewrites (to place the statements that delete them), ~3 000 times over what an install
compiles. It first finds, for each block, every variable defined or used in a block that can reach it,
by merging sets of names along every edge until nothing changes: sets as large as the function's
variables (3 400 in tier 1's full pair loop, 280 blocks), merged again on each pass. That analysis was
16-18 % of compiling the full family's pair and sphere loops (0.8-1.0 of 5-6 CPU s, timed per call).

:func:`install` replaces ``compute_live_map`` (in numba's modules that import it) with the same
fix-point iterations on Python integers used as bit sets (one bit per variable): unions and
intersections of whole words. The result is the same map of sets (the least fixed point of the same
equations; ``tests/test_liveness.py`` compares it with numba's own on demkit's largest functions), so
nothing downstream changes. If numba no longer looks as expected the patch stays out, and
``DEMKIT_PLAIN_LIVENESS=1`` keeps it out (to measure what it saves).
"""
from __future__ import annotations

import inspect

from numba.core import analysis

from .plain import left_out, replace_in

_numba_live_map = analysis.compute_live_map
#: numba's modules that call compute_live_map by the name they imported
_USERS = ("numba.core.analysis", "numba.core.ir_utils", "numba.parfors.parfor")


def _names(mask, names):
    """The set of names whose bits are set in ``mask``."""
    out = set()
    while mask:
        low = mask & -mask
        out.add(names[low.bit_length() - 1])
        mask ^= low
    return out


def _edges(cfg, order):
    """({block: its successors}, {block: its predecessors}) for the blocks in ``order``: numba's graph's
    own sets where it keeps them (walking its generators of (block, data) pairs cost as much as the
    whole analysis), else from those generators."""
    succs, preds = getattr(cfg, "_succs", None), getattr(cfg, "_preds", None)
    if isinstance(succs, dict) and isinstance(preds, dict):
        return ({label: succs.get(label, ()) for label in order},
                {label: preds.get(label, ()) for label in order})
    return ({label: [target for target, _ in cfg.successors(label)] for label in order},
            {label: [source for source, _ in cfg.predecessors(label)] for label in order})


def compute_live_map(cfg, blocks, var_use_map, var_def_map):
    """{block: the variables live at its entry} (numba's ``compute_live_map``): a variable is live at a
    block's entry if the block uses it before defining it, or it is live at a successor's entry, not
    defined in the block and defined or used in a block that reaches this one."""
    index, names = {}, []
    for sets in (var_use_map, var_def_map):
        for variables in sets.values():
            for name in variables:
                if name not in index:
                    index[name] = len(names)
                    names.append(name)

    def mask_of(variables):
        mask = 0
        for name in variables:
            mask |= 1 << index[name]
        return mask

    uses = {label: mask_of(variables) for label, variables in var_use_map.items()}
    defs = {label: mask_of(variables) for label, variables in var_def_map.items()}
    order = cfg.topo_order()
    successors, predecessors = _edges(cfg, order)
    # reached[b]: the variables defined or used in a block that reaches b (b included)
    reached = {}
    changed = True
    while changed:
        changed = False
        for label in order:
            mask = reached.get(label, 0) | defs[label] | uses[label]
            reached[label] = mask
            for target in successors[label]:
                old = reached.get(target, 0)
                if old | mask != old:
                    reached[target] = old | mask
                    changed = True
    live = {label: uses[label] for label in blocks}
    changed = True
    while changed:
        changed = False
        for label in reversed(order):
            here = live[label]
            for source in predecessors[label]:
                old = live[source]
                new = old | (here & reached.get(source, 0) & ~defs[source])
                if new != old:
                    live[source] = new
                    changed = True
    return {label: _names(mask, names) for label, mask in live.items()}


def _agrees():
    """Does the replacement take numba's arguments and give numba's map on a function with a loop and
    branches?"""
    if list(inspect.signature(_numba_live_map).parameters) != ["cfg", "blocks", "var_use_map", "var_def_map"]:
        return False
    from numba.core import compiler
    from numba.core.ir_utils import compute_cfg_from_blocks

    def sample(n, x):
        total = 0.0
        for k in range(n):
            y = x * k
            if y > 2.0:
                total += y
            elif k == 3:
                z = y - 1.0
                total -= z
        return total

    blocks = compiler.run_frontend(sample).blocks
    cfg = compute_cfg_from_blocks(blocks)
    usedefs = analysis.compute_use_defs(blocks)
    theirs = _numba_live_map(cfg, blocks, usedefs.usemap, usedefs.defmap)
    mine = compute_live_map(cfg, blocks, usedefs.usemap, usedefs.defmap)
    return list(theirs) == list(mine) and theirs == mine and any(mine.values())


def install():
    """Patch numba's liveness analysis (once); returns whether the patch is in place."""
    if analysis.compute_live_map is compute_live_map:
        return True
    if left_out("LIVENESS"):
        return False
    return replace_in(_USERS, "compute_live_map", _numba_live_map, compute_live_map, _agrees)


INSTALLED = install()
