"""Fragments: connected components of spheres over intact bonds and rigid clumps (SPEC 1.2, 4).

A fragment is a set of spheres held together: by intact bonds (a breakable clump, or what is left
of it) or by being members of one rigid clump. An unbroken clump is one fragment; a sphere that
lost all its bonds, or never had any, is a fragment of 1. Each fragment has its number of member
spheres, its mass (the sum of its spheres' masses, in gid order; a rigid clump's own mass, which
differs from the members' sum with a volume-corrected mass model) and the clump id of its spheres
(-1 for loose spheres that never were in a clump).

`fragments(sim)` is collective: the ranks' owned spheres, intact bonds (each held once: by the
owner of its first sphere) and rigid clumps are gathered to rank 0, which labels the components
by union-find over gids. Fragments are listed in order of their smallest gid, so the result does
not depend on the rank count. Units: kg.
"""
import numpy as np
from numba import njit

from .clumps import empty_clump_table, empty_member_table


@njit(cache=True)
def _find(parent, a):
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@njit(cache=True)
def components(n, a, b):
    """Component label (the smallest index of its component) of each of n nodes joined by the
    edges (a[k], b[k])."""
    parent = np.arange(n)
    for k in range(a.shape[0]):
        ra = _find(parent, a[k])
        rb = _find(parent, b[k])
        if ra < rb:
            parent[rb] = ra
        elif rb < ra:
            parent[ra] = rb
    for v in range(n):
        parent[v] = _find(parent, v)
    return parent


def label_fragments(gid, mass, clump, bond_gid1, bond_gid2, clump_ids=None, clump_mass=None, member_gid=None,
                    member_clump=None):
    """(n_members [f], mass [f], clump [f]) of the fragments of spheres ``gid`` (any order) with
    masses ``mass`` [kg] and clump ids ``clump``, joined by the bonds (bond_gid1, bond_gid2) and by
    rigid clumps (``clump_ids``/``clump_mass`` and their members ``member_gid``/``member_clump``).
    Pure; fragments in order of their smallest gid."""
    order = np.argsort(gid, kind="stable")
    g, m, c = np.asarray(gid)[order], np.asarray(mass, np.float64)[order], np.asarray(clump)[order]
    n = len(g)
    label, rigid_of = _labels(g, bond_gid1, bond_gid2, member_gid, member_clump)
    roots, inverse, counts = np.unique(label, return_inverse=True, return_counts=True)
    frag_mass = np.zeros(len(roots))
    for k in range(n):  # gid order within each fragment: a fixed summation order
        frag_mass[inverse[k]] += m[k]
    if clump_ids is not None and len(clump_ids):
        cm = dict(zip(np.asarray(clump_ids).tolist(), np.asarray(clump_mass, np.float64).tolist()))
        for f, root in enumerate(roots):
            if rigid_of[root] >= 0:
                frag_mass[f] = cm[int(rigid_of[root])]
    return counts.astype(np.int64), frag_mass, c[roots].astype(np.int64)


def _labels(g, bond_gid1, bond_gid2, member_gid, member_clump):
    """(label [n], rigid_of [n]) of the spheres of increasing gids ``g``: the index in ``g`` of
    the smallest gid of each sphere's fragment, and the rigid clump each sphere is a member of
    (-1: none)."""
    n = len(g)
    a = [np.searchsorted(g, np.asarray(bond_gid1, np.int64))]
    b = [np.searchsorted(g, np.asarray(bond_gid2, np.int64))]
    rigid_of = np.full(n, -1, np.int64)
    if member_gid is not None and len(member_gid):
        rows = np.searchsorted(g, np.asarray(member_gid, np.int64))
        mc = np.asarray(member_clump, np.int64)
        first = {}
        ra, rb = [], []
        for r, cid in zip(rows, mc):  # every member to the first member of its clump
            if cid in first:
                ra.append(first[cid])
                rb.append(r)
            else:
                first[cid] = r
        a.append(np.array(ra, np.int64))
        b.append(np.array(rb, np.int64))
        rigid_of[rows] = mc
    return components(n, np.concatenate(a).astype(np.int64), np.concatenate(b).astype(np.int64)), rigid_of


def _gathered(sim, columns):
    """Collective: on rank 0 the owned spheres' ``columns`` of every rank, the intact bonds (gid
    pairs, each once: held by the owner of its first sphere) and the rigid clumps' tables
    (``cid``, ``cmass``, members ``mgid``, ``mclump``); None on the other ranks."""
    p, comm = sim.particles, sim.comm
    nl = p.n_local
    law = sim.law
    kind = sim.kind("sphere_sphere")
    c = kind.contacts
    rows = kind.owned_rows(nl)  # held by the owner of the first sphere: each bond once
    if hasattr(law, "intact") and len(rows):
        rows = rows[law.intact(c.params[rows], c.history[rows])]
    else:
        rows = rows[:0]
    g1, g2 = p.gid[c.i[rows]], p.gid[c.j[rows]]
    gather = comm.gather_rows
    out = {k: gather(np.ascontiguousarray(getattr(p, k)[:nl])) for k in columns}
    out["b1"], out["b2"] = gather(np.ascontiguousarray(g1)), gather(np.ascontiguousarray(g2))
    ct, mt = sim.clumps.table() if sim.clumps is not None else (empty_clump_table(), empty_member_table())
    out["cid"], out["cmass"] = gather(ct["id"]), gather(ct["mass"])
    out["mgid"], out["mclump"] = gather(mt["gid"]), gather(mt["clump"])
    return out if comm.rank == 0 else None


def fragments(sim):
    """Collective: on rank 0 a dict ``n_members``, ``mass`` [kg], ``clump`` (one entry per
    fragment, in order of the fragments' smallest gid), ``member_radius_min`` [m] (smallest
    radius of a sphere in a clump, or of any sphere if none is) and ``n_bonds`` (intact bonds);
    None on the other ranks."""
    d = _gathered(sim, ("gid", "mass", "clump", "radius"))
    if d is None:
        return None
    gid, clump, radius, b1 = d["gid"], d["clump"], d["radius"], d["b1"]
    n, m, cl = label_fragments(gid, d["mass"], clump, b1, d["b2"], d["cid"], d["cmass"], d["mgid"], d["mclump"])
    in_clump = clump >= 0
    rmin = float(radius[in_clump].min()) if in_clump.any() else float(radius.min())
    return {"n_members": n, "mass": m, "clump": cl, "member_radius_min": rmin, "n_bonds": len(b1)}


def fragment_ids(sim):
    """Collective: on rank 0 the fragment of every sphere in increasing gid, named by the
    smallest gid of its fragment (int64 [n]); None on the other ranks."""
    d = _gathered(sim, ("gid",))
    if d is None:
        return None
    g = np.sort(d["gid"], kind="stable")
    label, _ = _labels(g, d["b1"], d["b2"], d["mgid"], d["mclump"])
    return g[label]
