"""Faster compilation: numba's IR statements list their variables in one pass, not one call per value.

numba (0.59 to 0.68 at least) finds the variables a statement reads or writes (``Inst.list_vars``) by a
recursive method that makes a new list at every level and tests each value against four types. Its
analyses ask this of every statement again and again (use-def maps after each rewrite, the inliner,
the SSA pass, dead-variable removal): over every piece of code an install compiles, ~2 x 10^6 calls
(cProfile: the largest Python-level cost of numba's front end after the calls into LLVM).

:func:`install` replaces ``Stmt.list_vars``, ``Expr.list_vars`` and ``Inst._rec_list_vars`` with one
pass that appends to a single list and looks up what a value is by its type once per type. The list is
the same, in the same order (statements that list their variables their own way, such as parfors, are
asked as before); ``tests/test_variables.py`` compares it with numba's own on every statement of
demkit's largest functions. If numba's IR no longer looks as expected the patch stays out, and
``DEMKIT_PLAIN_VARIABLES=1`` keeps it out (to measure what it saves).
"""
from __future__ import annotations


from numba.core import ir

from .plain import left_out

_numba_rec = ir.Inst._rec_list_vars
_numba_stmt = ir.Stmt.list_vars
_numba_expr = ir.Expr.list_vars

# what a value is, by its type: a variable, a statement or expression listed the stock way (its
# __dict__, its _kws), another instruction (asked), a sequence, a mapping, or nothing to list
VAR, STMT, EXPR, OTHER, SEQUENCE, MAPPING, LEAF = range(7)
_KINDS = {}


def _kind(t):
    """The kind of values of type ``t`` (the tests of numba's ``_rec_list_vars``, in its order)."""
    if issubclass(t, ir.Var):
        kind = VAR
    elif issubclass(t, ir.Inst):
        listing = t.list_vars
        kind = STMT if listing is list_vars_of_statement else EXPR if listing is list_vars_of_expression else OTHER
    elif issubclass(t, (list, tuple)):
        kind = SEQUENCE
    elif issubclass(t, dict):
        kind = MAPPING
    else:
        kind = LEAF
    _KINDS[t] = kind
    return kind


def _collect(val, out):
    """Append the variables in ``val`` to ``out`` (depth first, as numba's recursion lists them)."""
    kind = _KINDS.get(type(val))
    if kind is None:
        kind = _kind(type(val))
    if kind == LEAF:
        return
    if kind == VAR:
        out.append(val)
    elif kind == SEQUENCE:
        for v in val:
            _collect(v, out)
    elif kind == MAPPING or kind == STMT:
        for v in (val if kind == MAPPING else val.__dict__).values():
            _collect(v, out)
    elif kind == EXPR:
        for v in val._kws.values():
            _collect(v, out)
    else:
        out.extend(val.list_vars())


def rec_list_vars(self, val):
    """numba's ``Inst._rec_list_vars``: the variables in ``val``, as one list."""
    out = []
    _collect(val, out)
    return out


def list_vars_of_statement(self):
    """The variables a statement reads or writes (``Stmt.list_vars``)."""
    return rec_list_vars(self, self.__dict__)


def list_vars_of_expression(self):
    """The variables an expression reads (``Expr.list_vars``)."""
    return rec_list_vars(self, self._kws)


def _agrees():
    """Do the replacements list what numba's own do, on a few statements of each shape?"""
    scope = ir.Scope(None, ir.Loc("demkit", 0))
    loc = ir.Loc("demkit", 1)
    a, b, c = (ir.Var(scope, name, loc) for name in "abc")
    call = ir.Expr.call(a, [b, c], [("k", a)], loc)
    samples = [ir.Assign(call, c, loc), ir.SetItem(a, b, c, loc), ir.Return(a, loc),
               ir.Assign(ir.Expr.build_tuple([a, ir.Expr.getattr(b, "x", loc)], loc), c, loc),
               ir.Branch(a, 1, 2, loc), ir.Assign(ir.Const(1.0, loc), a, loc)]
    for stmt in samples:
        mine = list_vars_of_statement(stmt)
        if [v.name for v in mine] != [v.name for v in _numba_stmt(stmt)]:
            return False
        if [v.name for v in rec_list_vars(stmt, stmt.__dict__)] != [v.name for v in _numba_rec(stmt, stmt.__dict__)]:
            return False
    return [v.name for v in list_vars_of_expression(call)] == [v.name for v in _numba_expr(call)]


def install():
    """Patch numba's variable listing (once); returns whether the patch is in place."""
    if ir.Stmt.list_vars is list_vars_of_statement:
        return True
    if left_out("VARIABLES"):
        return False
    if not (ir.Stmt.list_vars is ir.Assign.list_vars and "list_vars" in vars(ir.Expr) and _agrees()):
        return False  # numba lists variables differently now: leave it as it is
    ir.Inst._rec_list_vars = rec_list_vars
    ir.Stmt.list_vars = list_vars_of_statement
    ir.Expr.list_vars = list_vars_of_expression
    _KINDS.clear()  # (kinds found before the swap name numba's functions)
    return True


INSTALLED = install()
