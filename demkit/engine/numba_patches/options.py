"""Faster compilation: numba's compile options listed in one dictionary merge, not one property call each.

numba keeps the function it typed for a call in a cache keyed by the argument types and the options of
the compile at hand (its ``Flags``). All ``Flags`` hash alike (the hash covers the option names, not their
values), so every lookup compares the options with those of each entry of the same argument types, and
each comparison lists ~20 options twice through Python properties (``TargetConfig.values``). demkit
compiles with a dozen option sets (kernels, helpers, entries, steps, loops, on threads), and typing a
large function makes thousands of lookups: listing the options was ~2 % of compiling the scene-level
functions (paired, in one process: 3.33 -> 3.26 CPU s for six of them).

:func:`install` replaces ``TargetConfig.values`` with one dictionary merge of the class's defaults and the
options set: the same dictionary (checked on install against numba's on a set of flags, else the patch stays
out). ``DEMKIT_PLAIN_OPTIONS=1`` keeps numba as it is.
"""
from __future__ import annotations


from numba.core import targetconfig

from .plain import left_out

_DEFAULTS = {}  # TargetConfig subclass -> {option name: default}


def values(self):
    """A dict of every option's value (``TargetConfig.values``): the defaults, updated by those set."""
    cls = type(self)
    defaults = _DEFAULTS.get(cls)
    if defaults is None:
        defaults = _DEFAULTS[cls] = {name: option.default for name, option in cls.options.items()}
    return {**defaults, **self._values}


_numba_values = targetconfig.TargetConfig.values


def _sample():
    from numba.core.compiler import Flags
    flags = Flags()
    flags.nrt = True
    flags.error_model = "numpy"
    flags.no_cpython_wrapper = True
    return flags


def install():
    """Patch numba's option listing (once); returns whether the patch is in place."""
    if targetconfig.TargetConfig.values is values:
        return True
    if left_out("OPTIONS"):
        return False
    flags = _sample()
    if not (isinstance(getattr(flags, "_values", None), dict) and values(flags) == _numba_values(flags)
            and list(values(flags)) == list(_numba_values(flags))):
        return False  # numba keeps its options differently now: leave it as it is
    targetconfig.TargetConfig.values = values
    return True


INSTALLED = install()
