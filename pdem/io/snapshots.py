"""Particle snapshots for ParaView: one HDF5 file per run plus an XDMF index beside it.

Owns the snapshot layout and its writer. Ranks pass their owned particles; rank 0 gathers them
(``comm.gather_rows``), orders them by gid and writes; the XDMF file is then rebuilt from the
HDF5 file's complete snapshots and replaced atomically, so ParaView never sees a half-written
index. Must not import mpi4py nor pdem physics modules.

Layout (schema ``pdem-snapshots``, version 1)::

    snapshots.h5
      attrs  schema="pdem-snapshots", schema_version=1
      step_000000000100/           attrs: step (int64), time [s], n_particles, fields (JSON list),
                                          complete=1 (written last)
        position     float64[n, 3]  [m]     rows ordered by gid
        radius       float64[n]     [m]
        velocity     float64[n, 3]  [m/s]
        gid          int64[n]
        connectivity int32[n, 1]    0..n-1 (Polyvertex topology for XDMF readers; compressed)
        <field>      [n] or [n, 3]  optional extra per-particle fields (angvel, material ...)
    snapshots.xmf                  XDMF 3: a temporal collection of Polyvertex grids, one per
                                   snapshot, referencing the datasets above by relative path
                                   ("snapshots.h5:/step_000000000100/position"); attributes
                                   radius, velocity, gid and the extra fields, centred on nodes.

Open ``snapshots.xmf`` in ParaView (Xdmf3 reader) and render the points with the Point Gaussian
representation scaled by ``radius``, or apply a Glyph filter (sphere, scale by radius, factor 2).
"""

from __future__ import annotations

import json
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from pdem.io._h5 import one_line, open_h5, open_tagged
from pdem.io.atomic import atomic_write_text

SCHEMA = "pdem-snapshots"
SCHEMA_VERSION = 1
_GROUP_RE = re.compile(r"^step_(\d{12})$")
_BASE = ("position", "radius", "velocity", "gid")

__all__ = ["SnapshotError", "SnapshotWriteError", "SnapshotWriter", "write_xdmf"]


class SnapshotError(RuntimeError):
    """A snapshot cannot be written; the message is one line: ``<file>: <what>``."""

    def __init__(self, path, reason: str):
        self.path = Path(path)
        self.reason = " ".join(str(reason).split())
        super().__init__(f"{self.path.name}: {self.reason}")


class SnapshotWriteError(SnapshotError):
    """The system failed a snapshot write (disk full, file system gone, out of memory): raised on
    every rank, exit status 5 like a failed checkpoint write (`pdem.driver.failures.classify`)."""


def _group_name(step: int) -> str:
    return f"step_{int(step):012d}"


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


def write_xdmf(h5_path, xmf_path) -> int:
    """Rebuild the XDMF index of every complete snapshot in ``h5_path``; returns their number.

    The HDF5 path inside the XDMF file is relative to the XDMF file's directory (both files
    normally sit side by side, so the run directory can be moved).
    """
    h5_path, xmf_path = Path(h5_path), Path(xmf_path)
    rel = Path(os.path.relpath(h5_path.resolve(), xmf_path.parent.resolve())).as_posix()
    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    series = ET.SubElement(domain, "Grid", Name="particles", GridType="Collection", CollectionType="Temporal")
    count = 0
    with open_h5(h5_path, "r") as f:
        for name in sorted(n for n in f if _GROUP_RE.match(n)):
            g = f[name]
            if int(g.attrs.get("complete", 0)) != 1:
                continue
            grid = ET.SubElement(series, "Grid", Name=name, GridType="Uniform")
            ET.SubElement(grid, "Time", Value=repr(float(g.attrs["time"])))
            n = g["gid"].shape[0]
            topo = ET.SubElement(grid, "Topology", TopologyType="Polyvertex",
                                 NumberOfElements=str(n), NodesPerElement="1")
            _data_item(topo, rel, g["connectivity"])
            geom = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
            _data_item(geom, rel, g["position"])
            fields = ["radius", "velocity", "gid"] + json.loads(g.attrs.get("fields", "[]"))
            for field in fields:
                ds = g[field]
                kind = "Vector" if ds.ndim == 2 and ds.shape[1] == 3 else "Scalar"
                attr = ET.SubElement(grid, "Attribute", Name=field, AttributeType=kind, Center="Node")
                _data_item(attr, rel, ds)
            count += 1
    ET.indent(root)
    text = '<?xml version="1.0" ?>\n' + ET.tostring(root, encoding="unicode") + "\n"
    atomic_write_text(xmf_path, text)
    return count


class SnapshotWriter:
    """Write particle snapshots to ``<directory>/snapshots.h5`` and index them in ``snapshots.xmf``.

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
                self.xmf_path.unlink(missing_ok=True)
            elif self.h5_path.exists():
                self._prepare_append(restart_step, log)
            else:
                self.xmf_path.unlink(missing_ok=True)  # an index without its data

    @property
    def _rank0(self) -> bool:
        return self.comm is None or self.comm.rank == 0

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

    def write(self, step, time, gid, position, radius, velocity, fields=None) -> None:
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
            a = np.asarray(a)
            local[name] = a.astype(np.uint8) if a.dtype.kind == "b" else a  # XDMF has no bool
        n = local["gid"].shape[0]
        for name, a in local.items():
            if a.ndim == 0 or a.shape[0] != n or a.ndim > 2 or (a.ndim == 2 and a.shape[1] != 3):
                err = f"{name} has shape {a.shape}, expected ({n},) or ({n}, 3)"
            elif a.dtype.kind not in "biuf":
                err = f"{name} has dtype {a.dtype}, expected numbers"
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
                self._write_rank0(int(step), float(time), data, sorted(fields))
            except (OSError, MemoryError) as exc:  # the system's failure, not the data's
                outcome, error = ("system", one_line(exc) or type(exc).__name__), exc
            except Exception as exc:
                outcome, error = ("error", one_line(exc)), exc
        if self.comm is not None:
            outcome = self.comm.bcast(outcome)
        if outcome[0] != "ok":
            cls = SnapshotWriteError if outcome[0] == "system" else SnapshotError
            raise cls(h5, f"step {int(step)}: {outcome[1]}") from error

    def _write_rank0(self, step: int, time: float, data: dict, extra: list) -> None:
        order = np.argsort(data["gid"], kind="stable")
        gid = data["gid"][order]
        if gid.size > 1 and np.any(gid[1:] == gid[:-1]):
            dup = gid[1:][gid[1:] == gid[:-1]][0]
            raise ValueError(f"gid {dup} passed twice (a particle owned by two ranks?)")
        n = gid.size
        with self._open() as f:
            name = _group_name(step)
            if name in f:
                del f[name]
            g = f.create_group(name)
            g.attrs["step"] = np.int64(step)
            g.attrs["time"] = np.float64(time)
            g.attrs["n_particles"] = np.int64(n)
            g.attrs["fields"] = json.dumps(extra)
            for key in _BASE + tuple(extra):
                g.create_dataset(key, data=np.ascontiguousarray(data[key][order]))
            conn_type = np.int32 if n < 2**31 else np.int64
            conn = np.arange(n, dtype=conn_type).reshape(n, 1)
            if n > 0:
                g.create_dataset("connectivity", data=conn, chunks=(min(n, 1 << 16), 1),
                                 compression="gzip", shuffle=True)
            else:
                g.create_dataset("connectivity", data=conn)
            g.attrs["complete"] = np.int64(1)
        write_xdmf(self.h5_path, self.xmf_path)
