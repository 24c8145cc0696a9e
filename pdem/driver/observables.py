"""Global scalar observables of a running simulation, reduced so that they do not depend on
the rank count (exact sums, max/min reductions).

- unbalanced force ratio: mean over free bodies (a rigid clump is one body) of |F + m g| divided
  by the mean contact force magnitude (Yade's ``unbalancedForce``) [-]
- wall forces: total force of the spheres on each wall [N] (exact sums over contacts)
- top of the bed: max over spheres of z + r [m]
- facets: total force of the spheres on a group of facets (e.g. a frame) [N] (exact sums)
- the largest overlap of any real contact over the smaller radius of its pair [-]
  (`pdem.checks.diagnostics.max_overlap_ratio`, the guard's)
- rigid boxes: force of the spheres on each box [N] (exact sums) and centre [m]; the force on a
  box's bottom face apart from the rest (side friction)
- overlap statistics by group of contacts (`overlap_statistics`): the largest and the mean
  overlap over the smaller radius [-] of the sphere pairs without a bond, of the intact bonds
  in compression, and of the spheres on walls, facets and boxes; the intact bonds [-]
"""
import numpy as np

from ..checks.diagnostics import free_bodies, max_overlap_ratio  # noqa: F401  (max_overlap_ratio: an observable)


def wall_forces(sim):
    """[n_walls, 3] total force exerted by the spheres on each wall [N] (exact sums)."""
    kind = sim.kind("sphere_wall")
    return np.zeros((len(sim.walls), 3)) if kind is None else kind.totals(sim.comm)


def facet_force(sim, facets):
    """[3] total force of the spheres on the facets of index ``facets`` [N]: an exact sum over
    their contacts on all ranks (collective; the same bits on any rank count)."""
    kind = sim.kind("sphere_facet")
    if kind is None:
        return np.zeros(3)
    c = kind.contacts
    rows = c.real_rows()
    group = np.isin(kind.body_of[c.j[rows]], facets).astype(np.int64)
    return sim.comm.exact_sum_groups(-c.force[rows], group, 2)[1]


def unbalanced_force(sim):
    """Yade's unbalanced force ratio: mean |net force| on the free owned bodies (gravity
    included) over the mean |contact force| [-]; 1 when there are no contacts."""
    p = sim.particles
    nl = p.n_local
    free = free_bodies(sim)  # a rigid clump is one body: |F + M g| of the clump, not of its members
    net = p.force[:nl][free] + p.mass[:nl][free, None] * sim.gravity
    if sim.clumps is not None:
        net = np.concatenate([net, sim.clumps.net_forces(sim.gravity)])
    body = np.linalg.norm(net, axis=1)
    mags = [np.linalg.norm(kind.row_force(kind.owned_rows(nl)), axis=1) for kind in sim.kinds]
    mags = np.concatenate(mags) if mags else np.zeros(0)
    n_body = sim.comm.allreduce_sum_int(len(body))
    n_cont = sim.comm.allreduce_sum_int(len(mags))
    if n_cont == 0 or n_body == 0:
        return 1.0
    mean_body = sim.comm.exact_sum(body) / n_body
    mean_contact = sim.comm.exact_sum(mags) / n_cont
    return mean_body / mean_contact if mean_contact > 0 else 1.0


def bed_top(sim):
    p = sim.particles
    nl = p.n_local
    local = float(np.max(p.pos[:nl, 2] + p.radius[:nl])) if nl else -np.inf
    return sim.comm.allreduce_max(local)


def box_forces(sim):
    """[n_boxes, 3] total force of the spheres on each rigid box [N] at the last force computation
    (an exact sum over all ranks: identical bits on any rank count)."""
    if sim.boxes is None:
        return np.zeros((0, 3))
    return sim.boxes.contact_force.copy()


def box_face_forces(sim, box=0):
    """(bottom, sides) [N, 3 each]: the force of the spheres on box ``box`` split by where they
    touch it: ``bottom`` from the spheres whose centre is below the box's bottom plane (its bottom
    face and bottom edges, or its bottom members), ``sides`` from all others (its vertical faces:
    for a sleeper pushed down, their z part is the side friction). Exact sums over all ranks
    (collective); their sum is `box_forces` up to the rounding of one addition."""
    out = np.zeros((2, 3)) if not sim.box_kinds else None
    bottom = sim.boxes.center[box, 2] - sim.boxes.half[box, 2]
    for kind in sim.box_kinds:
        c, p = kind.contacts, sim.particles
        rows = c.real_rows()
        rows = rows[kind.body_of[c.j[rows]] == box]
        side = (p.pos[c.i[rows], 2] >= bottom).astype(np.int64)
        sums = sim.comm.exact_sum_groups(-c.force[rows], side, 2)
        out = sums if out is None else out + sums
    return out[0], out[1]


def box_positions(sim):
    """[n_boxes, 3] centre of each rigid box [m] (replicated: the same on every rank)."""
    if sim.boxes is None:
        return np.zeros((0, 3))
    return sim.boxes.center.copy()


def box_gaps(sim, floor=0.0):
    """[n_boxes] void under each rigid box [m] (collective): from its base down to the top
    (z + r) of the highest sphere whose centre lies under the box's footprint and below its
    base; 0 where the box rests on (or presses into) the ballast; base − ``floor`` if no sphere
    is under it. A max reduction: the same bits on any rank count."""
    bx = sim.boxes
    if bx is None:
        return np.zeros(0)
    p = sim.particles
    nl = p.n_local
    pos, r = p.pos[:nl], p.radius[:nl]
    top = np.full(len(bx), -np.inf)
    for k in range(len(bx)):
        c, h = bx.center[k], bx.half[k]
        base = c[2] - h[2]
        under = (np.abs(pos[:, 0] - c[0]) <= h[0]) & (np.abs(pos[:, 1] - c[1]) <= h[1]) & (pos[:, 2] < base)
        if under.any():
            top[k] = float(np.max(pos[under, 2] + r[under]))
    top = np.asarray(sim.comm.allreduce_max(top), np.float64)
    base = bx.center[:, 2] - bx.half[:, 2]
    return np.where(np.isfinite(top), np.maximum(base - top, 0.0), base - floor)


def box_end_gaps(sim, floor=0.0):
    """[n_boxes, 2] void under the two end thirds of each rigid box along its own y axis [m]
    (collective): lo is the third at local y <= −h_y/3, hi at y >= h_y/3 (a whole sleeper's outer
    thirds; a half model's body: the third at the track's centre line and the outer third). In
    the box's axes (it may be turned: p = Rᵀ(x − c) for a sphere centre x), from the base face
    (p_z = −h_z) down to the top p_z + r of the highest sphere whose centre lies under that third
    of the footprint (|p_x| <= h_x) and below the base; 0 where the box rests on (or presses
    into) the ballast; if no sphere is under it, the height above ``floor`` of the third's base
    centre. A max reduction: the same bits on any rank count."""
    bx = sim.boxes
    if bx is None:
        return np.zeros((0, 2))
    p = sim.particles
    nl = p.n_local
    pos, r = p.pos[:nl], p.radius[:nl]
    top = np.full((len(bx), 2), -np.inf)
    for k in range(len(bx)):
        h = bx.half[k]
        local = (pos - bx.center[k]) @ bx.rotation[k]  # Rᵀ (x − c), row by row
        below = (np.abs(local[:, 0]) <= h[0]) & (local[:, 2] < -h[2])
        for e, third in enumerate((local[:, 1] <= -h[1] / 3.0, local[:, 1] >= h[1] / 3.0)):
            under = below & third & (np.abs(local[:, 1]) <= h[1])
            if under.any():
                top[k, e] = float(np.max(local[under, 2] + r[under]))
    top = np.asarray(sim.comm.allreduce_max(top.ravel()), np.float64).reshape(len(bx), 2)
    base = -bx.half[:, 2][:, None]
    empty = np.zeros((len(bx), 2))
    for k in range(len(bx)):
        h = bx.half[k]
        for e, sign in enumerate((-1.0, 1.0)):
            empty[k, e] = bx.center[k, 2] + bx.rotation[k, 2] @ np.array([0.0, sign * 2.0 * h[1] / 3.0, -h[2]]) - floor
    return np.where(np.isfinite(top), np.maximum(base - top, 0.0), empty)
def unique_contacts(sim, name, second, column):
    """Collective: on rank 0 (keys [k, 2], values [k]) of the real contacts of kind ``name``,
    each once, in key order (gid1, then ``second``: "gid2" or "index"), with the magnitudes of
    their force ``column`` of `Simulation.contacts` ("force", "normal_force") [N]; None
    elsewhere. A pair held by two ranks (straddling a slab edge) is counted once, so the arrays
    do not depend on the rank count."""
    c = sim.contacts(name)
    key = np.stack([c["gid1"], c[second]], axis=1).astype(np.int64)
    value = np.linalg.norm(c[column], axis=1)
    keys, values = sim.comm.gather_rows(key), sim.comm.gather_rows(value)
    if sim.comm.rank != 0:
        return None
    _, first = np.unique(keys[:, 0] * (1 << 32) + keys[:, 1], return_index=True)  # sorted by key
    return keys[first], values[first]


def contact_force_samples(sim):
    """Forces of every real contact, each once, in key order, on rank 0 (None elsewhere):
    ``sleeper_ballast`` |normal force| [N] of each sphere–box contact (axis-aligned or turning
    boxes: a scene's sleepers are all of one kind) and ``sleeper_index`` (its box),
    ``ballast_ballast`` |total force| [N] of each sphere pair. Collective; a pair
    held by two ranks (straddling a slab edge) is counted once, so the arrays do not depend
    on the rank count."""
    out = {}
    for name, second in (("sphere_box", "index"), ("sphere_oriented_box", "index"), ("sphere_sphere", "gid2")):
        if sim.kind(name) is None:
            continue
        out[name] = unique_contacts(sim, name, second, "force" if name == "sphere_sphere" else "normal_force")
    if sim.comm.rank != 0:
        return None
    res = {}
    boxes = out.get("sphere_box", out.get("sphere_oriented_box"))
    if boxes is not None:
        res["sleeper_ballast"] = boxes[1]
        res["sleeper_index"] = boxes[0][:, 1]
    if "sphere_sphere" in out:
        res["ballast_ballast"] = out["sphere_sphere"][1]
    return res


def rank_loads(sim):
    """Work and halo of every rank (collective; the same dict on every rank): ``owned`` bodies,
    ``ghosts``, real ``contacts`` counted by the rank, the domain's load measure ``work`` =
    owned bodies + the contacts of their rows (what the slab balancer equalises), its
    ``imbalance`` max/mean [-], the slab ``edges`` [m] and halo width [m], and the cumulative
    ``migrated`` bodies and ``rebalanced`` edge moves of the domain."""
    p = sim.particles
    nl = p.n_local
    contacts = sum(len(kind.owned_rows(nl)) for kind in sim.kinds)
    work = float(nl)  # as `SlabDomain`'s balancer counts: 1 per owned body + 1 per contact row end it owns
    for kind in sim.kinds:
        for idx in kind.body_rows(kind.contacts.real_rows()):
            work += float(np.count_nonzero((idx >= 0) & (idx < nl)))
    d = sim.domain
    row = np.array([[p.n_local, p.n_ghost, contacts, work, getattr(d, "n_migrated", 0)]], np.float64)
    rows = sim.comm.allgather_rows(row)
    w = rows[:, 3]
    return {"owned": rows[:, 0].astype(int).tolist(), "ghosts": rows[:, 1].astype(int).tolist(),
            "contacts": rows[:, 2].astype(int).tolist(), "work": w.tolist(),
            "imbalance": float(w.max() / w.mean()) if w.mean() > 0 else 1.0,
            "edges": None if getattr(d, "edges", None) is None else [float(e) for e in d.edges],
            "halo": float(getattr(d, "halo", 0.0)), "migrated": int(rows[:, 4].sum()),
            "rebalanced": int(getattr(d, "n_rebalanced", 0))}


def box_rest(sim, v_ref):
    """(largest |net force| / weight [-], largest speed / v_ref [-]) over the rigid boxes'
    free translations: contact force + applied load + weight (replicated: the same on every
    rank). 0, 0 without boxes."""
    bx = sim.boxes
    if bx is None:
        return 0.0, 0.0
    f_ratio, v_ratio = 0.0, 0.0
    for k in range(len(bx)):
        free = np.array([not (int(bx.blocked[k]) >> a) & 1 for a in range(3)])
        weight = bx.mass[k] * float(np.linalg.norm(sim.gravity))
        net = bx.contact_force[k] + bx.load_force[k] + bx.mass[k] * sim.gravity
        f_ratio = max(f_ratio, float(np.linalg.norm(net[free])) / weight if weight > 0 else 0.0)
        v_ratio = max(v_ratio, float(np.linalg.norm(bx.velocity[k][free])) / v_ref)
    return f_ratio, v_ratio


OVERLAP_GROUPS = ("pair", "bond", "boundary")  # the groups of `overlap_statistics`, in its order


def overlap_statistics(sim):
    """Overlap δ over the smaller radius r of every real contact in compression (δ > 0), by group
    (collective; the same bits on any rank count: max reductions, exact sums, integer counts):

    - ``pair``: sphere pairs without an intact bond (members of different grains, fragments,
      loose spheres; a broken bond's members once they touch again)
    - ``bond``: sphere pairs with an intact bond (members of one breakable grain pressed together;
      the geometric overlap, which for a bond made stress free includes the overlap it was made on)
    - ``boundary``: a sphere on a wall, facet or box (base, cylinder, platen)

    Returns {``<group>_overlap_max``: largest δ/r [-], ``<group>_overlap_mean``: mean δ/r [-]
    over the group's contacts with δ > 0 (0 for an empty group), ``intact_bonds``: bonds not
    broken [-] (each once over the ranks)}. δ is the overlap of the last force computation, as
    the stability guard's `max_overlap_ratio` (the largest of the three maxima is that)."""
    p, comm, law = sim.particles, sim.comm, sim.law
    intact = getattr(law, "intact", None)
    ratios, groups, bonds = [], [], 0
    for kind in sim.kinds:
        c = kind.contacts
        rows = kind.owned_rows(p.n_local)  # each contact once over the ranks
        if len(rows) == 0:
            continue
        ratio = c.overlap[rows] / kind.min_radius(p.radius, rows)
        if kind.sphere_pair:
            bonded = intact(c.params[rows], c.history[rows]) if intact is not None else np.zeros(len(rows), bool)
            bonds += int(np.count_nonzero(bonded))
            group = bonded.astype(np.int64)  # 0 pair, 1 bond
        else:
            group = np.full(len(rows), 2, np.int64)
        press = c.overlap[rows] > 0.0
        ratios.append(ratio[press])
        groups.append(group[press])
    ratio = np.concatenate(ratios) if ratios else np.zeros(0)
    group = np.concatenate(groups) if groups else np.zeros(0, np.int64)
    n = len(OVERLAP_GROUPS)
    count = np.asarray(comm.allreduce_sum_int(np.bincount(group, minlength=n).astype(np.int64)))
    total = comm.exact_sum_groups(ratio[:, None], group, n).reshape(n)
    largest = np.zeros(n)
    for g in range(n):
        if np.any(group == g):
            largest[g] = float(np.max(ratio[group == g]))
    largest = np.asarray(comm.allreduce_max(largest), np.float64)
    out = {"intact_bonds": comm.allreduce_sum_int(bonds)}
    for g, name in enumerate(OVERLAP_GROUPS):
        out[f"{name}_overlap_max"] = float(largest[g])
        out[f"{name}_overlap_mean"] = float(total[g] / count[g]) if count[g] else 0.0
    return out
