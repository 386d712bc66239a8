"""numba's compiler made faster without changing what it makes (docs/engine.md, "numba's compiler, made faster").

Each module patches one place in numba (0.59 to 0.68 at least) when ``import demkit`` imports it, keeps numba's
original function beside its own, and checks on install that numba still looks as the patch expects (else it
stays out, and numba runs as it is). Each gives numba's own output (its tests compare with the original), and each
is kept out by its variable ``DEMKIT_PLAIN_<NAME>=1`` (:mod:`.plain`; to measure what it saves):

* :mod:`.inlining`: the inliner copies a callee's IR with one memo per copy, faster (INLINING);
* :mod:`.mangling`: symbol names escaped by ``str.translate`` (MANGLING);
* :mod:`.ssa`: the SSA pass rewrites only the blocks where a variable appears (SSA);
* :mod:`.options`: compile options listed by one dictionary merge (OPTIONS);
* :mod:`.variables`: IR statements list their variables in one pass (VARIABLES);
* :mod:`.liveness`: variable liveness on bit sets (LIVENESS);
* :mod:`.ufunc_loops`: the loop of a NumPy ufunc for given types remembered (UFUNC_LOOPS);
* :mod:`.collector`: Python's garbage collector starts less often while numba compiles (COLLECTOR).
"""
from __future__ import annotations

from . import inlining, mangling, ssa, options, variables, liveness, ufunc_loops, collector  # (each installs its patch)

__all__ = ["inlining", "mangling", "ssa", "options", "variables", "liveness", "ufunc_loops",
           "collector"]
