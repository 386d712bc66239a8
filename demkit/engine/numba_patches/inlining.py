"""Faster compilation: numba's inliner copies a function's IR with one memo per copy, not per block.

demkit's kernels inline their pair functions, force passes and list upkeep into one time loop
(``inline='always'``). For each call it inlines, numba (0.59 to 0.68 at least) deep-copies the
callee's IR twice, one block at a time with a fresh ``copy.deepcopy`` memo per block, so every block
drags along its own copy of the callee's whole variable scope: the cost grows as blocks × variables,
quadratic in the size of the callee. For a two-sphere frictional Hertz scene on a wall that copying
was 40-55 % of the compile time (cProfile: 19.8 of 36.8 s).

:func:`install` wraps ``InlineWorker.inline_ir`` so that the blocks of one IR copy share one memo: the
copy is the same object graph as the original (one scope shared by all blocks, as in the original),
made in time linear in its size. The copy itself is :func:`deep_copy`: ``copy.deepcopy``'s rules
(the same objects shared, the same ``__deepcopy__`` methods called, the same memo entries) with the
IR's plain classes copied through their ``__dict__`` directly instead of ``copy``'s general protocol
(pickling's ``__reduce_ex__``, a dozen tests per object): copying was still 3.4 % of an install's
compile time (sampled), about a third of it as fast. Nothing else in numba changes; the compiled code
is the same (the test suite's bit-for-bit checks run with it). If numba's inliner no longer looks as
expected the patch stays out, and ``DEMKIT_PLAIN_INLINING=1`` keeps it out (to measure what it saves).
"""
from __future__ import annotations

import copy
import copyreg

from numba.core import inline_closurecall, ir

from .plain import left_out


# how deep_copy copies an object of a given class (copy.deepcopy's rules, looked up once per class)
ATOMIC, LIST, DICT, TUPLE, OWN, PLAIN, GENERAL = range(7)
_HOW = {}


def _how(cls):
    """How :func:`deep_copy` copies instances of ``cls``."""
    handler = copy._deepcopy_dispatch.get(cls)
    if handler is copy._deepcopy_atomic or issubclass(cls, type):
        how = ATOMIC
    elif handler is not None:
        how = {list: LIST, dict: DICT, tuple: TUPLE}.get(cls, GENERAL)
    elif getattr(cls, "__deepcopy__", None) is not None:
        how = OWN
    elif (cls not in copyreg.dispatch_table and cls.__reduce_ex__ is object.__reduce_ex__
          and cls.__reduce__ is object.__reduce__ and getattr(cls, "__getstate__", None) in (None, _OBJECT_STATE)
          and not hasattr(cls, "__setstate__") and not issubclass(cls, (list, dict, tuple, set))
          and all("__slots__" not in vars(base) for base in cls.__mro__[:-1])):
        how = PLAIN  # pickling's default: a new object of the class, its __dict__ copied into it
    else:
        how = GENERAL
    _HOW[cls] = how
    return how


_OBJECT_STATE = getattr(object, "__getstate__", None)


def deep_copy(x, memo):
    """``copy.deepcopy(x, memo)``, faster on numba's IR (module docstring)."""
    cls = type(x)
    how = _HOW.get(cls)
    if how is None:
        how = _how(cls)
    if how == ATOMIC:
        return x
    key = id(x)
    y = memo.get(key, memo)
    if y is not memo:
        return y
    if how == PLAIN:
        y = cls.__new__(cls)
        memo[key] = y
        state = x.__dict__
        if state:
            y.__dict__.update(deep_copy(state, memo))
    elif how == LIST:
        y = []
        memo[key] = y
        append = y.append
        for item in x:
            append(deep_copy(item, memo))
    elif how == DICT:
        y = {}
        memo[key] = y
        for k, v in x.items():
            y[deep_copy(k, memo)] = deep_copy(v, memo)
    elif how == TUPLE:
        items = [deep_copy(item, memo) for item in x]
        y = memo.get(key, memo)  # (a tuple reached again through its own items)
        if y is not memo:
            return y
        y = x if all(a is b for a, b in zip(x, items)) else tuple(items)
    elif how == OWN:
        y = x.__deepcopy__(memo)
    else:
        return copy.deepcopy(x, memo)
    if y is not x:  # (as copy.deepcopy: memoised, and the original kept alive while the memo lives)
        memo[key] = y
        alive = memo.get(id(memo))
        if alive is None:
            memo[id(memo)] = [x]
        else:
            alive.append(x)
    return y


class _OneMemoPerCopy:
    """Stands in for the ``copy`` module inside numba's inliner: a block copied while an inlining is
    under way shares the memo of the other blocks of the same IR (same scope object)."""

    def __init__(self):
        self.memo, self.scope = None, None

    def deepcopy(self, x, memo=None):
        if memo is None and self.memo is not None and isinstance(x, ir.Block):
            if x.scope is not self.scope or id(x) in self.memo:  # another IR, or this one again
                self.memo, self.scope = {}, x.scope
            return deep_copy(x, self.memo)
        return copy.deepcopy(x, memo)

    def __getattr__(self, name):
        return getattr(copy, name)


def install():
    """Patch numba's inliner (once); returns whether the patch is in place."""
    worker = inline_closurecall.InlineWorker
    if getattr(worker.inline_ir, "demkit_one_memo", False):
        return True
    if left_out("INLINING"):
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
