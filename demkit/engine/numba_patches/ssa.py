"""Faster compilation: numba's SSA reconstruction rewrites only the blocks where a variable appears.

numba (0.59 to 0.68 at least) brings a function's IR into SSA form one variable at a time: for each
variable assigned more than once it rebuilds every block of the function twice (fresh names for its
assignments, then each use pointed at the assignment that reaches it), calling a Python handler and a
logger for every statement of every block. The time grows as (variables assigned more than once) ×
(statements). demkit's generated pair and sphere loops assign the same few locals in every branch of
their law switch (hundreds of such variables, thousands of statements): the SSA pass was ~22 % of
compiling the full family's pair loop (cProfile).

:func:`install` wraps numba's ``ssa._run_ssa`` so that, while it runs, ``ssa._run_block_rewrite``
hands the handler only the blocks where the variable at hand is assigned or read; any other block is
copied as it is (a new block, the same statements), which is what the handler would have returned for
each of its statements. The order of the fresh names, the phi nodes and the statements are the same,
so the IR is the same (``tests/test_ssa.py`` compares it with numba's own on demkit's largest
functions). If numba's SSA module no longer looks as expected the patch stays out, and
``DEMKIT_PLAIN_SSA=1`` keeps it out (to measure what it saves).
"""
from __future__ import annotations

import threading

from numba.core import ir, ssa

from .plain import left_out

_state = threading.local()  # the current _run_ssa's map: variable name -> labels of the blocks it appears in


def _where(blocks):
    """variable name -> the labels of the blocks in which it is assigned or read."""
    where = {}
    for label, block in blocks.items():
        for stmt in block.body:
            for var in stmt.list_vars():
                labels = where.get(var.name)
                if labels is None:
                    where[var.name] = {label}
                else:
                    labels.add(label)
    return where


def run_block_rewrite(blocks, states, handler):
    """numba's ``_run_block_rewrite``, the handler given only the blocks where ``states['varname']``
    appears (during a :func:`run_ssa`; elsewhere numba's own)."""
    where = getattr(_state, "where", None)
    labels = None if where is None else where.get(states.get("varname"))
    if labels is None:
        return _numba_rewrite(blocks, states, handler)
    newblocks = {}
    for label, blk in blocks.items():
        if label in labels:
            newblocks.update(_numba_rewrite({label: blk}, states, handler))
        else:
            newblk = ir.Block(scope=blk.scope, loc=blk.loc)
            newblk.body = list(blk.body)
            newblocks[label] = newblk
    return newblocks


def run_ssa(blocks):
    """numba's ``_run_ssa`` with the rewrites of :func:`run_block_rewrite`."""
    saved = getattr(_state, "where", None)
    _state.where = _where(blocks) if blocks else None
    try:
        return _numba_run_ssa(blocks)
    finally:
        _state.where = saved


_numba_run_ssa = ssa._run_ssa
_numba_rewrite = ssa._run_block_rewrite


def install():
    """Patch numba's SSA reconstruction (once); returns whether the patch is in place."""
    if ssa._run_ssa is run_ssa:
        return True
    if left_out("SSA"):
        return False
    needed = ("_run_ssa", "_run_block_rewrite", "_fresh_vars", "_fix_ssa_vars", "_FreshVarHandler", "_FixSSAVars")
    if not all(hasattr(ssa, name) for name in needed):
        return False  # numba's SSA pass changed: leave it as it is
    ssa._run_ssa = run_ssa
    ssa._run_block_rewrite = run_block_rewrite
    return True


INSTALLED = install()
