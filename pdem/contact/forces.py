"""Sums of contact forces per body, in a fixed order (race-free, rank- and thread-invariant).

Every body's force and torque are summed from zero in this order: its sphere partners by
increasing gid, then walls by index, then facets by index. The order depends only on global ids
and indices, never on rows, threads or ranks, so any decomposition gives the same bits.
Also: order-independent totals on boundary bodies (walls, boxes: exact sums, `pdem.exactsum`).
"""
import numpy as np
from numba import njit, prange

from ..exactsum import NLIMBS, acc_add, acc_normalize
from ..kernels import kernel


@kernel()
def sum_sphere_pairs(n_local, inc_ptr, slot_f, slot_t, force, torque):
    """force/torque[b] = Σ over b's slots (its sphere pairs by partner gid; +f, torque_1 where b
    is the pair's body 1, −f, torque_2 where it is body 2: written by the pair loop,
    `pdem.contact.loops`). The slots of a body are contiguous, so this is a streaming pass."""
    for b in prange(n_local):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for k in range(inc_ptr[b], inc_ptr[b + 1]):
            fx += slot_f[k, 0]
            fy += slot_f[k, 1]
            fz += slot_f[k, 2]
            tx += slot_t[k, 0]
            ty += slot_t[k, 1]
            tz += slot_t[k, 2]
        force[b, 0] = fx
        force[b, 1] = fy
        force[b, 2] = fz
        torque[b, 0] = tx
        torque[b, 1] = ty
        torque[b, 2] = tz


@kernel()
def add_sphere_contacts(n_local, ptr, contact_force, contact_torque, force, torque):
    """Add wall or facet contact forces (rows grouped per sphere, CSR `ptr`) to the bodies."""
    for b in prange(n_local):
        for p in range(ptr[b], ptr[b + 1]):
            for c in range(3):
                force[b, c] += contact_force[p, c]
                torque[b, c] += contact_torque[p, c]


@kernel()
def zero_forces(n_local, force, torque):
    for b in prange(n_local):
        for c in range(3):
            force[b, c] = 0.0
            torque[b, c] = 0.0


@njit(cache=True)
def boundary_totals_acc(n, state, j, force, body_of, n_bodies):
    """Exact accumulators (`pdem.exactsum`) of the force of the spheres on each boundary body:
    Σ −force[p] over the real rows p (state 1) of a boundary contact list, into body
    ``body_of[j[p]]``: int64[n_bodies * 3, NLIMBS], body-major (finish with
    `pdem.parallel.comm` ``exact_sum_accumulators``)."""
    accs = np.zeros((n_bodies * 3, NLIMBS), np.int64)
    for p in range(n):
        if state[p] == 1:
            g = body_of[j[p]]
            for c in range(3):
                acc_add(accs[g * 3 + c], -force[p, c])
    for r in range(n_bodies * 3):
        acc_normalize(accs[r])
    return accs
