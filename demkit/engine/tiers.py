"""Which compiled code runs a scene: the generic module (tier 1) or its own code (tier 2).

A scene of shipped interactions starts on tier 1 (:mod:`demkit.engine.generic`: compiled once per install,
loaded in a fraction of a second). Its own code (:mod:`demkit.engine.kernels`: with neighbour lists its own
pair and sphere loops called by tier 1's time loops, in open space a fused module, or its pieces
when it solves induced moments) runs 0-25 % faster but costs 3-30 CPU s to compile the first time a
combination of interactions is run. So a run

1. starts on tier 1;
2. compiles tier 2 on another thread (or loads it, when numba's cache has it) once the run has at
   least :data:`WORTH_COMPILING` seconds left (:data:`WORTH_COMPILING_OPEN` for a fused module,
   :data:`WORTH_LOADING` when cached), while it goes on;
   the seconds that earlier runs of the same combination spent on tier 1 in this process count too
   (a sweep of many short runs, such as the paper's replication, pays for tier 2 as a long run does),
   and once this process has tier 2 of a combination, every later run of it switches at once;
3. switches to tier 2 between two compiled chunks as soon as it is ready.

Both tiers do the same arithmetic in the same order, so a run gives the same bits whenever the
switch happens, or whether it happens at all (``tests/test_tiers.py``). A run that ends before
tier 2 is ready never waits for it, and one shorter than :data:`WORTH_COMPILING` (with what earlier
runs of its combination spent) never compiles it.
``Scene(tier=1)`` never switches, ``Scene(tier=2)`` starts on tier 2; ``sim.statistics`` (``tier``,
``tier_reason``, ``tier_switch_step``), the progress bar and ``demkit info`` say which tier ran.
"""
from __future__ import annotations

import threading

from .notice import BACKGROUND

#: a run with at least this many seconds left on tier 1 compiles tier 2 in the background (a first
#: compile of a combination costs 5-30 CPU s on the other core; tier 2 saves 0-25 % of the run)
WORTH_COMPILING = 20.0
#: ... and for a scene without neighbour lists whose tier 2 is a fused module, which steps many times
#: faster than tier 1 (two spheres: 11.7 M against 1.0 M steps/s) and compiles in about 5 CPU s
WORTH_COMPILING_OPEN = 8.0
#: ... and loads it from numba's cache with at least this many seconds left (about 1 s to load)
WORTH_LOADING = 2.0
#: per combination and time loop (tier 2's module name, loop name): seconds run on tier 1 by this
#: process's runs, and the combinations whose tier 2 this process has compiled or loaded
_SPENT = {}
_READY = set()


def _asked(scene, tier):
    """How the scene asked for its tier: tier=1 or DEMKIT_TIER=1."""
    return f"DEMKIT_TIER={tier}" if scene.tier_from_environment else f"tier={tier}"


class TierChoice:
    """Chooses, between chunks, the tier whose loops one Simulation runs."""

    def __init__(self, scene, name):
        self.scene, self.name = scene, name
        self.tier = scene.tier
        self.switch_step = None
        self.switchable = scene.tier == 1 and scene.tier_requested is None
        if scene.tier == 2:
            self.reason = (f"{_asked(scene, 2)} asked for" if scene.tier_requested == 2 else
                           f"the generic module cannot run this scene ({scene.program_refusal})")
        elif scene.tier_requested == 1:
            self.reason = f"{_asked(scene, 1)} asked for"
        else:
            self.reason = "the generic module (tier 1) until the scene's own code (tier 2) is worth compiling"
        self._work = None
        self._failure = None  # what stopped tier 2's compilation, if it failed
        self._modules = None  # (serial, thread or None) of tier 2, once compiled
        self._cached = None
        self._key = None  # (tier 2's module name, loop name), once asked for
        self._hurried = False  # hurry(): tier 2 at the next chunk

    def hurry(self):
        """Compile (or load) tier 2 at the next chunk, whatever the run has left (``demkit info
        --measure`` times the tier a long run will use)."""
        self._hurried = True

    def worth_switching(self, seconds_left):
        """Would a run with ``seconds_left`` on tier 1 compile (or load) tier 2? (What earlier runs of
        the combination spent on tier 1 in this process counts too.)"""
        return self.switchable and seconds_left + _SPENT.get(self.key, 0.0) >= self._worth()

    def _worth(self):
        """Seconds of run on tier 1 that make tier 2 worth compiling or loading."""
        key = self.key
        if key in _READY or self._hurried:
            return 0.0
        if self._cached is None:  # (key[0] names the module: its source is generated once)
            from .modules import cached_function
            from .plan import functions_importable
            if self.scene._pieces_tier_2():
                self._cached = cached_function(key[0], "piece_pairs_forces")
            else:
                self._cached = functions_importable(self.scene.plan) and cached_function(key[0], self.name)
        if self._cached:
            return WORTH_LOADING
        return WORTH_COMPILING if self.scene._pieces_tier_2() else WORTH_COMPILING_OPEN

    @property
    def key(self):
        """(tier 2's module name, the run's loop): what runs of the same combination share."""
        if self._key is None:
            from .templates import TEMPLATES
            from .modules import fused_name, pieces_source
            scene = self.scene
            name = (pieces_source(scene.plan, scene.program_columns)[1] if scene._pieces_tier_2() else
                    fused_name(scene.plan, TEMPLATES))
            self._key = (name, self.name)
        return self._key

    def ran(self, seconds):
        """The run stepped ``seconds`` more on tier 1 (counted for later runs of the combination)."""
        if self.tier == 1 and self.switchable:
            _SPENT[self.key] = _SPENT.get(self.key, 0.0) + seconds

    def ready(self, seconds_left, busy=False):
        """Tier 2's (serial module, thread module or None) when the run should switch to it now, else
        None; ``seconds_left`` of run at the current rate (None: not measured yet); ``busy``: another
        background compilation runs (tier 2 waits for it: both would queue on numba's lock)."""
        if not self.switchable or seconds_left is None:
            return None
        if self._work is None:
            if busy or not self.worth_switching(seconds_left):
                return None
            self._start()
            return None
        if self._work.is_alive():
            return None
        if self._modules is None:
            self.switchable = False
            self.reason = f"tier 2 failed to compile in the background ({self._failure}); tier 1 ran on"
            return None
        self.switchable = False
        _READY.add(self.key)
        return self._modules

    def switched(self, step):
        """The run now runs tier 2, from global step ``step`` on."""
        self.tier, self.switch_step = 2, step
        self.reason = (f"the scene's own code (tier 2), {'loaded' if self._cached else 'compiled'} while the "
                       f"run went on, from step {step} (tier 1 before: the same bits)")

    def _start(self):
        """Compile (or load) tier 2's loop for this run on another thread: the serial module, and the
        thread module too when the scene may run on threads."""
        scene, name = self.scene, self.name

        def work():
            try:
                signatures = {}  # the generic loops' (the same state types on both tiers)
                for function in (name, "record_frame"):
                    for generic in (scene.kernels, scene._thread_kernels):
                        compiled = getattr(generic, function).signatures if generic is not None else []
                        if compiled:
                            signatures[function] = compiled[0]
                modules = []
                for threads in ((False, True) if scene.parallel else (False,)):
                    module = scene._kernels(threads, tier=2)
                    for function, signature in signatures.items():
                        getattr(module, function).compile(signature)
                    modules.append(module)
                self._modules = (modules[0], modules[1] if len(modules) > 1 else None)
            except Exception as error:  # noqa: BLE001 - a failed compile keeps the run on tier 1, and says so
                self._modules = None
                self._failure = f"{type(error).__name__}: {error}"

        from .threads import _UNFINISHED
        self._work = threading.Thread(target=work, name=BACKGROUND, daemon=True)
        self._work.start()
        _UNFINISHED.append(self._work)

    def describe(self):
        """One line for ``demkit info``: which tier runs this scene and why."""
        if self.switchable:
            worth, faster = ((WORTH_COMPILING, "up to 25 % faster") if self.scene._pieces_tier_2() else
                             (WORTH_COMPILING_OPEN, "several times faster in open space"))
            return (f"tier 1, the generic module (compiled once per install); the scene's own code (tier 2, "
                    f"the same bits, {faster}) is compiled in the background by runs with more than "
                    f"{worth:g} s to go (counting earlier runs of the combination in the process), loaded by "
                    f"runs of more than {WORTH_LOADING:g} s once cached")
        return f"tier {self.tier}: {self.reason}"

    @property
    def compiling(self):
        return self._work is not None and self._work.is_alive()

    def statistics(self):
        return {"tier": self.tier, "tier_reason": self.reason, "tier_switch_step": self.switch_step}
