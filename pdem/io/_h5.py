"""Small helpers the pdem.io writers share: opening HDF5 files, checksums, JSON, one-line errors.

Free space is checked before every HDF5 file is opened for writing (`ensure_space`): HDF5 does
not survive a write that fails with ENOSPC (the process segfaults inside the library, with no
chance to report or checkpoint), so a nearly full disk raises ``OSError(ENOSPC)`` first, while
the run can still end with one line. The floor is `MIN_FREE_BYTES` (8 MiB; the environment
variable PDEM_MIN_FREE_BYTES overrides it) plus twice the bytes about to be written.

Private to pdem.io. Must not import mpi4py or pdem modules outside pdem.io.
"""

from __future__ import annotations

import errno
import json
import os
import zlib
from pathlib import Path

import h5py
import numpy as np

MIN_FREE_BYTES = 8 << 20


def ensure_space(path, nbytes: int = 0) -> None:
    """Raise ``OSError(ENOSPC)`` naming ``path`` unless its file system has `MIN_FREE_BYTES`
    plus twice ``nbytes`` free (file systems that cannot tell are not checked)."""
    floor = int(os.environ.get("PDEM_MIN_FREE_BYTES", MIN_FREE_BYTES))
    directory = Path(path).parent
    try:
        st = os.statvfs(directory if str(directory) else ".")
    except OSError:
        return
    free = st.f_bavail * st.f_frsize
    need = floor + 2 * int(nbytes)
    if st.f_blocks and free < need:
        raise OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)} ({free} bytes free, {need} needed)", str(path))


def open_h5(path, mode: str, need: int = 0, **kwargs) -> h5py.File:
    """Open an HDF5 file; file locking is best-effort (cluster file systems often lack flock).

    pdem never has two processes on one file at once (checkpoints are written under a private
    temporary name), so a file system without locking must not stop a run. A mode that writes
    first checks the free space (`ensure_space`, ``need`` bytes about to be written).
    """
    if mode != "r":
        ensure_space(path, need)
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
    ``schema_version`` attributes; a failure raises ``error(path, one line)`` (a full disk
    raises OSError: it is not the file's fault)."""
    ensure_space(path)
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
