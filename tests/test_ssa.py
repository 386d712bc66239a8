"""demkit.engine.numba_patches.ssa: numba's SSA reconstruction, rewriting only the blocks where a variable appears, gives
numba's own IR.

Independent truth: numba's original ``_run_ssa`` (kept by the module) on the same IR: the same blocks
statement by statement (numba's IR equality) and the same text (fresh names, phi nodes), on a function
that assigns the same locals in every branch of a switch, as tier 1's loops do, and on tier 1's largest
generated loops; compiled code computes what Python computes. The compile time it saves is measured in
benchmarks/bench_latency.py (``DEMKIT_PLAIN_SSA=1`` keeps the patch out: tests/test_inlining.py).
"""
import copy

import numba
from numba.core import compiler, ssa

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import ssa as patch
from demkit.engine.generic_modules import _pieces


def switchy(kind, x, n):
    total = 0.0
    for k in range(n):
        a = 0.0
        b = 0.0
        if kind == 0:
            a, b = x, 2.0 * x
        elif kind == 1:
            a = x * k
            if a > 3.0:
                b = a
        elif kind == 2:
            a, b = -x, x + k
        else:
            b = 1.0
        total += a - b
    return total


def _both(function):
    """(numba's SSA form, the patched one) of function's IR."""
    blocks = compiler.run_frontend(function).blocks
    mine, theirs = copy.deepcopy(blocks), copy.deepcopy(blocks)
    saved = ssa._run_ssa, ssa._run_block_rewrite
    ssa._run_ssa, ssa._run_block_rewrite = patch._numba_run_ssa, patch._numba_rewrite
    try:
        theirs = ssa._run_ssa(theirs)
    finally:
        ssa._run_ssa, ssa._run_block_rewrite = saved
    return theirs, patch.run_ssa(mine)


def _text(blocks):
    return "\n".join(f"{label}:\n" + "\n".join(str(stmt) for stmt in block.body) for label, block in blocks.items())


def test_the_patch_is_in_place_after_importing_demkit():
    assert patch.INSTALLED
    assert ssa._run_ssa is patch.run_ssa and ssa._run_block_rewrite is patch.run_block_rewrite
    assert patch.install()  # a second install keeps the one patch


def test_the_ssa_form_is_numbas_own():
    theirs, mine = _both(switchy)
    assert list(theirs) == list(mine)
    assert all(theirs[label] == mine[label] for label in theirs)
    assert _text(theirs) == _text(mine)
    assert "phi" in _text(mine)  # (the switch's locals need phi nodes: the test has something to compare)


def test_tier_1_largest_loops_get_numbas_own_ssa_form():
    pieces = _pieces("full")  # (the module's text loaded: nothing compiles)
    for name in ("pairs_forces_chunk", "sphere_forces", "pairs_energies_rows"):
        theirs, mine = _both(getattr(pieces, name).py_func)
        assert sum(len(block.body) for block in mine.values()) > 500
        assert _text(theirs) == _text(mine), name


def test_compiled_code_computes_what_python_computes():
    compiled = numba.njit(switchy)
    for kind in range(4):
        for x, n in ((0.5, 7), (2.0, 3)):
            assert compiled(kind, x, n) == switchy(kind, x, n)

