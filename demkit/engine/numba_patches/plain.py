"""What demkit's numba patches share: which are kept out (``DEMKIT_PLAIN_<NAME>=1`` leaves numba as it is
there), and the modules of numba that hold a function under the name they imported it by."""
from __future__ import annotations

import importlib
import os


def left_out(name):
    """Is the patch ``name`` kept out (``DEMKIT_PLAIN_<name>`` set to anything but 0)?"""
    return os.environ.get(f"DEMKIT_PLAIN_{name}", "") not in ("", "0")


def holders(modules, name, original):
    """numba's ``modules`` (names), imported, if each holds ``original`` as ``name`` (they imported the
    function by name: a patch replaces it in each); else None (numba changed: the patch stays out)."""
    found = [importlib.import_module(module) for module in modules]
    return found if all(getattr(module, name, None) is original for module in found) else None
