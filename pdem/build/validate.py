"""Checks of input values, one helper per type, each raising `InputError` with one line that
names the field, the value and what is allowed. Strict, and the same for every key: a boolean is
not a number (TOML ``true`` must not become 1), a string is not a number (``"1.5"`` is text, also
as an element of a list: `vectors` and `numbers` refuse what `number` refuses), a string is not a
boolean, numbers are finite.
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
        if not _all_numbers(value):
            raise ValueError
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{label} = {_short(value)}: must be a list of (x, y, z) numbers (not text, not "
                         "true/false)") from None
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


def numbers(label, value, n=None, lo=None, *, lo_open=False, allow=None):
    """float64 [n] from one number (repeated n times) or a list of numbers (n of them if n is
    given), each checked as `number` checks a scalar: a list element that is text, a boolean or
    not finite is refused exactly as the scalar would be. ``allow`` as in `number`."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, np.ndarray) and value.ndim == 1 and value.dtype.kind in "iuf":
        a = value.astype(np.float64)  # already numbers (a caller's array): the count, then the values at once
        if n is not None and len(a) != n:
            raise InputError(f"{label}: must be one number or {n} of them, got {len(a)}")
        ok = np.isfinite(a) if lo is None else np.isfinite(a) & ((a > lo) if lo_open else (a >= lo))
        if not np.all(ok):
            k = int(np.flatnonzero(~ok)[0])
            number(f"{label}[{k}]", float(a[k]), lo, lo_open=lo_open, allow=allow)
        return a
    if isinstance(value, (list, tuple, np.ndarray)):
        items = list(np.asarray(value, dtype=object).reshape(-1)) if isinstance(value, np.ndarray) else list(value)
        if n is not None and len(items) != n:
            raise InputError(f"{label}: must be one number or {n} of them, got {len(items)}")
        out = [number(f"{label}[{k}]", x, lo, lo_open=lo_open, allow=allow) for k, x in enumerate(items)]
        return np.array(out, dtype=np.float64)
    x = number(label, value, lo, lo_open=lo_open, allow=allow)
    return np.full(1 if n is None else n, x)


def _all_numbers(value):
    """True if ``value`` is a number or a (nested) list/array of numbers only (no text, no booleans)."""
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "iuf" or (value.dtype == object and all(_all_numbers(v) for v in value.ravel()))
    if isinstance(value, (list, tuple)):
        return all(_all_numbers(v) for v in value)
    return _is_number(value)


def _short(value, limit=60):
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
