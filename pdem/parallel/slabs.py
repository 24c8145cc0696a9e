"""Slab decomposition along one axis: pure functions of coordinates and edges.

Owns: slab edges (uniform and load-balanced), the owner rank of a coordinate, the neighbour
ranks that need a body as a ghost, and the load-imbalance measure.  Everything here is plain
numpy on arrays and scalars, deterministic, and unit-tested without MPI; it must not import
mpi4py or ``pdem.parallel.comm`` (STYLE §7).

Conventions
-----------
``edges`` is an increasing ``float64[size + 1]`` array; rank ``r`` owns the half-open slab
``[edges[r], edges[r + 1])``.  A coordinate exactly on an interior edge therefore belongs to the
*upper* slab.  Coordinates below ``edges[0]`` belong to rank 0 and coordinates at or above
``edges[-1]`` to rank ``size - 1`` (bodies that leave the box stay owned by an end slab), so
every coordinate has exactly one owner.
"""

import numpy as np

__all__ = ["balanced_edges", "ghost_destinations", "imbalance", "owner", "uniform_edges"]


def uniform_edges(lo, hi, size):
    """Edges of ``size`` equal slabs covering ``[lo, hi]``.

    Parameters
    ----------
    lo, hi : float
        Extent of the decomposed axis [m], ``lo < hi``.
    size : int
        Number of slabs (ranks), >= 1.

    Returns
    -------
    edges : float64[size + 1]
        ``edges[0] == lo`` and ``edges[-1] == hi`` exactly.
    """
    size = int(size)
    if size < 1:
        raise ValueError(f"size must be >= 1, got {size}")
    if not hi > lo:
        raise ValueError(f"need lo < hi, got lo={lo}, hi={hi}")
    edges = np.linspace(float(lo), float(hi), size + 1)
    edges[0], edges[-1] = lo, hi
    return edges


def max_slabs(lo, hi, width):
    """The most slabs `uniform_edges` can cut ``[lo, hi]`` into with every interior slab at
    least ``width`` thick (the tolerance of `ghost_destinations`); two slabs have no interior
    one, so at least 2."""
    span, width = float(hi) - float(lo), float(width)
    if not width > 0 or not span > 0:
        return 2
    return max(2, int(np.floor(span / (width * (1.0 - 1e-9)))))


def _check_edges(edges):
    edges = np.asarray(edges, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2:
        raise ValueError(f"edges must be 1-D with at least 2 entries, got shape {edges.shape}")
    if not np.all(np.diff(edges) > 0):
        raise ValueError(f"edges must be strictly increasing: {edges}")
    return edges


def owner(x, edges):
    """Rank that owns each coordinate.

    Parameters
    ----------
    x : float or array_like of float
        Coordinates along the decomposed axis [m].
    edges : float64[size + 1]
        Slab edges (see the module docstring).

    Returns
    -------
    int or int64 array (same shape as ``x``)
        ``r`` with ``edges[r] <= x < edges[r + 1]``; a coordinate on an interior edge goes to
        the upper slab; below the first edge -> 0; at or above the last edge -> ``size - 1``.
    """
    edges = _check_edges(edges)
    size = edges.size - 1
    xa = np.asarray(x, dtype=np.float64)
    r = np.searchsorted(edges, xa, side="right") - 1
    r = np.clip(r, 0, size - 1).astype(np.int64)
    if xa.ndim == 0:
        return int(r)
    return r


def ghost_destinations(x, edges, width, owners=None):
    """Neighbour ranks that must hold each body as a ghost.

    A body owned by rank ``o`` is a ghost on rank ``o - 1`` if its distance to that slab,
    ``x - edges[o]``, is ``<= width``, and on rank ``o + 1`` if ``edges[o + 1] - x <= width``.
    Only immediate neighbours are considered, which is exact when every interior slab is at
    least ``width`` thick (checked, with a relative tolerance of 1e-9 so that rounding in the
    edges, e.g. ``uniform_edges(0, 1, 5)`` with ``width=0.2``, is accepted).

    Parameters
    ----------
    x : array_like of float, shape (n,)
        Coordinates along the decomposed axis [m].
    edges : float64[size + 1]
        Slab edges.
    width : float
        Halo width [m]: maximum contact range plus the Verlet skin (2 r_max + skin, wider for
        clumps).
    owners : int array, shape (n,), optional
        The rank that owns each body (default ``owner(x, edges)``); a rigid clump's member is
        owned with its clump and may lie outside its owner's slab.

    Returns
    -------
    dest : int64[n, 2]
        ``dest[i, 0]`` is the lower neighbour rank (``owner - 1``) or -1, ``dest[i, 1]`` the upper
        neighbour rank (``owner + 1``) or -1.  ``dest[:, 0] >= 0`` selects what to send "lo".

    Raises
    ------
    ValueError
        If ``width`` is negative or an interior slab (ranks ``1 .. size-2``) is thinner than
        ``width``: a halo would then reach past the immediate neighbour.
    """
    edges = _check_edges(edges)
    width = float(width)
    if not width >= 0:
        raise ValueError(f"halo width must be >= 0, got {width}")
    size = edges.size - 1
    thick = np.diff(edges)
    thin = [r for r in range(1, size - 1) if thick[r] < width * (1.0 - 1e-9)]
    if thin:
        raise ValueError(
            f"slab(s) {thin} thinner than the halo width {width:g} m "
            f"(thicknesses {thick[thin].tolist()}); use fewer ranks or balanced_edges(..., "
            f"min_thickness=width)"
        )
    xa = np.asarray(x, dtype=np.float64).reshape(-1)
    own = owner(xa, edges) if owners is None else np.asarray(owners, np.int64).reshape(-1)
    dest = np.full((xa.size, 2), -1, dtype=np.int64)
    if size == 1:
        return dest
    to_lo = (own > 0) & (xa - edges[own] <= width)
    to_hi = (own < size - 1) & (edges[own + 1] - xa <= width)
    dest[to_lo, 0] = own[to_lo] - 1
    dest[to_hi, 1] = own[to_hi] + 1
    return dest


def balanced_edges(x, weights, size, lo, hi, min_thickness=0.0):
    """Edges that give each of ``size`` slabs about the same total weight.

    The interior edges are weighted quantiles of ``x``: edge ``k`` splits the bodies, sorted by
    ``(x, weight)``, where the running weight is closest to ``k / size`` of the total, and lies
    midway between the last body of the lower slab and the first of the upper one.  The result
    depends only on the multiset of ``(x, weight)`` pairs, not on their order (so it is the same
    whatever the rank count that gathered them).  Then each slab is made at least
    ``min_thickness`` thick (edges pushed apart, lower edges first).

    Parameters
    ----------
    x : array_like of float, shape (n,)
        Body coordinates along the decomposed axis [m]; clipped to ``[lo, hi]``.
    weights : array_like of float, shape (n,) or scalar
        Work per body (e.g. 1 + number of contacts), >= 0.
    size : int
        Number of slabs.
    lo, hi : float
        First and last edge [m].
    min_thickness : float
        Minimum slab thickness [m], typically the halo width.  0 means "strictly increasing"
        (a floor of ``(hi - lo) * 1e-9``).

    Returns
    -------
    edges : float64[size + 1]
        ``edges[0] == lo``, ``edges[-1] == hi``, strictly increasing.  With no bodies or zero
        total weight, ``uniform_edges(lo, hi, size)``.
    """
    edges = uniform_edges(lo, hi, size)
    lo, hi, size = float(lo), float(hi), int(size)
    # Floor for "strictly increasing": well above the spacing of doubles near the edges.
    min_t = max(float(min_thickness), (hi - lo) * 1e-9, 16 * np.spacing(max(abs(lo), abs(hi))))
    if size * min_t > hi - lo:
        raise ValueError(
            f"{size} slabs of at least {min_t:g} m do not fit into [{lo:g}, {hi:g}]: "
            f"use fewer ranks or a smaller halo"
        )
    xa = np.clip(np.asarray(x, dtype=np.float64).reshape(-1), lo, hi)
    w = np.broadcast_to(np.asarray(weights, dtype=np.float64), xa.shape)
    if w.size and not np.all(np.isfinite(w) & (w >= 0)):
        raise ValueError("weights must be finite and >= 0")
    if size > 1 and xa.size and w.sum() > 0:
        order = np.lexsort((w, xa))  # by x, then weight: independent of the input order
        xs, ws = xa[order], w[order]
        cum = np.cumsum(ws)  # deterministic: fixed order
        total = cum[-1]
        xpad = np.concatenate(([lo], xs, [hi]))
        for k in range(1, size):
            target = total * k / size
            i = int(np.searchsorted(cum, target, side="left"))  # cum[i-1] < target <= cum[i]
            i = min(i, xs.size - 1)
            below = cum[i - 1] if i > 0 else 0.0
            j = i if cum[i] - target < target - below else i - 1  # last body of the lower slab
            edges[k] = 0.5 * (xpad[j + 1] + xpad[j + 2])
    # Thickness: clamp edge k into [lo + k*min_t, hi - (size-k)*min_t], then push upward.
    for k in range(1, size):
        edges[k] = min(max(edges[k], lo + k * min_t), hi - (size - k) * min_t)
    for k in range(1, size):
        edges[k] = max(edges[k], edges[k - 1] + min_t)
    edges[0], edges[-1] = lo, hi
    return edges


def imbalance(loads):
    """Load imbalance ``max(loads) / mean(loads)`` (1 is perfect; 1.0 if all loads are 0)."""
    loads = np.asarray(loads, dtype=np.float64).reshape(-1)
    if loads.size == 0:
        raise ValueError("imbalance of no loads")
    mean = loads.mean()
    if mean <= 0:
        return 1.0
    return float(loads.max() / mean)
