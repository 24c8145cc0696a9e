"""Declaring clumps: member spheres, rigid-clump rows and bonds, checked, as `pdem.build.scene.Scene`
builds them (`Scene.add_clumps`, `Scene.add_clump`, `Scene.add_breakable_clump`).

`member_sets` checks the member lists (at least 2 and at most `MAX_MEMBERS` spheres, one
radius > 0 or one per member, no member wholly inside another, one connected body of
overlapping or touching spheres, `pdem.bodies.bonds.touching_pairs`); `check_bond_overlaps`
the members of a breakable clump against simulation.max_overlap_ratio; `rigid_rows` computes each rigid
clump's mass properties (`pdem.bodies.clump_properties`) and the members' initial velocities
(v_i = v + ω × (x_i − x_c), ω_i = ω); `owner_positions` gives the position that decides which
rank owns a body (a member goes with its clump's centre, `pdem.parallel.slab_domain`).
Units: m, m/s, rad/s, kg·m²/s.
"""
import numpy as np

from .bonds import touching_pairs
from .clump_properties import (
    MASS_MODELS,
    add,
    angular_momentum,
    clump_properties,
    cross,
    sub,
)
from .clumps import CLUMP_FLOATS, CLUMP_INTS
from ..errors import InputError
from ..build.validate import number, numbers, vector3, vectors

MAX_MEMBERS = 3000  # the most member spheres of one clump (the Nottingham grain has 135)


def member_sets(label, members):
    """[(pos[n, 3], radius[n], (i, j) touching pairs)] from a list of (positions, radii) pairs."""
    if isinstance(members, (str, bytes)) or not hasattr(members, "__len__"):
        raise InputError(f"{label}: must be a list of (member positions, member radii)")
    out = []
    for k, item in enumerate(members):
        where = f"{label}[{k}]" if len(members) > 1 else label
        try:
            pos, radius = item
        except (TypeError, ValueError):
            raise InputError(f"{where}: must be a pair (member positions, member radii)") from None
        pos = vectors(f"{where}.member_pos", pos)
        n = len(pos)
        if n < 2:
            raise InputError(f"{where}.member_pos: a clump needs at least 2 member spheres, got {n}")
        check_member_count(f"{where}.member_pos", n)
        r = numbers(f"{where}.member_radius", radius, n, 0.0, lo_open=True, allow="a number > 0 [m]")
        check_not_inside(f"{where}.member_pos", pos, r)
        out.append((pos, r, touching_pairs(f"{where}.member_pos", pos, r)))
    return out


def check_member_count(label, n):
    """InputError unless a clump of ``n`` members is plausible: at most `MAX_MEMBERS`."""
    if n > MAX_MEMBERS:
        raise InputError(f"{label}: a clump of {n} member spheres; at most {MAX_MEMBERS} are allowed (a grain of "
                         "thousands of members is a member radius or spacing in the wrong unit?)")


def check_not_inside(label, pos, r):
    """InputError if a member lies wholly inside another (same centre, or |x_i − x_j| + r_i <= r_j):
    it adds nothing to the shape and only double-counts mass (a repeated row?)."""
    d = pos[None, :, :] - pos[:, None, :]
    dist = np.sqrt(np.einsum("ijk,ijk->ij", d, d))
    inside = dist + r[:, None] <= r[None, :]
    np.fill_diagonal(inside, False)
    if np.any(inside):
        i, j = (int(x[0]) for x in np.nonzero(inside))
        raise InputError(f"{label}: member {i} at {pos[i].tolist()} (r {r[i]:g} m) lies wholly inside member {j} at "
                         f"{pos[j].tolist()} (r {r[j]:g} m); a member must stick out of the others (a repeated row?)")


def check_bond_overlaps(label, sets, max_overlap_ratio):
    """InputError if two members of a breakable clump overlap by more than ``max_overlap_ratio``
    of the smaller radius: they are free spheres, so the run's guard would stop at step 1 with an
    overlap past the limit, wrongly blaming the time step. The one-line error names the real
    cause: the members' spacing against simulation.max_overlap_ratio."""
    for k, (pos, r, (i, j)) in enumerate(sets):
        if not len(i):
            continue
        dist = np.linalg.norm(pos[j] - pos[i], axis=1)
        small = np.minimum(r[i], r[j])
        ratio = (r[i] + r[j] - dist) / small
        q = int(np.argmax(ratio))
        if ratio[q] > max_overlap_ratio:
            where = f"{label}[{k}]" if len(sets) > 1 else label
            spacing = r[i][q] + r[j][q] - max_overlap_ratio * small[q]
            raise InputError(f"{where}: breakable members {int(i[q])} and {int(j[q])} are {dist[q]:.4g} m apart, "
                             f"overlapping by {ratio[q]:.3g} of the smaller radius, more than simulation."
                             f"max_overlap_ratio = {max_overlap_ratio:g} (bonded members are free spheres; the run "
                             f"would stop at step 1): space them at least {spacing:.4g} m apart (member_spacing) "
                             "or raise max_overlap_ratio")


def mass_settings(label, mass_model, discretization, samples):
    if mass_model not in MASS_MODELS:
        raise InputError(f"{label}.mass_model = {mass_model!r}: must be one of {', '.join(MASS_MODELS)}")
    if mass_model == "grid":
        number(f"{label}.discretization", discretization, 1, integer=True,
               allow="an integer >= 1 (cells along the shortest side of the clump)")
    if mass_model == "monte_carlo":
        number(f"{label}.samples", samples, 1000, integer=True, allow="an integer >= 1000 (random points)")


def rigid_rows(sets, density, ids, gids, vel, angvel, angmom, mass_model, discretization, samples, seed):
    """(clump rows, member rows, member vel [m, 3], member angvel [m, 3]) of rigid clumps.

    ``sets`` from `member_sets`; ``ids`` the clump ids; ``density`` [m] and ``gids`` [m] of the
    members (in the order of the sets); ``vel``/``angvel`` [n, 3] of each clump, ``angmom`` [n, 3] or None
    (then L = I ω)."""
    crow = {k: [] for k in (*CLUMP_INTS, *CLUMP_FLOATS)}
    mrow = {"gid": [], "clump": [], "relpos": []}
    mvel, mw = [], []
    at = 0
    for k, (pos, r, _) in enumerate(sets):
        props = clump_properties(pos, r, density[at: at + len(r)], mass_model, discretization, samples, seed + k)
        v, w = [float(x) for x in vel[k]], [float(x) for x in angvel[k]]
        lm = angular_momentum(props["ori"], props["inertia"], w) if angmom is None else [float(x) for x in angmom[k]]
        for name, value in (("id", ids[k]), ("aspherical", int(props["aspherical"])), ("pos", props["pos"]),
                            ("vel", v), ("angvel", w), ("angmom", lm), ("ori", list(props["ori"])),
                            ("mass", props["mass"]), ("inertia", props["inertia"])):
            crow[name].append(value)
        for q, x in enumerate(pos):
            mrow["gid"].append(gids[at + q])
            mrow["clump"].append(ids[k])
            mrow["relpos"].append(props["rel_pos"][q])
            mvel.append(add(v, cross(w, sub([float(c) for c in x], props["pos"]))))
            mw.append(w)
        at += len(pos)
    clumps = {k: np.array(v, np.int64) for k, v in crow.items() if k in CLUMP_INTS}
    clumps.update({k: np.array(v, np.float64).reshape((len(sets),) + ((w,) if w > 1 else ()))
                   for k, v in crow.items() if k in CLUMP_FLOATS for w in (CLUMP_FLOATS[k],)})
    members = {"gid": np.array(mrow["gid"], np.int64), "clump": np.array(mrow["clump"], np.int64),
               "relpos": np.array(mrow["relpos"], np.float64).reshape(-1, 3)}
    return clumps, members, np.array(mvel, np.float64).reshape(-1, 3), np.array(mw, np.float64).reshape(-1, 3)


def per_clump(label, value, n):
    """float64 [n, 3] from one (x, y, z) triple or n of them."""
    a = np.asarray(value, dtype=object)
    if a.shape == (3,):
        return np.repeat(vector3(label, value)[None], n, axis=0)
    return vectors(label, value, n)


def owner_positions(cols, clumps, members):
    """Positions [n, 3] that decide the owning rank of the bodies ``cols``: their own, or for a
    member of a rigid clump its clump's centre."""
    pos = np.array(cols["pos"], np.float64, copy=True)
    if len(members["gid"]) == 0:
        return pos
    order = np.argsort(cols["gid"], kind="stable")
    rows = order[np.searchsorted(np.asarray(cols["gid"])[order], members["gid"])]
    cid = np.asarray(clumps["id"])
    corder = np.argsort(cid, kind="stable")
    pos[rows] = np.asarray(clumps["pos"])[corder[np.searchsorted(cid[corder], members["clump"])]]
    return pos


def check_tables(cols, clumps, members):
    """ValueError (one line) unless every member of ``members`` is a sphere of ``cols`` whose
    ``clump`` column names its clump, and every clump has members."""
    gid = np.asarray(cols["gid"])
    order = np.argsort(gid, kind="stable")
    at = np.minimum(np.searchsorted(gid[order], members["gid"]), max(len(gid) - 1, 0))
    if len(members["gid"]) and (len(gid) == 0 or np.any(gid[order][at] != members["gid"])):
        bad = members["gid"][(gid[order][at] != members["gid"]) if len(gid) else slice(None)][0]
        raise ValueError(f"clump member gid {int(bad)} is not a sphere of the scene")
    if len(members["gid"]) and np.any(np.asarray(cols["clump"])[order][at] != members["clump"]):
        k = int(np.flatnonzero(np.asarray(cols["clump"])[order][at] != members["clump"])[0])
        raise ValueError(f"sphere gid {int(members['gid'][k])} is a member of clump {int(members['clump'][k])} but its "
                         f"clump column says {int(np.asarray(cols['clump'])[order][at][k])}")
    lonely = np.setdiff1d(clumps["id"], members["clump"])
    if len(lonely):
        raise ValueError(f"clump {int(lonely[0])} has no members")
    if len(np.unique(clumps["id"])) != len(clumps["id"]):
        raise ValueError("two clumps have the same id")
