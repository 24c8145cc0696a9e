"""Plain-Python (float) re-implementation of the Yade 2023.02a / Eigen 3.4 arithmetic needed for clumps,
written for bit-for-bit comparison with the reference data (no numpy in the arithmetic: numpy's eigh and
matmul use other evaluation orders and do not reproduce Yade's last bits).

Conventions: vectors are 3-lists; quaternions are tuples (w, x, y, z); a 3x3 matrix is a list of rows.
Evaluation orders (YADE_MODEL.md 9, Eigen built with EIGEN_DONT_VECTORIZE, no FMA):
  dot(a, b) = a0*b0 + (a1*b1 + a2*b2)      (also every row of a Matrix3*Vector3 product, and the trace)
  quaternion squared norm = (x*x + y*y) + (z*z + w*w)
Powers: GCC turns pow(x, 2) into x*x at compile time (exact), so Yade's pow(r, 2) is r*r; pow(r, 3.) stays a
call to glibc's pow, which Python's math.pow (and float ** float) also calls.  math.pow(r, 2) differs from r*r for
about 1 radius in 1000 (glibc's pow is not always correctly rounded): use r*r.
Used by check_clump_integrator.py; run with python3, not inside Yade.
"""
import math

EPS = 2.220446049250313e-16        # numeric_limits<double>::epsilon()
TINY = 2.2250738585072014e-308     # numeric_limits<double>::min()


# ---------------------------------------------------------------- vectors, matrices
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


def matvec(A, v):
    return [dot(A[0], v), dot(A[1], v), dot(A[2], v)]


def sign(x):
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


# ---------------------------------------------------------------- quaternions (w, x, y, z)
def qmul(a, b):
    """Eigen's quat_product, left to right."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by + ay * bw + az * bx - ax * bz,
            aw * bz + az * bw + ax * by - ay * bx)


def qconj(q):
    return (q[0], -q[1], -q[2], -q[3])


def qrot(q, v):
    """Eigen's Quaternion * Vector3 (_transformVector; q need not be normalised):
    uv = qv x v; uv += uv; return v + w*uv + qv x uv."""
    qv = [q[1], q[2], q[3]]
    uv = cross(qv, v)
    uv = [uv[0] + uv[0], uv[1] + uv[1], uv[2] + uv[2]]
    t = add(v, smul(q[0], uv))
    return add(t, cross(qv, uv))


def qnormalize(q):
    w, x, y, z = q
    n = math.sqrt((x * x + y * y) + (z * z + w * w))
    return (w / n, x / n, y / n, z / n)


def to_rotation_matrix(q):
    """Eigen's Quaternion::toRotationMatrix."""
    w, x, y, z = q
    tx, ty, tz = 2.0 * x, 2.0 * y, 2.0 * z
    twx, twy, twz = tx * w, ty * w, tz * w
    txx, txy, txz = tx * x, ty * x, tz * x
    tyy, tyz, tzz = ty * y, tz * y, tz * z
    return [[1.0 - (tyy + tzz), txy - twz, txz + twy],
            [txy + twz, 1.0 - (txx + tzz), tyz - twx],
            [txz - twy, tyz + twx, 1.0 - (txx + tyy)]]


def from_matrix(m):
    """Eigen's Quaternion(const Matrix3&) (no normalisation here)."""
    t = m[0][0] + (m[1][1] + m[2][2])
    c = [0.0, 0.0, 0.0]   # x, y, z
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


def det3(m):
    # only its sign is used
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
        s = -t * c
    else:
        t = p / q
        u = math.sqrt(1.0 + t * t)
        if q < 0.0:
            u = -u
        s = -1.0 / u
        c = -t * s
    return c, s


def eigh3(A):
    """SelfAdjointEigenSolver<Matrix3d>(A).compute(): (eigenvalues ascending, eigenvector matrix, columns = vectors).
    Uses the lower triangle of A: scaling by the largest |coefficient|, the closed-form 3x3 Householder
    tridiagonalisation, implicit symmetric QR steps with Wilkinson shift and Givens rotations, selection sort."""
    mat = [[A[i][j] if j <= i else 0.0 for j in range(3)] for i in range(3)]
    scale = max(abs(mat[i][j]) for i in range(3) for j in range(3))
    if scale == 0.0:
        scale = 1.0
    for i in range(3):
        for j in range(i + 1):
            mat[i][j] = mat[i][j] / scale
    diag = [mat[0][0], 0.0, 0.0]
    sub = [0.0, 0.0]
    v1norm2 = mat[2][0] * mat[2][0]
    if v1norm2 <= TINY:
        diag[1], diag[2] = mat[1][1], mat[2][2]
        sub[0], sub[1] = mat[1][0], mat[2][1]
        Q = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    else:
        beta = math.sqrt(mat[1][0] * mat[1][0] + v1norm2)
        inv_beta = 1.0 / beta
        m01 = mat[1][0] * inv_beta
        m02 = mat[2][0] * inv_beta
        q = 2.0 * m01 * mat[2][1] + m02 * (mat[2][2] - mat[1][1])
        diag[1] = mat[1][1] + m02 * q
        diag[2] = mat[2][2] - m02 * q
        sub[0] = beta
        sub[1] = mat[2][1] - m01 * q
        Q = [[1.0, 0.0, 0.0], [0.0, m01, m02], [0.0, m02, -m01]]
    n, end, start, it = 3, 2, 0, 0
    precision_inv = 1.0 / EPS
    while end > 0:
        for i in range(start, end):
            if abs(sub[i]) < TINY:
                sub[i] = 0.0
            else:
                sc = precision_inv * sub[i]
                if sc * sc <= (abs(diag[i]) + abs(diag[i + 1])):
                    sub[i] = 0.0
        while end > 0 and sub[end - 1] == 0.0:
            end -= 1
        if end <= 0:
            break
        it += 1
        if it > 30 * n:
            raise RuntimeError('SelfAdjointEigenSolver: no convergence')
        start = end - 1
        while start > 0 and sub[start - 1] != 0.0:
            start -= 1
        # tridiagonal_qr_step(diag, sub, start, end, Q)
        td = (diag[end - 1] - diag[end]) * 0.5
        e = sub[end - 1]
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
        z = sub[start]
        k = start
        while k < end and z != 0.0:
            c, s = _make_givens(x, z)
            sdk = s * diag[k] + c * sub[k]
            dkp1 = s * sub[k] + c * diag[k + 1]
            diag[k] = c * (c * diag[k] - s * sub[k]) - s * (c * sub[k] - s * diag[k + 1])
            diag[k + 1] = s * sdk + c * dkp1
            sub[k] = c * sdk - s * dkp1
            if k > start:
                sub[k - 1] = c * sub[k - 1] - s * z
            x = sub[k]
            if k < end - 1:
                z = -s * sub[k + 1]
                sub[k + 1] = c * sub[k + 1]
            # Q = Q*G  (applyOnTheRight(k, k+1, rot) = rotation in the plane with (c, -s))
            if not (c == 1.0 and s == 0.0):
                for i in range(n):
                    xi, yi = Q[i][k], Q[i][k + 1]
                    Q[i][k] = c * xi + (-s) * yi
                    Q[i][k + 1] = s * xi + c * yi
            k += 1
    for i in range(n - 1):   # selection sort, first minimum
        kk = i
        for j in range(i + 1, n):
            if diag[j] < diag[kk]:
                kk = j
        if kk != i:
            diag[i], diag[kk] = diag[kk], diag[i]
            for r in range(n):
                Q[r][i], Q[r][kk] = Q[r][kk], Q[r][i]
    return [d * scale for d in diag], Q


# ---------------------------------------------------------------- Clump::updateProperties (Yade 2023.02a)
def _translate(I, m, off):
    """Clump::inertiaTensorTranslate: I + m*(off.off*Identity - off*off^T), coefficient-wise."""
    dd = dot(off, off)
    return [[I[i][j] + m * ((dd if i == j else 0.0) - off[i] * off[j]) for j in range(3)] for i in range(3)]


def clump_properties(members, discretization=0):
    """members: list of (centre, radius, density) in increasing member id.  Returns a dict with mass, pos,
    inertia (principal moments, ascending), ori (w,x,y,z), relPos, relOri (lists in member order), R (the
    eigenvector matrix actually used), det_flipped (True if its third column was negated) and intersecting."""
    intersecting = False
    if discretization > 0:
        for i, (ci, ri, _) in enumerate(members):
            for j, (cj, rj, _) in enumerate(members):
                if i != j:
                    un = (ri + rj) - math.sqrt(dot(sub(ci, cj), sub(ci, cj)))
                    if un > 0.001 * min(ri, rj):
                        intersecting = True
    M = 0.0
    Sg = [0.0, 0.0, 0.0]
    Ig = [[0.0] * 3 for _ in range(3)]
    if intersecting:
        lo = [math.inf] * 3
        hi = [-math.inf] * 3
        for c, r, _ in members:
            for p in (add(c, [r, r, r]), sub(c, [r, r, r])):
                lo = [min(lo[i], p[i]) for i in range(3)]
                hi = [max(hi[i], p[i]) for i in range(3)]
        diag = sub(hi, lo)
        rmin = min(diag[0], min(diag[1], diag[2]))
        dx = rmin / discretization
        dv = math.pow(dx, 3)                # a real pow() call (glibc), like Python's math.pow
        cell = (dx * dx) / 6.               # pow(dx, 2)/6. -> (dx*dx)/6.
        x0 = lo[0] + dx / 2.
        while x0 < hi[0]:
            x1 = lo[1] + dx / 2.
            while x1 < hi[1]:
                x2 = lo[2] + dx / 2.
                while x2 < hi[2]:
                    x = [x0, x1, x2]
                    for c, r, dens in members:
                        d = sub(x, c)
                        if dot(d, d) < r * r:              # pow(r, 2) -> r*r
                            m = dens * dv
                            M += m
                            Sg = add(Sg, smul(m, x))
                            xx = dot(x, x)
                            Ig = [[Ig[i][j] + m * (((xx if i == j else 0.0) - x[i] * x[j]) + (cell if i == j else 0.0))
                                   for j in range(3)] for i in range(3)]
                            break
                    x2 += dx
                x1 += dx
            x0 += dx
    else:
        for c, r, dens in members:
            vol = (4. / 3.) * math.pi * math.pow(r, 3.)
            m = dens * vol
            M += m
            Sg = add(Sg, smul(m, c))
            Id = (2 / 5.) * m * (r * r)        # pow(r, 2): GCC folds it to r*r
            T = _translate([[Id if i == j else 0.0 for j in range(3)] for i in range(3)], m, smul(-1., c))
            Ig = [[Ig[i][j] + T[i][j] for j in range(3)] for i in range(3)]
    pos = [Sg[0] / M, Sg[1] / M, Sg[2] / M]
    Ic = _translate(Ig, -M, pos)
    Ic[1][0], Ic[2][0], Ic[2][1] = Ic[0][1], Ic[0][2], Ic[1][2]
    inertia, R = eigh3(Ic)
    flipped = det3(R) < 0
    if flipped:   # Yade makes the eigenvector matrix a rotation by negating its third column
        for r in range(3):
            R[r][2] = -R[r][2]
    ori = qnormalize(from_matrix(R))
    qc = qconj(ori)
    rel_pos = [qrot(qc, sub(c, pos)) for c, _, _ in members]
    rel_ori = [qmul(qc, (1.0, 0.0, 0.0, 0.0)) for _ in members]   # members keep ori = identity
    return {'mass': M, 'pos': pos, 'inertia': inertia, 'ori': ori, 'relPos': rel_pos, 'relOri': rel_ori,
            'R': R, 'det_flipped': flipped, 'intersecting': intersecting, 'Ic': Ic}


# ---------------------------------------------------------------- NewtonIntegrator, one step of a free clump
def dot_q(w, Q):
    """NewtonIntegrator::DotQ(angVel_body, Q) -> (w, x, y, z)."""
    qw, qx, qy, qz = Q
    return ((-qx * w[0] - qy * w[1] - qz * w[2]) / 2,
            (qw * w[0] - qz * w[1] + qy * w[2]) / 2,
            (qz * w[0] + qw * w[1] - qx * w[2]) / 2,
            (-qy * w[0] + qx * w[1] + qw * w[2]) / 2)


def clump_step(st, member_f, member_t, member_pos, rel_pos, rel_ori, dt, damping, gravity):
    """One NewtonIntegrator step of a clump that is not blocked.  st: dict pos, vel, ori (w,x,y,z), angVel,
    angMom, mass, inertia.  member_f/member_t: the members' force/torque accumulators of this step, in increasing
    member id; member_pos: member positions at the start of the step.  Returns (new clump state, F, T
    (the summed accumulators, before damping), members' new pos, ori, vel, angVel)."""
    F = [0.0, 0.0, 0.0]
    T = [0.0, 0.0, 0.0]
    for f, t, p in zip(member_f, member_t, member_pos):   # Clump::addForceTorqueFromMembers
        F = add(F, f)
        T = add(T, add(t, cross(sub(p, st['pos']), f)))
    vel, ang_vel, ang_mom, ori = st['vel'], st['angVel'], st['angMom'], st['ori']
    m, inertia = st['mass'], st['inertia']
    acc = [F[i] / m + gravity[i] for i in range(3)]
    acc = [acc[i] * (1 - damping * sign(acc[i] * (vel[i] + 0.5 * dt * acc[i]))) for i in range(3)]  # cundallDamp2nd
    vel = add(vel, smul(dt, acc))
    Md = [T[i] * (1 - damping * sign(T[i] * ang_vel[i])) for i in range(3)]                      # cundallDamp1st
    pos = add(st['pos'], [vel[0] * dt, vel[1] * dt, vel[2] * dt])          # leapfrogTranslate: pos += vel*dt
    # leapfrogAsphericalRotate
    A = to_rotation_matrix(qconj(ori))
    l_n = add(ang_mom, smul(dt / 2., Md))
    l_b_n = matvec(A, l_n)
    w_b_n = [l_b_n[i] / inertia[i] for i in range(3)]
    dq = dot_q(w_b_n, ori)
    q_half = tuple(ori[i] + (dt / 2.) * dq[i] for i in range(4))
    ang_mom = add(ang_mom, smul(dt, Md))
    l_b_half = matvec(A, ang_mom)
    w_b_half = [l_b_half[i] / inertia[i] for i in range(3)]
    dq = dot_q(w_b_half, q_half)
    ori_new = tuple(ori[i] + dt * dq[i] for i in range(4))
    ang_vel = qrot(ori_new, w_b_half)
    ori_new = qnormalize(ori_new)
    new = dict(st, pos=pos, vel=vel, ori=ori_new, angVel=ang_vel, angMom=ang_mom)
    # Clump::moveMembers
    mp, mo, mv, mw = [], [], [], []
    for rp, ro in zip(rel_pos, rel_ori):
        p = add(pos, qrot(ori_new, rp))
        mp.append(p)
        mo.append(qmul(ori_new, ro))
        mv.append(add(vel, cross(ang_vel, sub(p, pos))))
        mw.append(list(ang_vel))
    return new, F, T, mp, mo, mv, mw
