"""Results file writers: time series of global scalars (/series) and whole tables (/cycles).

Owns the mechanics of writing a results HDF5 file; what the file holds (its schema name and
version, the columns of each kind of run and their units) is defined once, in
`pdem.format.schema`, and passed in by pdem's driver (the engine never imports `analysis`). Only one process
writes (rank 0): the
caller passes values already reduced over ranks; with ``comm`` given, the other ranks get a
writer that does nothing. Which steps produce a row (the schedule) is the caller's business.
Must not import mpi4py nor pdem physics modules. The analysis package reads this file with h5py.

Layout::

    results.h5
      attrs  schema, schema_version (the ``schema`` argument: checked, or set on a new file)
      series/                       attrs: columns (JSON list, column order), plus the caller's attrs
        <column>                    1-D resizable dataset, one entry per row; attr units
                                    ("step" is int64, other columns float64 unless told)
      cycles/                       written whole by write_table (any group name works)
        attrs  columns (JSON list), n_rows
        <column>                    1-D dataset; attr units

Rows are buffered and written every ``every`` rows; the file is opened and closed around each
write, so a crash between writes leaves a consistent file, and loses at most the buffered rows.
On a restart, ``append=True, restart_step=s`` drops the rows with ``step > s`` (written after the
checkpoint the run resumes from), so the resumed run does not duplicate them; if the columns
ended with different lengths (a crash inside a write), all are cut to the shortest.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from pdem.io._h5 import json_dumps, open_tagged

_CHUNK = 1024

__all__ = ["ResultsFileError", "TimeSeriesWriter", "write_table"]


_WHAT_TO_DO = ("move it aside to continue with a new results file (the checkpoints are kept), or start over "
               "with --fresh after removing it")


def _one(exc) -> str:
    return " ".join(str(exc).split())[:200]


class ResultsFileError(RuntimeError):
    """The results file cannot be used; the message is one line: ``<file>: <what>``."""

    def __init__(self, path, reason: str):
        self.path = Path(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"{self.path.name}: {self.reason}")


def _open_results(path: Path, schema):
    """Open (create) the results file for writing and check or set its schema attributes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return open_tagged(path, schema[0], schema[1], ResultsFileError)


def _set_attrs(obj, attrs) -> None:
    for key, value in (attrs or {}).items():
        if isinstance(value, (str, bool, int, float, np.number, np.bool_)):
            obj.attrs[key] = value
        else:
            obj.attrs[key] = json_dumps(value)


def _column_specs(columns) -> dict:
    """name -> (units, dtype) from name -> units or name -> (units, dtype)."""
    if not isinstance(columns, dict) or not columns:
        raise ValueError("columns must be a non-empty dict of name -> units")
    specs = {}
    for name, spec in columns.items():
        if not isinstance(name, str) or not name or "/" in name:
            raise ValueError(f"column name {name!r} is not allowed")
        if isinstance(spec, str):
            units, dtype = spec, (np.int64 if name == "step" else np.float64)
        else:
            units, dtype = spec
        specs[name] = (str(units), np.dtype(dtype))
    return specs


class TimeSeriesWriter:
    """Append rows of global scalars to ``/<group>/<column>`` of a results file.

    Parameters
    ----------
    path : path
        Results file (created if missing; other groups in it are kept).
    columns : dict
        Column name -> units (e.g. ``{"step": "1", "time": "s", "f_platen": "N"}``) or
        name -> (units, dtype). ``step`` defaults to int64, other columns to float64.
    attrs : dict, optional
        Attributes of the group (scene, seed ...); non-scalars are stored as JSON text.
    every : int
        Rows buffered before they are written to the file (>= 1).
    append : bool
        False: start the series afresh (an existing group of that name is replaced).
        True: continue an existing series (the columns must match).
    restart_step : int, optional
        With ``append``: rows with ``step > restart_step`` are dropped first.
    schema : (str, int)
        The file's schema name and version (checked, or set on a new file).
    group : str
        Group name, default ``series``.
    comm : Comm, optional
        If given, only rank 0 writes; elsewhere every method is a no-op.
    """

    def __init__(self, path, columns, *, schema, attrs=None, every=1, append=False, restart_step=None,
                 group="series", comm=None):
        self.path = Path(path)
        self.schema = schema
        self.group = group
        self.specs = _column_specs(columns)
        self.every = int(every)
        if self.every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        if restart_step is not None and "step" not in self.specs:
            raise ValueError("restart_step needs a 'step' column")
        self.active = comm is None or comm.rank == 0
        self._buffer: list[tuple] = []
        self._written = 0
        self._closed = False
        failure = None
        if self.active:
            try:
                self._start(attrs, append, restart_step)
            except ResultsFileError as exc:
                failure = ("results", exc.reason)
            except OSError as exc:  # disk full ...
                failure = ("os", exc.errno, exc.strerror, exc.filename)
        if comm is not None:  # every rank raises together: no rank is left waiting for rank 0
            failure = comm.bcast(failure)
        if failure is not None:
            if failure[0] == "results":
                raise ResultsFileError(self.path, failure[1])
            raise OSError(*failure[1:])

    def _start(self, attrs, append, restart_step) -> None:
        """Create the group, or (append) continue it; a file that cannot be continued raises
        ResultsFileError naming what to do."""
        try:
            self._start_file(attrs, append, restart_step)
        except ResultsFileError as exc:
            raise ResultsFileError(self.path, f"{exc.reason}; {_WHAT_TO_DO}") from None
        except OSError as exc:
            if exc.errno is not None:  # the system's (disk full ...), not the file's
                raise
            raise ResultsFileError(self.path, f"damaged ({_one(exc)}); {_WHAT_TO_DO}") from None
        except (KeyError, ValueError, TypeError, RuntimeError) as exc:
            raise ResultsFileError(self.path, f"damaged ({type(exc).__name__}: {_one(exc)}); {_WHAT_TO_DO}") from None

    def _start_file(self, attrs, append, restart_step) -> None:
        with _open_results(self.path, self.schema) as f:
            if not append and self.group in f:
                del f[self.group]
            if self.group in f:
                g = f[self.group]
                have = set(json.loads(g.attrs.get("columns", "[]")))
                if have != set(self.specs):
                    raise ResultsFileError(
                        self.path,
                        f"group {self.group} has columns {sorted(have)}, this run writes {sorted(self.specs)}",
                    )
                n = min(g[c].shape[0] for c in self.specs)
                if restart_step is not None:
                    after = np.flatnonzero(g["step"][:n] > restart_step)
                    if after.size:
                        n = int(after[0])
                for c in self.specs:
                    g[c].resize((n,))
                self._written = n
            else:
                g = f.create_group(self.group)
                g.attrs["columns"] = json.dumps(list(self.specs))
                for c, (units, dtype) in self.specs.items():
                    ds = g.create_dataset(c, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(_CHUNK,))
                    ds.attrs["units"] = units
            _set_attrs(g, attrs)

    @property
    def rows(self) -> int:
        """Rows in the series, written or still buffered."""
        return self._written + len(self._buffer)

    def append(self, row=None, **values) -> None:
        """Add one row: a mapping and/or keywords giving every column exactly once."""
        if not self.active:
            return
        if self._closed:
            raise ResultsFileError(self.path, f"{self.group}: writer is closed")
        if row:
            values = {**row, **values}
        if values.keys() != self.specs.keys():
            missing = sorted(set(self.specs) - set(values))
            extra = sorted(set(values) - set(self.specs))
            raise ValueError(f"{self.group} row: missing columns {missing}, unknown columns {extra}")
        self._buffer.append(tuple(values[c] for c in self.specs))
        if len(self._buffer) >= self.every:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows and close the file again."""
        if not self.active or not self._buffer:
            return
        k = len(self._buffer)
        data = list(zip(*self._buffer))
        with _open_results(self.path, self.schema) as f:
            g = f[self.group]
            for i, c in enumerate(self.specs):
                ds = g[c]
                ds.resize((self._written + k,))
                ds[self._written:] = np.asarray(data[i], dtype=self.specs[c][1])
        self._written += k
        self._buffer.clear()

    def close(self) -> None:
        """Write what is buffered; further appends raise."""
        if self.active and not self._closed:
            self.flush()
        self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def write_table(path, group, columns, units, *, schema, attrs=None, comm=None) -> None:
    """Write a whole table (e.g. one row per load cycle) to ``/<group>``, replacing it.

    Parameters
    ----------
    path : path
        Results file (created if missing).
    group : str
        Group name, e.g. ``"cycles"``.
    columns : dict
        Column name -> 1-D array; all of the same length.
    units : dict
        Column name -> units string, for every column.
    attrs : dict, optional
        Attributes of the group.
    schema : (str, int)
        The file's schema name and version (checked, or set on a new file).
    comm : Comm, optional
        If given, only rank 0 writes.
    """
    if comm is not None and comm.rank != 0:
        return
    path = Path(path)
    arrays = {c: np.asarray(a) for c, a in columns.items()}
    lengths = {a.shape[0] if a.ndim == 1 else None for a in arrays.values()}
    if not arrays or None in lengths or len(lengths) != 1:
        raise ValueError(f"table {group}: columns must be 1-D arrays of one length")
    missing = sorted(set(arrays) - set(units))
    if missing:
        raise ValueError(f"table {group}: no units for columns {missing}")
    with _open_results(path, schema) as f:
        if group in f:
            del f[group]
        g = f.create_group(group)
        g.attrs["columns"] = json.dumps(list(arrays))
        g.attrs["n_rows"] = np.int64(lengths.pop())
        for c, a in arrays.items():
            ds = g.create_dataset(c, data=a)
            ds.attrs["units"] = str(units[c])
        _set_attrs(g, attrs)
