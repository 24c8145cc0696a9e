"""What a ParaView snapshot of a running simulation holds (`pdem.io.snapshots` writes it).

`open_snapshots` makes the run's writer from its [run] settings (None when
``run.snapshot_every`` is 0: then nothing here runs); `write_snapshot(snaps, sim)` (collective,
between steps, never inside one) writes one snapshot:

- per sphere, in increasing gid (the same file on any rank count): position [m], radius [m],
  velocity [m/s], gid, ``force`` (the contact force summed on the sphere in the last step, no
  gravity; 0 before the first step) [N], ``angvel`` [rad/s], ``body_kind`` (`BODY_KINDS`); with
  clumps in the scene ``clump_id`` (-1: none); with breakable clumps ``fragment_id`` (the smallest
  gid of the sphere's fragment: its connected set over intact bonds and rigid clumps,
  `pdem.bodies.fragments`);
- ``walls`` (if the scene has walls): each infinite wall drawn as a quadrilateral in its plane,
  spanning the bounding box of the spheres (centre ± radius), walls, facets and boxes, 5 %
  wider on every side; cell fields ``wall`` (its index) and ``force`` (of the spheres on it,
  an exact sum) [N];
- ``facets`` (if any): the triangles; ``facet`` (index), ``velocity`` [m/s];
- ``boxes`` (if any: sleepers, platens, cover plates): hexahedra at their centre, half extents
  and orientation (a turning box drawn turned); ``box`` (index), ``velocity`` [m/s], ``angvel``
  [rad/s], ``force`` (of the spheres on it, exact) [N];
- ``contacts`` (only with ``run.snapshot_contacts = true``): the contact network, a line between
  the centres of the two spheres of every real sphere–sphere contact (bonds included), each once
  in key order; ``normal_force`` |F_n| [N] (Yade's normalForce magnitude), ``gid1``, ``gid2``.

Walls, facets and boxes are replicated (every rank holds the same bits), so rank 0 draws them;
the sums and gathers are the collective parts. Units SI.
"""
import numpy as np

from ..bodies.fragments import fragment_ids
from ..bodies.state import DOF_ALL
from ..io.snapshots import Block, SnapshotWriter
from . import observables

# body_kind values: what moves a sphere (clump membership wins over a fixed DOF mask)
FREE, FIXED, RIGID_MEMBER, BREAKABLE_MEMBER = 0, 1, 2, 3
BODY_KINDS = {FREE: "free sphere", FIXED: "fixed sphere (all six DOFs blocked)",
              RIGID_MEMBER: "member of a rigid clump", BREAKABLE_MEMBER: "member of a breakable clump (bonded)"}
MARGIN = 0.05  # the walls' quadrilaterals reach this fraction of the bounding box beyond it
_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                     [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], np.float64)  # VTK hexahedron order


class Snapshots:
    """The run's snapshot writer and what the scene asked to be in it."""

    def __init__(self, writer, contacts=False):
        self.writer = writer
        self.contacts = bool(contacts)


def open_snapshots(out, comm, run, restart_step=None, log=None):
    """The run's `Snapshots` in ``out`` (appending after ``restart_step`` when resuming), or None
    if ``run["snapshot_every"]`` is 0."""
    if not run["snapshot_every"]:
        return None
    log = log or (lambda m: print(m, flush=True))
    writer = SnapshotWriter(out, comm=comm, append=restart_step is not None, restart_step=restart_step, log=log)
    return Snapshots(writer, contacts=run.get("snapshot_contacts", False))


def body_kind(sim):
    """`BODY_KINDS` value of each owned sphere (uint8 [n_local])."""
    p = sim.particles
    nl = p.n_local
    kind = np.zeros(nl, np.uint8)
    kind[p.blocked[:nl] == DOF_ALL] = FIXED
    kind[p.clump[:nl] >= 0] = BREAKABLE_MEMBER
    if sim.clumps is not None:
        kind[np.isin(p.gid[:nl], sim.clumps.mgid)] = RIGID_MEMBER  # owned with their clump
    return kind


def write_snapshot(snaps, sim):
    """One snapshot of ``sim`` now (collective)."""
    p, comm = sim.particles, sim.comm
    nl = p.n_local
    kind = body_kind(sim)
    fields = {"force": p.force[:nl], "angvel": p.angvel[:nl], "body_kind": kind}
    if comm.any_flag(np.any(p.clump[:nl] >= 0)):
        fields["clump_id"] = p.clump[:nl]
    rank0 = {}
    if comm.any_flag(np.any(kind == BREAKABLE_MEMBER)):
        rank0["fragment_id"] = fragment_ids(sim)
    blocks = boundary_blocks(sim)
    if snaps.contacts and sim.kind("sphere_sphere") is not None:
        net = observables.unique_contacts(sim, "sphere_sphere", "gid2", "normal_force")
        if net is not None:
            keys, fn = net
            blocks["contacts"] = Block("Polyline", keys, cell_fields={"normal_force": fn, "gid1": keys[:, 0],
                                                                      "gid2": keys[:, 1]})
    snaps.writer.write(sim.step, sim.time, p.gid[:nl], p.pos[:nl], p.radius[:nl], p.vel[:nl], fields=fields,
                       rank0_fields=rank0 if comm.rank == 0 else None, blocks=blocks if comm.rank == 0 else None)


def boundary_blocks(sim):
    """The ``walls``, ``facets`` and ``boxes`` blocks of the scene's boundaries (collective: the
    bounding box and the walls' and boxes' forces are reductions)."""
    p, comm = sim.particles, sim.comm
    nl = p.n_local
    blocks = {}
    walls, facets, boxes = sim.walls, sim.facets, sim.boxes
    if len(facets):
        blocks["facets"] = Block("Triangle", np.arange(3 * len(facets)).reshape(-1, 3),
                                 facets.vertices.reshape(-1, 3),
                                 {"facet": np.arange(len(facets), dtype=np.int32), "velocity": facets.velocity})
    if boxes is not None:
        blocks["boxes"] = Block("Hexahedron", np.arange(8 * len(boxes)).reshape(-1, 8),
                                _box_corners(boxes).reshape(-1, 3),
                                {"box": np.arange(len(boxes), dtype=np.int32), "velocity": boxes.velocity,
                                 "angvel": boxes.angvel, "force": boxes.contact_force})
    if len(walls):
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        if nl:
            lo = np.minimum(lo, (p.pos[:nl] - p.radius[:nl, None]).min(axis=0))
            hi = np.maximum(hi, (p.pos[:nl] + p.radius[:nl, None]).max(axis=0))
        lo = np.asarray(comm.allreduce_min(lo), np.float64)
        hi = np.asarray(comm.allreduce_max(hi), np.float64)
        for b in blocks.values():
            lo, hi = np.minimum(lo, b.points.min(axis=0)), np.maximum(hi, b.points.max(axis=0))
        for k in range(len(walls)):
            a = walls.axis[k]
            lo[a], hi[a] = min(lo[a], walls.position[k]), max(hi[a], walls.position[k])
        lo, hi = np.where(np.isfinite(lo), lo, 0.0), np.where(np.isfinite(hi), hi, 0.0)
        pad = MARGIN * max(float(np.max(hi - lo)), 1e-12)
        lo, hi = lo - pad, hi + pad
        quads = np.empty((len(walls), 4, 3))
        for k in range(len(walls)):
            a = int(walls.axis[k])
            u, v = (a + 1) % 3, (a + 2) % 3
            for c, (su, sv) in enumerate(((0, 0), (1, 0), (1, 1), (0, 1))):
                quads[k, c, a] = walls.position[k]
                quads[k, c, u] = (lo, hi)[su][u]
                quads[k, c, v] = (lo, hi)[sv][v]
        blocks["walls"] = Block("Quadrilateral", np.arange(4 * len(walls)).reshape(-1, 4), quads.reshape(-1, 3),
                                {"wall": np.arange(len(walls), dtype=np.int32),
                                 "force": observables.wall_forces(sim)})
    return blocks


def _box_corners(boxes):
    """[n, 8, 3] corners of the boxes [m]: centre + R (±half) in VTK's hexahedron order."""
    local = _CORNERS[None] * boxes.half[:, None, :]
    return boxes.center[:, None, :] + np.einsum("bij,bcj->bci", boxes.rotation, local)
