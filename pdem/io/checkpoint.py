"""Checkpoints: one HDF5 file per checkpoint holding everything needed to continue a run exactly.

Owns writing (gather to rank 0, sort by key, drop duplicate rows, atomic publish, keep-K pruning),
validating and reading checkpoints, and choosing the one to resume from. It does not know what the
tables mean (particles, contacts, walls ...): the simulation builds them and reads them back, and a
restart may use any number of ranks because every table is global and ordered by its key.
Must not import mpi4py (the ``comm`` object passed in hides MPI) nor pdem physics modules.

File layout (schema ``pdem-checkpoint``, version 1), readable with plain h5py::

    ckpt_000000000100.h5                  name: ckpt_{step:012d}.h5; HDF5 1.10 file format
      attrs  schema=b"pdem-checkpoint", schema_version=1, step (int64),
             time, dt (float64, copied from meta when present, for convenience),
             tables = JSON list of table names,
             complete = 1 (written last; a file without it is not a checkpoint)
      meta                                uint8[n]: UTF-8 bytes of the JSON of the meta dict
                                          (step, time, dt, scene spec, pdem version, rng state,
                                          keys ...); attr crc32
      tables/<table>/                     one group per table; the name may nest
                                          ("contacts/sphere_sphere" -> tables/contacts/sphere_sphere)
        attrs  keys = JSON list of key columns, columns = JSON list of columns, n_rows (int64)
        <column>                          dataset [n_rows] or [n_rows, ...], rows sorted by the
                                          key columns (lexicographic), keys unique; attrs crc32 =
                                          CRC-32 of the dataset's bytes in C order, dtype = numpy
                                          dtype string ("<f8"; bools are HDF5 enums, "|b1")

Text attributes are fixed-length byte strings (h5py returns ``bytes``; ``json.loads`` takes them):
they live in the object headers, which the 1.10 format checksums, so damaged metadata is refused
rather than misread. Validation checks every dataset's CRC-32 and dtype, row counts and the
attributes above; any failure is a one-line `CheckpointError`.

Reading without pdem::

    import h5py, json
    with h5py.File("ckpt_000000000100.h5", "r") as f:
        meta = json.loads(f["meta"][()].tobytes())
        pos = f["tables/particles/pos"][()]

A checkpoint is written under ``<name>.tmp`` in the same directory, fsynced and renamed with
``os.replace``, so a crash (SIGKILL, node failure) leaves the previous checkpoints intact and at
worst a stale ``.tmp`` file, which the next successful write removes. The checkpoint directory
holds one trajectory: writing step s also removes checkpoints with a step above s (they belong to
an abandoned continuation and would otherwise be picked by the next resume).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from pdem.io._h5 import crc32, json_dumps, one_line, open_h5
from pdem.io.atomic import TMP_SUFFIX, atomic_path, fsync_dir

SCHEMA = "pdem-checkpoint"
SCHEMA_VERSION = 1
_NAME_RE = re.compile(r"^ckpt_(\d{12})\.h5$")
_TMP_RE = re.compile(r"^ckpt_(\d{12})\.h5" + re.escape(TMP_SUFFIX) + "$")

__all__ = [
    "CheckpointError",
    "checkpoint_name",
    "find_resume_checkpoint",
    "list_checkpoints",
    "read_checkpoint",
    "verify_checkpoint",
    "write_checkpoint",
]


class CheckpointError(RuntimeError):
    """A checkpoint cannot be written or read; the message is one line: ``<file>: <what>``."""

    def __init__(self, path, reason: str):
        self.path = Path(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"{self.path.name}: {self.reason}")


class CheckpointWriteError(CheckpointError):
    """Writing a checkpoint failed (disk full, unwritable directory ...); raised on every rank."""


def checkpoint_name(step: int) -> str:
    """File name of the checkpoint at ``step``."""
    return f"ckpt_{int(step):012d}.h5"


def list_checkpoints(directory) -> list[tuple[int, Path]]:
    """``(step, path)`` of every file named like a checkpoint in ``directory``, oldest first.

    Only names are looked at; use `verify_checkpoint` to know whether a file is usable.
    """
    directory = Path(directory)
    if not directory.is_dir():
        return []
    found = []
    for entry in directory.iterdir():
        m = _NAME_RE.match(entry.name)
        if m and entry.is_file():
            found.append((int(m.group(1)), entry))
    return sorted(found)


# ----------------------------------------------------------------------------------------------
# Writing


def _signature(tables) -> dict:
    """Table -> column -> (dtype, trailing shape): what every rank must agree on to gather."""
    return {
        t: {c: (np.asarray(a).dtype.str, list(np.shape(a)[1:])) for c, a in cols.items()}
        for t, cols in tables.items()
    }


def _check_local(tables, keys) -> str | None:
    """Why this rank's tables cannot be checkpointed, or None."""
    if not isinstance(tables, dict):
        return "tables must be a dict of table name -> {column: array}"
    names = sorted(tables)
    for i, t in enumerate(names):
        if not t or t.startswith("/") or t.endswith("/") or "//" in t:
            return f"table name {t!r} is not a valid group path"
        if i + 1 < len(names) and names[i + 1].startswith(t + "/"):
            return f"table {t!r} cannot also be the parent group of table {names[i + 1]!r}"
        cols = tables[t]
        if not isinstance(cols, dict) or not cols:
            return f"table {t}: needs a dict with at least one column"
        if t not in keys:
            return f"table {t}: no key columns in meta['keys']"
        k = keys[t]
        if isinstance(k, str) or not k:
            return f"table {t}: meta['keys'][{t!r}] must be a non-empty list of column names"
        rows = None
        for c, a in cols.items():
            if not isinstance(c, str) or not c or "/" in c:
                return f"table {t}: column name {c!r} is not allowed"
            a = np.asarray(a)
            if a.ndim == 0:
                return f"table {t}: column {c} is a scalar, expected an array with one row per entry"
            if a.dtype.kind not in "biuf" and a.dtype.kind != "c":
                return f"table {t}: column {c} has dtype {a.dtype}, expected bool, int or float"
            if rows is None:
                rows = a.shape[0]
            elif a.shape[0] != rows:
                return f"table {t}: column {c} has {a.shape[0]} rows, other columns have {rows}"
        for kc in k:
            if kc not in cols:
                return f"table {t}: key column {kc} is not a column"
            a = np.asarray(cols[kc])
            if a.ndim != 1 or a.dtype.kind not in "biu":
                return f"table {t}: key column {kc} must be a 1-D integer array"
    return None


def _sort_unique(table: str, cols: dict, keys: list) -> dict:
    """Rows sorted by ``keys`` (lexicographic), exact duplicates dropped; differing ones raise."""
    n = next(iter(cols.values())).shape[0]
    if n == 0:
        return cols
    order = np.lexsort([cols[k] for k in reversed(keys)])
    cols = {c: np.ascontiguousarray(a[order]) for c, a in cols.items()}
    if n == 1:
        return cols
    same = np.ones(n - 1, dtype=bool)
    for k in keys:
        same &= cols[k][1:] == cols[k][:-1]
    dup = np.flatnonzero(same) + 1  # rows whose key equals the previous row's
    if dup.size == 0:
        return cols
    for c, a in cols.items():
        raw = a.reshape(n, -1).view(np.uint8).reshape(n, -1)  # bitwise: exact copies only
        differ = np.any(raw[dup] != raw[dup - 1], axis=1)
        if differ.any():
            row = dup[np.argmax(differ)]
            key = ", ".join(f"{k}={cols[k][row]}" for k in keys)
            raise ValueError(
                f"table {table}: rows with the same key ({key}) differ in column {c} "
                "(copies of one row from different ranks must be identical)"
            )
    keep = np.ones(n, dtype=bool)
    keep[dup] = False
    return {c: a[keep] for c, a in cols.items()}


def _write_file(final: Path, step: int, tables: dict, meta: dict, meta_json: str) -> None:
    with atomic_path(final) as tmp:
        # HDF5 1.10 file format: its superblock and object headers carry checksums, so damaged
        # metadata is refused instead of misread (readable by any HDF5 >= 1.10, h5py >= 2.8).
        payload = sum(a.nbytes for cols in tables.values() for a in cols.values()) + len(meta_json)
        with open_h5(tmp, "w", need=payload, libver=("v110", "v110")) as f:
            f.attrs["schema"] = _text(SCHEMA)
            f.attrs["schema_version"] = np.int64(SCHEMA_VERSION)
            f.attrs["step"] = np.int64(step)
            for name in ("time", "dt"):
                if isinstance(meta.get(name), (int, float, np.number)):
                    f.attrs[name] = np.float64(meta[name])
            f.attrs["tables"] = _text(json.dumps(sorted(tables)))
            meta_bytes = np.frombuffer(meta_json.encode("utf-8"), np.uint8)
            ds = f.create_dataset("meta", data=meta_bytes)
            ds.attrs["crc32"] = np.uint32(crc32(meta_bytes))
            for t in sorted(tables):
                cols = tables[t]
                g = f.create_group("tables/" + t)
                g.attrs["keys"] = _text(json.dumps(list(meta["keys"][t])))
                g.attrs["columns"] = _text(json.dumps(sorted(cols)))
                g.attrs["n_rows"] = np.int64(next(iter(cols.values())).shape[0])
                for c in sorted(cols):
                    d = g.create_dataset(c, data=cols[c])
                    d.attrs["crc32"] = np.uint32(crc32(cols[c]))
                    d.attrs["dtype"] = _text(cols[c].dtype.str)  # numpy dtype string, e.g. "<f8", "|b1"
            f.attrs["complete"] = np.int64(1)  # last: only a fully written file carries it
            f.flush()


def _text(value: str) -> np.bytes_:
    """A fixed-length string attribute: kept in the object header, which HDF5 checksums."""
    return np.bytes_(value.encode("utf-8"))


def _str(value) -> str | None:
    """Attribute value as text (fixed-length strings come back as bytes)."""
    if value is None:
        return None
    return value.decode("utf-8", errors="replace") if isinstance(value, bytes) else str(value)


def _prune(directory: Path, step: int, keep: int | None) -> None:
    """Remove stale temp files, checkpoints after ``step`` and all but the newest ``keep``."""
    for entry in directory.iterdir():
        if _TMP_RE.match(entry.name):
            entry.unlink(missing_ok=True)
    found = list_checkpoints(directory)
    doomed = [p for s, p in found if s > step]
    kept = [p for s, p in found if s <= step]
    if keep is not None:
        doomed += kept[: max(len(kept) - keep, 0)]
    for p in doomed:
        p.unlink(missing_ok=True)
    fsync_dir(directory)


def write_checkpoint(directory, step: int, tables: dict, meta: dict, comm, keep: int | None = 3) -> Path:
    """Write the checkpoint of ``step`` to ``directory`` and return its path (on every rank).

    Collective: every rank calls it with its local rows.

    Parameters
    ----------
    directory : path
        Checkpoint directory (created if missing); holds one trajectory.
    step : int
        Step number; the file is ``ckpt_{step:012d}.h5``.
    tables : dict
        Table name -> {column name -> array}. All columns of a table have the same first dimension
        (rows); columns may be 2-D (``pos[n, 3]``, ``history[n, w]``). Every rank passes the same
        tables and columns (same dtypes and trailing shapes), possibly with zero rows.
    meta : dict
        JSON-able run state (step, time, dt, scene spec, pdem version, rng state ...). Must hold
        ``meta["keys"][table]``: the key columns of each table (1-D integer columns, e.g.
        ``["gid"]`` or ``["gid_i", "gid_j"]``). Rank 0's ``meta`` is written.
    comm : Comm
        ``rank``, ``size``, ``gather_rows``, ``bcast``, ``any_flag`` (pdem.parallel.comm).
    keep : int or None
        Number of newest checkpoints kept (>= 1); None keeps all.

    Raises
    ------
    CheckpointError
        On every rank, with one line naming the file and the cause: inconsistent tables, rows
        with the same key that differ (a bug upstream), or an I/O failure.
    """
    directory = Path(directory)
    step = int(step)
    final = directory / checkpoint_name(step)
    if keep is not None and int(keep) < 1:
        raise CheckpointError(final, f"keep must be >= 1 or None, got {keep}")
    keys = meta.get("keys", {}) if isinstance(meta, dict) else {}

    # Every rank checks its own tables, then all agree on rank 0's structure before gathering:
    # a mismatch must raise everywhere, not leave ranks waiting in different collectives.
    err = _check_local(tables, keys) if isinstance(meta, dict) else "meta must be a dict"
    if comm.any_flag(err is not None):
        raise CheckpointError(final, err or "invalid tables on another rank")
    sig = comm.bcast(_signature(tables) if comm.rank == 0 else None)
    mismatch = _signature(tables) != sig
    if comm.any_flag(mismatch):
        raise CheckpointError(
            final,
            f"rank {comm.rank} tables or columns differ from rank 0's" if mismatch
            else "tables or columns differ between ranks",
        )

    gathered = {}
    for t in sorted(tables):
        gathered[t] = {c: comm.gather_rows(np.ascontiguousarray(tables[t][c])) for c in sorted(tables[t])}

    outcome = None
    if comm.rank == 0:
        try:
            meta_json = json_dumps(meta)
            merged = {t: _sort_unique(t, cols, list(keys[t])) for t, cols in gathered.items()}
            directory.mkdir(parents=True, exist_ok=True)
            _write_file(final, step, merged, meta, meta_json)
            _prune(directory, step, keep)
            outcome = ("ok", str(final))
        except Exception as exc:  # reported on every rank below
            outcome = ("error", one_line(exc))
            error = exc
    outcome = comm.bcast(outcome)
    if outcome[0] != "ok":
        if comm.rank == 0:
            raise CheckpointWriteError(final, outcome[1]) from error
        raise CheckpointWriteError(final, outcome[1])
    return Path(outcome[1])


# ----------------------------------------------------------------------------------------------
# Reading


def _load(path, keep_data: bool):
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(path, "file does not exist")
    try:
        f = open_h5(path, "r")
    except Exception as exc:
        raise CheckpointError(path, f"cannot open as HDF5 ({one_line(exc)})") from None
    try:
        return _load_open(path, f, keep_data)
    except CheckpointError:
        raise
    except Exception as exc:  # damaged HDF5 metadata surfaces as assorted h5py errors
        raise CheckpointError(path, f"unreadable ({type(exc).__name__}: {one_line(exc)})") from None


def _load_open(path: Path, f, keep_data: bool):

    def fail(reason):
        raise CheckpointError(path, reason)

    with f:
        schema = f.attrs.get("schema")
        if isinstance(schema, bytes):
            schema = schema.decode(errors="replace")
        if schema is None:
            fail("not a pdem checkpoint (no schema attribute)")
        if schema != SCHEMA:
            fail(f"schema is {schema!r}, expected {SCHEMA!r}")
        version = f.attrs.get("schema_version")
        if version is None or int(version) > SCHEMA_VERSION or int(version) < 1:
            fail(f"schema_version {version} is not readable by this pdem (reads 1..{SCHEMA_VERSION})")
        if int(f.attrs.get("complete", 0)) != 1:
            fail("incomplete (attribute complete is not 1)")
        m = _NAME_RE.match(path.name)
        if m and int(f.attrs.get("step", -1)) != int(m.group(1)):
            fail(f"file name says step {int(m.group(1))} but attribute step is {f.attrs.get('step')}")

        if "meta" not in f:
            fail("dataset meta missing")
        try:
            raw = f["meta"][()]
        except Exception as exc:
            fail(f"dataset meta unreadable ({one_line(exc)})")
        if not isinstance(raw, np.ndarray) or raw.dtype != np.uint8 or raw.ndim != 1:
            fail("dataset meta is not a 1-D uint8 array")
        if crc32(raw) != int(f["meta"].attrs.get("crc32", -1)):
            fail("dataset meta checksum mismatch")
        try:
            meta = json.loads(raw.tobytes().decode("utf-8"))
            names = json.loads(f.attrs["tables"])
        except Exception as exc:
            fail(f"meta or tables attribute is not valid JSON ({one_line(exc)})")

        tables = {}
        for t in names:
            if "tables/" + t not in f:
                fail(f"table {t} missing")
            g = f["tables/" + t]
            try:
                columns = json.loads(g.attrs["columns"])
                keys = json.loads(g.attrs["keys"])
                n_rows = int(g.attrs["n_rows"])
            except Exception as exc:
                fail(f"table {t} attributes unreadable ({one_line(exc)})")
            for k in keys:
                if k not in columns:
                    fail(f"table {t}: key column {k} is not among its columns")
            cols = {}
            for c in columns:
                name = f"{t}/{c}"
                if c not in g:
                    fail(f"dataset {name} missing")
                ds = g[c]
                if ds.ndim == 0 or ds.shape[0] != n_rows:
                    fail(f"dataset {name} has shape {ds.shape}, table has {n_rows} rows")
                try:
                    data = ds[()]
                except Exception as exc:
                    fail(f"dataset {name} unreadable ({one_line(exc)})")
                if "crc32" not in ds.attrs:
                    fail(f"dataset {name} has no checksum")
                if crc32(data) != int(ds.attrs["crc32"]):
                    fail(f"dataset {name} checksum mismatch")
                if data.dtype.str != _str(ds.attrs.get("dtype")):
                    fail(f"dataset {name} reads as dtype {data.dtype.str}, written as {_str(ds.attrs.get('dtype'))}")
                if keep_data:
                    cols[c] = data
            if keep_data:
                tables[t] = cols
    return tables, meta


def read_checkpoint(path) -> tuple[dict, dict]:
    """Validate and read a checkpoint: ``(tables, meta)``.

    ``tables`` maps table name -> {column -> array} (rows sorted by the table's keys); ``meta`` is
    the dict given to `write_checkpoint` (after a JSON round trip: tuples and numpy arrays come
    back as lists). Raises `CheckpointError` with one line (file and cause) if the file does not
    open, lacks ``complete``, has another schema or version, a dataset fails its checksum, or row
    counts disagree.
    """
    return _load(path, keep_data=True)


def verify_checkpoint(path) -> None:
    """Run every check of `read_checkpoint` without keeping the data; raise `CheckpointError`."""
    _load(path, keep_data=False)


def find_resume_checkpoint(directory, log=print, comm=None) -> Path | None:
    """Newest valid checkpoint in ``directory``, or None if there is none.

    Damaged checkpoints newer than the one returned are reported through ``log``, one line
    each, naming the file, what is wrong, and which checkpoint is used instead. With ``comm``,
    rank 0 searches and logs and every rank gets its answer.
    """
    if comm is not None:
        result = find_resume_checkpoint(directory, log) if comm.rank == 0 else None
        result = comm.bcast(None if result is None else str(result))
        return None if result is None else Path(result)

    damaged = []
    for _, path in reversed(list_checkpoints(directory)):
        try:
            verify_checkpoint(path)
        except CheckpointError as exc:
            damaged.append(exc)
            continue
        for exc in damaged:
            log(f"checkpoint {exc.path.name} is damaged ({exc.reason}); resuming from {path.name}")
        return path
    for exc in damaged:
        log(f"checkpoint {exc.path.name} is damaged ({exc.reason}); no valid checkpoint in {directory}")
    return None
