"""Faster compilation: numba remembers which loop of a NumPy ufunc takes given argument types.

numba (0.59 to 0.68 at least) types each scalar ``*``, ``+``, ``-``, ``/`` and comparison of compiled code
through the NumPy ufunc of that operator, and for each it searches the ufunc's loops for the first one
the argument types cast to safely (``ufunc_find_matching_loop``): 5 750 searches to type tier 1's full
pair loop, 45 000 over what an install compiles (~2.5 % of that time, sampled), nearly all of them for
a dozen (ufunc, types) pairs.

:func:`install` keeps the answer per (ufunc, argument types) for NumPy's own ufuncs, whose loops are
fixed (numba's growing ``DUFunc``\\ s are searched each time, as before), and hands out a fresh copy of
it each time (the loop spec holds lists). The answer is the one numba's search gives
(``tests/test_ufunc_loops.py``). ``DEMKIT_PLAIN_UFUNC_LOOPS=1`` keeps numba as it is.
"""
from __future__ import annotations

import numpy as np
from numba.np import numpy_support

from .plain import left_out, replace_in

_numba_search = numpy_support.ufunc_find_matching_loop
_FOUND = {}  # (ufunc, argument types) -> the loop spec, or None
#: numba's modules that search by the name they imported
_USERS = ("numba.np.numpy_support", "numba.core.typing.npydecl", "numba.np.npyimpl")


def ufunc_find_matching_loop(ufunc, arg_types):
    """numba's ``ufunc_find_matching_loop`` (the first loop of ``ufunc`` the types cast to), remembered
    for NumPy's ufuncs."""
    if type(ufunc) is not np.ufunc:
        return _numba_search(ufunc, arg_types)
    key = (ufunc, tuple(arg_types))
    try:
        spec = _FOUND[key]
    except KeyError:
        spec = _FOUND[key] = _numba_search(ufunc, arg_types)
    except TypeError:  # (an unhashable type)
        return _numba_search(ufunc, arg_types)
    return None if spec is None else type(spec)(list(spec.inputs), list(spec.outputs), spec.ufunc_sig)


def _agrees():
    """Does numba's search still answer as the patch expects (a spec holding lists)?"""
    from numba.core import types
    probe = _numba_search(np.multiply, (types.float64, types.int64))
    return probe is not None and isinstance(probe.inputs, list) and probe.ufunc_sig == "dd->d"


def install():
    """Patch numba's ufunc loop search (once); returns whether the patch is in place."""
    if numpy_support.ufunc_find_matching_loop is ufunc_find_matching_loop:
        return True
    if left_out("UFUNC_LOOPS"):
        return False
    return replace_in(_USERS, "ufunc_find_matching_loop", _numba_search, ufunc_find_matching_loop, _agrees)


INSTALLED = install()
