"""Checks of user-given numbers, shared by particles, boxes, interactions, effects and builders.

A numeric parameter accepts real numbers only: Python ints and floats, numpy integers and floats
(and 0-d numeric arrays), fractions. Strings ("1"), bools (``True`` is not one kilogram), None and
complex numbers raise TypeError naming the parameter, where ``float()`` would have let a string or
a bool through. Array parameters accept arrays and nested lists of such numbers.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

_NONE = object()  # "nothing found" (None may be what is found)
_KINDS = {"b": "booleans", "U": "strings", "S": "bytes", "c": "complex numbers", "M": "dates", "m": "time spans",
          "V": "records"}


def _show(value):
    shown = repr(value)
    return shown if len(shown) <= 60 else shown[:57] + "..."


def _refuse(name, value, what="a number (int, float or a numpy number)"):
    raise TypeError(f"{name} must be {what}, got {type(value).__name__} {_show(value)}"
                    + (": write numbers without quotes" if isinstance(value, (str, bytes)) else ""))


def number(name, value):
    """float(value) for a real number; TypeError for anything else (strings, bools, None, complex)."""
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return float(value)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        _refuse(name, value)
    return float(value)


def finite(name, value):
    """A real number that is finite (ValueError for NaN or inf)."""
    value = number(name, value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value}")
    return value


def positive(name, value):
    """A real number that is finite and > 0."""
    value = number(name, value)
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value}")
    return value


def writer_interval(every, overwrite, resume, kept):
    """A writer's ``every``: a positive finite time interval; ``overwrite`` and ``resume`` refused
    together (``kept``: what resume continues)."""
    try:
        every = float(every)
    except (TypeError, ValueError):
        raise ValueError(f"every must be a positive time interval, got {every!r}") from None
    if not math.isfinite(every) or every <= 0:
        raise ValueError(f"every must be a positive finite time interval, got {every}")
    if overwrite and resume:
        raise ValueError(f"overwrite=True deletes the {kept} that resume=True continues: pass one of them")
    return every


def non_negative(name, value):
    """A real number that is finite and >= 0."""
    value = number(name, value)
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a non-negative finite number, got {value}")
    return value


def flag(name, value):
    """A bool (Python or numpy); TypeError for anything else (0, 1, "yes", None)."""
    if not isinstance(value, (bool, np.bool_)):
        _refuse(name, value, "True or False")
    return bool(value)


def _array(name, value):
    try:
        return np.asarray(value)
    except ValueError:
        raise ValueError(f"{name} must be a rectangular array of numbers (rows of equal length), got "
                         f"{_show(value)}") from None


def real_array(name, value):
    """A new float64 array of the numbers in ``value`` (an array or nested lists); TypeError if it
    holds anything but real numbers, ValueError if its rows have unequal lengths. NaN and inf pass
    (callers check finiteness with their own message)."""
    arr = _array(name, value)
    if arr.ndim == 0 and arr.dtype.kind not in "iuf":
        _refuse(name, value, "a number or an array of numbers (ints or floats)")
    odd = _NONE
    if arr.dtype.kind == "O":
        odd = next((item for item in arr.flat if isinstance(item, (bool, np.bool_))
                    or not isinstance(item, numbers.Real)), _NONE)
    elif arr.dtype.kind in "iuf":
        odd = _bool_in(value)  # numpy turns [1, True] into [1, 1]
    else:
        what = _KINDS.get(arr.dtype.kind, f"dtype {arr.dtype}")
        raise TypeError(f"{name} must hold numbers (ints or floats), got {what}: {_show(value)}"
                        + (" (write numbers without quotes)" if arr.dtype.kind in "US" else ""))
    if odd is not _NONE:
        raise TypeError(f"{name} must hold numbers (ints or floats), got {type(odd).__name__} {_show(odd)} in "
                        f"{_show(value)}")
    return np.array(arr, dtype=np.float64)


def _bool_in(value):
    """The first bool in nested lists and tuples (numpy arrays: of a bool dtype), or _NONE."""
    if isinstance(value, (bool, np.bool_)):
        return value
    if isinstance(value, np.ndarray):
        return value.flat[0] if value.dtype.kind == "b" and value.size else _NONE
    if isinstance(value, (list, tuple)):
        for item in value:
            found = _bool_in(item)
            if found is not _NONE:
                return found
    return _NONE


def integer_array(name, value):
    """A new int64 array of whole numbers (integers, or floats with no fractional part)."""
    arr = _array(name, value)
    if arr.dtype.kind in "iu":
        return arr.astype(np.int64)  # exactly, also beyond 2**53
    arr = real_array(name, arr)
    if not (np.isfinite(arr).all() and np.all(arr == np.round(arr))):
        raise ValueError(f"{name} must hold whole numbers, got {_show(value)}")
    return arr.astype(np.int64)


#: the widest a scene may be, in radii of its smallest sphere: float64 positions there still resolve a
#: radius to about 1e-4 (doubles near 1e12 R are 1.2e-4 R apart), and cell counts fit an int64
WIDEST = 1e12


def resolvable(what, extent, radius, unit="the smallest radius"):
    """Raise ValueError when a length ``extent`` spans more than :data:`WIDEST` times ``radius`` (the
    smallest of them, named ``unit`` in the message)."""
    extent, radius = float(np.max(extent)), float(np.min(radius))
    if not extent <= WIDEST * radius:
        raise ValueError(f"{what} spans {extent:.6g}, more than {WIDEST:g} times {unit} {radius:.6g}: "
                         f"float64 positions cannot resolve the spheres there (rescale the units or the box)")
