"""The engine: demkit's compiled core, in two tiers (docs/engine.md).

Nothing here is needed to *use* demkit (``dk.Scene``, ``dk.Simulation`` and the interactions are the public
API); it is what turns a scene into compiled loops:

* :mod:`~demkit.engine.state`: the named state a compiled loop sees (a numba structref), and the neighbour
  lists' own state;
* :mod:`~demkit.engine.motion`: the compiled building blocks of a step (kicks, drifts, spins, frames), and
  the compile options the interactions' laws use;
* :mod:`~demkit.engine.neighbours`: cell lists, Verlet lists with per-pair history, sorting (the history carried
  across a rebuild by tag: :mod:`~demkit.engine.pair_history`);
* :mod:`~demkit.engine.templates`: the time loops of the integrators, as templates pasted into generated code;
* :mod:`~demkit.engine.catalogue`: the shipped laws and effects, each an integer *kind*;
* :mod:`~demkit.engine.program`: a scene's *program*, the table tier 1's loops read;
* :mod:`~demkit.engine.generic`, :mod:`~demkit.engine.generic_modules`: **tier 1**, one generic module per
  install, where a scene is data (its program) and every shipped law sits behind an integer kind switch:
  its text, and the modules built, loaded and called;
* :mod:`~demkit.engine.plan`: the plan of a scene's pair loops, which both tiers share;
* :mod:`~demkit.engine.snippets`: lines of generated code both tiers write alike;
* :mod:`~demkit.engine.kernels`: **tier 2**, the scene's own code (a fused module in open space, the scene's
  own pieces under tier 1's loops with neighbour lists);
* :mod:`~demkit.engine.modules`: generated modules named, cached, compiled once per machine and loaded;
* :mod:`~demkit.engine.own_laws`: adapters that let tier 1 call functions of your own;
* :mod:`~demkit.engine.tiers`: when a run goes over from tier 1 to tier 2 (between chunks, the same bits);
* :mod:`~demkit.engine.threads`: whether the pair loops run on numba's threads, measured while running;
* :mod:`~demkit.engine.events`: contact events located within a step (``resolve_contacts=True``);
* :mod:`~demkit.engine.numba_cache`: numba's disk cache kept fresh across demkit's files, one compile per machine;
* :mod:`~demkit.engine.numba_patches`: numba's compiler made faster, its output the same (its inliner, symbol
  names, SSA pass, option listing, variable listing, liveness analysis, ufunc loop search, and the garbage
  collector while it compiles).

Imports go one way: the engine imports nothing of demkit outside it except the progress notices
(:mod:`demkit.progress`) and the memory model (:mod:`demkit.memory`); the interactions import the engine's
compile options; scenes and runs import both.
"""
