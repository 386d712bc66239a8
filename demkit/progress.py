"""What long steps tell the user while they work: progress bars (tqdm) and the compile notice.

Progress bars (:class:`Progress`) are drawn on stderr by tqdm for simulation runs
(``Simulation.run(progress=...)``), for accuracy studies (``demkit.accuracy.work_precision``, one
bar over the study's runs) and for rendering animations (``demkit.viz.animate``):

* ``progress=None`` (the default): a bar only when stderr is a terminal and the work is going to
  take more than about :data:`AUTO_SECONDS` of wall time; nothing in logs, pipes or tests, and
  nothing for short steps. ``DEMKIT_QUIET=1`` in the environment turns these automatic bars off.
* ``progress=True``: a bar always (also when stderr is redirected); ``False``: never.

On a terminal that reports 0 columns (some CI runners and containers; tqdm draws nothing there) the
bar is plain lines instead (:class:`PlainBar`): one at the first update, then one at most every
:data:`PLAIN_SECONDS`, one when the stage shown changes, and the last one at the end.

The compile notice (:class:`compile_notice`): when demkit's compiled kernels are not in the on-disk
cache and must be compiled (the first run of a scene on a machine, 5-30 s), one line on stderr
says so (once the compilation has taken :data:`NOTICE_AFTER` = 1 s), and one how long it took after;
nothing is printed when the cache is warm. Scenes announce it while being built, simulations
while being made and during the first chunk of a run.
It is printed also when stderr is not a terminal (it explains a slow start in a log);
``DEMKIT_QUIET=1`` turns it off. A cache miss is known exactly, not guessed from timings: numba
announces a real compilation with its ``numba:compile`` event (loading from the cache does not).
"""
from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

#: automatic bars appear only for work estimated to take longer than this (wall-clock seconds)
AUTO_SECONDS = 2.0
#: ... judged after this much wall time of the work (and never before its second update)
AUTO_AFTER = 0.5
#: on a terminal of 0 columns, a plain progress line at most this often (wall-clock seconds)
PLAIN_SECONDS = 5.0


def quiet():
    """True when ``DEMKIT_QUIET`` is set to anything but '' or '0'."""
    return os.environ.get("DEMKIT_QUIET", "") not in ("", "0")


def check_progress(progress):
    """``progress`` as given (None, True or False); TypeError for anything else."""
    if progress is None or isinstance(progress, bool):
        return progress
    raise TypeError(f"progress must be None (a bar on a terminal for long work), True or False, got {progress!r}")


class Progress:
    """A tqdm bar over ``total`` units of work, made only when wanted (see the module docstring).

    Call :meth:`update` with the units done so far (absolute, not increments) and :meth:`close`
    when the work ends (however it ends). A forced bar is made at the first update; with
    ``progress=None`` it is made at the first update
    after :data:`AUTO_AFTER` seconds when the work then looks like it will take longer than
    :data:`AUTO_SECONDS` in all; before that, and when no bar is wanted, an update costs one clock
    reading. ``scale``/``span``: the postfix shows ``label = start + done * scale`` / ``span``
    (simulated time for runs); None: no postfix; ``update(done, note)`` shows ``note`` instead.
    ``total`` may be set after construction, before the first update (when it is known later).
    ``tqdm_options`` go to tqdm (unit, unit_scale, ...). ``done`` and ``note`` are the last
    update's (a note stays until another is given). Several steps of work may share one bar:
    :func:`demkit.sweep` takes a Progress as ``progress=`` and counts on from its ``done``.
    """

    def __init__(self, total, progress=None, desc="demkit", scale=None, start=0.0, span=None, label="t",
                 **tqdm_options):
        progress = check_progress(progress)
        self.total = total
        self.forced = progress is True
        self.auto = progress is None and not quiet() and _is_terminal(sys.stderr)
        self.bar = None
        self.desc, self.options = desc, tqdm_options
        self.scale, self.start, self.span, self.label = scale, start, span, label
        self._first = None  # (clock, done) at the first update: the rate is judged from there on
        self.extra = None  # a few words after the postfix (runs: how many threads)
        self.done, self.note = 0, None

    @property
    def active(self):
        """Is a bar shown or still possible?"""
        return self.bar is not None or self.auto or (self.forced and self.total > 0)

    def update(self, done, note=None):
        """``done`` units of ``total`` are done; ``note`` (a short text, e.g. what runs now) replaces
        the postfix when given."""
        self.done = done
        if note is not None:
            self.note = note
        note = self.note
        if self.bar is None and self.forced:
            self._open(0)  # at the first update, not before: after any compile notice
        elif self.bar is None:
            if not self.auto:
                return
            now = time.perf_counter()
            if self._first is None:
                self._first = (now, done)
                return
            began, done0 = self._first
            elapsed = now - began
            if elapsed < AUTO_AFTER or done <= done0:
                return
            remaining = (self.total - done) * elapsed / (done - done0)
            self.auto = False  # judged once
            if elapsed + remaining < AUTO_SECONDS or done >= self.total:
                return
            self._open(done)  # tqdm's rate and time left count from here
        if self.scale is not None and note is None:
            extra = f", {self.extra}" if self.extra else ""
            self.bar.set_postfix_str(f"{self.label} = {self.start + done * self.scale:.6g}/{self.span:.6g}{extra}",
                                     refresh=False)
        stage = note is not None and note != self.bar.postfix
        if stage:
            self.bar.set_postfix_str(note, refresh=False)
        self.bar.update(done - self.bar.n)
        if stage:  # a new stage (a few per run at most): show it now
            self.bar.refresh()

    def _open(self, initial):
        if _columns(sys.stderr) == 0:  # tqdm would draw nothing at all
            self.bar = PlainBar(self.total, initial, self.desc, sys.stderr, **self.options)
            return
        from tqdm import tqdm

        self.bar = tqdm(total=self.total, initial=initial, desc=self.desc, file=sys.stderr, leave=True,
                        dynamic_ncols=True, mininterval=0.2, **self.options)

    def close(self):
        """End the bar (idempotent); it stays on screen where it stopped."""
        self.auto = False
        if self.bar is not None:
            self.bar.close()
            self.bar = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _is_terminal(stream):
    try:
        return stream is not None and stream.isatty()
    except (AttributeError, ValueError):  # closed or replaced by an object without isatty
        return False


def _columns(stream):
    """The width of the terminal ``stream`` is (what tqdm sizes its bar by), or the environment's
    COLUMNS for a terminal-like stream without a file descriptor; None when neither is known."""
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, ValueError, OSError, TypeError):  # not a terminal, or no descriptor
        pass
    if not _is_terminal(stream):
        return None
    try:
        return int(os.environ["COLUMNS"])
    except (KeyError, ValueError):
        return None


class PlainBar:
    """What stands in for a tqdm bar on a terminal of 0 columns: whole lines of tqdm's text
    (``desc:  45% 9/20 [00:04<00:05, 2.1run/s, note]``): one at the first update, then at most one
    every :data:`PLAIN_SECONDS`, one for each new stage (:meth:`refresh`) and the last at the end.
    It has the parts of tqdm that :class:`Progress` uses."""

    def __init__(self, total, initial, desc, file, unit="it", unit_scale=False, **_):
        self.total, self.n, self.desc, self.file = total, initial, desc, file
        self.unit, self.unit_scale = unit, unit_scale
        self.postfix = None
        self.start = time.perf_counter()
        self.shown, self.last = None, None  # clock and (n, postfix) of the last line

    def _line(self):
        from tqdm import tqdm

        self.shown, self.last = time.perf_counter(), (self.n, self.postfix)
        text = tqdm.format_meter(self.n, self.total, self.shown - self.start, ncols=0, prefix=self.desc,
                                 unit=self.unit, unit_scale=self.unit_scale, postfix=self.postfix)
        try:
            print(text, file=self.file, flush=True)
        except (OSError, ValueError):
            pass

    def update(self, n):
        self.n += n
        if self.shown is None or time.perf_counter() - self.shown >= PLAIN_SECONDS:
            self._line()

    def set_postfix_str(self, text, refresh=True):
        self.postfix = text
        if refresh:
            self.refresh()

    def refresh(self):
        """A line now, unless the last one shows the same."""
        if self.last != (self.n, self.postfix):
            self._line()

    def close(self):
        self.refresh()


# ---- the compile notice ------------------------------------------------------------------------
#: what the notice says the first compile takes when the scene does not say (see compile_estimate)
COMPILE_ESTIMATE = "usually 5-30 s"
#: a compilation is announced once it has taken this long (wall-clock seconds): shorter ones pass
#: silently (one scene's small diagnostics kernels compile in a fraction of a second)
NOTICE_AFTER = 1.0
#: name of the thread that compiles a scene's thread module in the background (demkit.threads)
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
    if estimate and estimate.startswith("once for this machine"):  # tier 1 (demkit.tiers)
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
                return  # the thread module compiling beside a run (demkit.threads): not announced
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
#: the cell-list code, compiled once per install when the first scene with lists is built (~15 s)
ESTIMATES = {"small": (5, 15), "lists": (10, 25), "lists_scene": (0, 2), "cell_lists": 15, "generic": (15, 45),
             "induction": 9, "own": (1, 3)}


def compile_estimate(plan, phase, tier=2):
    """Text of the compile notice for a scene of this plan at ``phase`` ("scene": building it, "run":
    its first run): the expected seconds, from :data:`ESTIMATES`; on ``tier`` 1 (the generic module)
    a one-time compile for this machine."""
    if tier == 1:
        from . import generic, own_laws
        if any(own_laws.own_members(plan)) and generic.is_cached(False, "forces_of"):
            lo, hi = ESTIMATES["own"]
            return f"about {lo}-{hi} s on an idle machine: the adapters of your own functions (demkit.own_laws)"
        lo, hi = ESTIMATES["generic"]
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
    the module a scene of magnetisable spheres has imported: progress sits below the physics.)"""
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
