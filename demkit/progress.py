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

The compile notice ("demkit: compiling kernels ...") is the engine's: :mod:`demkit.engine.notice`.
"""
from __future__ import annotations

import os
import sys
import time

from .engine.notice import quiet  # noqa: F401 (DEMKIT_QUIET: bars, notes and notices)

#: automatic bars appear only for work estimated to take longer than this (wall-clock seconds)
AUTO_SECONDS = 2.0
#: ... judged after this much wall time of the work (and never before its second update)
AUTO_AFTER = 0.5
#: on a terminal of 0 columns, a plain progress line at most this often (wall-clock seconds)
PLAIN_SECONDS = 5.0


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
