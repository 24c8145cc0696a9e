"""Snapshots for ParaView: one HDF5 file per run plus XDMF indexes beside it.

Owns the snapshot layout and its writer. Ranks pass their owned particles; rank 0 gathers them
(``comm.gather_rows``), orders them by gid and writes, with the blocks (`Block`: walls, facets,
boxes, the contact network) the caller hands to rank 0; the XDMF files are then rebuilt from the
HDF5 file's complete snapshots and replaced atomically, so ParaView never sees a half-written
index. What goes into the fields and blocks is the driver's business (`pdem.driver.snapshots`).
Must not import mpi4py nor pdem physics modules.

Layout (schema ``pdem-snapshots``, version 1; the blocks and extra fields are optional, so a
file without them is the layout as first written)::

    snapshots.h5
      attrs  schema="pdem-snapshots", schema_version=1
      step_000000000100/           attrs: step (int64), time [s], n_particles, fields (JSON list),
                                          complete=1 (written last)
        position     float64[n, 3]  [m]     rows ordered by gid
        radius       float64[n]     [m]
        velocity     float64[n, 3]  [m/s]
        gid          int64[n]
        connectivity int32[n, 1]    0..n-1 (Polyvertex topology for XDMF readers; compressed)
        <field>      [n] or [n, 3]  extra per-particle fields (force, angvel, body_kind ...)
        <block>/                    attrs: topology (XDMF TopologyType), fields (JSON list),
                                           on_particles (1: the cells join particle rows)
          points       float64[m, 3] [m]   the block's vertices (absent when on_particles)
          connectivity int32[k, v]         vertex indices of each cell (rows of ``position``
                                           when on_particles)
          <field>      [k] or [k, 3]       per-cell fields
    snapshots.xmf                  XDMF 3: one temporal collection of Polyvertex grids, one per
                                   snapshot, referencing the datasets above by relative path
                                   ("snapshots.h5:/step_000000000100/position"); attributes
                                   position, radius, velocity, gid and the extra fields, on nodes.
    snapshots_<block>.xmf          the same for each block found in the file: one temporal
                                   collection of the block's cells (attributes on cells; the
                                   vertices' ``position`` on nodes).

One temporal collection per file: meshio's ``xdmf.TimeSeriesReader`` reads one collection and
takes its mesh from the first step, so each step also carries its vertices as the node attribute
``position`` (a second reference to the same dataset, no extra data): ``read_data(k)`` gives
step k's positions and fields. Open ``snapshots.xmf`` in ParaView (Xdmf3 reader) and render the
points with the Point Gaussian representation scaled by ``radius``, or apply a Glyph filter
(sphere, scale by radius, factor 2); open the block files beside it (docs/snapshots.md).
"""

from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from pdem.io._h5 import one_line, open_h5, open_tagged
from pdem.io.atomic import atomic_write_text

SCHEMA = "pdem-snapshots"
SCHEMA_VERSION = 1
_GROUP_RE = re.compile(r"^step_(\d{12})$")
_BASE = ("position", "radius", "velocity", "gid")
# XDMF topology -> vertices per cell (the blocks' cell shapes)
TOPOLOGIES = {"Polyline": 2, "Triangle": 3, "Quadrilateral": 4, "Hexahedron": 8}
_BLOCK_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")

__all__ = ["Block", "SnapshotError", "SnapshotWriteError", "SnapshotWriter", "block_xmf_path", "write_xdmf"]


class SnapshotError(RuntimeError):
    """A snapshot cannot be written; the message is one line: ``<file>: <what>``."""

    def __init__(self, path, reason: str):
        self.path = Path(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"{self.path.name}: {self.reason}")


class SnapshotWriteError(SnapshotError):
    """The system failed a snapshot write (disk full, file system gone, out of memory): raised on
    every rank, exit status 5 like a failed checkpoint write (`pdem.driver.failures.classify`)."""


@dataclass
class Block:
    """Cells written beside the particles of a snapshot (walls, facets, boxes, contacts).

    ``topology`` is a key of `TOPOLOGIES`; ``cells`` [k, vertices per cell] are indices into
    ``points`` [m, 3] [m], or, with ``points`` None, particle gids (the cells join particle
    centres, e.g. the contact network); ``cell_fields`` name -> [k] or [k, 3] numbers.
    """

    topology: str
    cells: np.ndarray
    points: np.ndarray | None = None
    cell_fields: dict = field(default_factory=dict)


def _group_name(step: int) -> str:
    return f"step_{int(step):012d}"


def block_xmf_path(xmf_path, block: str) -> Path:
    """The XDMF index of ``block`` beside the particles' index ``xmf_path``."""
    xmf_path = Path(xmf_path)
    return xmf_path.with_name(f"{xmf_path.stem}_{block}{xmf_path.suffix}")


def _xdmf_type(dtype: np.dtype) -> tuple[str, str]:
    kind = {"f": "Float", "i": "Int", "u": "UInt"}[dtype.kind]
    return kind, str(dtype.itemsize)


def _data_item(parent, h5_name: str, ds) -> None:
    number_type, precision = _xdmf_type(ds.dtype)
    item = ET.SubElement(
        parent, "DataItem", Dimensions=" ".join(str(d) for d in ds.shape),
        NumberType=number_type, Precision=precision, Format="HDF",
    )
    item.text = f"{h5_name}:{ds.name}"


def _grid(series, name, time, rel, topology, conn, points, attributes, center) -> None:
    """One uniform grid of a temporal collection: its topology ``conn`` [k, v] on the vertices
    ``points`` [m, 3], the vertices again as the node attribute ``position`` and ``attributes``
    (HDF5 datasets) centred on ``center``."""
    grid = ET.SubElement(series, "Grid", Name=name, GridType="Uniform")
    ET.SubElement(grid, "Time", Value=repr(float(time)))
    topo = ET.SubElement(grid, "Topology", TopologyType=topology, NumberOfElements=str(conn.shape[0]),
                         NodesPerElement=str(conn.shape[1]))
    _data_item(topo, rel, conn)
    geom = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
    _data_item(geom, rel, points)
    for ds, where in [(points, "Node")] + [(a, center) for a in attributes]:
        kind = "Vector" if ds.ndim == 2 and ds.shape[1] == 3 else "Scalar"
        attr = ET.SubElement(grid, "Attribute", Name="position" if ds is points else ds.name.rsplit("/", 1)[1],
                             AttributeType=kind, Center=where)
        _data_item(attr, rel, ds)


def _write_index(root, xmf_path) -> None:
    ET.indent(root)
    atomic_write_text(xmf_path, '<?xml version="1.0" ?>\n' + ET.tostring(root, encoding="unicode") + "\n")


def _collection(name):
    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    return root, ET.SubElement(domain, "Grid", Name=name, GridType="Collection", CollectionType="Temporal")


def write_xdmf(h5_path, xmf_path) -> int:
    """Rebuild the XDMF indexes of every complete snapshot in ``h5_path``: the particles' in
    ``xmf_path`` and each block's in `block_xmf_path` (an index of a block no snapshot holds is
    removed); returns the number of snapshots.

    The HDF5 path inside the XDMF files is relative to their directory (both files normally sit
    side by side, so the run directory can be moved).
    """
    h5_path, xmf_path = Path(h5_path), Path(xmf_path)
    rel = Path(os.path.relpath(h5_path.resolve(), xmf_path.parent.resolve())).as_posix()
    root, series = _collection("particles")
    blocks = {}  # name -> (root, collection)
    count = 0
    with open_h5(h5_path, "r") as f:
        for name in sorted(n for n in f if _GROUP_RE.match(n)):
            g = f[name]
            if int(g.attrs.get("complete", 0)) != 1:
                continue
            time = g.attrs["time"]
            fields = ["radius", "velocity", "gid"] + json.loads(g.attrs.get("fields", "[]"))
            _grid(series, name, time, rel, "Polyvertex", g["connectivity"], g["position"], [g[k] for k in fields],
                  "Node")
            for bname in sorted(k for k, v in g.items() if isinstance(v, h5py.Group)):
                b = g[bname]
                if bname not in blocks:
                    blocks[bname] = _collection(bname)
                points = g["position"] if int(b.attrs.get("on_particles", 0)) else b["points"]
                _grid(blocks[bname][1], name, time, rel, str(b.attrs["topology"]), b["connectivity"], points,
                      [b[k] for k in json.loads(b.attrs.get("fields", "[]"))], "Cell")
            count += 1
    _write_index(root, xmf_path)
    for bname, (broot, _) in blocks.items():
        _write_index(broot, block_xmf_path(xmf_path, bname))
    for stale in _block_indexes(xmf_path):
        if stale not in [block_xmf_path(xmf_path, b) for b in blocks]:
            stale.unlink(missing_ok=True)
    return count


class SnapshotWriter:
    """Write snapshots to ``<directory>/snapshots.h5`` and index them in ``snapshots.xmf`` (and
    ``snapshots_<block>.xmf`` per block).

    Parameters
    ----------
    directory : path
        Run output directory (created if missing).
    comm : Comm, optional
        ``rank``, ``gather_rows``, ``bcast``, ``any_flag``; None means this process holds every
        particle.
    append : bool
        False: start afresh (existing snapshot files are replaced). True: continue after a restart.
    restart_step : int, optional
        With ``append``: snapshots with a step above it are removed first.
    log : callable
        Receives one line if an unreadable snapshot file is moved aside on ``append``.
    """

    def __init__(self, directory, comm=None, append=False, restart_step=None, log=print,
                 h5_name="snapshots.h5", xmf_name="snapshots.xmf"):
        self.directory = Path(directory)
        self.comm = comm
        self.h5_path = self.directory / h5_name
        self.xmf_path = self.directory / xmf_name
        if self._rank0:
            self.directory.mkdir(parents=True, exist_ok=True)
            if not append:
                self.h5_path.unlink(missing_ok=True)
                for path in self._block_indexes():
                    path.unlink(missing_ok=True)
                self.xmf_path.unlink(missing_ok=True)
            elif self.h5_path.exists():
                self._prepare_append(restart_step, log)
            else:
                self.xmf_path.unlink(missing_ok=True)  # an index without its data
                for path in self._block_indexes():
                    path.unlink(missing_ok=True)

    @property
    def _rank0(self) -> bool:
        return self.comm is None or self.comm.rank == 0

    def _block_indexes(self):
        return _block_indexes(self.xmf_path)

    def _open(self):
        return open_tagged(self.h5_path, SCHEMA, SCHEMA_VERSION, SnapshotError)

    def _prepare_append(self, restart_step, log) -> None:
        try:
            f = self._open()
        except SnapshotError as exc:
            # A kill during a snapshot write can leave the file unreadable; keep it for the
            # record and continue in a fresh one rather than refuse to resume the run.
            aside = self.h5_path.with_name(self.h5_path.name + ".damaged")
            self.h5_path.replace(aside)
            log(
                f"snapshot file {self.h5_path.name} is damaged ({exc.reason}); moved to {aside.name}, starting "
                "a new one"
            )
        else:
            with f:
                for name in list(f):
                    m = _GROUP_RE.match(name)
                    if not m:
                        continue
                    stale = restart_step is not None and int(m.group(1)) > restart_step
                    if stale or int(f[name].attrs.get("complete", 0)) != 1:
                        del f[name]
        with self._open():
            pass
        write_xdmf(self.h5_path, self.xmf_path)

    def write(self, step, time, gid, position, radius, velocity, fields=None, rank0_fields=None,
              blocks=None) -> None:
        """Write one snapshot (collective when a comm was given).

        Parameters
        ----------
        step : int
        time : float
            Simulated time [s].
        gid : int array [n_local]
            Global particle ids of this rank's owned particles (no ghosts).
        position, velocity : float arrays [n_local, 3]
            [m], [m/s].
        radius : float array [n_local]
            [m].
        fields : dict, optional
            Extra per-particle fields, name -> array [n_local] or [n_local, 3].
        rank0_fields : dict, optional
            Extra per-particle fields already gathered, on rank 0 only: name -> array [n] of every
            particle in increasing gid (ignored on the other ranks).
        blocks : dict, optional
            name -> `Block`, on rank 0 only (ignored on the other ranks).
        """
        fields = dict(fields or {})
        local = {"gid": np.asarray(gid, dtype=np.int64),
                 "position": np.asarray(position, dtype=np.float64),
                 "radius": np.asarray(radius, dtype=np.float64),
                 "velocity": np.asarray(velocity, dtype=np.float64)}
        err = None
        for name, a in fields.items():
            if name in _BASE or name == "connectivity" or "/" in name:
                err = f"field name {name!r} is reserved or invalid"
            local[name] = _numbers(a)
        n = local["gid"].shape[0]
        for name, a in local.items():
            err = err or _shape_error(name, a, n)
        if local["position"].shape != (n, 3) or local["velocity"].shape != (n, 3):
            err = err or "position and velocity must be [n, 3]"
        h5 = self.h5_path
        if self.comm is not None:
            if self.comm.any_flag(err is not None):
                raise SnapshotError(h5, err or "invalid snapshot arrays on another rank")
            names = sorted(local)
            data = {k: self.comm.gather_rows(np.ascontiguousarray(local[k])) for k in names}
        elif err is not None:
            raise SnapshotError(h5, err)
        else:
            data = local

        outcome, error = ("ok", ""), None
        if self._rank0:
            try:
                self._write_rank0(int(step), float(time), data, sorted(fields), dict(rank0_fields or {}),
                                  dict(blocks or {}))
            except (OSError, MemoryError) as exc:  # the system's failure, not the data's
                outcome, error = ("system", one_line(exc) or type(exc).__name__), exc
            except Exception as exc:
                outcome, error = ("error", one_line(exc)), exc
        if self.comm is not None:
            outcome = self.comm.bcast(outcome)
        if outcome[0] != "ok":
            cls = SnapshotWriteError if outcome[0] == "system" else SnapshotError
            raise cls(h5, f"step {int(step)}: {outcome[1]}") from error

    def _write_rank0(self, step: int, time: float, data: dict, extra: list, sorted_fields: dict,
                     blocks: dict) -> None:
        order = np.argsort(data["gid"], kind="stable")
        gid = data["gid"][order]
        if gid.size > 1 and np.any(gid[1:] == gid[:-1]):
            dup = gid[1:][gid[1:] == gid[:-1]][0]
            raise ValueError(f"gid {dup} passed twice (a particle owned by two ranks?)")
        n = gid.size
        columns = {key: data[key][order] for key in _BASE + tuple(extra)}
        for name, a in sorted(sorted_fields.items()):
            if name in columns or name == "connectivity" or "/" in name:
                raise ValueError(f"field name {name!r} is reserved, invalid or given twice")
            a = _numbers(a)
            if _shape_error(name, a, n):
                raise ValueError(_shape_error(name, a, n))
            columns[name] = a
        groups = {bname: _block_arrays(bname, b, gid) for bname, b in sorted(blocks.items())}
        with self._open() as f:
            name = _group_name(step)
            if name in f:
                del f[name]
            g = f.create_group(name)
            g.attrs["step"] = np.int64(step)
            g.attrs["time"] = np.float64(time)
            g.attrs["n_particles"] = np.int64(n)
            g.attrs["fields"] = json.dumps([k for k in columns if k not in _BASE])
            for key, a in columns.items():
                g.create_dataset(key, data=np.ascontiguousarray(a))
            conn = np.arange(n, dtype=_index_type(n)).reshape(n, 1)
            if n > 0:
                g.create_dataset("connectivity", data=conn, chunks=(min(n, 1 << 16), 1),
                                 compression="gzip", shuffle=True)
            else:
                g.create_dataset("connectivity", data=conn)
            for bname, (attrs, arrays) in groups.items():
                b = g.create_group(bname)
                for k, v in attrs.items():
                    b.attrs[k] = v
                for k, a in arrays.items():
                    b.create_dataset(k, data=a)
            g.attrs["complete"] = np.int64(1)
        write_xdmf(self.h5_path, self.xmf_path)


def _block_indexes(xmf_path):
    """The block indexes beside ``xmf_path`` (``<stem>_<block><suffix>``)."""
    xmf_path = Path(xmf_path)
    stem, suffix = xmf_path.stem, xmf_path.suffix
    return [p for p in xmf_path.parent.glob(f"{stem}_*{suffix}")
            if _BLOCK_NAME_RE.match(p.name[len(stem) + 1: len(p.name) - len(suffix)])]


def _numbers(a):
    a = np.asarray(a)
    return a.astype(np.uint8) if a.dtype.kind == "b" else a  # XDMF has no bool


def _shape_error(name, a, n):
    """Why ``a`` is no per-row field of ``n`` rows, or None."""
    if a.ndim == 0 or a.shape[0] != n or a.ndim > 2 or (a.ndim == 2 and a.shape[1] != 3):
        return f"{name} has shape {a.shape}, expected ({n},) or ({n}, 3)"
    if a.dtype.kind not in "biuf":
        return f"{name} has dtype {a.dtype}, expected numbers"
    return None


def _index_type(n):
    return np.int32 if n < 2**31 else np.int64


def _block_arrays(name, block, gid):
    """(attributes, datasets) of ``block`` in a snapshot of the particles ``gid`` (sorted);
    ValueError (one line) if it is malformed."""
    if not _BLOCK_NAME_RE.match(name) or name in _BASE or name == "connectivity":
        raise ValueError(f"block name {name!r} is reserved or invalid (lower case letters, digits, _)")
    if block.topology not in TOPOLOGIES:
        raise ValueError(f"block {name}: topology {block.topology!r}, expected one of {', '.join(TOPOLOGIES)}")
    v = TOPOLOGIES[block.topology]
    cells = np.asarray(block.cells, np.int64).reshape(-1, v)
    k = cells.shape[0]
    arrays = {}
    if block.points is None:  # cells given by particle gids
        rows = np.searchsorted(gid, cells)
        found = rows < gid.size
        found[found] = gid[rows[found]] == cells[found]
        if not found.all():
            raise ValueError(f"block {name}: gid {int(cells[~found][0])} is no particle of the snapshot")
        n_points = gid.size
    else:
        points = np.asarray(block.points, np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise ValueError(f"block {name}: points have shape {points.shape}, expected (m, 3)")
        rows, n_points = cells, points.shape[0]
        if k and (rows.min() < 0 or rows.max() >= n_points):
            raise ValueError(f"block {name}: a cell names a vertex outside 0..{n_points - 1}")
        arrays["points"] = np.ascontiguousarray(points)
    arrays["connectivity"] = rows.astype(_index_type(n_points))
    fields = []
    for fname, a in sorted(block.cell_fields.items()):
        a = _numbers(a)
        err = _shape_error(f"block {name} field {fname}", a, k)
        if err or fname in ("points", "connectivity", "position") or "/" in fname:
            raise ValueError(err or f"block {name}: field name {fname!r} is reserved or invalid")
        arrays[fname] = np.ascontiguousarray(a)
        fields.append(fname)
    attrs = {"topology": block.topology, "fields": json.dumps(fields), "on_particles": np.int64(block.points is None)}
    return attrs, arrays
