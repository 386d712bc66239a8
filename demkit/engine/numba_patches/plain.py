"""What demkit's numba patches share: which are kept out (``DEMKIT_PLAIN_<NAME>=1`` leaves numba as it is
there), and putting a function in place of numba's in each of its modules that imported it by name."""
from __future__ import annotations

import importlib
import os


def left_out(name):
    """Is the patch ``name`` kept out (``DEMKIT_PLAIN_<name>`` set to anything but 0)?"""
    return os.environ.get(f"DEMKIT_PLAIN_{name}", "") not in ("", "0")


def replace_in(modules, name, original, replacement, agrees):
    """Put ``replacement`` as ``name`` in each of numba's ``modules`` (names; they imported ``original`` by
    name) if each holds ``original`` there and ``agrees()`` (the patch's check against numba's own answer);
    returns whether it did (numba changed otherwise: the patch stays out)."""
    found = [importlib.import_module(module) for module in modules]
    if not (all(getattr(module, name, None) is original for module in found) and agrees()):
        return False
    for module in found:
        setattr(module, name, replacement)
    return True
