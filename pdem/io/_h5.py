"""Small helpers the pdem.io writers share: opening HDF5 files, checksums, JSON, one-line errors.

Private to pdem.io. Must not import mpi4py or pdem modules outside pdem.io.
"""

from __future__ import annotations

import json
import zlib

import h5py
import numpy as np


def open_h5(path, mode: str, **kwargs) -> h5py.File:
    """Open an HDF5 file; file locking is best-effort (cluster file systems often lack flock).

    pdem never has two processes on one file at once (checkpoints are written under a private
    temporary name), so a file system without locking must not stop a run.
    """
    try:
        return h5py.File(path, mode, locking="best-effort", **kwargs)
    except (TypeError, ValueError) as exc:  # HDF5 < 1.12.1 does not know best-effort
        if "lock" not in str(exc).lower():
            raise
        return h5py.File(path, mode, **kwargs)


def crc32(array: np.ndarray) -> int:
    """CRC-32 of an array's bytes in C order (the bytes h5py hands back on read)."""
    a = np.ascontiguousarray(array)
    if a.nbytes == 0:
        return 0
    return zlib.crc32(memoryview(a).cast("B")) & 0xFFFFFFFF


def _json_default(obj):
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON-serialisable")


def json_dumps(obj) -> str:
    """JSON text of ``obj``; numpy scalars and arrays become plain numbers and lists."""
    return json.dumps(obj, default=_json_default, sort_keys=True)


def one_line(exc: BaseException, limit: int = 240) -> str:
    """An exception's message squeezed onto one line (HDF5 errors span several)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def open_tagged(path, schema: str, version: int, error):
    """Open (create) an HDF5 file for appending and check or set its ``schema`` and
    ``schema_version`` attributes; a failure raises ``error(path, one line)``."""
    try:
        f = open_h5(path, "a")
    except Exception as exc:
        raise error(path, f"cannot open as HDF5 ({one_line(exc)})") from None
    found, found_version = f.attrs.get("schema"), f.attrs.get("schema_version")
    if found is None:
        f.attrs["schema"] = schema
        f.attrs["schema_version"] = np.int64(version)
    elif found != schema or found_version is None or int(found_version) != version:
        f.close()
        raise error(path, f"schema is {found!r} version {found_version}, expected {schema!r} version {version}")
    return f
