"""Contact geometry of each contact kind, exactly as Yade 2023.02a computes it (YADE_MODEL.md §3).

One class per geometry, holding njit-inline functions with scalar results that the generated pair
loop (`pdem.contact.loops`) calls; a geometry knows nothing of forces (that is the law's,
`pdem.contact.linear` and its siblings). For the candidate row (i, j) of a contact list:

``contact(fresh, i, j, pos, radius, other_f, other_i) -> (status, nx, ny, nz, pen)``
    Ig2: `SKIP` (no contact and none before: the row is clear, nothing to do), `OPEN` (a
    contact that opened, pen < 0: a frictional Law2 deletes it, a law with bonds
    (``TENSILE``) decides) or `CONTACT`, both with the unit normal n (from body 1 to body 2)
    and the overlap pen [m].
``ip2_args(i, j, radius, material, mass, other_f, other_i) -> (mat1, mat2, r1, r2, m1, m2)``
    what Ip2 sees at creation: the materials of body 1 and 2 in Yade's order (a wall or facet
    is body 1), the reference radii (sphere: r; wall: r and r; facet: 2r and r; box member: its
    radius and r) and the masses
    [kg] (inf for a boundary).
``spins(i, j, angvel) -> (ω1+ω2, ω2−ω1)`` [rad/s]: for the twist of ScGeom::precompute and for
    rolling laws.
``relative_velocity(i, j, nx, ny, nz, pen, pos, vel, angvel, radius, other_f)`` [m/s]: of body 2
    with respect to body 1 at the contact, before the normal part is removed (sphere–sphere,
    wall and box: Yade's avoidGranularRatcheting with full-radius levers and the factor
    α = (r1+r2)/(r1+r2−pen); facet: at the contact point, no ratcheting correction).
``contact_velocity(i, j, nx, ny, nz, pen, pos, vel, angvel, radius, other_f)`` [m/s]: the same
    relative velocity taken at the contact point in the middle of the overlap, without the
    ratcheting factor: (v2 − v1) − (l1 ω1 + l2 ω2) × n with the levers below (LIGGGHTS's
    surface model, tests/validation/liggghts_reference/NOTES.md §3.1, §5). Its normal part is the
    true approach velocity that a viscous dashpot needs; laws with ``CONTACT_POINT_VELOCITY``
    get this one.
``levers(i, j, pen, radius) -> (l1, l2)`` [m]: torque lever arms r − pen/2 (Law2's
    sphericalBodies branch; the facet's body-1 radius is 2r but only the sphere's lever is used).
``contact_point(i, j, nx, ny, nz, pen, pos, radius, other_f) -> (cx, cy, cz)`` [m]: Yade's
    contactPoint, for laws whose torque lever is (contact point − centre) (``CONTACT_POINT_LEVER``,
    the cohesive law): sphere–sphere x1 + (r1 − pen/2) n; wall: the centre projected on the
    plane; facet and box: x2 − (r − pen/2) n.
``TWO_PARTICLES``: body 1 is a particle (its slot gets +f and its torque, body 2's slot −f and
    its torque: `pdem.contact.loops`); otherwise body 1 is a boundary and the row holds the force
    on the sphere (−f) and its torque.

Boundary rows (``other_f``, ``other_i``, one row per wall, facet or box) are laid out by the
containers: `pdem.boundaries.walls.Walls` (f: position, velocity; i: axis, sense, material),
`pdem.boundaries.facets.Facets` (f: FACET_COLUMNS of geometry, velocity; i: material) and
`pdem.bodies.boxes.Boxes` (f: centre, half extents, velocity, rotation box → global (row-major),
angular velocity; i: material).

Every 3-vector product follows Yade's Eigen evaluation order (`pdem.vec`), so results are
bit-identical to Yade's. Imports numba and `pdem.vec` only.
"""
from math import inf, sqrt

from numba import njit

from ..vec import cross3, dot3

SKIP = 0
OPEN = 1
CONTACT = 2


# ---------------------------------------------------------------------------- shared pieces
@njit(inline="always", cache=True)
def _boundary_ip2(s, b, radius, material, mass, other_i, material_col, radius_factor):
    r = radius[s]
    return other_i[b, material_col], material[s], radius_factor * r, r, inf, mass[s]


@njit(inline="always", cache=True)
def _sphere_spins(s, b, angvel):
    wx = angvel[s, 0]
    wy = angvel[s, 1]
    wz = angvel[s, 2]
    return wx, wy, wz, wx, wy, wz


@njit(inline="always", cache=True)
def _sphere_lever(s, b, pen, radius):
    lever = radius[s] - 0.5 * pen
    return lever, lever


@njit(inline="always", cache=True)
def _flat_relative_velocity(s, nx, ny, nz, pen, vel, angvel, radius, bvx, bvy, bvz):
    """A sphere on a flat boundary moving at (bvx, bvy, bvz): ratcheting factor with both
    reference radii r (Ig2_Wall_Sphere_ScGeom)."""
    r = radius[s]
    rs = r + r
    alpha = rs / (rs - pen)
    ax = (vel[s, 0] - bvx) * alpha
    ay = (vel[s, 1] - bvy) * alpha
    az = (vel[s, 2] - bvz) * alpha
    bx, by, bz = cross3(angvel[s, 0], angvel[s, 1], angvel[s, 2], (-r) * nx, (-r) * ny, (-r) * nz)
    return ax + bx, ay + by, az + bz


@njit(inline="always", cache=True)
def _flat_contact_velocity(s, nx, ny, nz, pen, vel, angvel, radius, bvx, bvy, bvz):
    """A sphere on a flat boundary moving at (bvx, bvy, bvz), at the contact point: v − v_b −
    (r − pen/2) ω × n."""
    lever = radius[s] - 0.5 * pen
    cx, cy, cz = cross3(lever * angvel[s, 0], lever * angvel[s, 1], lever * angvel[s, 2], nx, ny, nz)
    return (vel[s, 0] - bvx) - cx, (vel[s, 1] - bvy) - cy, (vel[s, 2] - bvz) - cz


# ---------------------------------------------------------------------------- sphere–sphere
@njit(inline="always", cache=True)
def _two_spheres(fresh, dx, dy, dz, rs):
    """Ig2_Sphere_Sphere_ScGeom from the centre distance (dx, dy, dz) of body 2 from body 1 and
    the sum of their radii rs."""
    d2 = dot3(dx, dy, dz, dx, dy, dz)
    if fresh and rs * rs - d2 < 0.0:
        return SKIP, 0.0, 0.0, 0.0, 0.0
    dist = sqrt(d2)
    pen = rs - dist
    return OPEN if pen < 0.0 else CONTACT, dx / dist, dy / dist, dz / dist, pen


@njit(inline="always", cache=True)
def _ss_contact(fresh, i, j, pos, radius, other_f, other_i):
    return _two_spheres(fresh, pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2],
                        radius[i] + radius[j])


@njit(inline="always", cache=True)
def _ss_ip2(i, j, radius, material, mass, other_f, other_i):
    return material[i], material[j], radius[i], radius[j], mass[i], mass[j]


@njit(inline="always", cache=True)
def _ss_spins(i, j, angvel):
    return (angvel[i, 0] + angvel[j, 0], angvel[i, 1] + angvel[j, 1], angvel[i, 2] + angvel[j, 2],
            angvel[j, 0] - angvel[i, 0], angvel[j, 1] - angvel[i, 1], angvel[j, 2] - angvel[i, 2])


@njit(inline="always", cache=True)
def _ss_relative_velocity(i, j, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    r1 = radius[i]
    r2 = radius[j]
    rs = r1 + r2
    alpha = rs / (rs - pen)
    ax = (vel[j, 0] - vel[i, 0]) * alpha
    ay = (vel[j, 1] - vel[i, 1]) * alpha
    az = (vel[j, 2] - vel[i, 2]) * alpha
    bx, by, bz = cross3(angvel[j, 0], angvel[j, 1], angvel[j, 2], (-r2) * nx, (-r2) * ny, (-r2) * nz)
    cx, cy, cz = cross3(angvel[i, 0], angvel[i, 1], angvel[i, 2], r1 * nx, r1 * ny, r1 * nz)
    return ax + bx - cx, ay + by - cy, az + bz - cz


@njit(inline="always", cache=True)
def _ss_contact_velocity(i, j, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    l1 = radius[i] - 0.5 * pen
    l2 = radius[j] - 0.5 * pen
    wx = l1 * angvel[i, 0] + l2 * angvel[j, 0]
    wy = l1 * angvel[i, 1] + l2 * angvel[j, 1]
    wz = l1 * angvel[i, 2] + l2 * angvel[j, 2]
    cx, cy, cz = cross3(wx, wy, wz, nx, ny, nz)
    return (vel[j, 0] - vel[i, 0]) - cx, (vel[j, 1] - vel[i, 1]) - cy, (vel[j, 2] - vel[i, 2]) - cz


@njit(inline="always", cache=True)
def _ss_levers(i, j, pen, radius):
    return radius[i] - 0.5 * pen, radius[j] - 0.5 * pen


@njit(inline="always", cache=True)
def _ss_contact_point(i, j, nx, ny, nz, pen, pos, radius, other_f):
    lever = radius[i] - 0.5 * pen
    return pos[i, 0] + lever * nx, pos[i, 1] + lever * ny, pos[i, 2] + lever * nz


class SphereSphere:
    """Ig2_Sphere_Sphere_ScGeom (interactionDetectionFactor 1, noRatch)."""

    name = "sphere_sphere"
    TWO_PARTICLES = True
    contact = _ss_contact
    ip2_args = _ss_ip2
    spins = _ss_spins
    relative_velocity = _ss_relative_velocity
    contact_velocity = _ss_contact_velocity
    levers = _ss_levers
    contact_point = _ss_contact_point


@njit(inline="always", cache=True)
def _ssp_contact(fresh, i, j, pos, radius, other_f, other_i):
    """Across periodic ends: the branch vector (x_j − x_i) + (s_j − s_i), s = ``other_f`` the
    image shift of each particle row [m] (0 or ±L: s_j − s_i is exact, and so the same bits
    whichever of the two bodies is the image on the rank computing it)."""
    return _two_spheres(fresh, (pos[j, 0] - pos[i, 0]) + (other_f[j, 0] - other_f[i, 0]),
                        (pos[j, 1] - pos[i, 1]) + (other_f[j, 1] - other_f[i, 1]),
                        (pos[j, 2] - pos[i, 2]) + (other_f[j, 2] - other_f[i, 2]), radius[i] + radius[j])


class PeriodicSphereSphere(SphereSphere):
    """`SphereSphere` of a scene with periodic ends (`pdem.parallel.periodic_domain`): the
    branch vector with the rows' image shifts (``other_f`` [n_rows, 3]). Its contact point is
    not shifted: laws with ``CONTACT_POINT_LEVER`` are refused with periodic ends."""

    name = "sphere_sphere_periodic"
    contact = _ssp_contact


# ---------------------------------------------------------------------------- sphere–wall
@njit(inline="always", cache=True)
def _wall_contact(fresh, s, w, pos, radius, other_f, other_i):
    a = other_i[w, 0]
    r = radius[s]
    dist = pos[s, a] - other_f[w, 0]
    if fresh and abs(dist) > r:
        return SKIP, 0.0, 0.0, 0.0, 0.0
    pen = -(abs(dist) - r)
    sense = other_i[w, 1]
    sign = (1.0 if dist > 0.0 else -1.0) if sense == 0 else (1.0 if sense == 1 else -1.0)
    return (OPEN if pen < 0.0 else CONTACT, sign if a == 0 else 0.0, sign if a == 1 else 0.0, sign if a == 2 else 0.0,
            pen)


@njit(inline="always", cache=True)
def _wall_ip2(s, w, radius, material, mass, other_f, other_i):
    return _boundary_ip2(s, w, radius, material, mass, other_i, 2, 1.0)


@njit(inline="always", cache=True)
def _wall_relative_velocity(s, w, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    return _flat_relative_velocity(s, nx, ny, nz, pen, vel, angvel, radius, other_f[w, 1], other_f[w, 2],
                                   other_f[w, 3])


@njit(inline="always", cache=True)
def _wall_contact_velocity(s, w, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    return _flat_contact_velocity(s, nx, ny, nz, pen, vel, angvel, radius, other_f[w, 1], other_f[w, 2],
                                  other_f[w, 3])


@njit(inline="always", cache=True)
def _wall_contact_point(s, w, nx, ny, nz, pen, pos, radius, other_f):
    """The sphere centre projected on the plane."""
    cx = pos[s, 0]
    cy = pos[s, 1]
    cz = pos[s, 2]
    p = other_f[w, 0]
    if nx != 0.0:
        cx = p
    elif ny != 0.0:
        cy = p
    else:
        cz = p
    return cx, cy, cz


@njit(inline="always", cache=True)
def _sphere_contact_point(s, b, nx, ny, nz, pen, pos, radius, other_f):
    """x2 − (r − pen/2) n: Ig2_Facet_Sphere_ScGeom's contact point (the sphere is body 2)."""
    lever = radius[s] - 0.5 * pen
    return pos[s, 0] - lever * nx, pos[s, 1] - lever * ny, pos[s, 2] - lever * nz


class SphereWall:
    """Ig2_Wall_Sphere_ScGeom: an infinite axis-aligned plane is body 1; contact point on the
    plane, radius1 = radius2 = r."""

    name = "sphere_wall"
    TWO_PARTICLES = False
    contact = _wall_contact
    ip2_args = _wall_ip2
    spins = _sphere_spins
    relative_velocity = _wall_relative_velocity
    contact_velocity = _wall_contact_velocity
    levers = _sphere_lever
    contact_point = _wall_contact_point


# ---------------------------------------------------------------------------- sphere–facet
@njit(inline="always", cache=True)
def _facet_contact(fresh, s, f, pos, radius, other_f, other_i):
    """Face, edge and vertex contact of Ig2_Facet_Sphere_ScGeom (facet rows: `pdem.boundaries.facets`:
    centre c at 0, normal at 3, edge normals ne_k at 6 + 3k, icr at 15, vertex unit vectors
    vu_k at 16 + 3k, their lengths vl_k at 25 + k)."""
    g = other_f
    r = radius[s]
    clx = pos[s, 0] - g[f, 0]
    cly = pos[s, 1] - g[f, 1]
    clz = pos[s, 2] - g[f, 2]
    nfx = g[f, 3]
    nfy = g[f, 4]
    nfz = g[f, 5]
    big_l = dot3(nfx, nfy, nfz, clx, cly, clz)
    if big_l < 0.0:
        nfx = -nfx
        nfy = -nfy
        nfz = -nfz
        big_l = -big_l
    if fresh and big_l > r:
        return SKIP, 0.0, 0.0, 0.0, 0.0
    cpx = clx - big_l * nfx
    cpy = cly - big_l * nfy
    cpz = clz - big_l * nfz
    bm = dot3(g[f, 6], g[f, 7], g[f, 8], cpx, cpy, cpz)
    m = 0
    for k in range(1, 3):
        q = dot3(g[f, 6 + 3 * k], g[f, 7 + 3 * k], g[f, 8 + 3 * k], cpx, cpy, cpz)
        if q > bm:
            bm = q
            m = k
    icr = g[f, 15]
    if bm < icr:
        pen = r - big_l
        nn = sqrt(dot3(nfx, nfy, nfz, nfx, nfy, nfz))
        nx = nfx / nn
        ny = nfy / nn
        nz = nfz / nn
    else:
        cpx = cpx + g[f, 6 + 3 * m] * (icr - bm)
        cpy = cpy + g[f, 7 + 3 * m] * (icr - bm)
        cpz = cpz + g[f, 8 + 3 * m] * (icr - bm)
        mp = 2 if m - 1 < 0 else m - 1
        if dot3(cpx, cpy, cpz, g[f, 6 + 3 * mp], g[f, 7 + 3 * mp], g[f, 8 + 3 * mp]) > icr:
            cpx = g[f, 16 + 3 * m] * g[f, 25 + m]
            cpy = g[f, 17 + 3 * m] * g[f, 25 + m]
            cpz = g[f, 18 + 3 * m] * g[f, 25 + m]
        else:
            m = 0 if m + 1 > 2 else m + 1
            if dot3(cpx, cpy, cpz, g[f, 6 + 3 * m], g[f, 7 + 3 * m], g[f, 8 + 3 * m]) > icr:
                cpx = g[f, 16 + 3 * m] * g[f, 25 + m]
                cpy = g[f, 17 + 3 * m] * g[f, 25 + m]
                cpz = g[f, 18 + 3 * m] * g[f, 25 + m]
        nx = clx - cpx
        ny = cly - cpy
        nz = clz - cpz
        nn = sqrt(dot3(nx, ny, nz, nx, ny, nz))
        nx /= nn
        ny /= nn
        nz /= nn
        pen = r - nn
    if fresh and not pen > 0.0:
        return SKIP, 0.0, 0.0, 0.0, 0.0
    return OPEN if pen < 0.0 else CONTACT, nx, ny, nz, pen  # OPEN: a real contact that opened


@njit(inline="always", cache=True)
def _facet_ip2(s, f, radius, material, mass, other_f, other_i):
    return _boundary_ip2(s, f, radius, material, mass, other_i, 0, 2.0)


@njit(inline="always", cache=True)
def _facet_relative_velocity(s, f, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    lever = radius[s] - 0.5 * pen
    # contact point x2 - (r - pen/2) n, then its offset from the sphere centre (Yade's order)
    c2x = (pos[s, 0] - lever * nx) - pos[s, 0]
    c2y = (pos[s, 1] - lever * ny) - pos[s, 1]
    c2z = (pos[s, 2] - lever * nz) - pos[s, 2]
    wx, wy, wz = cross3(angvel[s, 0], angvel[s, 1], angvel[s, 2], c2x, c2y, c2z)
    return ((vel[s, 0] + wx) - other_f[f, 28], (vel[s, 1] + wy) - other_f[f, 29],
            (vel[s, 2] + wz) - other_f[f, 30])


class SphereFacet:
    """Ig2_Facet_Sphere_ScGeom: a triangle is body 1 (radius1 = 2r), no ratcheting correction."""

    name = "sphere_facet"
    TWO_PARTICLES = False
    contact = _facet_contact
    ip2_args = _facet_ip2
    spins = _sphere_spins
    relative_velocity = _facet_relative_velocity
    contact_velocity = _facet_relative_velocity  # already at the contact point, no ratcheting factor
    levers = _sphere_lever
    contact_point = _sphere_contact_point


# ---------------------------------------------------------------------------- sphere–box
@njit(inline="always", cache=True)
def _closest_on_box(fresh, r, dx, dy, dz, hx, hy, hz):
    """Contact of a sphere of radius r whose centre is at (dx, dy, dz) from the centre of a box of
    half extents (hx, hy, hz), in the box's axes (see `_box_contact`)."""
    ex = dx - min(max(dx, -hx), hx)
    ey = dy - min(max(dy, -hy), hy)
    ez = dz - min(max(dz, -hz), hz)
    if ex != 0.0 or ey != 0.0 or ez != 0.0:
        dist = sqrt(dot3(ex, ey, ez, ex, ey, ez))
        if fresh and dist > r:
            return SKIP, 0.0, 0.0, 0.0, 0.0
        nx = ex / dist
        ny = ey / dist
        nz = ez / dist
        pen = r - dist
    else:
        gx = hx - abs(dx)
        gy = hy - abs(dy)
        gz = hz - abs(dz)
        nx = 0.0
        ny = 0.0
        nz = 0.0
        if gx <= gy and gx <= gz:
            nx = 1.0 if dx >= 0.0 else -1.0
            pen = r + gx
        elif gy <= gz:
            ny = 1.0 if dy >= 0.0 else -1.0
            pen = r + gy
        else:
            nz = 1.0 if dz >= 0.0 else -1.0
            pen = r + gz
    return OPEN if pen < 0.0 else CONTACT, nx, ny, nz, pen


@njit(inline="always", cache=True)
def _box_contact(fresh, s, b, pos, radius, other_f, other_i):
    """Closest point q of the box to the centre x (clamp per axis); outside: n = (x − q)/|x − q|,
    pen = r − |x − q| (face, edge or corner); centre inside: out through the nearest face,
    n = ±e_a, pen = r + (h_a − |x_a − c_a|) (ties: x before y before z)."""
    return _closest_on_box(fresh, radius[s], pos[s, 0] - other_f[b, 0], pos[s, 1] - other_f[b, 1],
                           pos[s, 2] - other_f[b, 2], other_f[b, 3], other_f[b, 4], other_f[b, 5])


@njit(inline="always", cache=True)
def _box_ip2(s, b, radius, material, mass, other_f, other_i):
    return _boundary_ip2(s, b, radius, material, mass, other_i, 0, 1.0)


@njit(inline="always", cache=True)
def _box_relative_velocity(s, b, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    return _flat_relative_velocity(s, nx, ny, nz, pen, vel, angvel, radius, other_f[b, 6], other_f[b, 7],
                                   other_f[b, 8])


@njit(inline="always", cache=True)
def _box_contact_velocity(s, b, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    return _flat_contact_velocity(s, nx, ny, nz, pen, vel, angvel, radius, other_f[b, 6], other_f[b, 7],
                                  other_f[b, 8])


class SphereBox:
    """A sphere on an axis-aligned rigid box (body 1, translating, never rotating): parameters
    and relative velocity as for a wall (radius1 = radius2 = r, ratcheting factor)."""

    name = "sphere_box"
    TWO_PARTICLES = False
    contact = _box_contact
    ip2_args = _box_ip2
    spins = _sphere_spins
    relative_velocity = _box_relative_velocity
    contact_velocity = _box_contact_velocity
    levers = _sphere_lever
    contact_point = _sphere_contact_point

# ---------------------------------------------------------------------------- sphere–oriented box
@njit(inline="always", cache=True)
def _to_world(g, b, x, y, z):
    """R v for the box row b (R box → global at columns 9–17, row-major)."""
    return (dot3(g[b, 9], g[b, 10], g[b, 11], x, y, z), dot3(g[b, 12], g[b, 13], g[b, 14], x, y, z),
            dot3(g[b, 15], g[b, 16], g[b, 17], x, y, z))


@njit(inline="always", cache=True)
def _oriented_box_contact(fresh, s, b, pos, radius, other_f, other_i):
    """`_box_contact` in the box's own axes: the centre's offset d into the box frame (Rᵀ d), the
    closest point and normal there, the normal back to the global frame (R n)."""
    g = other_f
    dx = pos[s, 0] - g[b, 0]
    dy = pos[s, 1] - g[b, 1]
    dz = pos[s, 2] - g[b, 2]
    lx = dot3(g[b, 9], g[b, 12], g[b, 15], dx, dy, dz)
    ly = dot3(g[b, 10], g[b, 13], g[b, 16], dx, dy, dz)
    lz = dot3(g[b, 11], g[b, 14], g[b, 17], dx, dy, dz)
    status, nx, ny, nz, pen = _closest_on_box(fresh, radius[s], lx, ly, lz, g[b, 3], g[b, 4], g[b, 5])
    if status == SKIP:
        return status, nx, ny, nz, pen
    wx, wy, wz = _to_world(g, b, nx, ny, nz)
    return status, wx, wy, wz, pen


@njit(inline="always", cache=True)
def _point_velocity(s, b, nx, ny, nz, pen, pos, radius, g):
    """Velocity [m/s] of the box's material point at the contact point x − (r − pen/2) n:
    v_b + ω_b × (point − centre)."""
    lever = radius[s] - 0.5 * pen
    ox, oy, oz = cross3(g[b, 18], g[b, 19], g[b, 20], (pos[s, 0] - lever * nx) - g[b, 0],
                        (pos[s, 1] - lever * ny) - g[b, 1], (pos[s, 2] - lever * nz) - g[b, 2])
    return g[b, 6] + ox, g[b, 7] + oy, g[b, 8] + oz


@njit(inline="always", cache=True)
def _oriented_box_relative_velocity(s, b, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    bvx, bvy, bvz = _point_velocity(s, b, nx, ny, nz, pen, pos, radius, other_f)
    return _flat_relative_velocity(s, nx, ny, nz, pen, vel, angvel, radius, bvx, bvy, bvz)


@njit(inline="always", cache=True)
def _oriented_box_contact_velocity(s, b, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    bvx, bvy, bvz = _point_velocity(s, b, nx, ny, nz, pen, pos, radius, other_f)
    return _flat_contact_velocity(s, nx, ny, nz, pen, vel, angvel, radius, bvx, bvy, bvz)


class SphereOrientedBox:
    """A sphere on a rigid box with free rotations (`pdem.bodies.boxes`, rows with the rotation R
    box → global at columns 9–17 and ω at 18–20): the box contact in the box's axes, the box's
    velocity taken at the contact point (v_b + ω_b × (x_c − c_b)); otherwise as `SphereBox`."""

    name = "sphere_oriented_box"
    TWO_PARTICLES = False
    contact = _oriented_box_contact
    ip2_args = _box_ip2
    spins = _sphere_spins
    relative_velocity = _oriented_box_relative_velocity
    contact_velocity = _oriented_box_contact_velocity
    levers = _sphere_lever
    contact_point = _sphere_contact_point


# ---------------------------------------------------------------------------- sphere–box member
@njit(inline="always", cache=True)
def _member_contact(fresh, s, m, pos, radius, other_f, other_i):
    """Ig2_Sphere_Sphere_ScGeom with the member (row m of `pdem.bodies.boxes.BoxMembers`) as body 1."""
    return _two_spheres(fresh, pos[s, 0] - other_f[m, 0], pos[s, 1] - other_f[m, 1], pos[s, 2] - other_f[m, 2],
                        other_f[m, 6] + radius[s])


@njit(inline="always", cache=True)
def _member_ip2(s, m, radius, material, mass, other_f, other_i):
    return other_i[m, 0], material[s], other_f[m, 6], radius[s], inf, mass[s]


@njit(inline="always", cache=True)
def _member_relative_velocity(s, m, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    """Yade's sphere–sphere relative velocity with body 1 the member, translating with its box
    without spin: ((v2 − v1) α + ω2 × (−r2 n)), α = (r1 + r2)/(r1 + r2 − pen)."""
    r2 = radius[s]
    rs = other_f[m, 6] + r2
    alpha = rs / (rs - pen)
    ax = (vel[s, 0] - other_f[m, 3]) * alpha
    ay = (vel[s, 1] - other_f[m, 4]) * alpha
    az = (vel[s, 2] - other_f[m, 5]) * alpha
    bx, by, bz = cross3(angvel[s, 0], angvel[s, 1], angvel[s, 2], (-r2) * nx, (-r2) * ny, (-r2) * nz)
    return ax + bx, ay + by, az + bz


@njit(inline="always", cache=True)
def _member_contact_velocity(s, m, nx, ny, nz, pen, pos, vel, angvel, radius, other_f):
    return _flat_contact_velocity(s, nx, ny, nz, pen, vel, angvel, radius, other_f[m, 3], other_f[m, 4],
                                  other_f[m, 5])


class SphereMember:
    """A sphere on a member sphere of a rigid box (`pdem.bodies.boxes.BoxMembers`: the thesis's clump
    sleeper): the sphere–sphere geometry and relative velocity with the member as body 1, moving
    with its box and never spinning; the row holds the force on the sphere."""

    name = "sphere_member"
    TWO_PARTICLES = False
    contact = _member_contact
    ip2_args = _member_ip2
    spins = _sphere_spins
    relative_velocity = _member_relative_velocity
    contact_velocity = _member_contact_velocity
    levers = _sphere_lever
    contact_point = _sphere_contact_point


GEOMETRIES = {g.name: g for g in (SphereSphere, SphereWall, SphereFacet, SphereBox, SphereOrientedBox, SphereMember)}
