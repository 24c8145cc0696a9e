"""Bonds of breakable clumps: which member pairs are bonded, and the bonded contact rows made at
set-up (SPEC 1.2; thesis 4.5; YADE_MODEL.md §6).

A breakable clump is a group of spheres (each an ordinary sphere, ``clump`` = the group's id)
joined by bonds: contacts of a law with bonds (`pdem.contact.cohesive`) made when the scene is
built between every two members that overlap or touch (centre distance ≤ (r_i + r_j)(1 +
`TOUCH`)). A bond is contact history like any other (parameters, history), so it migrates with
its spheres, is checkpointed and breaks by the law; a broken bond is an ordinary frictional
contact until the spheres part.

`touching_pairs` finds the pairs of a member list and checks that they join every member;
`bonded_rows` makes the contact rows (keys, parameters, history) of the bonds of a scene.
Units: m.
"""
import numpy as np

from ..contact.loops import NORMAL_COLUMNS
from ..contact.store import KEY_SHIFT_SPHERE
from ..errors import InputError

TOUCH = 1e-9  # relative gap still counted as touching (grid-placed members touch up to roundoff)


def touching_pairs(label, pos, radius):
    """(i[m], j[m]), i < j, of the member pairs that overlap or touch; InputError (one line,
    naming ``label``) if the members do not form one connected body."""
    pos = np.asarray(pos, np.float64)
    r = np.asarray(radius, np.float64)
    n = len(r)
    d = pos[None, :, :] - pos[:, None, :]
    dist = np.sqrt(np.einsum("ijk,ijk->ij", d, d))
    touch = dist <= (r[:, None] + r[None, :]) * (1.0 + TOUCH)
    np.fill_diagonal(touch, False)
    # connected components by repeated propagation from member 0
    reached = np.zeros(n, bool)
    reached[0] = True
    while True:
        more = reached | touch[reached].any(axis=0)
        if more.sum() == reached.sum():
            break
        reached = more
    if not reached.all():
        k = int(np.flatnonzero(~reached)[0])
        raise InputError(f"{label}: member {k} at {pos[k].tolist()} (r {r[k]:g} m) neither overlaps nor touches "
                         f"the other members (a clump's members must form one connected body)")
    i, j = np.nonzero(np.triu(touch, 1))
    return i.astype(np.int64), j.astype(np.int64)


def bonded_rows(law, props, pos, radius, material, gid1, gid2, row_of, stress_free, step=0):
    """Contact rows of bonds between the spheres ``gid1[k] < gid2[k]``, made now.

    ``pos``/``radius``/``material``: columns of all spheres, ``row_of(gids)`` their rows.
    Returns (key, params, history) for `ContactList.add_carried` of the sphere pairs: the law's
    parameters and bond history (`law.bond_rows`), the creation step, and the current normal in
    the geometry's history columns (so that the first step computes exactly what a contact made
    in that step would: zero rotation of a zero shear force)."""
    a, b = row_of(gid1), row_of(gid2)
    d = pos[b] - pos[a]
    dist = np.sqrt(d[:, 0] * d[:, 0] + (d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]))
    pen = (radius[a] + radius[b]) - dist
    normal = d / dist[:, None]
    lp, lh = law.bond_rows(props, material[a], material[b], radius[a], radius[b], pen, stress_free)
    params = np.concatenate([lp, np.full((len(a), 1), float(step))], axis=1)
    history = np.concatenate([lh, normal, np.zeros((len(a), NORMAL_COLUMNS - 3))], axis=1)
    key = (np.asarray(gid1, np.int64) << KEY_SHIFT_SPHERE) | np.asarray(gid2, np.int64)
    return key, params, history, pen


def check_bond_strengths(law, props, names, material):
    """InputError unless every material in ``material`` has c_N > 0 and c_T > 0."""
    cn, ct = law.bond_strengths(props, np.asarray(material, np.int64))
    for m, a, b in zip(material, cn, ct):
        if not (a > 0.0 and b > 0.0):
            key, v = ("normal_cohesion", a) if not a > 0.0 else ("shear_cohesion", b)
            raise InputError(f"materials.{names[m]}.{key} = {float(v)!r}: must be > 0 [Pa] for bonds (the scene bonds "
                             "spheres of this material)")
