"""demkit.engine.numba_patches.ufunc_loops: numba's search for a NumPy ufunc's loop, remembered, gives numba's own answer.

Independent truth: numba's original ``ufunc_find_matching_loop`` (kept by the module) on the operators'
ufuncs for the scalar types demkit's kernels use, mixed and unmatched types included (None); each answer
is a fresh copy (changing one leaves the next intact); compiled code computes what Python computes.
(``DEMKIT_PLAIN_UFUNC_LOOPS=1`` keeps the patch out: tests/test_inlining.py.)
"""
import numba
import numpy as np
from numba.core import types
from numba.core.typing import npydecl
from numba.np import numpy_support

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import ufunc_loops

CASES = [(ufunc, args) for ufunc in (np.multiply, np.add, np.subtract, np.true_divide, np.less, np.power, np.sqrt,
                                     np.floor)
         for args in ((types.float64, types.float64), (types.int64, types.int64), (types.float64, types.int64),
                      (types.int64,), (types.float64,), (types.boolean, types.boolean))
         if len(args) == ufunc.nin]


def test_the_patch_is_in_place_after_importing_demkit():
    assert ufunc_loops.INSTALLED
    assert numpy_support.ufunc_find_matching_loop is ufunc_loops.ufunc_find_matching_loop
    assert npydecl.ufunc_find_matching_loop is ufunc_loops.ufunc_find_matching_loop
    assert ufunc_loops.install()


def test_each_answer_is_numbas_own_and_a_fresh_copy():
    for _ in range(2):  # (the second time from memory)
        for ufunc, args in CASES:
            theirs = ufunc_loops._numba_search(ufunc, args)
            mine = ufunc_loops.ufunc_find_matching_loop(ufunc, args)
            assert (mine is None) == (theirs is None)
            if mine is not None:
                assert (mine.inputs, mine.outputs, mine.ufunc_sig) == (theirs.inputs, theirs.outputs, theirs.ufunc_sig)
    first = ufunc_loops.ufunc_find_matching_loop(np.multiply, (types.float64, types.int64))
    first.inputs.append(types.int8)
    assert ufunc_loops.ufunc_find_matching_loop(np.multiply, (types.float64, types.int64)).inputs == \
        [types.float64, types.float64]


def test_compiled_code_computes_what_python_computes():
    @numba.njit
    def mixed(a, k):
        return a * k + np.sqrt(a) - (k // 2) / a

    assert mixed(2.5, 7) == 2.5 * 7 + np.sqrt(2.5) - (7 // 2) / 2.5
