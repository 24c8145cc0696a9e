"""Neighbour search: linked cells plus a Verlet list with a skin (njit).

Candidates are pairs closer than r_i + r_j + skin; the list is rebuilt only when some body has
moved more than skin/2 since the last rebuild (then no contact can be missed). A sphere–sphere
pair is listed once, with ``gid[i] < gid[j]``, and only if at least one of the two is owned
(rows < n_local); ghost–ghost pairs belong to other ranks. Within each first body the partners
are sorted by gid, so the list does not depend on row order. Walls and facets get candidate lists
per owned sphere in index order.
"""
from math import floor, sqrt

import numpy as np
from numba import njit, prange

from ..kernels import kernel
from ..vec import dot3


@njit(cache=True)
def bin_cells(pos, n, cell_size, max_cells):
    """Counting sort of rows [0, n) into a grid over their bounding box.

    Returns (lo[3], dims[3], cell_size, cell_start[ncell+1], cell_items[n])."""
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = np.inf
        hi[a] = -np.inf
    for k in range(n):
        for a in range(3):
            lo[a] = min(lo[a], pos[k, a])
            hi[a] = max(hi[a], pos[k, a])
    dims = np.ones(3, np.int64)
    while True:
        total = 1
        for a in range(3):
            dims[a] = max(1, int(floor((hi[a] - lo[a]) / cell_size)) + 1) if n > 0 else 1
            total *= dims[a]
        if total <= max_cells:
            break
        cell_size *= 1.26
    cell_of = np.empty(n, np.int64)
    counts = np.zeros(total + 1, np.int64)
    for k in range(n):
        c = 0
        for a in range(3):
            ia = min(int((pos[k, a] - lo[a]) / cell_size), dims[a] - 1)
            c = c * dims[a] + ia
        cell_of[k] = c
        counts[c + 1] += 1
    for c in range(total):
        counts[c + 1] += counts[c]
    fill = counts[:-1].copy()
    items = np.empty(n, np.int64)
    for k in range(n):
        c = cell_of[k]
        items[fill[c]] = k
        fill[c] += 1
    return lo, dims, cell_size, counts, items


@njit(inline="always", cache=True)
def _run(u, k0, k1, pos, radius, n_local, skin, cell_items, buf, cnt, base, last):
    """Rows ``cell_items[k0:k1]`` closer to body u than r_u + r_v + skin (not both ghosts):
    appended to ``buf[base + cnt ...]`` without branching on the tests (a coin toss per row,
    mispredicted half of the time as a branch); returns the new count. A slot is written for
    every row and kept only if the count advances; slots past `last` all land on `last`."""
    ghost_u = u >= n_local
    for k in range(k0, k1):
        v = cell_items[k]
        dx = pos[v, 0] - pos[u, 0]
        dy = pos[v, 1] - pos[u, 1]
        dz = pos[v, 2] - pos[u, 2]
        cut = radius[u] + radius[v] + skin
        take = (dot3(dx, dy, dz, dx, dy, dz) <= cut * cut) & ((not ghost_u) | (v < n_local))
        buf[min(base + cnt, last)] = v
        cnt += np.int64(take)
    return cnt


@njit(inline="always", cache=True)
def _scan_half(a, pos, radius, n_local, skin, lo, dims, cell_size, cell_start, cell_items, buf, base, width):
    """Neighbours of the body at position `a` of the cell order among the bodies after it: the
    rest of its cell and the 13 neighbour cells of larger linear index, so that every pair of
    bodies is met once (half the rows of a full 27-cell scan). In the cell order these are 5
    runs of rows: its own z column from `a` on, the column at y + 1, the three at x + 1."""
    u = cell_items[a]
    c0 = min(int((pos[u, 0] - lo[0]) / cell_size), dims[0] - 1)
    c1 = min(int((pos[u, 1] - lo[1]) / cell_size), dims[1] - 1)
    c2 = min(int((pos[u, 2] - lo[2]) / cell_size), dims[2] - 1)
    z0 = max(c2 - 1, 0)
    z1 = min(c2 + 1, dims[2] - 1)
    last = base + width - 1
    col = (c0 * dims[1] + c1) * dims[2]
    cnt = _run(u, a + 1, cell_start[col + z1 + 1], pos, radius, n_local, skin, cell_items, buf, 0, base, last)
    if c1 + 1 < dims[1]:
        col = (c0 * dims[1] + c1 + 1) * dims[2]
        cnt = _run(u, cell_start[col + z0], cell_start[col + z1 + 1], pos, radius, n_local, skin, cell_items, buf,
                   cnt, base, last)
    if c0 + 1 < dims[0]:
        for cy in range(max(c1 - 1, 0), min(c1 + 2, dims[1])):
            col = ((c0 + 1) * dims[1] + cy) * dims[2]
            cnt = _run(u, cell_start[col + z0], cell_start[col + z1 + 1], pos, radius, n_local, skin, cell_items, buf,
                       cnt, base, last)
    return cnt


@kernel(size_arg=4)
def build_sphere_pairs(pos, radius, gid, n_local, n_total, skin, cell_size, max_cells):
    """Verlet list (pi, pj) over rows [0, n_total): every pair closer than r_i + r_j + skin,
    not both ghosts, listed once under its body of lower gid (pi ascending); partners of each i
    sorted by gid. `cell_size` must be at least the largest r_i + r_j + skin.

    Each pair is found once (`_scan_half`, into a buffer of `width` slots per body, widened and
    rescanned in the rare case a body has more), then given to its lower-gid body (counting
    sort by that body) and the partners are insertion-sorted by gid. The list does not depend
    on the row order. (A full 27-cell scan per body finds each pair twice and took 1.7x as long
    at 50k bodies.)"""
    lo, dims, cs, cell_start, cell_items = bin_cells(pos, n_total, cell_size, max_cells)
    found = np.zeros(n_total, np.int64)
    width = 16
    while True:
        buf = np.empty(max(n_total, 1) * width, np.int64)
        for a in prange(n_total):
            found[a] = _scan_half(a, pos, radius, n_local, skin, lo, dims, cs, cell_start, cell_items, buf, a * width,
                                  width)
        most = 0
        for a in range(n_total):
            most = max(most, found[a])
        if most < width:
            break
        width = most + 1
    # each pair to its body of lower gid
    ptr = np.zeros(n_total + 1, np.int64)
    for a in range(n_total):
        u = cell_items[a]
        for k in range(a * width, a * width + found[a]):
            v = buf[k]
            ptr[(u if gid[u] < gid[v] else v) + 1] += 1
    for i in range(n_total):
        ptr[i + 1] += ptr[i]
    m = ptr[n_total]
    pi = np.empty(m, np.int64)
    pj = np.empty(m, np.int64)
    fill = ptr[:-1].copy()
    for a in range(n_total):
        u = cell_items[a]
        for k in range(a * width, a * width + found[a]):
            v = buf[k]
            if gid[u] < gid[v]:
                pj[fill[u]] = v
                fill[u] += 1
            else:
                pj[fill[v]] = u
                fill[v] += 1
    for i in prange(n_total):
        a = ptr[i]
        b = ptr[i + 1]
        for k in range(a, b):
            pi[k] = i
        # insertion sort of the partners by gid
        for k in range(a + 1, b):
            v = pj[k]
            g = gid[v]
            q = k - 1
            while q >= a and gid[pj[q]] > g:
                pj[q + 1] = pj[q]
                q -= 1
            pj[q + 1] = v
    return pi, pj


@kernel()
def build_incidence(n_local, n_pairs, pi, pj, gid):
    """Per owned body, its sphere pairs sorted by partner gid (CSR).

    Returns (ptr[n_local+1], pair[m], first[m]) with first = 1 where the body is pair's i.
    (The partner gids are gathered once and the per-body insertion sort runs on them, not on
    gid[pj[pair[k]]]: 3 dependent loads and a branch per comparison before.)"""
    ptr = np.zeros(n_local + 1, np.int64)
    for p in range(n_pairs):
        if pi[p] < n_local:
            ptr[pi[p] + 1] += 1
        if pj[p] < n_local:
            ptr[pj[p] + 1] += 1
    for b in range(n_local):
        ptr[b + 1] += ptr[b]
    m = ptr[n_local]
    pair = np.empty(m, np.int32)  # rows of the contact list (int32, as its i and j)
    first = np.empty(m, np.int8)
    pg = np.empty(m, np.int64)  # partner gid of each entry
    fill = ptr[:-1].copy()
    for p in range(n_pairs):
        i = pi[p]
        j = pj[p]
        if i < n_local:
            k = fill[i]
            pair[k] = p
            first[k] = 1
            pg[k] = gid[j]
            fill[i] = k + 1
        if j < n_local:
            k = fill[j]
            pair[k] = p
            first[k] = 0
            pg[k] = gid[i]
            fill[j] = k + 1
    for b in prange(n_local):  # the sort of each body's entries touches only its own range
        a = ptr[b]
        e = ptr[b + 1]
        for k in range(a + 1, e):
            vp = pair[k]
            vf = first[k]
            g = pg[k]
            q = k - 1
            while q >= a and pg[q] > g:
                pair[q + 1] = pair[q]
                first[q + 1] = first[q]
                pg[q + 1] = pg[q]
                q -= 1
            pair[q + 1] = vp
            first[q + 1] = vf
            pg[q + 1] = g
    return ptr, pair, first


@njit(cache=True)
def pair_slots(n_pairs, n_slots, inc_pair, inc_first):
    """slot[n_pairs, 2] (int32): for each pair, the incidence entry (`build_incidence`) of its
    body 1 and of its body 2, −1 where that body is a ghost (no entry)."""
    slot = np.full((n_pairs, 2), -1, np.int32)
    for k in range(n_slots):
        slot[inc_pair[k], 1 - inc_first[k]] = k
    return slot


@njit(cache=True)
def candidates_from_mask(near):
    """(ptr[n+1], sphere[m], boundary[m]) CSR of the true entries of ``near[n, nb]``, in boundary
    index order per sphere: the candidate lists of walls, facets and boxes."""
    n, nb = near.shape
    ptr = np.zeros(n + 1, np.int64)
    for s in range(n):
        c = 0
        for b in range(nb):  # not np.count_nonzero(near[s]): a row view per sphere was 5x slower
            c += np.int64(near[s, b])
        ptr[s + 1] = ptr[s] + c
    ps = np.empty(ptr[n], np.int64)
    pb = np.empty(ptr[n], np.int64)
    k = 0
    for s in range(n):
        for b in range(nb):
            if near[s, b]:
                ps[k] = s
                pb[k] = b
                k += 1
    return ptr, ps, pb


@njit(cache=True)
def build_wall_candidates(pos, radius, n_local, skin, wall_axis, wall_pos):
    """(ptr[n_local+1], sphere[m], wall[m]): walls within r + skin of each owned sphere."""
    near = np.zeros((n_local, wall_axis.shape[0]), np.bool_)
    for s in range(n_local):
        for w in range(wall_axis.shape[0]):
            near[s, w] = abs(pos[s, wall_axis[w]] - wall_pos[w]) <= radius[s] + skin
    return candidates_from_mask(near)


@njit(inline="always", cache=True)
def _near_facet(px, py, pz, reach, g, verts):
    """Distance from a point to the triangle's plane and bounding box within `reach`."""
    d = abs(dot3(g[3], g[4], g[5], px - g[0], py - g[1], pz - g[2]))
    if d > reach:
        return False
    for a in range(3):
        lo = min(verts[0, a], min(verts[1, a], verts[2, a]))
        hi = max(verts[0, a], max(verts[1, a], verts[2, a]))
        x = px if a == 0 else (py if a == 1 else pz)
        if x < lo - reach or x > hi + reach:
            return False
    return True


@njit(cache=True)
def build_facet_candidates(pos, radius, n_local, skin, facet_geom, facet_vertices):
    """(ptr[n_local+1], sphere[m], facet[m]): facets within r + skin of each owned sphere."""
    near = np.zeros((n_local, facet_geom.shape[0]), np.bool_)
    for s in range(n_local):
        for f in range(facet_geom.shape[0]):
            near[s, f] = _near_facet(
                pos[s, 0], pos[s, 1], pos[s, 2], radius[s] + skin, facet_geom[f], facet_vertices[f]
            )
    return candidates_from_mask(near)


@kernel(size_arg=4)
def max_motion(pos, pos_at_rebuild, vel, radius, n):
    """(largest distance a body moved since the last rebuild [m], largest |v|/r [1/s]): the
    rebuild test and the runaway guard's step displacement |v|·Δt/r in one pass. A non-finite
    position or velocity gives |v|/r = inf (the guard then names the body), never a NaN that a
    max would silently drop."""
    m = 0.0
    w = 0.0
    for k in prange(n):
        dx = pos[k, 0] - pos_at_rebuild[k, 0]
        dy = pos[k, 1] - pos_at_rebuild[k, 1]
        dz = pos[k, 2] - pos_at_rebuild[k, 2]
        d2 = dx * dx + dy * dy + dz * dz
        v2 = vel[k, 0] * vel[k, 0] + vel[k, 1] * vel[k, 1] + vel[k, 2] * vel[k, 2]
        q = v2 / (radius[k] * radius[k])
        if not (q < np.inf and d2 < np.inf):  # NaN or inf: max() would drop a NaN; report it as infinitely fast
            q = np.inf
        m = max(m, d2)
        w = max(w, q)
    return sqrt(m), sqrt(w)


@njit(inline="always", cache=True)
def _near_box(pos, s, reach, c, h):
    """True if sphere row s's centre is within `reach` of the box (centre c, half extents h)."""
    d2 = 0.0
    for a in range(3):
        e = abs(pos[s, a] - c[a]) - h[a]
        if e > 0.0:
            d2 += e * e
    return d2 <= reach * reach


@njit(cache=True)
def build_box_candidates(pos, radius, n_local, skin, box_center, box_half, box_smooth):
    """(ptr[n_local+1], sphere[m], box[m]): boxes with flat faces (``box_smooth``) within r + skin
    of each owned sphere (distance from the centre to the box's AABB), in box index order per sphere."""
    near = np.zeros((n_local, box_center.shape[0]), np.bool_)
    for s in range(n_local):
        for b in range(box_center.shape[0]):
            near[s, b] = box_smooth[b] and _near_box(pos, s, radius[s] + skin, box_center[b], box_half[b])
    return candidates_from_mask(near)


@njit(cache=True)
def build_member_candidates(pos, radius, n_local, skin, member_pos, member_radius):
    """(ptr[n_local+1], sphere[m], member[m]): member spheres of boxes (`pdem.bodies.boxes.BoxMembers`)
    whose centre lies within r + r_member + skin of each owned sphere's, in member index order
    per sphere. Spheres outside the members' bounding box (grown by the largest reach) are
    skipped at once."""
    nm = member_pos.shape[0]
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    r_member = 0.0
    for m in range(nm):
        r_member = max(r_member, member_radius[m])
        for a in range(3):
            lo[a] = min(lo[a], member_pos[m, a])
            hi[a] = max(hi[a], member_pos[m, a])
    ptr = np.zeros(n_local + 1, np.int64)
    for sweep in range(2):  # count, then fill
        if sweep == 1:
            ps = np.empty(ptr[n_local], np.int64)
            pm = np.empty(ptr[n_local], np.int64)
        k = 0
        for s in range(n_local):
            reach = radius[s] + r_member + skin
            outside = False
            for a in range(3):
                outside = outside or pos[s, a] < lo[a] - reach or pos[s, a] > hi[a] + reach
            if not outside:
                for m in range(nm):
                    d2 = 0.0
                    for a in range(3):
                        e = pos[s, a] - member_pos[m, a]
                        d2 += e * e
                    reach_m = radius[s] + member_radius[m] + skin
                    if d2 <= reach_m * reach_m:
                        if sweep == 1:
                            ps[k] = s
                            pm[k] = m
                        k += 1
            if sweep == 0:
                ptr[s + 1] = k
    return ptr, ps, pm


@njit(cache=True)
def cell_order(pos, n, cell_size, max_cells):
    """Rows [0, n) in linear cell order (x slowest, z fastest; cells of `cell_size` over their
    bounding box), rows of one cell in their current order: order[new_row] = old_row.

    Sorting the owned rows this way at every rebuild keeps contact partners close in memory
    (the candidate list runs over rows, so a pair's bodies are neighbours in the arrays too).
    Rows are storage only: sums and keys go by gid, so the order never changes a result."""
    return bin_cells(pos, n, cell_size, max_cells)[4]
