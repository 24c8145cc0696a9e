"""Readers of the optional result groups: fragments, blast parameters, track, force distributions.

This module owns the validation and reading of the groups `pdem.format.schema` adds to the
version 1 format (``/fragments``, ``/blast``, ``/track``, ``/passages``, ``/forces``). The root
attributes and ``/series`` are read and version-checked by `pdem.format.read.read_results` first,
and the file is opened by `pdem.format.read.open_results`. Everything comes back as numpy arrays
in SI units ([s], [m], [N], [kg], [Pa]); a file that lacks a group or has a malformed one raises
`pdem.format.read.ResultFileError` with one line naming the file and the problem. Imports numpy
and h5py only.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import h5py
import numpy as np

from .read import (ResultFileError, Results, _plain, checked_units, open_results, read_finite, read_results,
                   results_file)
from .schema import (BLAST, BLAST_ATTR_UNITS, BLAST_SERIES, FORCE_UNITS, FORCES,
                     FRAGMENT_REQUIRED, FRAGMENT_UNITS, FRAGMENTS, FRAGMENTS_ATTR_UNITS,
                     PASSAGE_REQUIRED, PASSAGE_SCALARS, PASSAGE_UNITS, PASSAGES, TRACK, TRACK_UNITS)

@dataclass(frozen=True)
class FragmentRecord:
    """One fragment record: the fragments of the sample at one instant.

    Attributes
    ----------
    label : str
    step : int [-]
    time : float [s]
    n_members : ndarray of int64 [-]
        Member spheres of each fragment.
    mass : ndarray [kg]
    clump : ndarray of int64 or None
        Clump id of each fragment (-1: never in a clump), if the file has it.
    n_bonds : int or None
        Intact bonds in the sample, if the file has them (attribute ``n_bonds``).
    """

    label: str
    step: int
    time: float
    n_members: np.ndarray
    mass: np.ndarray
    clump: np.ndarray | None
    n_bonds: int | None = None


@dataclass(frozen=True)
class Fragments:
    """All fragment records of a file, ordered by step, time, label.

    Attributes
    ----------
    results : Results
    density : float [kg/m^3]
    member_radius_min : float [m]
    records : tuple of FragmentRecord
    """

    results: Results
    density: float
    member_radius_min: float
    records: tuple

    def record(self, label: str) -> FragmentRecord:
        for r in self.records:
            if r.label == label:
                return r
        names = ", ".join(r.label for r in self.records)
        raise KeyError(f"no fragment record {label!r} (records: {names})")


@dataclass(frozen=True)
class BlastParameters:
    """``/blast`` attributes: plate_areal_mass [kg/m^2], ceiling_area [m^2], F0 [N], tau [s]."""

    plate_areal_mass: float
    ceiling_area: float
    F0: float
    tau: float


@dataclass(frozen=True)
class TrackRecord:
    """The track groups of a kind "track" file.

    Attributes
    ----------
    results : Results
    sleeper_x : ndarray [n_sleepers] [m]
    settlement, force : ndarray [n_samples, n_sleepers] [m], [N]
    passages : dict of str -> ndarray
        ``passage``, ``t_start``, ``t_end`` [n_passages]; ``settlement_peak``,
        ``settlement_permanent`` and, if present, ``gap`` [n_passages, n_sleepers].
    forces : dict of str -> ForceRecord
        Force distributions by label, ordered by step, time, label.
    """

    results: Results
    sleeper_x: np.ndarray
    settlement: np.ndarray
    force: np.ndarray
    passages: dict
    forces: dict

    @property
    def n_sleepers(self) -> int:
        return len(self.sleeper_x)


@dataclass(frozen=True)
class ForceRecord:
    """One ``/forces/<label>`` record: step [-], time [s], force arrays [N] (None if absent)."""

    label: str
    step: int
    time: float
    sleeper_ballast: np.ndarray | None
    ballast_ballast: np.ndarray | None
    sleeper_index: np.ndarray | None


def read_fragments(path) -> Fragments:
    """Read and validate the ``/fragments`` records of a results file (at least one)."""
    path = results_file(path)
    results = read_results(path)
    with open_results(path) as f:
        if FRAGMENTS not in f or not isinstance(f[FRAGMENTS], h5py.Group):
            raise ResultFileError(path, f"group /{FRAGMENTS} missing (no fragment records; "
                                        f"kind is {results.kind!r})")
        top = f[FRAGMENTS]
        scalars = {name: _positive_attr(path, top, name) for name in FRAGMENTS_ATTR_UNITS}
        _check_units_attr(path, top, FRAGMENTS_ATTR_UNITS)
        records = []
        for label, g in top.items():
            where = f"/{FRAGMENTS}/{label}"
            if not isinstance(g, h5py.Group):
                raise ResultFileError(path, f"{where} is not a group")
            step, time = _step_time(path, g, where)
            data = _datasets(path, g, where, FRAGMENT_REQUIRED, FRAGMENT_UNITS,
                             same_length=True)
            n = data["n_members"]
            if not np.issubdtype(n.dtype, np.integer) or np.any(n < 1):
                raise ResultFileError(path, f"{where}/n_members must be integers >= 1")
            mass = data["mass"].astype(np.float64)
            if not np.all(np.isfinite(mass) & (mass > 0)):
                raise ResultFileError(path, f"{where}/mass must be finite and > 0")
            clump = data.get("clump")
            if clump is not None and not np.issubdtype(clump.dtype, np.integer):
                raise ResultFileError(path, f"{where}/clump must be integers")
            bonds = _plain(g.attrs["n_bonds"]) if "n_bonds" in g.attrs else None
            if bonds is not None and (not isinstance(bonds, int) or bonds < 0):
                raise ResultFileError(path, f"{where}: attribute n_bonds = {bonds!r} must be an integer >= 0")
            records.append(FragmentRecord(label=label, step=step, time=time,
                                          n_members=n.astype(np.int64), mass=mass,
                                          clump=None if clump is None else clump.astype(np.int64),
                                          n_bonds=bonds))
    if not records:
        raise ResultFileError(path, f"group /{FRAGMENTS} holds no records")
    records.sort(key=lambda r: (r.step, r.time, r.label))
    return Fragments(results=results, density=scalars["density"],
                     member_radius_min=scalars["member_radius_min"], records=tuple(records))


def read_blast(path) -> tuple[Results, BlastParameters]:
    """Read a kind "blast" result: its series (finite, >= 2 samples) and ``/blast``."""
    path = results_file(path)
    results = read_finite(path, BLAST_SERIES)
    with open_results(path) as f:
        if BLAST not in f or not isinstance(f[BLAST], h5py.Group):
            raise ResultFileError(path, f"group /{BLAST} missing (kind is {results.kind!r})")
        g = f[BLAST]
        _check_units_attr(path, g, BLAST_ATTR_UNITS)
        params = BlastParameters(**{name: _positive_attr(path, g, name)
                                    for name in BLAST_ATTR_UNITS})
    return results, params


def read_track(path) -> TrackRecord:
    """Read a kind "track" result: ``/track``, ``/passages`` (>= 1 row) and ``/forces``."""
    path = results_file(path)
    results = read_results(path)
    n_samples = len(results.series["time"])
    with open_results(path) as f:
        for group in (TRACK, PASSAGES):
            if group not in f or not isinstance(f[group], h5py.Group):
                raise ResultFileError(path, f"group /{group} missing (kind is {results.kind!r})")
        track = _datasets(path, f[TRACK], f"/{TRACK}", tuple(TRACK_UNITS), TRACK_UNITS,
                          ndims={"sleeper_x": 1, "settlement": 2, "force": 2})
        x = track["sleeper_x"].astype(np.float64)
        n_sleepers = len(x)
        if n_sleepers < 1:
            raise ResultFileError(path, f"/{TRACK}/sleeper_x is empty")
        for name in ("settlement", "force"):
            shape = track[name].shape
            if shape != (n_samples, n_sleepers):
                raise ResultFileError(path, f"/{TRACK}/{name} has shape {shape}, expected "
                                            f"({n_samples}, {n_sleepers}) = (samples in "
                                            f"/series, sleepers)")
        ndims = {name: 1 if name in PASSAGE_SCALARS else 2 for name in PASSAGE_UNITS}
        passages = _datasets(path, f[PASSAGES], f"/{PASSAGES}", PASSAGE_REQUIRED,
                             PASSAGE_UNITS, ndims=ndims)
        n_passages = len(passages["passage"])
        if n_passages < 1:
            raise ResultFileError(path, f"/{PASSAGES} has no rows")
        for name, values in passages.items():
            expected = (n_passages,) if ndims[name] == 1 else (n_passages, n_sleepers)
            if values.shape != expected:
                raise ResultFileError(path, f"/{PASSAGES}/{name} has shape {values.shape}, "
                                            f"expected {expected}")
        forces = _read_forces(path, f, n_sleepers)
    arrays = {"sleeper_x": x, **{k: v.astype(np.float64) for k, v in track.items()
                                 if k != "sleeper_x"},
              **{f"{PASSAGES}/{k}": v.astype(np.float64) for k, v in passages.items()}}
    for name, values in arrays.items():
        if not np.all(np.isfinite(values)):
            group = name if "/" in name else f"{TRACK}/{name}"
            raise ResultFileError(path, f"/{group} contains non-finite values")
    return TrackRecord(results=results, sleeper_x=x, settlement=arrays["settlement"],
                       force=arrays["force"],
                       passages={k: arrays[f"{PASSAGES}/{k}"] for k in passages},
                       forces=forces)


def _read_forces(path, f, n_sleepers) -> dict:
    """``/forces/<label>`` records by label (empty dict if the group is absent)."""
    if FORCES not in f:
        return {}
    records = []
    for label, g in f[FORCES].items():
        where = f"/{FORCES}/{label}"
        if not isinstance(g, h5py.Group):
            raise ResultFileError(path, f"{where} is not a group")
        step, time = _step_time(path, g, where)
        data = _datasets(path, g, where, (), FORCE_UNITS)
        if "sleeper_ballast" not in data and "ballast_ballast" not in data:
            raise ResultFileError(path, f"{where} has neither sleeper_ballast nor "
                                        f"ballast_ballast")
        for name in ("sleeper_ballast", "ballast_ballast"):
            if name in data and not np.all(np.isfinite(data[name]) & (data[name] >= 0)):
                raise ResultFileError(path, f"{where}/{name} must be finite and >= 0")
        idx = data.get("sleeper_index")
        if idx is not None:
            if (not np.issubdtype(idx.dtype, np.integer)
                    or "sleeper_ballast" not in data
                    or idx.shape != data["sleeper_ballast"].shape
                    or np.any((idx < 0) | (idx >= n_sleepers))):
                raise ResultFileError(path, f"{where}/sleeper_index must be sleeper numbers "
                                            f"0..{n_sleepers - 1}, one per sleeper_ballast")
        records.append(ForceRecord(
            label=label, step=step, time=time,
            sleeper_ballast=_as_float(data.get("sleeper_ballast")),
            ballast_ballast=_as_float(data.get("ballast_ballast")),
            sleeper_index=None if idx is None else idx.astype(np.int64)))
    records.sort(key=lambda r: (r.step, r.time, r.label))
    return {r.label: r for r in records}


def _datasets(path, g, where, required, known_units, ndims=None, same_length=False) -> dict:
    """Numeric datasets of a group with checked units and rank (1-D unless `ndims` says);
    with `same_length` all of equal length. Names outside `known_units` are ignored (a newer
    writer may add some)."""
    missing = [name for name in required if name not in g]
    if missing:
        raise ResultFileError(path, "dataset(s) missing: "
                                    + ", ".join(f"{where}/{name}" for name in missing))
    data, length = {}, None
    for name, units in known_units.items():
        if name not in g:
            continue
        checked_units(path, g[name], f"{where}/{name}", (ndims or {}).get(name, 1), units)
        data[name] = g[name][()]
        if same_length:
            if length is not None and len(data[name]) != length[1]:
                raise ResultFileError(path, f"{where} datasets differ in length "
                                            f"({length[0]}={length[1]}, {name}={len(data[name])})")
            length = length or (name, len(data[name]))
    return data


def _step_time(path, g, where) -> tuple[int, float]:
    for name in ("step", "time"):
        if name not in g.attrs:
            raise ResultFileError(path, f"{where} lacks attribute {name!r}")
    step, time = _plain(g.attrs["step"]), _plain(g.attrs["time"])
    if isinstance(step, float) and step.is_integer():
        step = int(step)
    if not isinstance(step, int) or not isinstance(time, (int, float)) or not np.isfinite(time):
        raise ResultFileError(path, f"{where}: attributes step={step!r}, time={time!r} "
                                    f"must be an integer and a finite number")
    return step, float(time)


def _positive_attr(path, g, name) -> float:
    if name not in g.attrs:
        raise ResultFileError(path, f"{g.name} lacks attribute {name!r}")
    value = _plain(g.attrs[name])
    if not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise ResultFileError(path, f"{g.name} attribute {name} = {value!r}, must be > 0")
    return float(value)


def _check_units_attr(path, g, expected: dict) -> None:
    """The group's ``units`` attribute, if present, must agree with the schema."""
    if "units" not in g.attrs:
        return
    try:
        units = json.loads(_plain(g.attrs["units"]))
    except (TypeError, ValueError):
        raise ResultFileError(path, f"{g.name} attribute 'units' is not JSON text") from None
    for name, unit in expected.items():
        if name in units and units[name] != unit:
            raise ResultFileError(path, f"{g.name} attribute {name} is in {units[name]!r}, "
                                        f"expected {unit!r}")


def _as_float(values):
    return None if values is None else np.asarray(values, dtype=np.float64)

