"""The compile notice: one line on stderr when demkit's kernels are compiled, one when that is done.

When demkit's compiled kernels are not in the on-disk cache and must be compiled (the first run of a
scene on a machine, 5-30 s), one line on stderr says so (once the compilation has taken
:data:`NOTICE_AFTER` = 1 s), and one how long it took after; nothing is printed when the cache is warm.
Scenes announce it while being built, simulations while being made and during the first chunk of a
run. It is printed also when stderr is not a terminal (it explains a slow start in a log);
``DEMKIT_QUIET=1`` turns it off. A cache miss is known exactly, not guessed from timings: numba
announces a real compilation with its ``numba:compile`` event (loading from the cache does not).
"""
from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path


def quiet():
    """True when ``DEMKIT_QUIET`` is set to anything but '' or '0'."""
    return os.environ.get("DEMKIT_QUIET", "") not in ("", "0")


#: what the notice says the first compile takes when the scene does not say (see compile_estimate)
COMPILE_ESTIMATE = "usually 5-30 s"
#: a compilation is announced once it has taken this long (wall-clock seconds): shorter ones pass
#: silently (one scene's small diagnostics kernels compile in a fraction of a second)
NOTICE_AFTER = 1.0
#: name of the thread that compiles a scene's thread module in the background (demkit.engine.threads)
BACKGROUND = "demkit-compile-threads"


class _Notice:
    """State of the compile notice. numba compiles under its global lock, so one thread compiles at
    a time; ``lock`` orders the listener, the timer that announces and the end of the scopes."""

    def __init__(self):
        self.lock = threading.RLock()
        self.listening = False
        self.reset()

    def reset(self):
        self.scopes = 0          # open compile_notice scopes
        self.depth = 0           # nesting of numba's compile events (callees compile inside callers)
        self.top_start = None    # perf_counter when the running top-level compilation began
        self.compiling = 0.0     # seconds of top-level compilation in the open scopes
        self.announced = False   # was the first line printed?
        self.cached = True       # are these kernels cached on disk (False: compiled in memory)
        self.timer = None
        self.estimate = None     # what the outermost scope expects compiling to take (text, or a function giving it)


_NOTICE = _Notice()


def _is_demkit(dispatcher):
    module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
    return module == "demkit" or module.startswith(("demkit.", "demkit_kernel_", "demkit_generic_", "demkit_pieces_",
                                                                     "demkit_own_"))


def _cached(dispatcher):
    """False for kernels compiled in memory (pair functions defined in __main__ or a notebook)."""
    return dispatcher.py_func.__globals__.get("DEMKIT_IN_MEMORY") is not True


def _announce():
    n = _NOTICE
    with n.lock:
        n.timer = None
        if n.announced or n.top_start is None or not n.scopes:  # finished (or left) in time
            return
        n.announced = True
        estimate = n.estimate() if callable(n.estimate) else n.estimate
        when = f"first run only, {estimate or COMPILE_ESTIMATE}" if n.cached else \
            "every run: pair functions defined in __main__ or a notebook are not cached"
    if estimate and estimate.startswith("once for this machine"):  # tier 1 (demkit.engine.tiers)
        _say(f"demkit: compiling kernels {estimate}...")
        return
    _say(f"demkit: compiling kernels for this scene ({when})...")


def _listener():
    from numba.core import event

    class CompileListener(event.Listener):
        """numba's compile events: time demkit's top-level compilations inside a notice scope and
        announce them once they take longer than NOTICE_AFTER."""

        def on_start(self, ev):
            if threading.current_thread().name == BACKGROUND:
                return  # the thread module compiling beside a run (demkit.engine.threads): not announced
            n = _NOTICE
            with n.lock:
                n.depth += 1
                dispatcher = ev.data.get("dispatcher")
                if n.depth != 1 or not n.scopes or not _is_demkit(dispatcher):
                    return
                n.top_start = time.perf_counter()
                n.cached = n.cached and _cached(dispatcher)
                if n.announced or n.timer is not None:
                    return
                if NOTICE_AFTER > 0:
                    n.timer = threading.Timer(max(0.0, NOTICE_AFTER - n.compiling), _announce)
                    n.timer.daemon = True
                    n.timer.start()
                    return
            _announce()

        def on_end(self, ev):
            if threading.current_thread().name == BACKGROUND:
                return
            n = _NOTICE
            with n.lock:
                n.depth -= 1
                if n.depth == 0 and n.top_start is not None:
                    n.compiling += time.perf_counter() - n.top_start
                    n.top_start = None
                    if n.timer is not None:
                        n.timer.cancel()
                        n.timer = None

    return CompileListener()


#: CPU seconds of compiling, measured with benchmarks/bench_latency.py on this project's 2-core
#: machines (benchmarks/results/latency.json; a busy or slower machine takes longer): a scene without
#: neighbour lists, one integrator (the paper's pair: 7-11 s); the first run of a scene with lists
#: (a 600-sphere magnetic gas with Hertz contacts and friction: 13-18 s) and building it (2-8 s);
#: the cell-list code, compiled once per install when the first scene with lists is built (~15 s); tier 1's
#: generic kernels on a new install: a scene in open space (the paper's pair: 10-12 s, 1 Dec 2026), the
#: first scene with lists (a frictional dipole gas beside a wall: 16 s on one thread, 48 s more on threads)
ESTIMATES = {"small": (5, 15), "lists": (10, 25), "lists_scene": (0, 2), "cell_lists": 15, "generic": (8, 15),
             "generic_lists": (15, 50), "induction": 9, "own": (1, 3)}


def compile_estimate(plan, phase, tier=2):
    """Text of the compile notice for a scene of this plan at ``phase`` ("scene": building it, "run":
    its first run): the expected seconds, from :data:`ESTIMATES`; on ``tier`` 1 (the generic module)
    a one-time compile for this machine."""
    if tier == 1:
        from . import generic_modules, own_laws
        if any(own_laws.own_members(plan)) and generic_modules.is_cached(False, "forces_of"):
            lo, hi = ESTIMATES["own"]
            return f"about {lo}-{hi} s on an idle machine: the adapters of your own functions (demkit.engine.own_laws)"
        lo, hi = ESTIMATES["generic_lists" if plan.growing else "generic"]
        return (f"once for this machine: demkit's generic kernels, which then serve every scene of shipped "
                f"interactions; about {lo}-{hi} s on an idle machine")
    lo, hi = ESTIMATES["lists" if plan.growing else "small"]
    if phase == "scene" and plan.growing:
        lo, hi = ESTIMATES["lists_scene"]  # the state only: the lists are built (and compiled) at the first run
    extra = ""
    if plan.growing and not cell_lists_cached():
        lo, hi = lo + ESTIMATES["cell_lists"], hi + ESTIMATES["cell_lists"]
        extra = "; the cell lists' code compiles once per install"
    if getattr(plan, "induction", None) is not None and not induction_cached():
        # the solve of the induced moments runs (and compiles) when the scene is built (6-9 s measured)
        lo, hi = lo + ESTIMATES["induction"], hi + ESTIMATES["induction"]
        extra += "; the solve of induced moments compiles once per install"
    return f"about {lo}-{hi} s on an idle machine{extra}"


def _on_disk(function, stem):
    """Is this cached numba function of demkit in numba's disk cache (any signature)?"""
    try:
        folder = Path(function._cache._cache_path)
    except AttributeError:
        return False
    return any(folder.glob(f"{stem}-*.nbi"))


def cell_lists_cached():
    """Is demkit's cell-list builder in numba's disk cache (compiled once per install)?"""
    from . import neighbours
    return _on_disk(neighbours.rebuild, "neighbours.rebuild")


def induction_cached():
    """Is the solve of induced moments in numba's disk cache (compiled once per install)? (Read from
    the module a scene of magnetisable spheres has imported: the engine sits below the physics.)"""
    induction = sys.modules.get("demkit.interactions.induction")
    return induction is not None and _on_disk(induction.induce, "induction.induce")


def _say(text):
    stream = sys.stderr
    if stream is not None:
        try:
            print(text, file=stream, flush=True)
        except (OSError, ValueError):
            pass


class compile_notice:
    """Scope in which compiling demkit's kernels is announced on stderr (see the module docstring):
    a compilation that takes more than :data:`NOTICE_AFTER` seconds prints a line; leaving the
    outermost scope (or :meth:`end`) then prints how long compiling took. Re-entrant; free when
    nothing compiles (numba calls the listener, registered once, only for a real compilation)."""

    def __init__(self, estimate=None):
        self._open = False
        self.estimate = estimate  # text for the notice, or a function giving it when announced

    def __enter__(self):
        if quiet():
            return self
        n = _NOTICE
        with n.lock:
            if not n.listening:
                from numba.core import event

                event.register("numba:compile", _listener())
                n.listening = True
            if not n.scopes:
                n.estimate = self.estimate
            n.scopes += 1
        self._open = True
        return self

    def end(self):
        """Leave the scope now (idempotent)."""
        if not self._open:
            return
        self._open = False
        n = _NOTICE
        with n.lock:
            n.scopes -= 1
            if n.scopes:
                return
            if n.timer is not None:
                n.timer.cancel()
            announced, seconds, cached = n.announced, n.compiling, n.cached
            depth = n.depth
            n.reset()
            n.depth = depth
        if announced:
            _say(f"demkit: kernels compiled in {seconds:.1f} s" + (" (cached for the next runs)" if cached else ""))

    def __exit__(self, *exc):
        self.end()
        return False
