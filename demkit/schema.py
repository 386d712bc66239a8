"""A small declarative schema for TOML documents: tables of keys with a type, a default, a
constraint, a physical dimension and a line of documentation, and one validator that walks them.

A schema is a :class:`Table` of named entries, each a :class:`Key` (a value), a :class:`Table`
(a sub-table), a :class:`Tables` (an array of tables, ``[[name]]``) or a :class:`Variant` (a table
whose keys depend on one of its values, e.g. ``kind = "lattice"``). :func:`validate` returns a
plain dict with every default filled in (optional keys without a default are None) or raises
:class:`SchemaError` naming the key path, with "did you mean ..." for unknown keys.

Value kinds (``Key.kind``): ``number`` (int or float, finite), ``integer``, ``bool``, ``string``,
``vector`` (three numbers), ``size`` (one number or three), ``flags`` (a bool or three bools),
``numbers`` (a number, or a list of them: one per sphere), ``series`` (a number, or a list of them
in time), ``vectors`` (a list of three-number
lists), ``bools`` (a list of bools), ``integers`` (a list of integers), ``strings`` (a list of names
among ``choices``), ``number_or_auto`` (a
number or the string "auto"), ``bool_or_auto`` (true, false or "auto"), ``direction`` (three
numbers, or one of ``choices``), ``row`` (``Key.length`` numbers). Constraints
(``Key.check``): ``positive``, ``non_negative``, ``at_least_one`` (integers).
"""
from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field

REQUIRED = object()  # a Key default: the key must be given

#: longest text of a value quoted in a message
QUOTE = 60


class SchemaError(ValueError):
    """A value that does not fit the schema: ``path`` (tuple of keys and list indices), ``problem``."""

    def __init__(self, path, problem):
        super().__init__(f"{dotted(path)}: {problem}")
        self.path, self.problem = tuple(path), problem


@dataclass(frozen=True)
class Key:
    kind: str
    default: object = None
    doc: str = ""
    check: str | None = None
    choices: tuple = ()
    dim: str | None = None  # physical dimension, for units = "si" (see demkit.scenefile)
    length: int | None = None  # kind "row": how many numbers


@dataclass(frozen=True)
class Table:
    keys: dict
    doc: str = ""
    required: bool = False
    #: groups of keys of which exactly one must be given (required=True) or at most one
    one_of: tuple = ()
    #: (key, others): when ``key`` is given none of ``others`` may be
    excludes: tuple = ()


@dataclass(frozen=True)
class Tables:
    table: Table
    doc: str = ""


@dataclass(frozen=True)
class Variant:
    key: str
    variants: dict
    doc: str = ""
    required: bool = False
    common: dict = field(default_factory=dict)
    #: {a likely wrong word: the variant meant}, for "did you mean" where spelling does not help
    aliases: dict = field(default_factory=dict)


def dotted(path):
    """('interactions', 'wall', 0, 'point') -> 'interactions.wall[0].point'."""
    out = ""
    for part in path:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(top level)"


def quote(value):
    """A short description of a TOML value for a message."""
    if isinstance(value, str):
        return repr(value) if len(value) <= QUOTE else f"a string of {len(value)} characters"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        text = repr(value)
        return text if len(text) <= QUOTE else f"a list of {len(value)} items"
    return repr(value)


def type_name(value):
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "a list"
    return f"a {type(value).__name__}"


def validate(schema, data, path=()):
    """``data`` (a dict from tomllib) checked against the Table ``schema``: a new dict with defaults.
    Every problem found in one pass is reported: one SchemaError, or :class:`SchemaErrors` for several."""
    found = []
    out = _validate(schema, data, path, found)
    if len(found) == 1:
        raise found[0]
    if found:
        raise SchemaErrors(found)
    return out


class SchemaErrors(SchemaError):
    """Several values that do not fit the schema, found in one pass (``errors``: a SchemaError each)."""

    def __init__(self, errors):
        super().__init__(errors[0].path, errors[0].problem)
        self.errors = list(errors)


def _validate(schema, data, path, found):
    """:func:`validate`'s pass: problems go into ``found`` and the check goes on with what remains (a
    value in error is left out of the result)."""
    if not isinstance(data, dict):
        found.append(SchemaError(path, f"must be a table, got {quote(data)}"))
        return None
    if isinstance(schema, Variant):
        return _variant(schema, data, path, found)
    meant = set()  # keys an unknown one was taken for: not also reported missing
    for key in (k for k in data if k not in schema.keys):
        near = difflib.get_close_matches(key, list(schema.keys), n=1, cutoff=0.6)
        meant.update(near)
        home = [name for name, entry in schema.keys.items() if isinstance(entry, Table) and key in entry.keys]
        hint = (f"; did you mean {near[0]!r}?" if near else
                f"; it belongs in [{dotted(path + (home[0],))}]" if home else f"; known keys: {', '.join(schema.keys)}")
        found.append(SchemaError(path + (key,), f"unknown key{hint}"))
    for group in schema.one_of:
        names, required = group
        given = [k for k in names if k in data]
        if len(given) > 1:
            found.append(SchemaError(path + (given[1],), f"give only one of {', '.join(names)} (also given: "
                                                         f"{given[0]})"))
        if required and not given and not meant & set(names):
            found.append(SchemaError(path, f"give one of {', '.join(names)}"))
    for key, others in schema.excludes:
        if key in data:
            clash = [k for k in others if k in data]
            if clash:
                found.append(SchemaError(path + (clash[0],), f"cannot be given together with {key}"))
    out = {}
    for name, entry in schema.keys.items():
        where = path + (name,)
        if isinstance(entry, Key):
            if name in data:
                try:
                    out[name] = value(entry, data[name], where)
                except SchemaError as err:
                    found.append(err)
                    out[name] = None
            elif entry.default is REQUIRED:
                if name not in meant:
                    found.append(SchemaError(where, f"missing: give {name} ({entry.doc})"))
                out[name] = None
            else:
                out[name] = entry.default
        elif isinstance(entry, Tables):
            items = data.get(name, [])
            if isinstance(items, dict):
                items = [items]
            if not isinstance(items, list):
                found.append(SchemaError(where, f"must be tables ([[{dotted(where)}]]), got {quote(items)}"))
                items = []
            out[name] = [_validate(entry.table, item, where + (k,), found) for k, item in enumerate(items)]
        elif name in data:
            out[name] = _validate(entry, data[name], where, found)
        elif entry.required:
            if name not in meant:
                found.append(SchemaError(where, f"missing: add a [{dotted(where)}] table ({entry.doc})"))
            out[name] = None
        else:
            out[name] = None
    return out


def _variant(schema, data, path, found):
    kind = data.get(schema.key)
    where = path + (schema.key,)
    if kind is None:
        found.append(SchemaError(where, f"missing: give {schema.key} = one of "
                                        f"{', '.join(map(repr, schema.variants))}"))
        return None
    if not isinstance(kind, str) or kind not in schema.variants:
        near = [] if not isinstance(kind, str) else (
            [schema.aliases[kind.lower()]] if kind.lower() in schema.aliases
            else difflib.get_close_matches(kind, list(schema.variants), n=1))
        hint = f"; did you mean {near[0]!r}?" if near else ""
        found.append(SchemaError(where, f"must be one of {', '.join(map(repr, schema.variants))}, got "
                                        f"{quote(kind)}{hint}"))
        return None
    table = schema.variants[kind]
    rest = {k: v for k, v in data.items() if k != schema.key}
    out = _validate(table, rest, path, found)
    out[schema.key] = kind
    return out


def _number(value, where, what="a number"):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SchemaError(where, f"must be {what}, got {type_name(value)} ({quote(value)})")
    if isinstance(value, int) and abs(value) > 2**53:
        raise SchemaError(where, f"{value:.3e} is too large (at most 2^53 in magnitude)")
    number = float(value)
    if not math.isfinite(number):
        raise SchemaError(where, f"must be finite, got {value!r} (numbers beyond 1.8e308 read as inf)")
    return number


def _integer(value, where):
    if isinstance(value, bool) or not isinstance(value, int):
        raise SchemaError(where, f"must be a whole number, got {type_name(value)} ({quote(value)})")
    if abs(value) > 2**62:
        raise SchemaError(where, f"{value:.3e} is too large")
    return value


def _bool(value, where):
    if not isinstance(value, bool):
        raise SchemaError(where, f"must be true or false, got {type_name(value)} ({quote(value)})")
    return value


def _list(value, where, what, length=None):
    if not isinstance(value, list) or (length is not None and len(value) != length):
        raise SchemaError(where, f"must be {what}, got {quote(value)}")
    return value


def value(key, raw, where):
    """One value checked against ``key``."""
    kind = key.kind
    if kind == "number":
        out = _number(raw, where)
    elif kind == "number_or_auto":
        out = raw if raw == "auto" else _number(raw, where, 'a number or "auto"')
    elif kind == "bool_or_auto":
        if raw != "auto" and not isinstance(raw, bool):
            raise SchemaError(where, f'must be true, false or "auto", got {type_name(raw)} ({quote(raw)})')
        out = raw
    elif kind == "integer":
        out = _integer(raw, where)
    elif kind == "bool":
        out = _bool(raw, where)
    elif kind == "string":
        if not isinstance(raw, str):
            raise SchemaError(where, f"must be a string, got {type_name(raw)} ({quote(raw)})")
        out = raw
    elif kind == "vector":
        out = [_number(v, where + (k,)) for k, v in enumerate(_list(raw, where, "three numbers [x, y, z]", 3))]
    elif kind == "row":
        out = [_number(v, where + (k,)) for k, v in enumerate(_list(raw, where, f"a list of {key.length} numbers",
                                                                    key.length))]
    elif kind == "direction":
        if isinstance(raw, str):
            out = raw
        else:
            out = [_number(v, where + (k,)) for k, v in enumerate(
                _list(raw, where, f"three numbers [x, y, z] or one of {', '.join(map(repr, key.choices))}", 3))]
    elif kind == "size":
        out = (_number(raw, where) if not isinstance(raw, list)
               else [_number(v, where + (k,)) for k, v in enumerate(_list(raw, where, "one number or three", 3))])
    elif kind == "cells":
        out = (_integer(raw, where) if not isinstance(raw, list)
               else [_integer(v, where + (k,)) for k, v in enumerate(_list(raw, where, "one integer or three", 3))])
    elif kind == "flags":
        out = (_bool(raw, where) if not isinstance(raw, list)
               else [_bool(v, where + (k,)) for k, v in enumerate(_list(raw, where, "true/false or three of them", 3))])
    elif kind in ("numbers", "series"):
        out = (_number(raw, where) if not isinstance(raw, list)
               else [_number(v, where + (k,)) for k, v in enumerate(raw)])
    elif kind == "vectors":
        rows = _list(raw, where, "a list of [x, y, z] rows, one per sphere")
        out = [[_number(v, where + (k, a)) for a, v in enumerate(_list(row, where + (k,), "three numbers [x, y, z]", 3))]
               for k, row in enumerate(rows)]
    elif kind == "bools":
        out = [_bool(v, where + (k,)) for k, v in enumerate(_list(raw, where, "a list of true/false, one per sphere"))]
    elif kind == "integers":
        out = [_integer(v, where + (k,)) for k, v in enumerate(_list(raw, where, "a list of whole numbers"))]
    elif kind == "strings":
        names = ", ".join(map(repr, key.choices))
        out = _list(raw, where, f"a list of names among {names}")
        for k, v in enumerate(out):
            if not isinstance(v, str) or v not in key.choices:
                raise SchemaError(where + (k,), f"must be one of {names}, got {quote(v)}")
    else:  # pragma: no cover - a schema bug
        raise AssertionError(f"unknown kind {kind}")
    if key.choices and isinstance(out, str) and out not in key.choices:
        near = difflib.get_close_matches(out, list(key.choices), n=1)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        raise SchemaError(where, f"must be one of {', '.join(map(repr, key.choices))}, got {quote(out)}{hint}")
    if key.check:
        _check(key.check, out, where)
    return out


def _check(check, out, where):
    flat = out if isinstance(out, list) else [out]
    flat = [x for row in flat for x in (row if isinstance(row, list) else [row])]
    for x in flat:
        if isinstance(x, str):
            continue
        if check == "positive" and not x > 0:
            raise SchemaError(where, f"must be positive, got {x!r}")
        if check == "non_negative" and not x >= 0:
            raise SchemaError(where, f"must be zero or positive, got {x!r}")
        if check == "at_least_one" and not x >= 1:
            raise SchemaError(where, f"must be at least 1, got {x!r}")


# ---- where a key is in the text ------------------------------------------------------------------
_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\[\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*((?:[A-Za-z0-9_-]+|\"[^\"]*\"|'[^']*')(?:\s*\.\s*(?:[A-Za-z0-9_-]+|\"[^\"]*\"|'[^']*'))*)\s*=(.*)$")


def _parts(text):
    return tuple(p.strip().strip("\"'") for p in re.findall(r"\"[^\"]*\"|'[^']*'|[^.]+", text))


def _brackets(text):
    """Net count of [ minus ] outside strings and comments."""
    depth, quote_char = 0, None
    for ch in text:
        if quote_char:
            if ch == quote_char:
                quote_char = None
        elif ch in "\"'":
            quote_char = ch
        elif ch == "#":
            break
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
    return depth


def key_lines(text):
    """{key path (tuple): line number (1-based)} for the tables and keys of a TOML text.

    A line-by-line scan (tomllib reports no positions): headers ``[a.b]`` and ``[[a.b]]`` (an array
    of tables gets list indices, counted in order) and ``key = ...`` lines, dotted keys included.
    Limits: keys inside inline tables ``{...}`` and items of multi-line arrays get the line of the
    key that opens them; multi-line strings are skipped by counting triple quotes, so a line that
    opens and closes two of them may confuse it; it is never wrong about a key it found, only silent
    (the caller then falls back to the nearest enclosing key it knows).
    """
    lines, table, arrays, depth, multiline = {}, (), {}, 0, None
    for number, line in enumerate(text.splitlines(), 1):
        if multiline:
            if multiline in line:
                multiline = None
            continue
        if depth > 0:
            depth += _brackets(line)
            continue
        header = _HEADER.match(line)
        if header:
            parts = _parts(header.group(2))
            resolved = ()
            for k, part in enumerate(parts):
                resolved += (part,)
                if k < len(parts) - 1 and resolved in arrays:
                    resolved += (arrays[resolved],)
            if header.group(1) == "[[":
                arrays[resolved] = arrays.get(resolved, -1) + 1
                lines.setdefault(resolved, number)
                resolved += (arrays[resolved],)
            table = resolved
            lines.setdefault(table, number)
            continue
        key = _KEY.match(line)
        if key:
            lines.setdefault(table + _parts(key.group(1)), number)
            rest = key.group(2)
            for mark in ('"""', "'''"):
                if rest.count(mark) % 2 == 1:
                    multiline = mark
            if not multiline:
                depth = max(0, _brackets(rest))
    return lines


def line_of(lines, path):
    """The line of ``path``, else the first line of a key inside it (``[a.b.c]`` for ``a``), else of
    its nearest enclosing key found, or None."""
    path = tuple(path)
    inside = [line for key, line in lines.items() if key[:len(path)] == path]
    if path and inside:
        return min(inside)
    while path:
        if path in lines:
            return lines[path]
        path = path[:-1]
    return None
