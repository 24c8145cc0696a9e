"""Writing a parsed TOML document (dicts, lists, scalars) back as TOML text.

Owns `dumps`, used to write each member's resolved scene file. The output parses back with
``tomllib`` to an equal document (strings, ints, floats including inf/nan, bools, dates, lists,
tables, arrays of tables). Imports the standard library only.
"""
import datetime as _dt
import json
import math
import re

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k):
    return k if _BARE.match(k) else _string(k)


def _string(s):
    # JSON's escapes are TOML's, except that TOML wants DEL escaped and JSON would write
    # characters outside the BMP as surrogate pairs (kept literal here: ensure_ascii=False)
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007f")


def _float(v):
    """The shorter of repr and the shortest exact scientific form (2.8e7, not 28000000.0)."""
    plain = repr(v)
    for digits in range(17):
        sci = f"{v:.{digits}e}"
        if float(sci) == v:
            break
    mant, exp = sci.split("e")
    sci = f"{mant}e{int(exp)}"
    return sci if len(sci) < len(plain) else plain


def _value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return _float(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (_dt.datetime, _dt.date, _dt.time)):
        return v.isoformat()
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} {v!r} as TOML")


def _is_table_array(v):
    return isinstance(v, list) and len(v) > 0 and all(isinstance(x, dict) for x in v)


def _table(lines, path, table):
    """Append the scalars of ``table`` (under header ``path``), then its sub-tables."""
    plain = [(k, v) for k, v in table.items() if not isinstance(v, dict) and not _is_table_array(v)]
    subs = [(k, v) for k, v in table.items() if isinstance(v, dict) or _is_table_array(v)]
    if path and (plain or not subs):
        lines.append(f"[{'.'.join(_key(p) for p in path)}]")
    for k, v in plain:
        lines.append(f"{_key(k)} = {_value(v)}")
    if plain:
        lines.append("")
    for k, v in subs:
        if isinstance(v, dict):
            _table(lines, path + [k], v)
        else:
            for item in v:
                lines.append(f"[[{'.'.join(_key(p) for p in path + [k])}]]")
                inner = [(a, b) for a, b in item.items() if not isinstance(b, dict) and not _is_table_array(b)]
                for a, b in inner:
                    lines.append(f"{_key(a)} = {_value(b)}")
                nested = {a: b for a, b in item.items() if isinstance(b, dict) or _is_table_array(b)}
                lines.append("")
                if nested:  # sub-tables of an array element: written inline to stay unambiguous
                    lines[-1:] = [f"{_key(a)} = {_value(b)}" for a, b in nested.items()] + [""]


def dumps(doc, header=""):
    """TOML text of ``doc`` (a dict as returned by ``tomllib.loads``); ``header`` is prepended
    as comment lines."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    if lines:
        lines.append("")
    _table(lines, [], doc)
    while lines and lines[-1] == "":
        lines.pop()
    return "\n".join(lines) + "\n"
