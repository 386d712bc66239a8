"""Which of demkit's numba patches are kept out: ``DEMKIT_PLAIN_<NAME>=1`` leaves numba as it is there."""
from __future__ import annotations

import os


def left_out(name):
    """Is the patch ``name`` kept out (``DEMKIT_PLAIN_<name>`` set to anything but 0)?"""
    return os.environ.get(f"DEMKIT_PLAIN_{name}", "") not in ("", "0")
