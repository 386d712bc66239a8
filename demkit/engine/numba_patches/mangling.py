"""Faster compilation: numba's symbol names escaped in one pass of C code, not one Python call per character.

numba names every compiled function after its argument types (Itanium C++ mangling), escaping each
character of a type's name outside ``[a-zA-Z0-9_]`` as ``_xx`` (its hex code). It does so with
``re.sub`` and a Python callback per such character. demkit's functions take the scene's state (a
structref of ~50 typed fields) and the tuple ``calls`` of ~20 first-class functions, whose type names run
to tens of thousands of characters: escaping them took 0.13 of the 0.9 CPU s a small scene-level
function compiles in (cProfile); six scene-level functions compiled in 3.33 CPU s with the patch against 3.87
without it (paired, in one process).

:func:`install` replaces ``itanium_mangler._escape_string`` with one that escapes an ASCII name by
``str.translate`` and hands any other name to numba's own: the same names, character for character
(checked on install against numba's, else the patch stays out), so the same code and the same cache
entries. ``DEMKIT_PLAIN_MANGLING=1`` keeps numba as it is (to measure what this saves).
"""
from __future__ import annotations

from numba.core import itanium_mangler

from .plain import left_out

#: code point -> its escape, for the ASCII characters numba escapes (all but letters, digits and _)
ESCAPES = {c: "_%02x" % c for c in range(128) if not (chr(c).isalnum() or chr(c) == "_")}

#: names the patch must escape exactly as numba does before it goes in
SAMPLES = ("float64", "array(float64, 2d, C)", "Tuple(int64, UniTuple(float64 x 3))", "a.b$c-d e_9",
           "x\u00e9\u2202", "", "0lead", "[]{}<>|#@!~`'\"\\/?^&*+=%;:,")


def escape(text):
    """``text`` escaped as numba's ``_escape_string`` does: ASCII by one translate, the rest by numba."""
    if text.isascii():
        return text.translate(ESCAPES)
    return _numba_escape(text)


_numba_escape = itanium_mangler._escape_string


def install():
    """Patch numba's mangler (once); returns whether the patch is in place."""
    current = itanium_mangler._escape_string
    if current is escape:
        return True
    if left_out("MANGLING"):
        return False
    if not all(escape(text) == current(text) for text in SAMPLES):
        return False  # numba escapes differently now: leave it as it is
    itanium_mangler._escape_string = escape
    return True


INSTALLED = install()
