"""Faster compilation: Python's cyclic garbage collector runs less often while numba compiles.

Compiling makes millions of short-lived objects (IR nodes, types, LLVM IR text) in a process that
already holds millions of long-lived ones (numba's and demkit's modules, caches of types and
signatures). Python's collector starts on every 700 new container objects; its older generations,
reached more often as objects pile up, walk all of them: 14-16 % of compiling tier 1's full pair and
sphere loops (paired, in one process: 11.4 -> 9.8 CPU s for five large functions with the collector off,
-> 10.1 with the threshold below).

:func:`install` wraps numba's ``Dispatcher.compile`` so that while any compile runs (in any thread) the
collector's first threshold is at least COMPILE_THRESHOLD new objects; the thresholds before it are put
back when the last compile ends. The collector keeps running (cyclic garbage is at most that many
objects behind; switched off entirely, two large compiles left 134 MB of it), nothing compiled changes,
and outside compiles the collector is as the user set it. ``DEMKIT_PLAIN_COLLECTOR=1`` keeps numba as
it is.
"""
from __future__ import annotations

import functools
import gc
import threading

from numba.core import dispatcher

from .plain import left_out

#: the collector's first threshold while numba compiles (Python's default: 700)
COMPILE_THRESHOLD = 100_000

_numba_compile = dispatcher.Dispatcher.compile
_lock = threading.Lock()
_running = 0  # compiles under way, nested and in other threads included
_saved = None  # the thresholds before the first of them


@functools.wraps(_numba_compile)
def compile(self, sig):
    """numba's ``Dispatcher.compile`` with the collector's first threshold raised while it runs."""
    global _running, _saved
    with _lock:
        if _running == 0:
            _saved = gc.get_threshold()
            if _saved[0] < COMPILE_THRESHOLD:
                gc.set_threshold(COMPILE_THRESHOLD, *_saved[1:])
        _running += 1
    try:
        return _numba_compile(self, sig)
    finally:
        with _lock:
            _running -= 1
            if _running == 0:
                gc.set_threshold(*_saved)


def install():
    """Wrap numba's compile (once); returns whether the wrapper is in place."""
    if dispatcher.Dispatcher.compile is compile:
        return True
    if left_out("COLLECTOR"):
        return False
    if not callable(_numba_compile) or _numba_compile.__code__.co_varnames[:2] != ("self", "sig"):
        return False  # numba compiles differently now: leave it as it is
    dispatcher.Dispatcher.compile = compile
    return True


INSTALLED = install()
