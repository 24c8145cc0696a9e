"""Initial packings: loose random clouds of spheres that do not overlap.

`loose_cloud` places spheres on a jittered cubic lattice of spacing a = 2·r_max·(1 + gap) inside a
box, in a random (seeded) order of sites. Each sphere stays inside its lattice cell (side a, wholly
inside the box), so nothing overlaps another sphere or a side of the box at the start, and the
result is the same on every rank and platform (numpy's PCG64 generator). A lattice of more than
`MAX_SITES` sites (tiny spheres in a large box: a radius in the wrong unit) is refused before
its arrays are allocated.
"""
import numpy as np

from ..errors import InputError

MAX_SITES = 2e7  # the most lattice sites of a cloud (its index arrays: about 1.5 GB at the most)


def sphere_radii(n, r_mean, spread, seed):
    """n radii uniform in r_mean·(1 ± spread) [m] (thesis: (0.6–1.4) r for spread 0.4)."""
    rng = np.random.default_rng(seed)
    if spread == 0:
        return np.full(n, float(r_mean))
    return rng.uniform(r_mean * (1 - spread), r_mean * (1 + spread), n)


def loose_cloud(lo, hi, n, r_mean, spread=0.0, seed=0, gap=0.05):
    """(pos[n,3], radius[n]) of n spheres in the box lo..hi [m]; raises InputError if they don't fit."""
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    # the room for the smallest possible largest radius first: a count that cannot fit is
    # refused before arrays of its size are allocated
    r_least = float(r_mean) * (1.0 - float(spread))
    room = np.floor((hi - lo) / (2.0 * r_least * (1.0 + gap)))
    if np.prod(np.maximum(room, 0.0)) < n:
        raise InputError(f"deposition: {n} spheres of radius {r_mean:.4g} m (spread {spread:g}) do not fit in the box "
                         f"{lo.tolist()}..{hi.tolist()} (room for at most {int(np.prod(np.maximum(room, 0.0)))}); "
                         "enlarge the box height or use fewer spheres")
    radius = sphere_radii(n, r_mean, spread, seed)
    r_max = float(radius.max())
    a = 2.0 * r_max * (1.0 + gap)
    counts = np.floor((hi - lo) / a).astype(int)
    if np.any(counts < 1) or np.prod(counts) < n:
        raise InputError(
            f"deposition: {n} spheres of radius up to {r_max:.4g} m do not fit in the box {lo.tolist()}..{hi.tolist()} "
            f"(room for {max(int(np.prod(np.maximum(counts, 0))), 0)}); enlarge the box height or use fewer spheres"
        )
    if np.prod(counts.astype(float)) > MAX_SITES:  # the arrays of the lattice would not fit in memory
        raise InputError(f"deposition: {n} spheres of radius {r_mean:.4g} m in the box {lo.tolist()}..{hi.tolist()} "
                         f"need a lattice of {np.prod(counts.astype(float)):.3g} sites, more than {MAX_SITES:.0e} "
                         "(a radius given in the wrong unit?)")
    rng = np.random.default_rng(seed + 1)
    ix, iy, iz = np.meshgrid(*(np.arange(c) for c in counts), indexing="ij")
    sites = np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1)
    # fill from the bottom up, random within a layer
    order = np.lexsort((rng.random(len(sites)), sites[:, 2]))[:n]
    jitter = rng.uniform(-0.5, 0.5, (n, 3)) * (a - 2.0 * radius[:, None])
    pos = lo + 0.5 * a + sites[order] * a + jitter * 0.9
    return pos, radius
