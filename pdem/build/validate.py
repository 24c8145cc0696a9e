"""Checks of input values, one helper per type, each raising `InputError` with one line that
names the field, the value and what is allowed. Strict: a boolean is not a number (TOML ``true``
must not become 1), a string is not a boolean, numbers are finite.
"""
from math import isfinite

import numpy as np

from ..errors import InputError


def _is_number(value):
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def number(label, value, lo=None, hi=None, *, lo_open=False, hi_open=False, integer=False, allow=None):
    """``value`` as a float (an int if ``integer``) within the bounds; else InputError.

    ``allow`` is the description of what is allowed (default: built from the bounds)."""
    if allow is None:
        kind = "an integer" if integer else "a number"
        parts = []
        if lo is not None:
            parts.append(f"{'>' if lo_open else '>='} {lo:g}")
        if hi is not None:
            parts.append(f"{'<' if hi_open else '<='} {hi:g}")
        allow = f"{kind} {' and '.join(parts)}" if parts else ("an integer" if integer else "a finite number")
    ok = _is_number(value) and isfinite(float(value))
    if ok and integer:
        ok = float(value) == int(value) and not isinstance(value, (float, np.floating))
    if ok:
        v = float(value)
        ok = not (
            (lo is not None and (v <= lo if lo_open else v < lo))
            or (hi is not None and (v >= hi if hi_open else v > hi))
        )
    if not ok:
        raise InputError(f"{label} = {value!r}: must be {allow}")
    return int(value) if integer else float(value)


def boolean(label, value):
    """``value`` if it is a boolean; else InputError (``"false"`` is a string, not False)."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{label} = {value!r}: must be true or false")
    return bool(value)


def vectors(label, value, n=None):
    """float64 [n, 3] from a list of (x, y, z) triples (or one triple when n is 1 or None)."""
    try:
        if isinstance(value, (str, bytes)) or _has_bool(value):
            raise ValueError
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{label} = {_short(value)}: must be a list of (x, y, z) numbers") from None
    if a.ndim == 1 and a.shape[0] == 3 and (n is None or n == 1):
        a = a[None]
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and a.shape[0] != n):
        want = f"{n} (x, y, z) triple{'s' if n != 1 else ''}" if n is not None else "(x, y, z) triples"
        raise InputError(f"{label}: must be a list of {want}, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{label}: contains a value that is not finite")
    return a


def vector3(label, value):
    """One finite (x, y, z) triple as float64 [3]."""
    return vectors(label, value, 1)[0]


def _has_bool(value):
    if isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, (list, tuple)):
        return any(_has_bool(v) for v in value)
    return isinstance(value, np.ndarray) and value.dtype == bool


def _short(value, limit=60):
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
