"""A simulation's state as global tables, and back: what checkpoints and staged scenes exchange.

Tables for `pdem.io.checkpoint.write_checkpoint` and their inverse. Everything a step reads
that is not rebuilt from these is either derived (neighbour lists, ghosts, incidence) or a
per-step output (forces, overlaps), so a restored run continues bit for bit on any number of
ranks (tests/io/test_restart.py, tests/mpi/test_restart_mpi.py).

Tables: ``particles`` (`pdem.bodies.state.FIELDS` of the owned bodies, key gid),
``contacts/<kind>`` (real contacts of each kind of `Simulation.kinds`: key, params, history; a
pair that straddles a slab edge is held, bit for bit identical, by both ranks and the writer
keeps one copy), ``walls`` (index, position, velocity), ``facets`` (index, geom, vertices,
velocity) and ``boxes`` (index, center, velocity; with a rotating box also ori, angmom, angvel and
rotation, `pdem.bodies.boxes`), replicated on every rank; with rigid clumps
``clumps`` (id, pos, vel, angvel, angmom, ori, mass, inertia, aspherical; `pdem.bodies.clumps`) and
``clump_members`` (gid, clump, relpos), written by the rank that owns each clump. Bonds of
breakable clumps are contacts (``contacts/sphere_sphere``, the law's history).

The clock (step, time, Δt, rebuild count, energy reference) goes into the meta and back through
`clock_state` and `restore_clock`, for restarts and for staged runs (`pdem.driver.stages`).
"""
import numpy as np

from ..bodies.clump_setup import check_tables, owner_positions
from ..bodies.clumps import CLUMP_TABLE, MEMBER_TABLE, empty_clump_table, empty_member_table, extent_of
from ..bodies.state import FIELDS, with_defaults
from ..timestep import update_dt

BOX_ROTATION = ("ori", "angmom", "angvel", "rotation")  # columns of the boxes table of a scene with rotating boxes


def _boundary_tables(sim):
    out = {}
    n = len(sim.walls)
    if n:
        out["walls"] = {"index": np.arange(n, dtype=np.int64), "position": sim.walls.position.copy(),
                        "velocity": sim.walls.velocity.copy()}
    n = len(sim.facets)
    if n:
        out["facets"] = {"index": np.arange(n, dtype=np.int64), "geom": sim.facets.geom.copy(),
                         "vertices": sim.facets.vertices.copy(), "velocity": sim.facets.velocity.copy()}
    if sim.boxes is not None:  # rigid boxes (pdem.bodies.boxes): the state their step evolves
        out["boxes"] = {"index": np.arange(len(sim.boxes), dtype=np.int64), "center": sim.boxes.center.copy(),
                        "velocity": sim.boxes.velocity.copy()}
        if sim.boxes.oriented_count():  # boxes with free rotations: their turning state too
            out["boxes"].update({k: getattr(sim.boxes, k).copy().reshape(len(sim.boxes), -1) for k in BOX_ROTATION})
    return out


def checkpoint_tables(sim):
    """(tables, meta) of this rank for `write_checkpoint` (collective writer; every rank calls).

    Meta: step, time, dt, the energy-check reference and the other scalars of the loop, the
    scene spec and the pdem version."""
    from ..version import __version__

    p = sim.particles
    tables = {"particles": p.columns()}
    keys = {"particles": ["gid"]}
    for kind in sim.kinds:
        c = kind.contacts
        rows = c.real_rows()
        name = f"contacts/{kind.name}"
        tables[name] = {"key": c.key[rows].copy(), "params": c.params[rows].copy(), "history": c.history[rows].copy()}
        keys[name] = ["key"]
    for name, table in _boundary_tables(sim).items():
        tables[name] = table
        keys[name] = ["index"]
    if sim.clumps is not None:  # rigid clumps (pdem.bodies.clumps): owned by one rank each, with their members
        tables[CLUMP_TABLE], tables[MEMBER_TABLE] = sim.clumps.table()
        keys[CLUMP_TABLE], keys[MEMBER_TABLE] = ["id"], ["gid"]
    meta = {
        **clock_state(sim),
        "moving_boundaries": sim.moving_boundaries,
        "n_bodies": int(sim.comm.allreduce_sum_int(p.n_local)),
        "scene": sim.spec,
        "pdem_version": __version__,
        "keys": keys,
    }
    return tables, meta


def restore_checkpoint(sim, tables, meta):
    """Continue from a checkpoint (`read_checkpoint`'s tables and meta) on this communicator.

    Call on every rank right after `Scene.build` of the same scene (any rank count): the
    bodies are replaced by the checkpointed ones (distributed like at build), walls and
    facets get their position/geometry and velocity back, the real contacts are injected as
    carried rows and picked up by key at a neighbour rebuild, and step, time, Δt, the
    energy-check reference and the rebuild count are restored. Raises ValueError with one
    line if the checkpoint does not fit this simulation."""
    if meta.get("scene") != sim.spec:
        raise ValueError("the checkpoint was written for a different scene (settings, materials, walls or "
                         "facets differ from the scene file)")
    cols = tables["particles"]
    if len(cols["gid"]) != int(meta.get("n_bodies", len(cols["gid"]))):
        raise ValueError(f"table particles has {len(cols['gid'])} bodies, meta says {meta.get('n_bodies')}")
    for name, n in (("walls", len(sim.walls)), ("facets", len(sim.facets)),
                    ("boxes", len(sim.boxes) if sim.boxes is not None else 0)):
        if n and (name not in tables or len(tables[name]["index"]) != n):
            raise ValueError(f"table {name}: expected {n} rows (the scene's {name})")
    for kind in sim.kinds:
        if f"contacts/{kind.name}" not in tables:
            raise ValueError(f"table contacts/{kind.name} missing (the scene has contacts of that kind)")
    if (sim.clumps is not None) != (CLUMP_TABLE in tables):
        raise ValueError("the checkpoint has rigid clumps and the scene has none" if CLUMP_TABLE in tables
                         else "the scene has rigid clumps and the checkpoint has none")
    sim.moving_boundaries = bool(meta.get("moving_boundaries", sim.moving_boundaries))
    load_state(sim, tables)
    restore_clock(sim, meta)
    return sim


def clock_state(sim):
    """The clock of the loop as checkpoint meta holds it: ``step``, ``time`` [s], ``dt`` [s] (the
    next step's), ``n_rebuilds`` and the energy check's ``energy_reference`` [J] (or None)."""
    return {
        "step": int(sim.step),
        "time": float(sim.time),
        "dt": float(sim.dt),
        "n_rebuilds": int(sim.n_rebuilds),
        "energy_reference": None if sim.energy_reference is None else [float(x) for x in sim.energy_reference],
    }


def restore_clock(sim, meta, continuing=True):
    """Set the clock of `clock_state` back from checkpoint ``meta`` (after the bodies are
    loaded): step, time and rebuild count; if ``continuing`` (a restart, a stage resumed inside)
    also the checkpoint's Δt and energy reference, so the run goes on bit for bit, else (a new
    stage from the last one's end) a fresh Δt estimate and energy reference. Empty ``meta``: the
    clock starts at zero."""
    if meta:
        sim.step = int(meta["step"])
        sim.time = float(meta["time"])
        sim.n_rebuilds = int(meta.get("n_rebuilds", sim.n_rebuilds))
    if continuing:
        ref = meta.get("energy_reference")
        sim.energy_reference = None if ref is None else [float(x) for x in ref]
        update_dt(sim, carried=meta["dt"])
    else:
        update_dt(sim, force=True)


def load_state(sim, tables):
    """Replace the bodies by ``tables["particles"]`` (FIELDS columns, any order; distributed
    like at build) and give back the contact history of ``tables["contacts/<kind>"]`` (rows
    whose bodies are gone are dropped at the next rebuild); walls, facets and boxes get their
    state back when their table is present. Every rank passes the same tables. Used by
    `restore_checkpoint` and by staged scenes between stages."""
    cols = with_defaults(tables["particles"])
    missing = [k for k in FIELDS if k not in cols]
    if missing:
        raise ValueError(f"table particles lacks column(s) {', '.join(missing)}")
    p = sim.particles
    p.n_ghost = 0
    p.n_local = 0
    cols = {k: np.asarray(cols[k]) for k in FIELDS}
    if sim.clumps is None:
        if CLUMP_TABLE in tables and len(tables[CLUMP_TABLE]["id"]):
            raise ValueError("table clumps: the scene was built without rigid clumps (declare them, e.g. "
                             "Scene.add_clump_tables)")
        sim.domain.distribute(p, cols)
    else:
        clumps = tables.get(CLUMP_TABLE, empty_clump_table())
        members = tables.get(MEMBER_TABLE, empty_member_table())
        check_tables(cols, clumps, members)
        sim.domain.distribute(p, cols, owner_positions(cols, clumps, members))
        sim.clumps.extent = extent_of(members)
        sim.clumps.set_rows(clumps, members)
        sim.clumps.keep(sim.domain.owns(sim.clumps.pos))
        sim.clumps.attach(p)
    if len(sim.walls) and "walls" in tables:
        sim.walls.position[:] = tables["walls"]["position"]
        sim.walls.velocity[:] = tables["walls"]["velocity"]
    if len(sim.facets) and "facets" in tables:
        f = tables["facets"]
        sim.facets.geom[:] = f["geom"]
        sim.facets.vertices[:] = f["vertices"]
        sim.facets.velocity[:] = f["velocity"]
    if sim.boxes is not None and "boxes" in tables:
        sim.boxes.center[:] = tables["boxes"]["center"]
        sim.boxes.velocity[:] = tables["boxes"]["velocity"]
        if "ori" in tables["boxes"]:
            b = tables["boxes"]
            sim.boxes.ori[:], sim.boxes.angmom[:], sim.boxes.angvel[:] = b["ori"], b["angmom"], b["angvel"]
            sim.boxes.kernel_f[:, 9:18] = np.asarray(b["rotation"]).reshape(-1, 9)
        sim.boxes.place_members()
    # contacts: every rank gets every row; `replace` at the rebuild keeps the keys it needs
    for kind in sim.kinds:
        name = f"contacts/{kind.name}"
        if name not in tables:
            continue
        t = tables[name]
        key = np.asarray(t["key"], np.int64)
        c = kind.contacts
        c.n = 0  # candidate rows of the build-time rebuild: no contacts yet (no force computed)
        c.add_carried(key, np.ones(len(key), np.int8), np.asarray(t["params"], np.float64),
                      np.asarray(t["history"], np.float64))
    sim.rebuild()
    return sim
