"""demkit.engine.numba_patches.options: numba's compile options listed by one dictionary merge give numba's own listing.

Independent truth: numba's original ``TargetConfig.values`` (kept by the module) on default flags, on
flags with options set (to their default values too), and on a copy; flags that differ in one option still
compare unequal, and compiled code runs. (``DEMKIT_PLAIN_OPTIONS=1`` keeps the patch out: tests/test_inlining.py.)
"""

import numba
from numba.core import targetconfig
from numba.core.compiler import Flags

import demkit  # noqa: F401 (installs the patch)
from demkit.engine.numba_patches import options


def _numbas(flags):
    return options._numba_values(flags)


def test_the_patch_is_in_place_after_importing_demkit():
    assert options.INSTALLED
    assert targetconfig.TargetConfig.values is options.values
    assert options.install()


def test_the_listing_is_numbas_own():
    plain = Flags()
    assert plain.values() == _numbas(plain) and list(plain.values()) == list(_numbas(plain))
    flags = Flags()
    flags.nrt = True
    flags.error_model = "numpy"
    flags.boundscheck = False  # set to its default
    flags.inline = "always"
    assert flags.values() == _numbas(flags)
    assert flags.values()["error_model"] == "numpy" and flags.values()["inline"].value == "always"
    assert flags.copy().values() == _numbas(flags)
    other = flags.copy()
    other.error_model = "python"
    assert other != flags and hash(other) == hash(flags)  # (numba's hash: the option names)
    assert plain != flags and Flags() == plain


def test_compiled_code_runs():
    @numba.njit(error_model="numpy", inline="always")
    def inner(x):
        return 2.0 * x

    @numba.njit
    def outer(x):
        return inner(x) + 1.0

    assert outer(3.0) == 7.0

