"""Clump shapes (member spheres of one grain) and clouds of randomly oriented grains.

Shapes, each centred at the origin, members on a cubic grid of spacing 2r (face neighbours touch,
so the members form one body, and bonds join them when the clump is breakable). ``spacing`` [m]
(≤ 2r, default 2r) puts nearest neighbours closer, so that they overlap by 2r − spacing: the thesis
puts spheres of Ø7.2 mm 7.1 mm apart (4.4–4.5: a cohesive contact needs an initial overlap), and
Yade's bonds made on such an overlap start loaded (``stress_free = false``):

- `shape_members("ellipsoid", r, radii)`: the grid points whose sphere lies inside the ellipsoid of
  semi-axes radii = (R_x, R_y, R_z): Σ (x_k/(R_k − r))² ≤ 1. The thesis generated its clumps so
  (4.1: "the clump's shape depends on the ellipsoid the small spheres are put into"); its table
  4.11 (`THESIS_SHAPES`) gives sphere (24, 24, 24), ellipsoid (24, 30, 19), "cylinder"
  (18, 18, 40) and "cake" (10, 37, 37) mm, chosen to keep the volume: (4/3)π R_x R_y R_z =
  57.9, 57.3, 54.3, 57.3 cm³ as ellipsoids (a true cylinder or disc of those sizes would be 81 or
  86 cm³), so the table's shapes are all ellipsoids.
- `shape_members("cylinder", r, radii)`: a true cylinder along z, elliptic cross-section of
  semi-axes R_x, R_y, half-length R_z.
- `shape_members("cake", r, radii)`: a disc, i.e. a cylinder along x of half-thickness R_x and
  cross-section semi-axes R_y, R_z.
  The grid is centred on a point or on a cell, whichever holds more members (with R = 24 mm,
  r = 8.48 mm the cell-centred grid gives the 2 × 2 × 2 "8-clump" the thesis relates to it).
- `nottingham_grain(r)`: the Nottingham breakable grain (Lim 2004; SPEC 2.2): 135 spheres of
  Ø7.1 mm in face-centred-cubic close packing, a centre sphere and its 7 nearest shells
  (1 + 12 + 6 + 24 + 12 + 24 + 8 + 48 = 135); touching neighbours; outer diameter
  2 (√7 · 2r + r) = 44.7 mm (inside the Ø48 mm grain).
- `ballast8(r)`: the 8-sphere ballast clump (SPEC 2.3, member r = 8.5 mm): 2 × 2 × 2 touching
  spheres at (±r, ±r, ±r).

- `custom_members(members)`: a grain of given spheres, rows (x, y, z, r) [m] about any origin
  (a scene file's ``shape = "custom"``), checked (finite, r > 0, no two on one centre, every
  member touching or overlapping another so that they form one body) and moved so that the
  volume-weighted mean of the member centres (Σ r³ x / Σ r³) is the origin.

`grain_cloud` places ``count`` copies of a shape, each turned by its own uniformly random
rotation (seeded), on a cubic lattice of grain sites inside a box (the thesis puts clumps in a
regular grid, 4.1), filling from the bottom up in random order within a layer. Units: m.
"""
import numpy as np

from ..errors import InputError
from ..build.validate import number, vector3
from .clump_setup import MAX_MEMBERS

THESIS_SHAPES = {"sphere": (0.024, 0.024, 0.024), "ellipsoid": (0.024, 0.030, 0.019),
                 "cylinder": (0.018, 0.018, 0.040), "cake": (0.010, 0.037, 0.037)}  # thesis table 4.11 [m]
SHAPES = ("ellipsoid", "cylinder", "cake")
NOTTINGHAM_MEMBER_RADIUS = 0.00355  # Ø7.1 mm [m]
BALLAST8_MEMBER_RADIUS = 0.0085  # [m]
_TOL = 1e-12


def _inside(shape, p, semi):
    q = p / semi
    if shape == "ellipsoid":
        return np.einsum("ij,ij->i", q, q) <= 1.0 + _TOL
    if shape == "cylinder":
        return (q[:, 0] ** 2 + q[:, 1] ** 2 <= 1.0 + _TOL) & (np.abs(q[:, 2]) <= 1.0 + _TOL)
    return (q[:, 1] ** 2 + q[:, 2] ** 2 <= 1.0 + _TOL) & (np.abs(q[:, 0]) <= 1.0 + _TOL)


def _spacing(r, spacing):
    """The nearest-neighbour distance [m]: 2r if ``spacing`` is None, else the checked value in (0, 2r]."""
    if spacing is None:
        return 2.0 * r
    return number("clumps.member_spacing", spacing, 0.0, 2.0 * r, lo_open=True,
                  allow=f"a number in (0, 2 member_radius = {2.0 * r:g}] [m] (members must touch or overlap)")


def shape_members(shape, member_radius, radii, spacing=None):
    """(pos [n, 3], radius [n]) of the members of one grain of ``shape`` ("ellipsoid",
    "cylinder", "cake") with semi-axes ``radii`` (R_x, R_y, R_z) [m], member radius [m] and grid
    ``spacing`` [m] (default 2 member_radius)."""
    if shape not in SHAPES:
        raise InputError(f"clumps.shape = {shape!r}: must be one of {', '.join(SHAPES)}, nottingham, ballast8")
    r = number("clumps.member_radius", member_radius, 0.0, lo_open=True, allow="a number > 0 [m]")
    h = _spacing(r, spacing)
    big = vector3("clumps.radii", radii)
    if not np.all(big > r):
        raise InputError(f"clumps.radii = {big.tolist()}: every semi-axis must exceed member_radius = {r:g} m")
    semi = big - r
    # before the grid is made (it could exhaust the memory): the members of the largest of the
    # shapes (a cylinder, 2π R_x R_y R_z) grown by one spacing, one per spacing³
    estimate = 2.0 * np.pi * float(np.prod(semi + h)) / h**3
    if estimate > 4 * MAX_MEMBERS or (2 * np.ceil(semi.max() / h) + 3) ** 3 > 1e8:
        _too_many(shape, big, r, h, f"about {estimate:.3g}")
    best = None
    for offset in (0.0, 0.5):  # grid through the centre, or centre in the middle of a cell
        k = np.arange(-int(np.ceil(semi.max() / h)) - 1, int(np.ceil(semi.max() / h)) + 2)
        g = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3) + offset
        p = g * h
        p = p[_inside(shape, p, semi)]
        if best is None or len(p) > len(best):
            best = p
    if len(best) > MAX_MEMBERS:
        _too_many(shape, big, r, h, len(best))
    if len(best) < 2:
        raise InputError(f"clumps.radii = {big.tolist()}: room for {len(best)} member(s) of radius {r:g} m; "
                         "a clump needs at least 2 (use a smaller member_radius)")
    return best, np.full(len(best), r)


def _too_many(shape, radii, r, h, count):
    raise InputError(f"clumps.member_radius = {r:g}: shape {shape!r} of semi-axes {radii.tolist()} m holds {count} "
                     f"members {h:g} m apart; at most {MAX_MEMBERS} are allowed (member_radius, member_spacing or "
                     "radii in the wrong unit?)")


def nottingham_grain(member_radius=NOTTINGHAM_MEMBER_RADIUS, spacing=None):
    """(pos [135, 3], radius [135]): a sphere and its 7 nearest shells of an FCC packing of
    spheres of ``member_radius`` [m], nearest neighbours ``spacing`` [m] apart (default 2r: touching)."""
    r = number("clumps.member_radius", member_radius, 0.0, lo_open=True, allow="a number > 0 [m]")
    h = _spacing(r, spacing)
    k = np.arange(-4, 5)
    g = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3)
    g = g[(g.sum(axis=1) % 2 == 0) & (np.einsum("ij,ij->i", g, g) <= 14)]  # |p|² ≤ 7 (2r)²
    pos = g * (h / np.sqrt(2.0))  # FCC sites (i, j, k)·a/2, i + j + k even, a/2 = h/√2
    return pos, np.full(len(pos), r)


def ballast8(member_radius=BALLAST8_MEMBER_RADIUS, spacing=None):
    """(pos [8, 3], radius [8]): 2 × 2 × 2 spheres of ``member_radius`` [m], ``spacing`` [m] apart
    (default 2r: touching)."""
    r = number("clumps.member_radius", member_radius, 0.0, lo_open=True, allow="a number > 0 [m]")
    h = _spacing(r, spacing)
    g = np.stack(np.meshgrid([-1.0, 1.0], [-1.0, 1.0], [-1.0, 1.0], indexing="ij"), -1).reshape(-1, 3)
    return g * (0.5 * h), np.full(8, r)


def custom_members(members, label="clumps"):
    """(pos [k, 3], radius [k]) [m] of a grain given as rows (x, y, z, r) [m] (module docstring);
    InputError naming ``label``.members and what is wrong."""
    field = f"{label}.members"
    rows = members if isinstance(members, list) else None
    if (not rows or not all(isinstance(m, list) and len(m) == 4 for m in rows)
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for m in rows for x in m)):
        text = repr(members)
        raise InputError(f"{field} = {text if len(text) <= 60 else text[:57] + '...'}: must be a non-empty list of "
                         "[x, y, z, r] rows of numbers [m]")
    a = np.asarray(rows, np.float64)
    if not np.all(np.isfinite(a)):
        raise InputError(f"{field}: a value is not finite; rows are [x, y, z, r] [m]")
    bad = np.flatnonzero(a[:, 3] <= 0.0)
    if len(bad):
        raise InputError(f"{field}[{bad[0]}] radius = {a[bad[0], 3]!r}: must be > 0 [m]")
    pos, r = a[:, :3], a[:, 3]
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    same = np.argwhere(np.triu(d == 0.0, 1))
    if len(same):
        i, j = same[0]
        raise InputError(f"{field}[{i}] and [{j}]: two members on one centre {pos[i].tolist()} m")
    touch = d <= (r[:, None] + r[None]) * (1.0 + 1e-9)
    seen, todo = {0}, [0]
    while todo:
        k = todo.pop()
        for j in np.flatnonzero(touch[k]):
            if int(j) not in seen:
                seen.add(int(j))
                todo.append(int(j))
    if len(seen) < len(r):
        k = min(set(range(len(r))) - seen)
        raise InputError(f"{field}[{k}] at {pos[k].tolist()} m: does not touch the others (member {k} is apart from "
                         "member 0's group); members must touch or overlap to form one grain")
    w = r ** 3
    return pos - (w[:, None] * pos).sum(axis=0) / w.sum(), r.copy()


def random_rotations(n, rng):
    """[n, 3, 3] uniformly distributed rotation matrices (normalised Gaussian quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    w, x, y, z = q.T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], axis=1)


def grain_cloud(pos, radius, lo, hi, count, seed=0, gap=0.05, label="clumps"):
    """``count`` grains of the shape (member ``pos`` about its centre, ``radius``), each turned
    at random, on a cubic lattice of spacing 2 R (1 + gap) inside the box lo..hi [m] (R the radius
    of the sphere around the grain); a list of (member positions, member radii) for
    `Scene.add_clumps`. InputError if they do not fit."""
    pos = np.asarray(pos, np.float64)
    radius = np.asarray(radius, np.float64)
    lo, hi = vector3(f"{label}.box_lo", lo), vector3(f"{label}.box_hi", hi)
    count = number(f"{label}.count", count, 1, integer=True)
    seed = number(f"{label}.seed", seed, 0, integer=True)
    if not np.all(hi > lo):
        raise InputError(f"{label}.box_hi = {hi.tolist()}: must be above box_lo = {lo.tolist()} on every axis")
    reach = float(np.max(np.sqrt(np.einsum("ij,ij->i", pos, pos)) + radius))
    a = 2.0 * reach * (1.0 + gap)
    sites_per_axis = np.floor((hi - lo) / a).astype(int)
    room = int(np.prod(np.maximum(sites_per_axis, 0)))
    if room < count:
        raise InputError(f"{label}.count = {count}: only {room} grains of diameter {2 * reach:.4g} m fit in the box "
                         f"{lo.tolist()}..{hi.tolist()}; enlarge the box or use fewer grains")
    rng = np.random.default_rng(seed)
    ix, iy, iz = np.meshgrid(*(np.arange(c) for c in sites_per_axis), indexing="ij")
    sites = np.stack([ix.ravel(), iy.ravel(), iz.ravel()], axis=1)
    order = np.lexsort((rng.random(len(sites)), sites[:, 2]))[:count]  # bottom up, random within a layer
    centres = lo + 0.5 * a + sites[order] * a
    rot = random_rotations(count, rng)
    return [(c + pos @ m.T, radius.copy()) for c, m in zip(centres, rot)]
