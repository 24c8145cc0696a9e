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

from .kernels import kernel
from .vec import dot3


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
def _scan(i, pos, radius, gid, n_local, skin, lo, dims, cell_size, cell_start, cell_items, buf, base, width):
    """Partners j of body i (gid[j] > gid[i], not both ghosts, closer than r_i + r_j + skin),
    written in cell order to ``buf[base : base + width]``; returns their number.

    Branch-free in the tests (the gid test is a coin toss, a branch on it was mispredicted for
    half of the ~80 rows scanned per body): every scanned row is written to the next free slot
    and the count advances only for a partner. The slots are valid only if the count is below
    `width` (the caller retries with a wider buffer otherwise). The three cells along z of each
    (x, y) column are contiguous in the cell order, so 9 runs of rows are scanned, not 27 cells."""
    cnt = 0
    ci0 = min(int((pos[i, 0] - lo[0]) / cell_size), dims[0] - 1)
    ci1 = min(int((pos[i, 1] - lo[1]) / cell_size), dims[1] - 1)
    ci2 = min(int((pos[i, 2] - lo[2]) / cell_size), dims[2] - 1)
    z0 = max(ci2 - 1, 0)
    z1 = min(ci2 + 1, dims[2] - 1)
    gi = gid[i]
    ghost_i = i >= n_local
    last = base + width - 1
    for cx in range(max(ci0 - 1, 0), min(ci0 + 2, dims[0])):
        for cy in range(max(ci1 - 1, 0), min(ci1 + 2, dims[1])):
            col = (cx * dims[1] + cy) * dims[2]
            for k in range(cell_start[col + z0], cell_start[col + z1 + 1]):
                j = cell_items[k]
                dx = pos[j, 0] - pos[i, 0]
                dy = pos[j, 1] - pos[i, 1]
                dz = pos[j, 2] - pos[i, 2]
                cut = radius[i] + radius[j] + skin
                near = dot3(dx, dy, dz, dx, dy, dz) <= cut * cut
                take = near & (gid[j] > gi) & ((not ghost_i) | (j < n_local))
                buf[min(base + cnt, last)] = j
                cnt += np.int64(take)
    return cnt


@kernel(size_arg=4)
def build_sphere_pairs(pos, radius, gid, n_local, n_total, skin, cell_size, max_cells):
    """Verlet list (pi, pj) over rows [0, n_total); partners of each i sorted by gid.

    One scan per body into a buffer of `width` slots per body (widened and rescanned in the rare
    case a body has more partners), then compaction and an insertion sort by gid."""
    lo, dims, cs, cell_start, cell_items = bin_cells(pos, n_total, cell_size, max_cells)
    counts = np.zeros(n_total + 1, np.int64)
    width = 16
    while True:
        buf = np.empty(max(n_total, 1) * width, np.int64)
        for i in prange(n_total):
            counts[i + 1] = _scan(i, pos, radius, gid, n_local, skin, lo, dims, cs, cell_start, cell_items, buf,
                                  i * width, width)
        most = 0
        for i in range(n_total):
            most = max(most, counts[i + 1])
        if most < width:
            break
        width = most + 1
    for i in range(n_total):
        counts[i + 1] += counts[i]
    m = counts[n_total]
    pi = np.empty(m, np.int64)
    pj = np.empty(m, np.int64)
    for i in prange(n_total):
        a = counts[i]
        b = counts[i + 1]
        base = i * width
        for k in range(a, b):
            pi[k] = i
            pj[k] = buf[base + k - a]
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


@njit(cache=True)
def build_incidence(n_local, n_pairs, pi, pj, gid):
    """Per owned body, its sphere pairs sorted by partner gid (CSR).

    Returns (ptr[n_local+1], pair[m], first[m]) with first = 1 where the body is pair's i."""
    ptr = np.zeros(n_local + 1, np.int64)
    for p in range(n_pairs):
        if pi[p] < n_local:
            ptr[pi[p] + 1] += 1
        if pj[p] < n_local:
            ptr[pj[p] + 1] += 1
    for b in range(n_local):
        ptr[b + 1] += ptr[b]
    m = ptr[n_local]
    pair = np.empty(m, np.int64)
    first = np.empty(m, np.int8)
    fill = ptr[:-1].copy()
    for p in range(n_pairs):
        i = pi[p]
        j = pj[p]
        if i < n_local:
            pair[fill[i]] = p
            first[fill[i]] = 1
            fill[i] += 1
        if j < n_local:
            pair[fill[j]] = p
            first[fill[j]] = 0
            fill[j] += 1
    for b in range(n_local):
        a = ptr[b]
        e = ptr[b + 1]
        for k in range(a + 1, e):
            vp = pair[k]
            vf = first[k]
            g = gid[pj[vp]] if vf == 1 else gid[pi[vp]]
            q = k - 1
            while q >= a:
                gq = gid[pj[pair[q]]] if first[q] == 1 else gid[pi[pair[q]]]
                if gq <= g:
                    break
                pair[q + 1] = pair[q]
                first[q + 1] = first[q]
                q -= 1
            pair[q + 1] = vp
            first[q + 1] = vf
    return ptr, pair, first


@njit(cache=True)
def candidates_from_mask(near):
    """(ptr[n+1], sphere[m], boundary[m]) CSR of the true entries of ``near[n, nb]``, in boundary
    index order per sphere: the candidate lists of walls, facets and boxes."""
    n, nb = near.shape
    ptr = np.zeros(n + 1, np.int64)
    for s in range(n):
        ptr[s + 1] = ptr[s] + np.count_nonzero(near[s])
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
            near[s, f] = _near_facet(pos[s, 0], pos[s, 1], pos[s, 2], radius[s] + skin, facet_geom[f], facet_vertices[f])
    return candidates_from_mask(near)


@kernel(size_arg=2)
def max_displacement(pos, pos_at_rebuild, n):
    """Largest distance a body moved since the last rebuild [m]."""
    m = 0.0
    for k in prange(n):
        dx = pos[k, 0] - pos_at_rebuild[k, 0]
        dy = pos[k, 1] - pos_at_rebuild[k, 1]
        dz = pos[k, 2] - pos_at_rebuild[k, 2]
        m = max(m, dx * dx + dy * dy + dz * dz)
    return sqrt(m)


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
def build_box_candidates(pos, radius, n_local, skin, box_center, box_half):
    """(ptr[n_local+1], sphere[m], box[m]): boxes within r + skin of each owned sphere (distance
    from the centre to the box's AABB), in box index order per sphere."""
    near = np.zeros((n_local, box_center.shape[0]), np.bool_)
    for s in range(n_local):
        for b in range(box_center.shape[0]):
            near[s, b] = _near_box(pos, s, radius[s] + skin, box_center[b], box_half[b])
    return candidates_from_mask(near)


@njit(cache=True)
def cell_order(pos, n, cell_size, max_cells):
    """Rows [0, n) in linear cell order (x slowest, z fastest; cells of `cell_size` over their
    bounding box), rows of one cell in their current order: order[new_row] = old_row.

    Sorting the owned rows this way at every rebuild keeps contact partners close in memory
    (the candidate list runs over rows, so a pair's bodies are neighbours in the arrays too).
    Rows are storage only: sums and keys go by gid, so the order never changes a result."""
    return bin_cells(pos, n, cell_size, max_cells)[4]
