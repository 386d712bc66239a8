"""demkit.engine.numba_patches.mangling: numba's symbol names escaped by str.translate give numba's own names.

Independent truth: numba's original ``_escape_string`` (kept by the module), on every ASCII character,
on long random names and on non-ASCII ones; a function compiled with the patch in place runs and its
symbol name is the one numba's own mangler gives. The compile time it saves is measured in
benchmarks/bench_latency.py (``DEMKIT_PLAIN_MANGLING=1`` keeps the patch out: tests/test_inlining.py).
"""
import random

import numba
from numba.core import funcdesc, itanium_mangler

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import mangling


def test_the_patch_is_in_place_after_importing_demkit():
    assert mangling.INSTALLED
    assert itanium_mangler._escape_string is mangling.escape
    assert mangling.install()  # a second install keeps the one patch


def test_every_name_escapes_as_numba_escapes_it():
    original = mangling._numba_escape
    assert original is not mangling.escape
    for c in range(128):
        assert mangling.escape(chr(c)) == original(chr(c)), c
    rng = random.Random(5)
    alphabet = [chr(c) for c in range(32, 127)] + ["\u00e9", "\u2202", "\U0001d400"]
    for _ in range(200):
        text = "".join(rng.choice(alphabet) for _ in range(rng.randrange(0, 300)))
        assert mangling.escape(text) == original(text)
    # a name as long as a scene's state type
    text = str(numba.typeof((1.0, (2, 3.0), "x"))) * 2000
    assert mangling.escape(text) == original(text)


def test_a_compiled_function_runs_and_is_named_as_numba_names_it():
    @numba.njit
    def weighted(x, pair):
        return x * pair[0] + pair[1]

    assert weighted(2.0, (3.0, 1)) == 7.0
    (signature,) = weighted.signatures
    name = weighted.overloads[signature].fndesc.mangled_name
    saved = itanium_mangler._escape_string
    itanium_mangler._escape_string = mangling._numba_escape
    try:
        fndesc = weighted.overloads[signature].fndesc
        expected = itanium_mangler.mangle(funcdesc.qualifying_prefix(fndesc.modname, fndesc.qualname),
                                          fndesc.argtypes, abi_tags=fndesc.abi_tags, uid=fndesc.uid)
    finally:
        itanium_mangler._escape_string = saved
    assert name == expected

