"""How many threads a run uses: measured while it runs, never a slowdown.

A scene that may run on threads (``Scene.parallel``: neighbour lists and at least 2000 spheres
whose force evaluation is estimated at THREADS_FROM_SECONDS or more, or ``parallel=True``) has two compiled modules with the same arithmetic: the serial one
(``scene.kernels``) and the thread module (``scene.thread_kernels``). Both cut the pair loops into
the same fixed chunks, summed in the same order, so a run gives the same bits whichever module
runs each of its compiled chunks (about 0.2 s of wall time each), and switching costs nothing.

Threads wait for each other at the end of every parallel loop (about a dozen per step). On an
idle machine that is cheap; with another busy program on one of the cores, each wait can last a
scheduler time slice, and two threads ran a 4000-sphere gas 8-40x slower than one. So with
``parallel=None`` (the default) a run

1. starts on one thread, and meanwhile compiles the thread module in the background (loaded from
   numba's cache when it was compiled before) when the run has at least :data:`WORTH_COMPILING`
   seconds to go, or half a second when the cache has it;
2. then runs a short probe chunk (about :data:`PROBE_SECONDS` of one-thread time) on all threads
   and keeps whichever ran more steps per second;
3. checks again after :data:`RECHECK_SECONDS` (doubling up to :data:`RECHECK_MAX` while threads keep
   losing), and leaves threads at once when a chunk on threads runs clearly slower than one thread
   did (under :data:`LEAVE` of its rate: a busy core makes threads up to 40x slower, while chunks
   of the same run differ by 20-30 % with the list rebuilds and sorts they happen to hold), or when
   the chunks on threads since they were chosen, :data:`SPELL_CHUNKS` or more, ran no faster than
   one thread did on average.

A new Simulation of a kind of scene already measured in this process (the same compiled loops, as
many spheres and threads) starts on the last choice made for it, with its rates, and checks it again
after :data:`RECHECK_SECONDS` as above (see ``_CHOSEN``).

``parallel=True`` always runs on threads, ``parallel=False`` never. ``Simulation.statistics``
(``threads``, ``threads_reason``), the progress bar and ``demkit info`` say what was chosen and why.
"""
from __future__ import annotations

import atexit
import os
import sys
import threading
import time

import numba

from .notice import BACKGROUND


def _own_numba_start_lock():
    """In a forked child: a lock of its own for the start of numba's threading layer.

    numba guards that start with a lock shared by every process forked from one parent (a
    multiprocessing RLock, made at its first use) and takes it in every ``numba.get_num_threads`` and
    ``set_num_threads``: a run's chunks call them. A child killed while holding it (``kill -9`` at a
    chunk boundary, a sweep's worker stopped) left it taken for its parent and every later sibling,
    whose next run then waited forever. Unset here, numba makes a new one at the child's first use."""
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    if parallel is not None and getattr(parallel, "_backend_init_process_lock", None) is not None:
        parallel._backend_init_process_lock = None


os.register_at_fork(after_in_child=_own_numba_start_lock)

#: rough serial cost of one pair and of one sphere in a force evaluation (seconds; measured on the
#: 2-core project machine with examples/magnetic_cluster/cluster.toml: 400 dipoles, all pairs,
#: velocity Verlet, one core: 11.8 ns per pair; the per-sphere passes, list checks included)
PAIR_SECONDS = 1.2e-8
SPHERE_SECONDS = 5.0e-8
#: scenes with at least this many spheres split their pair loops among threads (parallel=None)
PARALLEL_MIN = 2000
#: with parallel=None, a scene is cut into chunks for threads when one force evaluation is
#: estimated to take at least this long (seconds): below it the threads' waits cost what they gain
#: (measured: a 4000-sphere contact-only gas, 0.13 ms a step, estimated 0.28 ms, ran 0.66x as fast on
#: two threads on an idle machine; the N = 8000 reference scene's contacts, estimated 0.57 ms, 0.2-0.3
#: ms a step from its start, 1.12-1.31x as fast without friction and 1.14-1.46x with it; 8000
#: dipoles cut at 4 diameters, ~5 ms, 1.9x as fast). Chunks cost a serial run what summing their
#: buffers costs: 3 % for those 8000 contact-only spheres (15-24 % for the 4000-sphere gas, measured
#: when the buffers were also cleared in a pass of their own)
THREADS_FROM_SECONDS = 0.5e-3
#: length of a probe chunk on threads, in seconds of one-thread time (short: under load a chunk
#: on threads can run 40x slower than on one)
PROBE_SECONDS = 0.02
#: ... and at least this many steps (one step can hold a list rebuild and is no rate)
PROBE_STEPS = 8
#: first re-check of the choice, seconds of wall time; doubled each time threads lose, up to RECHECK_MAX
RECHECK_SECONDS = 4.0
RECHECK_MAX = 64.0
#: threads must be at least this much faster to be kept (timing noise between chunks)
MARGIN = 1.05
#: an ordinary chunk on threads leaves them only below this fraction of the last one-thread rate.
#: That rate can be seconds old and chunks differ by the rebuilds they hold: leaving at any loss
#: (MARGIN) sent the N = 8000 reference scene back to one thread after one slow chunk (144 against
#: 140 steps/s) where threads ran 1.5-1.9x as fast, and kept it there for seconds
LEAVE = 0.8
#: ... and after this many chunks on threads, when their mean rate is no better than one thread's
#: (beside a busy core the dipole reference scene ran 0.9x as fast on threads: never under LEAVE)
SPELL_CHUNKS = 3
#: a run shorter than this (seconds, at the one-thread rate) does not compile the thread module
WORTH_COMPILING = 5.0

#: the last measured choice per kind of scene in this process: (serial loop, spheres, threads) ->
#: (threads chosen, {threads: steps per second}, reason). A new Simulation of the same kind starts
#: there instead of on one thread (a sweep's or a benchmark's many short runs spent their first
#: second or more on one thread, loading the thread module and probing it)
_CHOSEN = {}


class ThreadChoice:
    """Chooses, chunk by chunk, the serial or the thread module for one Simulation."""

    def __init__(self, scene, template):
        self.scene = scene
        self.name = f"{template}_steps"
        self.serial_module = scene.loop_kernels  # the tier's modules (demkit.engine.tiers: tier 2 may replace them)
        self._thread_module = lambda: scene.thread_kernels
        self.serial_loop = getattr(self.serial_module, self.name)
        self.thread_loop = None
        self.max_threads = numba.get_num_threads() if scene.parallel else 1
        self.rates = {1: None, self.max_threads: None}  # steps per second of wall time, last measured
        self.recheck = RECHECK_SECONDS
        self.next_check = None
        self._compiling = None
        self._cached = None  # is the thread module's loop in numba's disk cache? (asked once)
        self.probing = False  # is the current chunk a probe (or the untimed "warm-up" step)?
        self._warm = False
        self._after_probe = False
        self._spell = [0, 0.0, 0]  # steps, seconds and chunks on threads since they were chosen
        if not scene.parallel:
            self.fixed, self.reason = 1, self._why_serial()
        elif self.max_threads == 1:
            self.fixed, self.reason = 1, "numba.set_num_threads(1) was called"
        elif scene.threads_requested is True:
            self.fixed, self.reason = self.max_threads, "parallel=True"
        else:
            self.fixed, self.reason = None, "measuring: one thread until the thread module is ready"
        self.threads = self.fixed or 1
        # the kind of scene: its compiled loops (the generic module runs every scene: its program too)
        self._key = (self.serial_loop, scene.program.tobytes() if scene.program is not None else None,
                     len(scene.particles), self.max_threads)
        if self.fixed is None and self._key in _CHOSEN:
            self._start_from(*_CHOSEN[self._key])

    def _start_from(self, threads, rates, reason):
        """Start where the last measured run of the same kind of scene (the same compiled loops, as
        many spheres and threads) in this process ended: on its choice, with its rates, the thread
        module already loaded; checked again after RECHECK_SECONDS like any choice."""
        self.thread_loop = self._threaded()
        self.rates = dict(rates)
        self.threads = threads
        self._warm = True
        self.next_check = time.perf_counter() + self.recheck
        self.reason = f"{reason} (in an earlier run of this kind of scene; checked again while running)"

    def _why_serial(self):
        scene = self.scene
        if scene.threads_requested is False:
            return "parallel=False"
        if int(numba.config.NUMBA_NUM_THREADS) < 2:
            return "numba has one thread (NUMBA_NUM_THREADS=1 or a one-core machine)"
        if not scene.plan.growing:
            return "a small open scene (all pairs, no neighbour lists)"
        if len(scene.particles) < PARALLEL_MIN:
            return f"fewer than {PARALLEL_MIN} spheres (parallel=True forces threads)"
        return (f"one force evaluation is estimated at {1e3 * self.scene.force_seconds:.2g} ms, under the "
                f"{1e3 * THREADS_FROM_SECONDS:.2g} ms where threads start to pay (parallel=True forces them)")

    @property
    def kernels(self):
        """The module whose record_frame a run calls from Python: the thread module when threads
        always run (parallel=True), else the serial one (so that it is compiled once)."""
        return self._thread_module() if self.fixed and self.fixed > 1 else self.serial_module

    @property
    def label(self):
        """A few words for the progress bar."""
        return "1 thread" if self.threads == 1 else f"{self.threads} threads"

    def loop(self, steps, remaining):
        """The compiled loop for the next chunk and its number of steps (at most ``steps``)."""
        if self.fixed is not None:
            self.threads = self.fixed
            if self.fixed > 1:
                numba.set_num_threads(self.fixed)
                return self._threaded(), steps
            return self._serial(), steps
        now = time.perf_counter()
        serial = self.rates[1]
        if self.thread_loop is None:
            if serial is not None and self._compiling is None and remaining / serial >= self._worth():
                self._start_compiling()
            if self._compiling is not None and not self._compiling.is_alive():
                self.thread_loop = getattr(self._thread_module(), self.name)
                self.next_check = now  # probe now
        after_probe, self._after_probe = self._after_probe, False
        if self.thread_loop is not None and serial is not None and now >= self.next_check and not after_probe:
            self._after_probe = True  # the next chunk runs on the choice made, whatever the clock says
            self.next_check = now + self.recheck
            probe = max(PROBE_STEPS, int(serial * PROBE_SECONDS))
            if self.threads == 1:  # probe the threads briefly
                numba.set_num_threads(self.max_threads)
                self.threads = self.max_threads
                self.probing = True
                if not self._warm:  # one step first, not timed: starting the thread pool, loading code
                    self._warm, self.probing, self.next_check = True, "warm-up", now
                    return self.thread_loop, 1
                return self.thread_loop, min(steps, probe)
            self.threads = 1  # on threads: look at one thread again, briefly
            self.probing = True
            return self._serial(), min(steps, probe)
        self.probing = False
        if self.threads > 1:
            numba.set_num_threads(self.threads)
            return self.thread_loop, steps
        return self._serial(), steps

    def _serial(self):
        """The serial loop, with numba's threads set to one: what a serial chunk calls on threads of
        its own (a P3M sum's mesh, demkit.interactions.p3m) follows the run's choice too. (A run
        gives numba's setting back when it ends: demkit.simulation._Stepping.)"""
        if numba.get_num_threads() != 1:
            numba.set_num_threads(1)
        return self.serial_loop

    def measured(self, steps, seconds, first=False):
        """The last chunk, of ``steps`` steps, took ``seconds`` on the current choice; ``first``: it
        included compilation (no rate to learn)."""
        probing, self.probing = self.probing, False
        if first or seconds <= 0 or probing == "warm-up":
            if probing == "warm-up":
                self.threads = 1
            return
        ran = self.threads
        self.rates[ran] = steps / seconds
        one, many = self.rates[1], self.rates[self.max_threads]
        if self.fixed is not None or one is None or many is None or (ran == 1 and not probing):
            return  # nothing to decide (an ordinary one-thread chunk decides nothing)
        if ran > 1 and not probing:  # an ordinary chunk on threads, against an older one-thread rate
            spell = self._spell
            spell[0], spell[1], spell[2] = spell[0] + steps, spell[1] + seconds, spell[2] + 1
            mean = spell[0] / spell[1]
            if many > LEAVE * one and (spell[2] < SPELL_CHUNKS or mean > one):
                return  # stay
            many = min(many, mean)
        faster = many > MARGIN * one
        self.threads = self.max_threads if faster else 1
        self._spell = [0, 0.0, 0]
        if faster:
            self.reason = f"{self.max_threads} threads measured {many / one:.2f}x as fast as one"
            self.recheck = RECHECK_SECONDS
        else:
            self.reason = (f"one thread: {self.max_threads} threads measured {many / one:.2f}x as fast "
                           f"(cores busy with other work, or too little work per step)")
            if probing and ran > 1:  # threads lost their probe: look again later and later
                self.recheck = min(2.0 * self.recheck, RECHECK_MAX)
            self.next_check = time.perf_counter() + self.recheck
        if self._key is not None:
            _CHOSEN[self._key] = (self.threads, {1: one, self.max_threads: many}, self.reason)

    def _worth(self):
        """Seconds of run left (at the one-thread rate) that make loading the thread module worth
        it: WORTH_COMPILING when it must be compiled, 0.5 s when numba's cache has it."""
        if self._cached is None:
            from .generic_modules import is_cached as generic_cached
            from .modules import cached_function, is_cached, pieces_source
            from .templates import TEMPLATES
            if self.serial_module is self.scene.kernels and self.scene.tier == 1:
                self._cached = generic_cached(True, self.name)
            elif self.scene._pieces_tier_2():  # tier 2 of its own pieces: the pieces on threads and tier 1's loop
                pieces = pieces_source(self.scene.plan, self.scene.program_columns, threads=True)[1]
                self._cached = generic_cached(True, self.name) and cached_function(pieces, "piece_pairs_forces")
            else:
                self._cached = is_cached(self.scene.plan, TEMPLATES, self.name, threads=True)
        return 0.5 if self._cached else WORTH_COMPILING

    def _threaded(self):
        if self.thread_loop is None:
            self.thread_loop = getattr(self._thread_module(), self.name)
        return self.thread_loop

    @property
    def compiling(self):
        """Is the thread module being compiled in the background?"""
        return self._compiling is not None and self._compiling.is_alive()

    def use_modules(self, serial, threaded):
        """Run the loops of these modules from now on (tier 2 took over: demkit.engine.tiers); ``threaded``
        None: the thread module is compiled when threads are worth it, as at a run's start."""
        self.serial_module = serial
        self.serial_loop = getattr(serial, self.name)
        scene = self.scene
        self._thread_module = (lambda: threaded) if threaded is not None else (lambda: scene._kernels(threads=True, tier=2))
        self.thread_loop = getattr(threaded, self.name) if threaded is not None else None
        self._compiling, self._cached = None, None
        if self.thread_loop is None and self.fixed is None and self.threads > 1:
            self.threads = 1  # back to one thread until tier 2's thread module is ready
        if self.thread_loop is not None and self.next_check is None:
            self.next_check = time.perf_counter()  # threads never probed yet: probe them now

    def _start_compiling(self):
        """Compile (or load from the cache) the thread module on another thread while the run goes
        on with one: the compiled chunks release the GIL."""
        name, serial, threaded = self.name, self.serial_module, self._thread_module

        def work():
            try:
                getattr(threaded(), name).compile(getattr(serial, name).signatures[0])
            except Exception:  # noqa: BLE001 - a failed compile just keeps the run on one thread
                pass

        self._compiling = threading.Thread(target=work, name=BACKGROUND, daemon=True)
        self._compiling.start()
        _UNFINISHED.append(self._compiling)

    def describe(self):
        """One line for ``demkit info``: how many threads runs of this scene use and why."""
        if self.fixed == 1:
            return f"1 ({self.reason})"
        if self.fixed:
            return f"{self.fixed} ({self.reason})"
        return (f"1 or {self.max_threads}, measured while running: one thread until {self.max_threads} prove "
                f"faster, checked again now and then (docs/nbody.md, Threads)")

    def statistics(self):
        return {"threads": self.threads, "threads_reason": self.reason,
                "steps_per_second_by_threads": {k: v for k, v in self.rates.items() if v is not None}}


def estimated_force_seconds(particles, reaches, skin, box):
    """Rough serial wall time of one force evaluation (seconds): N SPHERE_SECONDS + pairs
    PAIR_SECONDS, the pairs of each reach from the number density (box volume, else the spheres'
    bounding box; :func:`demkit.memory.pairs_per_sphere`); all pairs for an infinite reach."""
    import math

    import numpy as np

    from ..memory import pairs_per_sphere
    n = len(particles)
    if n < 2:
        return n * SPHERE_SECONDS
    radius = float(np.mean(particles.radius))
    if box is not None and np.all(np.isfinite(box.size)):
        volume = box.volume
    else:
        extent = np.ptp(particles.position, axis=0)
        volume = float(np.prod(np.maximum(extent, 2.0 * radius)))
    pairs = sum(n * pairs_per_sphere(n, r + skin if math.isfinite(r) else r, radius, volume)
                for r in set(reaches))
    return n * SPHERE_SECONDS + pairs * PAIR_SECONDS


#: background compilations, waited for at exit: a process that ends while numba compiles on
#: another thread can crash in its shutdown (seen: a benchmark child died without a word)
_UNFINISHED = []


@atexit.register
def finish_compiling():
    """Wait for the compilations running in the background (the thread module, a scene's fused
    module: demkit.engine.tiers), saying so on stderr."""
    alive = [t for t in _UNFINISHED if t.is_alive()]
    if alive:
        from .notice import quiet
        if not quiet():
            print("demkit: finishing a compilation started in the background (cached for the next runs)...",
                  file=sys.stderr, flush=True)
        for t in alive:
            t.join()
