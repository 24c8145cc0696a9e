"""The pdem results file format (HDF5), version 1, and a writer for it.

This module owns the format: names, units and the writers (`write_results` and those of the
optional groups). pdem's driver and scenes write their results with them, `pdem.format.read`
reads them back for `analysis`, and tests use them to make synthetic files. It imports only
numpy and h5py (nothing else of pdem, never analysis, numba, mpi4py or matplotlib).

Layout
------
root attributes
    ``schema`` = "pdem-results", ``schema_version`` = 1, ``scene`` (JSON text),
    ``pdem_version`` (text), ``kind`` (text, e.g. "box_test", "deposition"); optional
    ``external_work`` (int 0/1, written by plain scene runs: 1 if a boundary moves or a load
    acts, so the mechanical energy of /series may grow; 0: it can only fall).
``/series``
    1-D float64 datasets of equal length (one entry per output sample), each with a ``units``
    attribute. Always ``time`` [s] and ``step`` [-]; the box test adds ``sleeper_load`` [N]
    (applied program), ``sleeper_force`` [N] (force of the ballast on the sleeper, positive
    upward), ``sleeper_settlement`` [m] (positive downward, zero at the start of cycling),
    ``sleeper_force_bottom`` and ``sleeper_force_side`` [N] (that force split: on the bottom face,
    on the sides) and ``base_passed`` [-] (spheres below a two-sided base).
``/cycles`` (cyclic tests only)
    1-D float64 datasets, one entry per completed cycle: ``cycle`` [-] (1..N), ``t_start`` [s],
    ``settlement_start``, ``settlement_peak``, ``settlement_end`` [m], ``force_peak``,
    ``force_min`` [N].

Optional groups (added to version 1: a reader that does not know them ignores them, so the
version stays 1). Each group's scalar attributes are listed with units in the group's
``units`` attribute (JSON text, name -> units); every dataset has its own ``units`` attribute.
Attributes ``step`` are integers, ``time`` and the other scalars float64, labels text.

``/fragments`` (any kind with breakable clumps: oedometer, box test, track)
    attrs ``density`` [kg/m^3] (of the ballast material: the equivalent sieve diameter is
    d = (6 m / (pi density))^(1/3)), ``member_radius_min`` [m] (radius of the smallest member
    sphere: the smallest possible fragment, d_min = 2 member_radius_min).
``/fragments/<label>`` (one group per record: at the named stages "initial", "vibrated",
    "peak", "unloaded" or any label, and on schedule as ``fragment_label(step)`` =
    "step_000000120000"; records are ordered by ``step``, then ``time``, then label)
    attrs ``label`` (text, = the group name), ``step`` [-], ``time`` [s], optional ``n_bonds``
    [-] (the intact bonds then; the track writes it: "prepared" and "passage_<p>").
    A fragment is a connected component of clump members over intact bonds: an unbroken clump
    is one fragment, a loose sphere (never in a clump, or broken off) a fragment of 1.
    ``n_members`` int64 [n_fragments] [-], >= 1: member spheres of each fragment;
    ``mass`` float64 [n_fragments] [kg], > 0: its mass (sum of its members' masses);
    ``clump`` int64 [n_fragments] [-], optional: id of the clump the fragment came from
    (-1 for a sphere that was never in a clump); with it the analysis counts intact clumps.
Kind "blast" (SPEC 2.5, blast paper section 3)
    ``/series`` adds ``plate_position`` [m] (vertical coordinate of the cover plate's centre
    of mass, up positive), ``plate_velocity`` [m/s] (vertical, up positive),
    ``ceiling_stress`` [Pa] (sigma_0: total vertical force of the grains on the ceiling divided
    by ``ceiling_area``, compression positive) and ``input_force`` [N] (the applied load
    F(t) = F0 (1 - t/tau) on the plate, downward, as a positive magnitude).
    ``/blast`` (no datasets) attrs ``plate_areal_mass`` [kg/m^2], ``ceiling_area`` [m^2],
    ``F0`` [N], ``tau`` [s].
Kind "oedometer" (SPEC 2.2, thesis ch. 4)
    ``/series`` `OEDOMETER_SERIES`: ``platen_load`` [N] (the applied program, downward, as a
    positive magnitude), ``platen_force`` [N] (force of the ballast on the platen, positive
    upward), ``platen_displacement`` [m] (positive downward, zero when loading starts),
    ``max_overlap_ratio`` [-] (the largest overlap over the smaller radius of its pair);
    by group of contacts in compression (`pdem.driver.observables.overlap_statistics`: ``pair``
    sphere pairs without a bond, ``bond`` intact bonds, ``boundary`` spheres on the base, wall and
    platen) ``<group>_overlap_max`` and ``<group>_overlap_mean`` [-] (the largest and the mean
    overlap over the smaller radius), and ``intact_bonds`` [-];
    ``/fragments`` records "initial", "vibrated", "peak", "unloaded" with breakable clumps.
Kind "shear_box" (`pdem.scenes.shear_box`)
    ``/series`` `SHEAR_BOX_SERIES`: ``shear_displacement`` [m] of the upper frame along x,
    ``shear_force`` [N] (force of the sample resisting it), ``normal_force`` [N] (force of the
    sample on the platen, up), ``platen_z`` [m] (the platen's centre).
Kind "track" (SPEC 2.4). Sleepers are numbered 0..n_sleepers-1 along the track axis.
    pdem writes ``/series`` `TRACK_SERIES` (``applied_load`` [N]: total applied load on the
    sleepers, downward; ``ballast_force`` [N]: total force of the ballast on them, upward;
    ``mean_settlement`` [m]: mean over the sleepers, downward).
    ``/track/sleeper_x`` [n_sleepers] [m]: position of each sleeper's centre along the track;
    ``/track/settlement`` [n_samples, n_sleepers] [m]: settlement of each sleeper (positive
    downward, zero at the start of traffic); ``/track/force`` [n_samples, n_sleepers] [N]:
    force of the ballast on each sleeper (positive upward). Row i belongs to ``/series/time[i]``
    (n_samples = length of ``/series``; both are appended row by row).
    ``/passages`` (one row per passage of a train or axle group, in order):
    ``passage`` [n_passages] [-] (1..N), ``t_start``, ``t_end`` [n_passages] [s];
    ``settlement_peak`` [n_passages, n_sleepers] [m] (largest settlement during the passage),
    ``settlement_permanent`` [n_passages, n_sleepers] [m] (settlement at the end of the
    passage, unloaded), ``gap`` [n_passages, n_sleepers] [m], optional (void under the sleeper
    at the end of the passage: the vertical distance the unloaded sleeper could move down
    before touching the ballast, i.e. from its base to the top of the highest grain under its
    footprint; 0 where it rests on the ballast); ``load_peak`` [n_passages, n_sleepers] [N],
    optional (the largest load of the rail on the sleeper during the passage, downward: written
    when the rail is a beam, whose load on each sleeper depends on the bed).
``/forces/<label>`` (contact force distributions at named instants, e.g. "peak_passage_1",
    any kind) attrs ``label``, ``step`` [-], ``time`` [s]; at least one of
    ``sleeper_ballast`` [n_contacts] [N] (normal force of each sleeper-ballast contact) and
    ``ballast_ballast`` [n_contacts] [N] (magnitude of the total force of each grain-grain
    contact); optional ``sleeper_index`` int64 [-] (the sleeper of each sleeper-ballast
    contact, same length as ``sleeper_ballast``).

The writers of these groups (`write_fragments`, `write_blast_parameters`, `write_track`,
`append_track_rows`, `append_passages`, `write_forces`) take an open ``h5py.File`` or the path
of an existing results file (made by `write_results`) and add to it in place. A run resumed
from a checkpoint writes a record again with ``replace=True``, and cuts the ``/track`` rows
and ``/passages`` rows written after the checkpoint as it cuts ``/series``: the readers
require ``/track`` to have exactly one row per ``/series`` sample.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Mapping

import h5py
import numpy as np

SCHEMA = "pdem-results"
SCHEMA_VERSION = 1
ROOT_ATTRS = ("schema", "schema_version", "scene", "pdem_version", "kind")

# Units of every dataset name the schema defines [SI].
SERIES_UNITS = {
    "time": "s",
    "step": "-",
    "sleeper_load": "N",
    "sleeper_force": "N",
    "sleeper_settlement": "m",
    "plate_position": "m",
    "plate_velocity": "m/s",
    "ceiling_stress": "Pa",
    "input_force": "N",
    "platen_load": "N",
    "platen_force": "N",
    "platen_displacement": "m",
}
CYCLE_UNITS = {
    "cycle": "-",
    "t_start": "s",
    "settlement_start": "m",
    "settlement_peak": "m",
    "settlement_end": "m",
    "force_peak": "N",
    "force_min": "N",
}
# Optional per-cycle columns pdem writes too: the extremes of the applied load and the step at
# which the cycle was recorded.
# The box test adds (pdem.scenes.box_test): the settlement at the sample of the largest ballast
# force and the largest settlement in the cycle (from the same zero as the others), the ballast
# force on the sleeper's bottom face and on its sides (friction) at the peak sample, and the
# spheres below a two-sided base at the cycle's end.
CYCLE_OPTIONAL_UNITS = {"load_max": "N", "load_min": "N", "step": "-", "settlement_at_force_max": "m",
                        "settlement_max": "m", "force_bottom_peak": "N", "force_side_peak": "N",
                        "base_passed_end": "-"}

# What pdem's runs write (the driver and the scenes import these):
# a plain run's energies are those of `pdem.checks.diagnostics.energy`: kinetic_energy is translational +
# rotational, potential_energy = -sum m g.x (zero at the origin), total_energy = kinetic +
# potential + elastic; max_overlap_ratio is the largest overlap over the smaller radius [-].
# /series of a plain scene run (kind "scene"), the box test's load record (kind "box_test"),
# its preparation record (preparation.h5, kind "preparation") and the /cycles table.
RUN_SERIES = {"step": "-", "time": "s", "dt": "s", "kinetic_energy": "J", "elastic_energy": "J",
              "contacts_per_particle": "-", "unbalanced_force": "-", "bed_top": "m", "floor_force_z": "N",
              "potential_energy": "J", "total_energy": "J", "max_overlap_ratio": "-"}
BOX_TEST_SERIES = {"step": "-", "time": "s", "dt": "s", "sleeper_load": "N", "sleeper_force": "N",
                   "sleeper_settlement": "m", "kinetic_energy": "J", "contacts_per_particle": "-",
                   "sleeper_force_bottom": "N", "sleeper_force_side": "N", "base_passed": "-"}
# the track section's /series (kind "track"; its per-sleeper rows are /track): total applied
# load on the sleepers [N, down], total ballast force on them [N, up], mean settlement [m, down]
TRACK_SERIES = {"step": "-", "time": "s", "dt": "s", "applied_load": "N", "ballast_force": "N",
                "mean_settlement": "m", "kinetic_energy": "J", "contacts_per_particle": "-"}
PREPARATION_SERIES = {"step": "-", "time": "s", "stage": "-", "n_spheres": "-", "kinetic_energy": "J",
                      "unbalanced_force": "-", "contacts_per_particle": "-", "bed_top": "m", "sleeper_z": "m"}
# the oedometer's load record (kind "oedometer", pdem.scenes.oedometer)
OEDOMETER_SERIES = {"step": "-", "time": "s", "dt": "s", "platen_load": "N", "platen_force": "N",
                    "platen_displacement": "m", "kinetic_energy": "J", "contacts_per_particle": "-",
                    "max_overlap_ratio": "-", "pair_overlap_max": "-", "pair_overlap_mean": "-",
                    "bond_overlap_max": "-", "bond_overlap_mean": "-", "boundary_overlap_max": "-",
                    "boundary_overlap_mean": "-", "intact_bonds": "-"}
# the direct shear box's record (kind "shear_box", pdem.scenes.shear_box)
SHEAR_BOX_SERIES = {"step": "-", "time": "s", "dt": "s", "shear_displacement": "m", "shear_force": "N",
                    "normal_force": "N", "platen_z": "m"}
# the blast run's record (kind "blast", pdem.scenes.blast): time 0 at the start of the impulse
BLAST_RUN_SERIES = {"step": "-", "time": "s", "dt": "s", "plate_position": "m", "plate_velocity": "m/s",
                    "ceiling_stress": "Pa", "input_force": "N", "kinetic_energy": "J"}
CYCLE_COLUMNS = {**CYCLE_UNITS, **CYCLE_OPTIONAL_UNITS}
REQUIRED_SERIES = ("time", "step")
BOX_SERIES = ("sleeper_load", "sleeper_force", "sleeper_settlement")
CYCLE_FIELDS = tuple(CYCLE_UNITS)


def write_results(path, series: Mapping, cycles: Mapping | None, attrs: Mapping) -> Path:
    """Write a pdem results file, atomically (temporary file, then rename).

    Parameters
    ----------
    path : str or Path
        File to write; replaced if it exists.
    series : mapping name -> array or (array, units)
        Time series of equal length; ``time`` and ``step`` are required. Names in
        `SERIES_UNITS` take their units from there; other names must come as (array, units).
    cycles : mapping name -> array, or None
        Per-cycle table with all of `CYCLE_FIELDS`, or None for non-cyclic runs.
    attrs : mapping
        ``scene`` (dict, written as JSON, or JSON text), ``pdem_version`` and ``kind``.
        ``schema`` and ``schema_version`` are set here.

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    series_data = _prepare(series, SERIES_UNITS, "series")
    missing = [name for name in REQUIRED_SERIES if name not in series_data]
    if missing:
        raise ValueError(f"series lacks {', '.join(missing)}")
    cycle_data = None
    if cycles is not None:
        cycle_data = _prepare(cycles, CYCLE_UNITS, "cycles")
        missing = [name for name in CYCLE_FIELDS if name not in cycle_data]
        if missing:
            raise ValueError(f"cycles lacks {', '.join(missing)}")
    root = _root_attrs(attrs)

    tmp = path.with_name(path.name + ".tmp")
    with h5py.File(tmp, "w") as f:
        f.attrs.update(root)
        _write_group(f.create_group("series"), series_data)
        if cycle_data is not None:
            _write_group(f.create_group("cycles"), cycle_data)
    os.replace(tmp, path)
    return path


def _root_attrs(attrs: Mapping) -> dict:
    """Root attributes with the schema tag; the scene as JSON text."""
    missing = [k for k in ("scene", "pdem_version", "kind") if k not in attrs]
    if missing:
        raise ValueError(f"attrs lacks {', '.join(missing)}")
    scene = attrs["scene"]
    if not isinstance(scene, str):
        scene = json.dumps(scene, sort_keys=True)
    root = {k: v for k, v in attrs.items() if k not in ("schema", "schema_version")}
    root.update(schema=SCHEMA, schema_version=SCHEMA_VERSION, scene=scene,
                pdem_version=str(attrs["pdem_version"]), kind=str(attrs["kind"]))
    return root


def _prepare(data: Mapping, known_units: Mapping, group: str) -> dict:
    """name -> (float64 1-D array, units); all of equal length."""
    out = {}
    for name, value in data.items():
        if isinstance(value, tuple):
            values, units = value
        elif name in known_units:
            values, units = value, known_units[name]
        else:
            raise ValueError(f"{group}/{name}: units unknown, pass (array, units)")
        values = np.asarray(values, dtype=np.float64)
        if values.ndim != 1:
            raise ValueError(f"{group}/{name}: must be 1-D, got shape {values.shape}")
        out[name] = (values, str(units))
    lengths = {len(v) for v, _ in out.values()}
    if len(lengths) > 1:
        raise ValueError(f"{group}: datasets differ in length {sorted(lengths)}")
    return out


def _write_group(group: h5py.Group, data: dict) -> None:
    for name, (values, units) in data.items():
        ds = group.create_dataset(name, data=values)
        ds.attrs["units"] = units


# --- Optional groups: fragments, blast, track, force distributions (layout in the docstring) ---

FRAGMENTS = "fragments"
FRAGMENTS_ATTR_UNITS = {"density": "kg/m^3", "member_radius_min": "m"}
FRAGMENT_UNITS = {"n_members": "-", "mass": "kg", "clump": "-"}
FRAGMENT_REQUIRED = ("n_members", "mass")
RECORD_ATTR_UNITS = {"step": "-", "time": "s"}

BLAST = "blast"
BLAST_SERIES = ("plate_position", "plate_velocity", "ceiling_stress", "input_force")
BLAST_ATTR_UNITS = {"plate_areal_mass": "kg/m^2", "ceiling_area": "m^2", "F0": "N", "tau": "s"}

TRACK = "track"
TRACK_UNITS = {"sleeper_x": "m", "settlement": "m", "force": "N"}
PASSAGES = "passages"
PASSAGE_UNITS = {"passage": "-", "t_start": "s", "t_end": "s", "settlement_peak": "m",
                 "settlement_permanent": "m", "gap": "m", "load_peak": "N",
                 # turning sleepers (track.sleeper_rotation): at the end of the passage, per end of the
                 # sleeper body along its own y axis (lo, hi), and the beam's load share in the passage
                 "settlement_lo": "m", "settlement_hi": "m", "tilt_x": "rad", "tilt_y": "rad",
                 "gap_lo": "m", "gap_hi": "m", "load_share": "-",
                 # the passage's energy ledger (one value per passage): the work of the loads on the
                 # sleepers and the change of the mechanical energy of sleepers and ballast
                 "load_work": "J", "energy_change": "J"}
PASSAGE_OPTIONAL = ("gap", "load_peak", "settlement_lo", "settlement_hi", "tilt_x", "tilt_y", "gap_lo", "gap_hi",
                    "load_share", "load_work", "energy_change")
PASSAGE_SCALARS = ("passage", "t_start", "t_end", "load_work", "energy_change")  # one value per passage
PASSAGE_REQUIRED = ("passage", "t_start", "t_end", "settlement_peak", "settlement_permanent")

FORCES = "forces"
FORCE_UNITS = {"sleeper_ballast": "N", "ballast_ballast": "N", "sleeper_index": "-"}


def fragment_label(step: int) -> str:
    """Label of a scheduled fragment record: ``step_`` and the step in 12 digits."""
    return f"step_{int(step):012d}"


def write_fragments(target, label: str, n_members, mass, *, step: int, time: float,
                    density: float, member_radius_min: float, clump=None,
                    replace: bool = False, n_bonds: int | None = None) -> str:
    """Add one fragment record ``/fragments/<label>`` to a results file.

    Parameters
    ----------
    target : h5py.File or str or Path
        Open results file, or the path of one made by `write_results`.
    label : str
        Record name: a stage ("initial", "vibrated", "peak", "unloaded", ...) or
        ``fragment_label(step)``; no "/".
    n_members : array of int [-]
        Member spheres of each fragment, >= 1.
    mass : array [kg]
        Mass of each fragment, > 0.
    step : int [-]
    time : float [s]
    density : float [kg/m^3]
        Density of the ballast material (the same for every record of a file).
    member_radius_min : float [m]
        Radius of the smallest member sphere.
    clump : array of int, optional
        Id of each fragment's clump, -1 for spheres never in a clump.
    replace : bool
        Replace a record of the same label (a resumed run writing it again).
    n_bonds : int, optional
        Intact bonds in the sample [-] (attribute ``n_bonds``; the track writes it).

    Returns
    -------
    str
        The HDF5 path of the record.
    """
    label = _label(label)
    n = np.asarray(n_members)
    if n.ndim != 1 or not np.issubdtype(n.dtype, np.integer) or np.any(n < 1):
        raise ValueError("n_members must be a 1-D integer array, every entry >= 1")
    m = _float_1d(mass, "mass", len(n))
    if not np.all(np.isfinite(m) & (m > 0)):
        raise ValueError("mass must be finite and > 0")
    data = {"n_members": n.astype(np.int64), "mass": m}
    if clump is not None:
        c = np.asarray(clump)
        if c.shape != n.shape or not np.issubdtype(c.dtype, np.integer):
            raise ValueError("clump must be an integer array as long as n_members")
        data["clump"] = c.astype(np.int64)
    scalars = {"density": float(density), "member_radius_min": float(member_radius_min)}
    if not all(np.isfinite(v) and v > 0 for v in scalars.values()):
        raise ValueError(f"density and member_radius_min must be finite and > 0: {scalars}")
    with _opened(target) as f:
        top = f.require_group(FRAGMENTS)
        for name, value in scalars.items():
            if name in top.attrs and not np.isclose(top.attrs[name], value, rtol=1e-12):
                raise ValueError(f"/{FRAGMENTS} has {name} = {top.attrs[name]}, not {value}")
        top.attrs.update(scalars)
        top.attrs["units"] = json.dumps(FRAGMENTS_ATTR_UNITS)
        g = _new_group(top, label, replace)
        units = dict(RECORD_ATTR_UNITS)
        if n_bonds is not None:
            if int(n_bonds) < 0:
                raise ValueError(f"n_bonds = {n_bonds}: must be >= 0")
            g.attrs["n_bonds"] = np.int64(n_bonds)
            units["n_bonds"] = "-"
        g.attrs.update(label=label, step=np.int64(step), time=float(time), units=json.dumps(units))
        for name, values in data.items():
            g.create_dataset(name, data=values).attrs["units"] = FRAGMENT_UNITS[name]
        return g.name


def write_blast_parameters(target, *, plate_areal_mass: float, ceiling_area: float,
                           F0: float, tau: float) -> str:
    """Write the ``/blast`` group (the plate and the load) of a kind "blast" results file.

    Parameters
    ----------
    target : h5py.File or str or Path
    plate_areal_mass : float [kg/m^2]
        Mass of the cover plate per unit area.
    ceiling_area : float [m^2]
        Area that ``ceiling_stress`` is divided by.
    F0 : float [N]
        Initial value of the impulse load F(t) = F0 (1 - t/tau), 0 <= t <= tau.
    tau : float [s]
        Duration of the impulse load.
    """
    values = dict(plate_areal_mass=plate_areal_mass, ceiling_area=ceiling_area, F0=F0, tau=tau)
    values = {k: float(v) for k, v in values.items()}
    if not all(np.isfinite(v) and v > 0 for v in values.values()):
        raise ValueError(f"blast parameters must be finite and > 0: {values}")
    with _opened(target) as f:
        g = f.require_group(BLAST)
        g.attrs.update(values)
        g.attrs["units"] = json.dumps(BLAST_ATTR_UNITS)
        return g.name


def write_track(target, sleeper_x) -> str:
    """Create ``/track`` with the sleeper positions and empty per-sleeper series.

    Rows are added with `append_track_rows`, one per ``/series`` sample.

    Parameters
    ----------
    target : h5py.File or str or Path
    sleeper_x : array [m]
        Position of each sleeper's centre along the track axis.
    """
    x = _float_1d(sleeper_x, "sleeper_x")
    if len(x) < 1 or not np.all(np.isfinite(x)):
        raise ValueError("sleeper_x must hold at least one finite position")
    with _opened(target) as f:
        if TRACK in f:
            raise ValueError(f"/{TRACK} exists already")
        g = f.create_group(TRACK)
        g.create_dataset("sleeper_x", data=x).attrs["units"] = TRACK_UNITS["sleeper_x"]
        for name in ("settlement", "force"):
            ds = g.create_dataset(name, shape=(0, len(x)), maxshape=(None, len(x)),
                                  dtype=np.float64, chunks=(256, len(x)))
            ds.attrs["units"] = TRACK_UNITS[name]
        return g.name


def append_track_rows(target, settlement, force) -> int:
    """Append rows to ``/track/settlement`` [m] and ``/track/force`` [N].

    Parameters
    ----------
    target : h5py.File or str or Path
    settlement, force : array [n_rows, n_sleepers] (or [n_sleepers] for one row)

    Returns
    -------
    int
        Number of rows now stored.
    """
    with _opened(target) as f:
        if TRACK not in f:
            raise ValueError(f"/{TRACK} missing: call write_track first")
        g = f[TRACK]
        n_sleepers = g["sleeper_x"].shape[0]
        rows = {name: _rows(value, name, n_sleepers)
                for name, value in (("settlement", settlement), ("force", force))}
        if len(rows["settlement"]) != len(rows["force"]):
            raise ValueError("settlement and force differ in number of rows")
        for name, values in rows.items():
            _append(g[name], values)
        return g["settlement"].shape[0]


def append_passages(target, t_start, t_end, settlement_peak, settlement_permanent,
                    gap=None, load_peak=None, **more) -> int:
    """Append rows (passages) to the ``/passages`` table, creating it on the first call.

    Parameters
    ----------
    target : h5py.File or str or Path
    t_start, t_end : float or array [n] [s]
    settlement_peak, settlement_permanent : array [n, n_sleepers] (or [n_sleepers]) [m]
    gap : array [n, n_sleepers] (or [n_sleepers]) [m], optional
        Void under each sleeper; either always given or never.
    load_peak : array [n, n_sleepers] (or [n_sleepers]) [N], optional
        Largest rail load on each sleeper in the passage; either always given or never.
    **more : array [n, n_sleepers] (or [n_sleepers]), or [n] (or a float) for `PASSAGE_SCALARS`
        Any other table of `PASSAGE_OPTIONAL` (turning sleepers: ``settlement_lo``,
        ``settlement_hi`` [m], ``tilt_x``, ``tilt_y`` [rad], ``gap_lo``, ``gap_hi`` [m],
        ``load_share`` [-]; the energy ledger: ``load_work``, ``energy_change`` [J]); each
        either always given or never.

    Returns
    -------
    int
        Number of passages now stored.
    """
    t0, t1 = np.atleast_1d(np.asarray(t_start, float)), np.atleast_1d(np.asarray(t_end, float))
    if t0.ndim != 1 or t0.shape != t1.shape or np.any(t1 < t0):
        raise ValueError("t_start, t_end must be equal-length 1-D with t_end >= t_start")
    with _opened(target) as f:
        if TRACK not in f:
            raise ValueError(f"/{TRACK} missing: call write_track first")
        n_sleepers = f[TRACK]["sleeper_x"].shape[0]
        tables = {"settlement_peak": settlement_peak,
                  "settlement_permanent": settlement_permanent}
        if gap is not None:
            tables["gap"] = gap
        if load_peak is not None:
            tables["load_peak"] = load_peak
        for name, value in more.items():
            if name not in PASSAGE_OPTIONAL:
                raise ValueError(f"/{PASSAGES}/{name}: not a passage table ({', '.join(PASSAGE_OPTIONAL)})")
            if value is not None:
                tables[name] = value
        rows = {k: np.atleast_1d(np.asarray(v, float)) if k in PASSAGE_SCALARS else _rows(v, k, n_sleepers)
                for k, v in tables.items()}
        if any(len(v) != len(t0) for v in rows.values()):
            raise ValueError("passage tables must have one row per t_start")
        g = f.get(PASSAGES)
        if g is None:
            g = f.create_group(PASSAGES)
            for name in ("passage", "t_start", "t_end"):
                ds = g.create_dataset(name, shape=(0,), maxshape=(None,), dtype=np.float64)
                ds.attrs["units"] = PASSAGE_UNITS[name]
            for name in rows:
                shape = (0,) if name in PASSAGE_SCALARS else (0, n_sleepers)
                ds = g.create_dataset(name, shape=shape, maxshape=(None, *shape[1:]), dtype=np.float64)
                ds.attrs["units"] = PASSAGE_UNITS[name]
        elif any((name in g) != (name in rows) for name in PASSAGE_OPTIONAL):
            raise ValueError(f"{', '.join(PASSAGE_OPTIONAL)} must each be given for every passage or for none")
        done = g["passage"].shape[0]
        _append(g["passage"], np.arange(done + 1, done + len(t0) + 1, dtype=np.float64))
        _append(g["t_start"], t0)
        _append(g["t_end"], t1)
        for name, values in rows.items():
            _append(g[name], values)
        return g["passage"].shape[0]


def write_forces(target, label: str, *, step: int, time: float, sleeper_ballast=None,
                 ballast_ballast=None, sleeper_index=None, replace: bool = False) -> str:
    """Add one contact force distribution ``/forces/<label>``.

    Parameters
    ----------
    target : h5py.File or str or Path
    label : str
        Name of the instant, e.g. "peak_passage_1".
    step : int [-]
    time : float [s]
    sleeper_ballast : array [N], optional
        Normal force of each sleeper-ballast contact.
    ballast_ballast : array [N], optional
        Magnitude of the force of each grain-grain contact.
    sleeper_index : array of int [-], optional
        Sleeper of each sleeper-ballast contact.
    replace : bool
        Replace a record of the same label.
    """
    label = _label(label)
    data = {}
    for name, values in (("sleeper_ballast", sleeper_ballast),
                         ("ballast_ballast", ballast_ballast)):
        if values is not None:
            v = _float_1d(values, name)
            if not np.all(np.isfinite(v) & (v >= 0)):
                raise ValueError(f"{name} must be finite and >= 0")
            data[name] = v
    if not data:
        raise ValueError("give sleeper_ballast, ballast_ballast or both")
    if sleeper_index is not None:
        idx = np.asarray(sleeper_index)
        if "sleeper_ballast" not in data or idx.shape != data["sleeper_ballast"].shape \
                or not np.issubdtype(idx.dtype, np.integer):
            raise ValueError("sleeper_index must be an integer array as long as sleeper_ballast")
        data["sleeper_index"] = idx.astype(np.int64)
    with _opened(target) as f:
        g = _new_group(f.require_group(FORCES), label, replace)
        g.attrs.update(label=label, step=np.int64(step), time=float(time),
                       units=json.dumps(RECORD_ATTR_UNITS))
        for name, values in data.items():
            g.create_dataset(name, data=values).attrs["units"] = FORCE_UNITS[name]
        return g.name


class _opened:
    """Context: an open h5py.File as is, or a results file path opened for appending."""

    def __init__(self, target):
        self.target, self.file = target, None

    def __enter__(self) -> h5py.File:
        if isinstance(self.target, h5py.File):
            return self.target
        path = Path(self.target)
        if not path.is_file():
            raise ValueError(f"{path}: no such results file (make it with write_results)")
        self.file = h5py.File(path, "r+")
        if self.file.attrs.get("schema") != SCHEMA:
            self.file.close()
            raise ValueError(f"{path}: not a pdem results file")
        return self.file

    def __exit__(self, *exc):
        if self.file is not None:
            self.file.close()
        return False


def _label(label) -> str:
    label = str(label)
    if not label or "/" in label or label in (".", ".."):
        raise ValueError(f"label {label!r}: must be a non-empty name without '/'")
    return label


def _new_group(parent: h5py.Group, name: str, replace: bool) -> h5py.Group:
    if name in parent:
        if not replace:
            raise ValueError(f"{parent.name}/{name} exists already (pass replace=True)")
        del parent[name]
    return parent.create_group(name)


def _float_1d(values, name, length=None) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {v.shape}")
    if length is not None and len(v) != length:
        raise ValueError(f"{name} has {len(v)} entries, expected {length}")
    return v


def _rows(values, name, n_columns) -> np.ndarray:
    v = np.asarray(values, dtype=np.float64)
    if v.ndim == 1:
        v = v[None, :]
    if v.ndim != 2 or v.shape[1] != n_columns:
        raise ValueError(f"{name} must have {n_columns} column(s) (one per sleeper), "
                         f"got shape {v.shape}")
    return v


def _append(ds: h5py.Dataset, values: np.ndarray) -> None:
    n = ds.shape[0]
    ds.resize(n + len(values), axis=0)
    ds[n:] = values
