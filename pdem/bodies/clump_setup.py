"""Declaring clumps: member spheres, rigid-clump rows and bonds, checked, as `pdem.build.scene.Scene`
builds them (`Scene.add_clumps`, `Scene.add_clump`, `Scene.add_breakable_clump`).

`member_sets` checks the member lists (at least 2 spheres, radii > 0, one connected body of
overlapping or touching spheres, `pdem.bodies.bonds.touching_pairs`); `rigid_rows` computes each rigid
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
from ..build.validate import number, vector3, vectors


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
        if np.ndim(radius) == 0:
            r = np.full(n, number(f"{where}.member_radius", radius, 0.0, lo_open=True, allow="a number > 0 [m]"))
        else:
            try:
                r = np.asarray(radius, np.float64)
            except (TypeError, ValueError):
                r = np.full(n, np.nan)
        if r.shape != (n,) or not np.all(np.isfinite(r) & (r > 0)):
            raise InputError(f"{where}.member_radius: must be one number > 0 [m] or {n} of them, got {radius!r:.60}")
        out.append((pos, r, touching_pairs(f"{where}.member_pos", pos, r)))
    return out


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
