"""demkit.engine.numba_patches.variables: numba's IR statements listing their variables in one pass give numba's own lists.

Independent truth: numba's original ``Stmt.list_vars``, ``Expr.list_vars`` and ``Inst._rec_list_vars`` (kept
by the module), statement by statement, on every statement of tier 1's largest generated loops and on a
function with calls, tuples, attributes and item stores; the same variables in the same order. Compiled
code computes what Python computes. (``DEMKIT_PLAIN_VARIABLES=1`` keeps the patch out: tests/test_inlining.py.)
"""
import numba
import numpy as np
from numba.core import ir
from numba.core.compiler import run_frontend

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import variables
from demkit.engine.generic_modules import _pieces


def shapes(a, b, k):
    t = (a[0], b[k], (a[1], k))
    b[k] = t[0] * t[2][0]
    s = a.shape[0] + len(b)
    return np.sqrt(s) + max(t[1], 1.0, k)


def _statements(function):
    for block in run_frontend(function).blocks.values():
        yield from block.body


def _numbas(stmt):
    if isinstance(stmt, ir.Stmt) and type(stmt).list_vars is variables.list_vars_of_statement:
        return variables._numba_stmt(stmt)
    return stmt.list_vars()  # (statements listing their own way: unchanged)


def test_the_patch_is_in_place_after_importing_demkit():
    assert variables.INSTALLED
    assert ir.Stmt.list_vars is variables.list_vars_of_statement
    assert ir.Expr.list_vars is variables.list_vars_of_expression
    assert ir.Assign.list_vars is variables.list_vars_of_statement
    assert variables.install()


def test_every_statement_lists_numbas_variables_in_numbas_order():
    pieces = _pieces("full")  # (the module's text loaded: nothing compiles)
    checked = expressions = 0
    for function in (shapes, pieces.pairs_forces_chunk.py_func, pieces.sphere_forces.py_func):
        for stmt in _statements(function):
            mine = stmt.list_vars()
            assert [v.name for v in mine] == [v.name for v in _numbas(stmt)], str(stmt)
            assert all(isinstance(v, ir.Var) for v in mine)
            checked += 1
            value = getattr(stmt, "value", None)
            if isinstance(value, ir.Expr):
                assert ([v.name for v in value.list_vars()]
                        == [v.name for v in variables._numba_expr(value)]), str(value)
                expressions += 1
    assert checked > 1000 and expressions > 500  # (the test has something to compare)


def test_nested_values_are_listed_depth_first():
    scope = ir.Scope(None, ir.Loc("t", 0))
    loc = ir.Loc("t", 1)
    a, b, c = (ir.Var(scope, name, loc) for name in "abc")
    inner = ir.Expr.build_tuple([b, ir.Expr.getattr(c, "x", loc)], loc)
    call = ir.Expr.call(a, [inner, c], [("k", b)], loc)
    stmt = ir.Assign(call, a, loc)
    assert [v.name for v in stmt.list_vars()] == [v.name for v in variables._numba_stmt(stmt)] == \
        ["a", "b", "c", "c", "b", "a"]  # (the value's, then the target)


def test_compiled_code_computes_what_python_computes():
    a, b = np.array([2.0, 3.0]), np.array([0.5, 4.0, 1.0])
    expected = shapes(a, b.copy(), 1)
    assert numba.njit(shapes)(a, b.copy(), 1) == expected
