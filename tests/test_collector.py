"""demkit.engine.numba_patches.collector: while numba compiles, Python's garbage collector starts less often; before and
after, it is as it was.

Independent truth: ``gc.get_threshold()`` seen from inside numba's compiles (its "numba:compile" event),
outside them, after a compile that fails, and with compiles in two threads at once; compiled code computes
what Python computes. (``DEMKIT_PLAIN_COLLECTOR=1`` keeps the wrapper out: tests/test_inlining.py.)
"""
import gc
import threading

import numba
import pytest
from numba.core import dispatcher, event

import demkit  # noqa: F401 (installs the wrapper)
from demkit.engine.numba_patches import collector


class Seen(event.Listener):
    def __init__(self):
        self.thresholds = []

    def on_start(self, ev):
        self.thresholds.append(gc.get_threshold()[0])

    def on_end(self, ev):
        pass


def _compiled(listener, function, *args):
    with event.install_listener("numba:compile", listener):
        return function(*args)


def test_the_wrapper_is_in_place_after_importing_demkit():
    assert collector.INSTALLED and dispatcher.Dispatcher.compile is collector.compile
    assert collector.install()


def test_the_threshold_is_raised_during_compiles_only_and_put_back():
    before = gc.get_threshold()
    seen = Seen()

    @numba.njit
    def inner(x):
        return 2.0 * x

    @numba.njit
    def outer(x):
        return inner(x) + 1.0

    assert _compiled(seen, outer, 3.0) == 7.0
    assert len(seen.thresholds) == 2  # (outer, and inner inside it)
    assert all(t == max(before[0], collector.COMPILE_THRESHOLD) for t in seen.thresholds)
    assert gc.get_threshold() == before


def test_a_failed_compile_puts_the_threshold_back():
    before = gc.get_threshold()

    @numba.njit
    def broken(x):
        return x.no_such_attribute

    with pytest.raises(numba.core.errors.TypingError):
        broken(1.0)
    assert gc.get_threshold() == before


def test_compiles_in_two_threads_put_the_threshold_back():
    before = gc.get_threshold()
    results = []

    def work(k):
        @numba.njit
        def f(x):
            total = 0.0
            for i in range(x):
                total += i * k
            return total
        results.append(f(10) == sum(i * k for i in range(10)))

    threads = [threading.Thread(target=work, args=(k,)) for k in (2, 3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert results == [True, True]
    assert gc.get_threshold() == before
