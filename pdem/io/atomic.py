"""Atomic file replacement: write to a temporary name, fsync, then ``os.replace``.

Owns the one way pdem publishes a file that a reader (a restart, ParaView, a campaign runner)
may open at any moment: the content is written under a temporary name in the *same* directory
(``os.replace`` is atomic only within one file system), flushed to disk with ``fsync``, renamed
over the final name, and the directory entry is fsynced too. A crash at any point leaves either
the old file or the new one under the final name, never a partial one; at worst a stale
``*.tmp`` file stays behind.

Must not import mpi4py, h5py or other pdem modules: it is plain file handling.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

TMP_SUFFIX = ".tmp"


def tmp_path_for(path: str | os.PathLike) -> Path:
    """The temporary name used while ``path`` is being written (same directory)."""
    path = Path(path)
    return path.with_name(path.name + TMP_SUFFIX)


def fsync_file(path: str | os.PathLike) -> None:
    """Flush a closed file's data to disk (fsync through a fresh descriptor)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_dir(directory: str | os.PathLike) -> None:
    """Make a rename or unlink in ``directory`` durable; a no-op where directories cannot be opened."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some file systems refuse fsync on directories; the rename is still atomic
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path to write; on success it is fsynced and renamed to ``path``.

    The caller must have closed the file before the ``with`` block ends. On an exception the
    temporary file is removed and ``path`` is left untouched.
    """
    path = Path(path)
    tmp = tmp_path_for(path)
    try:
        yield tmp
        fsync_file(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    fsync_dir(path.parent)


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Replace ``path`` atomically by a file holding ``data``."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> None:
    """Replace ``path`` atomically by a text file holding ``text``."""
    atomic_write_bytes(path, text.encode(encoding))
