"""Faster compilation: numba's inliner copies a function's IR with one memo per copy, not per block.

demkit's kernels inline their pair functions, force passes and list upkeep into one time loop
(``inline='always'``). For each call it inlines, numba (0.59 to 0.68 at least) deep-copies the
callee's IR twice, one block at a time with a fresh ``copy.deepcopy`` memo per block, so every block
drags along its own copy of the callee's whole variable scope: the cost grows as blocks × variables,
quadratic in the size of the callee. For a two-sphere frictional Hertz scene on a wall that copying
was 40-55 % of the compile time (cProfile: 19.8 of 36.8 s).

:func:`install` wraps ``InlineWorker.inline_ir`` so that the blocks of one IR copy share one memo: the
copy is the same object graph as the original (one scope shared by all blocks, as in the original),
made in time linear in its size. Nothing else in numba changes; the compiled code is the same (the
test suite's bit-for-bit checks run with it). If numba's inliner no longer looks as expected the
patch stays out, and ``DEMKIT_PLAIN_INLINING=1`` keeps it out (to measure what it saves).
"""
from __future__ import annotations

import copy
import os

from numba.core import inline_closurecall, ir


class _OneMemoPerCopy:
    """Stands in for the ``copy`` module inside numba's inliner: a block copied while an inlining is
    under way shares the memo of the other blocks of the same IR (same scope object)."""

    def __init__(self):
        self.memo, self.scope = None, None

    def deepcopy(self, x, memo=None):
        if memo is None and self.memo is not None and isinstance(x, ir.Block):
            if x.scope is not self.scope or id(x) in self.memo:  # another IR, or this one again
                self.memo, self.scope = {}, x.scope
            return copy.deepcopy(x, self.memo)
        return copy.deepcopy(x, memo)

    def __getattr__(self, name):
        return getattr(copy, name)


def install():
    """Patch numba's inliner (once); returns whether the patch is in place."""
    worker = inline_closurecall.InlineWorker
    if getattr(worker.inline_ir, "demkit_one_memo", False):
        return True
    if os.environ.get("DEMKIT_PLAIN_INLINING", "") not in ("", "0"):
        return False
    if inline_closurecall.copy is not copy or not callable(getattr(worker, "inline_ir", None)):
        return False  # numba's inliner changed: leave it as it is
    shim = _OneMemoPerCopy()
    original = worker.inline_ir

    def inline_ir(self, *args, **kwargs):
        saved = shim.memo, shim.scope
        shim.memo, shim.scope = {}, None
        try:
            return original(self, *args, **kwargs)
        finally:
            shim.memo, shim.scope = saved  # nothing of this copy is kept alive

    inline_ir.demkit_one_memo = True
    inline_ir.__doc__ = original.__doc__
    inline_closurecall.copy = shim
    worker.inline_ir = inline_ir
    return True


INSTALLED = install()
