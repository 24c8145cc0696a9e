"""Mass, centre, principal inertia and orientation of a rigid clump, as Yade 2023.02a computes
them (Clump::updateProperties), and volume-corrected alternatives.

Three mass models (SPEC 1.2; YADE_MODEL.md §8; tests/validation/yade_reference/NOTES.md, "Facts
for the implementer", construction steps 1–10):

- ``"members"`` (Yade's default, discretization 0): M = Σ m_i, m_i = ρ (4/3) π r_i³; centre
  x_c = Σ m_i x_i / M; inertia Σ (2/5 m_i r_i² I + m_i (|x_i|² I − x_i x_iᵀ)) moved to x_c.
  Overlapping volume is counted twice.
- ``"grid"`` (Yade's discretization N > 0): if some members overlap by more than 0.001 r_min,
  cells of side dx = (shortest side of the members' bounding box)/N are counted once each (a
  cell belongs to the first member containing its centre), each with mass ρ dx³ and its own
  moment ρ dx³ dx²/6; else as ``"members"``. Bit-identical to Yade for the same N.
- ``"monte_carlo"``: ``samples`` points uniform in the bounding box (seeded), the points inside
  some member give the volume, centre and inertia (overlaps counted once).

Then, as Yade: the inertia tensor about x_c, its eigen-decomposition by Eigen 3.4's iterative
``SelfAdjointEigenSolver`` (a line-by-line port, `eigh3`: numpy's eigh gives other bits),
principal moments ascending, the third eigenvector negated if det(R) < 0, the orientation
q = normalize(Quaternion(R)) (no sign convention, w < 0 happens) and each member's position in
the principal frame relPos_i = q̄·(x_i − x_c).

Every operation follows Yade's Eigen evaluation order (dot products x0 y0 + (x1 y1 + x2 y2),
Eigen's quaternion formulas): plain Python floats, whose arithmetic is IEEE double like Yade's.
Units: m, kg, kg·m². Quaternions are (w, x, y, z) tuples.
"""
import math

import numpy as np
from numba import njit

EPS = 2.220446049250313e-16  # numeric_limits<double>::epsilon()
TINY = 2.2250738585072014e-308  # numeric_limits<double>::min()
MASS_MODELS = ("members", "grid", "monte_carlo")


# ---------------------------------------------------------------- vectors, quaternions
def dot(a, b):
    return a[0] * b[0] + (a[1] * b[1] + a[2] * b[2])


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def add(a, b):
    return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]


def sub(a, b):
    return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]


def smul(s, a):
    return [s * a[0], s * a[1], s * a[2]]


def qconj(q):
    return (q[0], -q[1], -q[2], -q[3])


def qmul(a, b):
    """Eigen's quaternion product."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by + ay * bw + az * bx - ax * bz,
            aw * bz + az * bw + ax * by - ay * bx)


def qrot(q, v):
    """Eigen's Quaternion * Vector3: uv = 2 (qv × v); v + w uv + qv × uv."""
    qv = [q[1], q[2], q[3]]
    uv = cross(qv, v)
    uv = [uv[0] + uv[0], uv[1] + uv[1], uv[2] + uv[2]]
    return add(add(v, smul(q[0], uv)), cross(qv, uv))


def qnormalize(q):
    w, x, y, z = q
    n = math.sqrt((x * x + y * y) + (z * z + w * w))
    return (w / n, x / n, y / n, z / n)


def rotation_matrix(q):
    """Eigen's Quaternion::toRotationMatrix (rows)."""
    w, x, y, z = q
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    return [[1.0 - (tyy + tzz), txy - twz, txz + twy],
            [txy + twz, 1.0 - (txx + tzz), tyz - twx],
            [txz - twy, tyz + twx, 1.0 - (txx + tyy)]]


def quaternion_from_matrix(m):
    """Eigen's Quaternion(const Matrix3&), not normalised."""
    t = m[0][0] + (m[1][1] + m[2][2])
    c = [0.0, 0.0, 0.0]
    if t > 0.0:
        t = math.sqrt(t + 1.0)
        w = 0.5 * t
        t = 0.5 / t
        c = [(m[2][1] - m[1][2]) * t, (m[0][2] - m[2][0]) * t, (m[1][0] - m[0][1]) * t]
    else:
        i = 0
        if m[1][1] > m[0][0]:
            i = 1
        if m[2][2] > m[i][i]:
            i = 2
        j = (i + 1) % 3
        k = (j + 1) % 3
        t = math.sqrt(m[i][i] - m[j][j] - m[k][k] + 1.0)
        c[i] = 0.5 * t
        t = 0.5 / t
        w = (m[k][j] - m[j][k]) * t
        c[j] = (m[j][i] + m[i][j]) * t
        c[k] = (m[k][i] + m[i][k]) * t
    return (w, c[0], c[1], c[2])


def _det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


# ---------------------------------------------------------------- Eigen 3.4 SelfAdjointEigenSolver<Matrix3d>
def _hypot(x, y):
    x, y = abs(x), abs(y)
    p = max(x, y)
    if p == 0.0:
        return 0.0
    qp = min(y, x) / p
    return p * math.sqrt(1.0 + qp * qp)


def _make_givens(p, q):
    if q == 0.0:
        return (-1.0 if p < 0.0 else 1.0), 0.0
    if p == 0.0:
        return 0.0, (1.0 if q < 0.0 else -1.0)
    if abs(p) > abs(q):
        t = q / p
        u = math.sqrt(1.0 + t * t)
        if p < 0.0:
            u = -u
        c = 1.0 / u
        return c, -t * c
    t = p / q
    u = math.sqrt(1.0 + t * t)
    if q < 0.0:
        u = -u
    s = -1.0 / u
    return -t * s, s


def eigh3(a):
    """(eigenvalues ascending, eigenvector matrix with the vectors as columns) of the symmetric
    3×3 matrix ``a`` (rows; its lower triangle is used) as Eigen 3.4's SelfAdjointEigenSolver
    computes them: scaling by the largest |a_ij|, Householder tridiagonalisation, implicit
    symmetric QR steps with Wilkinson shift and Givens rotations, selection sort."""
    mat = [[a[i][j] if j <= i else 0.0 for j in range(3)] for i in range(3)]
    scale = max(abs(mat[i][j]) for i in range(3) for j in range(3))
    if scale == 0.0:
        scale = 1.0
    for i in range(3):
        for j in range(i + 1):
            mat[i][j] = mat[i][j] / scale
    diag = [mat[0][0], 0.0, 0.0]
    sub_ = [0.0, 0.0]
    v1norm2 = mat[2][0] * mat[2][0]
    if v1norm2 <= TINY:
        diag[1], diag[2] = mat[1][1], mat[2][2]
        sub_[0], sub_[1] = mat[1][0], mat[2][1]
        q = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    else:
        beta = math.sqrt(mat[1][0] * mat[1][0] + v1norm2)
        inv_beta = 1.0 / beta
        m01 = mat[1][0] * inv_beta
        m02 = mat[2][0] * inv_beta
        qq = 2.0 * m01 * mat[2][1] + m02 * (mat[2][2] - mat[1][1])
        diag[1] = mat[1][1] + m02 * qq
        diag[2] = mat[2][2] - m02 * qq
        sub_[0] = beta
        sub_[1] = mat[2][1] - m01 * qq
        q = [[1.0, 0.0, 0.0], [0.0, m01, m02], [0.0, m02, -m01]]
    n, end, start, it = 3, 2, 0, 0
    precision_inv = 1.0 / EPS
    while end > 0:
        for i in range(start, end):
            if abs(sub_[i]) < TINY:
                sub_[i] = 0.0
            else:
                sc = precision_inv * sub_[i]
                if sc * sc <= (abs(diag[i]) + abs(diag[i + 1])):
                    sub_[i] = 0.0
        while end > 0 and sub_[end - 1] == 0.0:
            end -= 1
        if end <= 0:
            break
        it += 1
        if it > 30 * n:
            raise ArithmeticError("clump inertia: the eigen-decomposition did not converge")
        start = end - 1
        while start > 0 and sub_[start - 1] != 0.0:
            start -= 1
        td = (diag[end - 1] - diag[end]) * 0.5
        e = sub_[end - 1]
        mu = diag[end]
        if td == 0.0:
            mu -= abs(e)
        elif e != 0.0:
            e2 = e * e
            h = _hypot(td, e)
            if e2 == 0.0:
                mu -= e / ((td + (h if td > 0.0 else -h)) / e)
            else:
                mu -= e2 / (td + (h if td > 0.0 else -h))
        x = diag[start] - mu
        z = sub_[start]
        k = start
        while k < end and z != 0.0:
            c, s = _make_givens(x, z)
            sdk = s * diag[k] + c * sub_[k]
            dkp1 = s * sub_[k] + c * diag[k + 1]
            diag[k] = c * (c * diag[k] - s * sub_[k]) - s * (c * sub_[k] - s * diag[k + 1])
            diag[k + 1] = s * sdk + c * dkp1
            sub_[k] = c * sdk - s * dkp1
            if k > start:
                sub_[k - 1] = c * sub_[k - 1] - s * z
            x = sub_[k]
            if k < end - 1:
                z = -s * sub_[k + 1]
                sub_[k + 1] = c * sub_[k + 1]
            if not (c == 1.0 and s == 0.0):
                for i in range(n):
                    xi, yi = q[i][k], q[i][k + 1]
                    q[i][k] = c * xi + (-s) * yi
                    q[i][k + 1] = s * xi + c * yi
            k += 1
    for i in range(n - 1):
        kk = i
        for j in range(i + 1, n):
            if diag[j] < diag[kk]:
                kk = j
        if kk != i:
            diag[i], diag[kk] = diag[kk], diag[i]
            for r in range(n):
                q[r][i], q[r][kk] = q[r][kk], q[r][i]
    return [d * scale for d in diag], q


# ---------------------------------------------------------------- mass models
def _translate(inertia, m, off):
    """Clump::inertiaTensorTranslate: I + m (off·off I − off offᵀ), coefficient-wise."""
    dd = dot(off, off)
    return [[inertia[i][j] + m * ((dd if i == j else 0.0) - off[i] * off[j]) for j in range(3)] for i in range(3)]


def _member_sums(centres, radii, density):
    """(M, Σ m x, inertia about the origin) of the members, overlaps counted twice."""
    mass = 0.0
    sg = [0.0, 0.0, 0.0]
    ig = [[0.0] * 3 for _ in range(3)]
    for c, r, dens in zip(centres, radii, density):
        m = dens * ((4. / 3.) * math.pi * math.pow(r, 3.))
        mass += m
        sg = add(sg, smul(m, c))
        own = (2 / 5.) * m * (r * r)  # Yade's pow(r, 2), folded to r*r by GCC
        t = _translate([[own if i == j else 0.0 for j in range(3)] for i in range(3)], m, smul(-1., c))
        ig = [[ig[i][j] + t[i][j] for j in range(3)] for i in range(3)]
    return mass, sg, ig


def _bounds(centres, radii):
    lo = [math.inf] * 3
    hi = [-math.inf] * 3
    for c, r in zip(centres, radii):
        for p in (add(c, [r, r, r]), sub(c, [r, r, r])):
            lo = [min(lo[i], p[i]) for i in range(3)]
            hi = [max(hi[i], p[i]) for i in range(3)]
    return lo, hi


def _intersecting(centres, radii):
    """Yade's test for grid integration: some pair overlaps by more than 0.001 r_min."""
    for i, (ci, ri) in enumerate(zip(centres, radii)):
        for j, (cj, rj) in enumerate(zip(centres, radii)):
            if i != j:
                d = sub(ci, cj)
                if (ri + rj) - math.sqrt(dot(d, d)) > 0.001 * min(ri, rj):
                    return True
    return False


@njit(cache=True)
def _grid_sums(centres, radii, density, lo, hi, dx, dv, cell):
    """Yade's grid loop (Clump::updateProperties, discretization > 0) in the same order: a cell
    counts for the first member containing its centre."""
    mass = 0.0
    sg = np.zeros(3)
    ig = np.zeros((3, 3))
    x0 = lo[0] + dx / 2.
    while x0 < hi[0]:
        x1 = lo[1] + dx / 2.
        while x1 < hi[1]:
            x2 = lo[2] + dx / 2.
            while x2 < hi[2]:
                for k in range(radii.shape[0]):
                    d0 = x0 - centres[k, 0]
                    d1 = x1 - centres[k, 1]
                    d2 = x2 - centres[k, 2]
                    r = radii[k]
                    if d0 * d0 + (d1 * d1 + d2 * d2) < r * r:
                        m = density * dv
                        mass += m
                        sg[0] = sg[0] + m * x0
                        sg[1] = sg[1] + m * x1
                        sg[2] = sg[2] + m * x2
                        xx = x0 * x0 + (x1 * x1 + x2 * x2)
                        for i in range(3):
                            xi = x0 if i == 0 else (x1 if i == 1 else x2)
                            for j in range(3):
                                xj = x0 if j == 0 else (x1 if j == 1 else x2)
                                if i == j:
                                    ig[i, j] = ig[i, j] + m * ((xx - xi * xj) + cell)
                                else:
                                    ig[i, j] = ig[i, j] + m * ((0.0 - xi * xj) + 0.0)
                        break
                x2 += dx
            x1 += dx
        x0 += dx
    return mass, sg, ig


def _grid(centres, radii, density, discretization):
    lo, hi = _bounds(centres, radii)
    side = sub(hi, lo)
    dx = min(side[0], min(side[1], side[2])) / discretization
    mass, sg, ig = _grid_sums(np.array(centres, np.float64), np.array(radii, np.float64), float(density),
                              np.array(lo), np.array(hi), dx, math.pow(dx, 3), (dx * dx) / 6.)
    return mass, [float(v) for v in sg], [[float(v) for v in row] for row in ig]


def _monte_carlo(centres, radii, density, samples, seed):
    """Volume, centre and inertia of the union of the members from ``samples`` random points."""
    c = np.array(centres, np.float64)
    r = np.array(radii, np.float64)
    lo, hi = (c - r[:, None]).min(axis=0), (c + r[:, None]).max(axis=0)
    rng = np.random.default_rng(seed)
    mass, first, second, count = 0.0, np.zeros(3), np.zeros((3, 3)), 0
    chunk = 1 << 16
    done = 0
    while done < samples:
        k = min(chunk, samples - done)
        x = lo + (hi - lo) * rng.random((k, 3))
        inside = np.zeros(k, bool)
        for cc, rr in zip(c, r):
            d = x - cc
            inside |= np.einsum("ij,ij->i", d, d) < rr * rr
        y = x[inside]
        count += len(y)
        first += y.sum(axis=0)
        second += y.T @ y
        done += k
    if count == 0:
        raise ArithmeticError("clump mass by Monte Carlo: no sample point fell inside the members")
    volume = float(np.prod(hi - lo)) * count / samples
    mass = density * volume
    dm = mass / count
    sg = (dm * first).tolist()
    xx = np.trace(second)
    ig = (dm * (xx * np.eye(3) - second)).tolist()
    return mass, sg, ig


def clump_properties(centres, radii, density, mass_model="members", discretization=0, samples=0, seed=0):
    """Rigid-clump properties of members at ``centres`` [m] with ``radii`` [m] and ``density``
    [kg/m³] (one value, or one per member for "members"; members in the order they are summed:
    increasing gid).

    Returns a dict: ``mass`` [kg], ``pos`` (centre [m]), ``inertia`` (principal moments
    ascending [kg·m²]), ``ori`` (w, x, y, z: body → global), ``rel_pos`` (members in the
    principal frame [m]), ``aspherical`` (principal moments not all equal: Yade then integrates
    the rotation with angular momentum and quaternion, else as a sphere)."""
    centres = [[float(v) for v in c] for c in centres]
    radii = [float(r) for r in radii]
    density = [float(x) for x in np.broadcast_to(np.asarray(density, np.float64), (len(radii),))]
    if mass_model == "grid" and discretization > 0 and _intersecting(centres, radii):
        mass, sg, ig = _grid(centres, radii, density[0], int(discretization))
    elif mass_model == "monte_carlo":
        mass, sg, ig = _monte_carlo(centres, radii, density[0], int(samples), seed)
    else:
        mass, sg, ig = _member_sums(centres, radii, density)
    pos = [sg[0] / mass, sg[1] / mass, sg[2] / mass]
    ic = _translate(ig, -mass, pos)
    ic[1][0], ic[2][0], ic[2][1] = ic[0][1], ic[0][2], ic[1][2]
    inertia, rot = eigh3(ic)
    if _det3(rot) < 0:  # Yade makes the eigenvector matrix a rotation by negating its third column
        for k in range(3):
            rot[k][2] = -rot[k][2]
    ori = qnormalize(quaternion_from_matrix(rot))
    back = qconj(ori)
    rel_pos = [qrot(back, sub(c, pos)) for c in centres]
    return {"mass": mass, "pos": pos, "inertia": inertia, "ori": ori, "rel_pos": rel_pos,
            "aspherical": inertia[0] != inertia[1] or inertia[0] != inertia[2]}


def angular_momentum(ori, inertia, angvel):
    """Global angular momentum [kg·m²/s] of a body with orientation ``ori``, principal moments
    ``inertia`` spinning at ``angvel`` (global) [rad/s]: L = q·(I ⊙ (q̄·ω))."""
    wb = qrot(qconj(ori), angvel)
    return qrot(ori, [inertia[0] * wb[0], inertia[1] * wb[1], inertia[2] * wb[2]])
