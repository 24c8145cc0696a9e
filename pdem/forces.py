"""Sums of contact forces per body, in a fixed order (race-free, rank- and thread-invariant).

Every body's force and torque are summed from zero in this order: its sphere partners by
increasing gid, then walls by index, then facets by index. The order depends only on global ids
and indices, never on rows, threads or ranks, so any decomposition gives the same bits.
Also: order-independent totals on walls (exact sums, `pdem.exactsum`).
"""
from numba import prange

from .kernels import kernel


@kernel()
def sum_sphere_pairs(n_local, inc_ptr, inc_pair, inc_first, pair_force, pair_torque_i, pair_torque_j, force, torque):
    """force/torque[b] = Σ over b's sphere pairs by partner gid (+f on i, −f on j).

    Branch-free in the side of the pair (whether b is the pair's i is random in a packing, and a
    branch on it was mispredicted half of the time): ``s·f`` with s = ±1 is exactly ``f`` or
    ``-f``, and the torque row is picked by a select, so the sums are bit-identical."""
    for b in prange(n_local):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for k in range(inc_ptr[b], inc_ptr[b + 1]):
            p = inc_pair[k]
            first = inc_first[k] == 1
            s = 2.0 * first - 1.0
            tq = pair_torque_i if first else pair_torque_j
            fx += s * pair_force[p, 0]
            fy += s * pair_force[p, 1]
            fz += s * pair_force[p, 2]
            tx += tq[p, 0]
            ty += tq[p, 1]
            tz += tq[p, 2]
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
