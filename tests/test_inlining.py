"""demkit.engine.numba_patches.inlining: numba's inliner copies a callee's IR with one memo per copy (linear,
not quadratic), each copy made by copy.deepcopy's rules.

Independent truths: the copy must equal the original block by block (numba's own IR equality), share
one scope like the original, be made afresh each time, and be what ``copy.deepcopy`` makes (the same
objects copied and kept alive); inlined code must compute what the plain Python functions compute.
Each of demkit's numba patches stays out when its variable is set. The compile time saved is measured
in benchmarks/bench_latency.py.
"""
import copy
import os
import subprocess
import sys

import numba
import pytest
from numba.core import inline_closurecall, ir
from numba.core.compiler import run_frontend

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import inlining
from demkit.engine.generic_modules import _pieces


def branchy(x, n):
    total = 0.0
    for k in range(n):
        if k % 3 == 0:
            total += x * k
        elif k % 3 == 1:
            total -= x
        else:
            total *= 0.5
    while total > 100.0:
        total /= 7.0
    return total


def test_the_patch_is_in_place_after_importing_demkit():
    assert inlining.INSTALLED
    assert getattr(inline_closurecall.InlineWorker.inline_ir, "demkit_one_memo", False)
    assert isinstance(inline_closurecall.copy, inlining._OneMemoPerCopy)
    assert inlining.install()  # a second install keeps the one patch


def test_a_copy_of_an_ir_equals_it_shares_one_new_scope_and_is_made_afresh_each_time():
    blocks = run_frontend(branchy).blocks
    assert len(blocks) > 5
    shim = inlining._OneMemoPerCopy()
    shim.memo = {}  # as during an inlining
    first = {label: shim.deepcopy(block) for label, block in blocks.items()}
    second = {label: shim.deepcopy(block) for label, block in blocks.items()}
    for copies in (first, second):
        assert copies == blocks  # numba's structural equality, statement by statement
        scopes = {id(block.scope) for block in copies.values()}
        assert len(scopes) == 1 and id(next(iter(blocks.values())).scope) not in scopes
    for label in blocks:
        assert first[label] is not second[label]
        assert first[label].body[0] is not second[label].body[0]
    # outside an inlining it is copy.deepcopy: every block its own scope copy
    shim.memo = None
    alone = [shim.deepcopy(block) for block in blocks.values()]
    assert len({id(block.scope) for block in alone}) == len(alone)


def test_the_fast_copy_is_copy_deepcopy():
    """deep_copy against copy.deepcopy on tier 1's largest loop: equal blocks, the same text, the same
    objects copied (memo keys) and kept alive, one scope shared by the copied blocks."""
    blocks = run_frontend(_pieces("full").pairs_forces_chunk.py_func).blocks
    theirs_memo, mine_memo = {}, {}
    theirs = {label: copy.deepcopy(block, theirs_memo) for label, block in blocks.items()}
    mine = {label: inlining.deep_copy(block, mine_memo) for label, block in blocks.items()}
    assert mine == theirs == blocks
    assert _text(mine) == _text(theirs)
    assert set(mine_memo) - {id(mine_memo)} == set(theirs_memo) - {id(theirs_memo)}
    assert len(mine_memo[id(mine_memo)]) == len(theirs_memo[id(theirs_memo)]) > 1000
    assert len({id(block.scope) for block in mine.values()}) == 1
    for label, block in blocks.items():
        assert mine[label] is not block and mine[label].body[0] is not block.body[0]
    # a tuple whose items copy to themselves is itself; one holding an IR node is a new tuple
    loc = ir.Loc("t", 1)
    assert inlining.deep_copy((1, "a", None), {}) == (1, "a", None)
    plain = (1, "a")
    assert inlining.deep_copy(plain, {}) is plain
    holding = (loc, 2)
    copied = inlining.deep_copy(holding, {})
    assert copied is not holding and copied[0] is not loc and copied[0] == loc


def _text(blocks):
    return "\n".join(f"{label}:\n" + "\n".join(str(stmt) for stmt in block.body) for label, block in blocks.items())


def test_inlined_functions_compute_what_python_computes():
    callee = numba.njit(inline="always")(branchy)

    @numba.njit
    def twice(x, n):
        return callee(x, n) + callee(x + 1.0, n + 5)

    for x, n in ((0.3, 10), (2.0, 40), (-1.5, 7)):
        assert twice(x, n) == branchy(x, n) + branchy(x + 1.0, n + 5)
    assert isinstance(next(iter(run_frontend(branchy).blocks.values())), ir.Block)


@pytest.mark.parametrize("variable, code", [
    ("DEMKIT_PLAIN_INLINING", "import copy; from numba.core import inline_closurecall as ic; "
                              "print(P.inlining.INSTALLED, ic.copy is not copy)"),
    ("DEMKIT_PLAIN_MANGLING", "from numba.core import itanium_mangler as im; "
                              "print(P.mangling.INSTALLED, im._escape_string is P.mangling.escape)"),
    ("DEMKIT_PLAIN_SSA", "from numba.core import ssa; print(P.ssa.INSTALLED, ssa._run_ssa is P.ssa.run_ssa)"),
    ("DEMKIT_PLAIN_OPTIONS", "from numba.core import targetconfig as tc; "
                             "print(P.options.INSTALLED, tc.TargetConfig.values is P.options.values)"),
    ("DEMKIT_PLAIN_VARIABLES", "from numba.core import ir; "
                               "print(P.variables.INSTALLED, ir.Stmt.list_vars is P.variables.list_vars_of_statement)"),
    ("DEMKIT_PLAIN_LIVENESS", "from numba.core import ir_utils; "
                              "print(P.liveness.INSTALLED, ir_utils.compute_live_map is P.liveness.compute_live_map)"),
    ("DEMKIT_PLAIN_UFUNC_LOOPS", "from numba.core.typing import npydecl; print(P.ufunc_loops.INSTALLED, "
                                 "npydecl.ufunc_find_matching_loop is P.ufunc_loops.ufunc_find_matching_loop)"),
    ("DEMKIT_PLAIN_COLLECTOR", "from numba.core import dispatcher; "
                               "print(P.collector.INSTALLED, dispatcher.Dispatcher.compile is P.collector.compile)"),
])
def test_each_of_demkits_numba_patches_stays_out_when_its_variable_is_set(variable, code):
    """(each module's own tests check what it changes)"""
    out = subprocess.run([sys.executable, "-c", "import demkit.engine.numba_patches as P; " + code],
                         env=dict(os.environ, **{variable: "1"}), capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
