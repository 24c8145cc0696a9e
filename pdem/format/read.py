"""Open, validate and read pdem results files (format in `pdem.format.schema`).

This module owns `ResultFileError`, the one way to open a results file (`open_results`),
`results_file` (a run directory or a file -> the results file) and the readers of the root
attributes, ``/series`` and ``/cycles`` (`read_results`; `pdem.format.groups` reads the optional
groups). Everything read comes back as plain numpy float64 arrays in SI units ([s], [m], [N]).
Any file that is not a valid pdem result raises `ResultFileError` with one line naming the file
and the problem (or, with ``lenient``, gives None). Imports numpy and h5py only.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from .schema import (BOX_SERIES, CYCLE_FIELDS, CYCLE_UNITS, REQUIRED_SERIES, ROOT_ATTRS,
                     SCHEMA, SCHEMA_VERSION, SERIES_UNITS)

RESULTS_NAME = "results.h5"  # the results file of a run directory


class ResultFileError(Exception):
    """A file is not a (usable) pdem results file; the message is one line."""

    def __init__(self, path, problem: str):
        super().__init__(f"{path}: {problem}")
        self.path = Path(path)
        self.problem = problem


@dataclass(frozen=True)
class Results:
    """Contents of one results file.

    Attributes
    ----------
    path : Path
    attrs : dict
        Root attributes (``kind``, ``pdem_version``, ``schema_version``, ...).
    scene : dict
        The scene, decoded from the ``scene`` JSON attribute.
    series : dict of str -> ndarray
        Time series, float64, equal length, SI units.
    units : dict of str -> str
        Units of every series.
    cycles : dict of str -> ndarray, or None
        Per-cycle table (fields `pdem.format.schema.CYCLE_FIELDS`), None if the file has none.
    """

    path: Path
    attrs: dict
    scene: dict
    series: dict
    units: dict
    cycles: dict | None

    @property
    def kind(self) -> str:
        return self.attrs["kind"]


def results_file(run_or_file) -> Path:
    """The results file of a run: ``RUN/results.h5`` for a directory, the path itself otherwise."""
    path = Path(run_or_file)
    if path.is_dir():
        inner = path / RESULTS_NAME
        if not inner.is_file():
            raise ResultFileError(path, f"run directory without {RESULTS_NAME}")
        return inner
    return path


class open_results:
    """Context: a results file opened read-only; a missing, non-HDF5 or damaged file (also one
    that fails while read) raises a one-line `ResultFileError`."""

    def __init__(self, path):
        self.path = Path(path)

    def __enter__(self) -> h5py.File:
        if not self.path.is_file():
            raise ResultFileError(self.path, "no such file")
        if not h5py.is_hdf5(self.path):
            raise ResultFileError(self.path, "not an HDF5 file")
        try:
            self.file = h5py.File(self.path, "r")
        except OSError as err:
            raise ResultFileError(self.path, f"unreadable HDF5 ({_first_line(err)})") from None
        return self.file

    def __exit__(self, exc_type, exc, tb):
        self.file.close()
        if isinstance(exc, OSError):  # h5py reports damaged files as OSError
            raise ResultFileError(self.path, f"unreadable HDF5 ({_first_line(exc)})") from None
        return False


def read_results(path, required=REQUIRED_SERIES, lenient=False) -> Results | None:
    """Read and validate a results file.

    Parameters
    ----------
    path : str or Path
        Results file or run directory (`results_file`).
    required : sequence of str
        Series that must be present (``time`` and ``step`` always are).
    lenient : bool
        Give None instead of raising for a file that is missing or not a valid result (e.g.
        a run that stopped before writing one).

    Raises
    ------
    ResultFileError
        Missing file, not HDF5, not a pdem result, unsupported version, missing or malformed
        datasets (not with ``lenient``).
    """
    try:
        path = results_file(path)
        with open_results(path) as f:
            attrs = _read_root_attrs(path, f)
            scene = _decode_scene(path, attrs["scene"])
            required = tuple(dict.fromkeys((*REQUIRED_SERIES, *required)))
            series, units = _read_group(path, f, "series", required, SERIES_UNITS,
                                        kind=attrs["kind"])
            cycles = None
            if "cycles" in f:
                cycles, _ = _read_group(path, f, "cycles", CYCLE_FIELDS, CYCLE_UNITS)
        _check_time(path, series["time"])
    except ResultFileError:
        if lenient:
            return None
        raise
    return Results(path=path, attrs=attrs, scene=scene, series=series, units=units,
                   cycles=cycles)


def read_series(path, required=REQUIRED_SERIES) -> dict:
    """The ``/series`` of a file with the schema tag but no run attributes (``preparation.h5`` of a
    staged run): name -> float64 array."""
    with open_results(path) as f:
        if _plain(f.attrs.get("schema")) != SCHEMA:
            raise ResultFileError(path, "not a pdem result (root attribute 'schema' missing)")
        series, _ = _read_group(path, f, "series", required, SERIES_UNITS)
    return series


def read_finite(path, names, min_samples=2) -> Results:
    """Read a result whose series ``names`` must be present and finite, with at least
    ``min_samples`` samples."""
    results = read_results(path, required=names)
    n = len(results.series["time"])
    if n < min_samples:
        raise ResultFileError(results.path, f"series has {n} sample(s), need at least {min_samples}")
    for name in names:
        if not np.all(np.isfinite(results.series[name])):
            raise ResultFileError(results.path, f"/series/{name} contains non-finite values")
    return results


def read_box_test(path) -> Results:
    """Read a box-test result: the sleeper series must be present, finite and >= 2 samples."""
    return read_finite(path, BOX_SERIES)


def _read_root_attrs(path: Path, f: h5py.File) -> dict:
    if "schema" not in f.attrs:
        raise ResultFileError(path, "not a pdem result (root attribute 'schema' missing)")
    attrs = {k: _plain(v) for k, v in f.attrs.items()}
    if attrs["schema"] != SCHEMA:
        raise ResultFileError(path, f"schema is {attrs['schema']!r}, expected {SCHEMA!r}")
    missing = [k for k in ROOT_ATTRS if k not in attrs]
    if missing:
        raise ResultFileError(path, f"root attribute(s) missing: {', '.join(missing)}")
    version = attrs["schema_version"]
    if not isinstance(version, int) or version > SCHEMA_VERSION or version < 1:
        raise ResultFileError(path, f"schema_version {version!r} not supported "
                                    f"(pdem.format reads 1..{SCHEMA_VERSION})")
    return attrs


def _decode_scene(path: Path, text) -> dict:
    try:
        scene = json.loads(text)
    except (TypeError, ValueError):
        raise ResultFileError(path, "root attribute 'scene' is not JSON text") from None
    if not isinstance(scene, dict):
        raise ResultFileError(path, "root attribute 'scene' is not a JSON object")
    return scene


def _read_group(path, f, group, required, known_units, kind=None):
    """All 1-D numeric datasets of a group as float64, with units; checks names and lengths."""
    if group not in f or not isinstance(f[group], h5py.Group):
        raise ResultFileError(path, f"group /{group} missing")
    g = f[group]
    missing = [name for name in required if name not in g]
    if missing:
        hint = f" (kind is {kind!r})" if kind is not None else ""
        names = ", ".join(f"/{group}/{name}" for name in missing)
        raise ResultFileError(path, f"dataset(s) missing: {names}{hint}")
    data, units = {}, {}
    for name, ds in g.items():
        units[name] = checked_units(path, ds, f"/{group}/{name}", 1, known_units.get(name))
        data[name] = np.asarray(ds[()], dtype=np.float64)
    lengths = {name: len(v) for name, v in data.items()}
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{k}={v}" for k, v in lengths.items())
        raise ResultFileError(path, f"/{group} datasets differ in length ({detail})")
    return data, units


def checked_units(path, ds, where, ndim, expected=None) -> str:
    """The ``units`` attribute of ``ds``, which must be a numeric dataset of rank ``ndim`` (and
    in the ``expected`` units, if given)."""
    if not isinstance(ds, h5py.Dataset) or ds.ndim != ndim:
        raise ResultFileError(path, f"{where} is not a {ndim}-D dataset")
    if not np.issubdtype(ds.dtype, np.number):
        raise ResultFileError(path, f"{where} is not numeric ({ds.dtype})")
    if "units" not in ds.attrs:
        raise ResultFileError(path, f"{where} has no 'units' attribute")
    unit = _plain(ds.attrs["units"])
    if expected is not None and unit != expected:
        raise ResultFileError(path, f"{where} is in {unit!r}, expected {expected!r}")
    return unit


def _check_time(path, time: np.ndarray) -> None:
    if not np.all(np.isfinite(time)):
        raise ResultFileError(path, "/series/time contains non-finite values")
    if np.any(np.diff(time) < 0):
        raise ResultFileError(path, "/series/time decreases")


def _plain(value):
    """HDF5 attribute -> str / int / float / list."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def _first_line(err: Exception) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__
