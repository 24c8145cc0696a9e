"""Rigid clumps: spheres fused into one rigid body, integrated as Yade 2023.02a does
(YADE_MODEL.md §7–8; thesis 3.3, eqs. 3.32–3.33; SPEC 1.2).

Members are ordinary spheres (rows of `pdem.bodies.state.Particles` with ``clump`` = the clump id):
they have contacts with everything except the members of their own clump (those pairs are
dropped from the candidate list, `drop_same_clump`). The clump body is a row of `Clumps`, owned
with all its members by the rank that owns its centre (`pdem.parallel.slab_domain`).

Per step (after the contact forces, `Simulation.compute_forces` / `integrate`):

1. `sum_member_forces`: F = Σ f_i, T = Σ (t_i + (x_i − x_c) × f_i) over the members in
   increasing gid (positions at the start of the step).
2. `leapfrog_clumps`: a = F/M + g, Cundall damping a_k ← a_k (1 − λ sgn(a_k (v_k + Δt a_k/2))),
   v ← v + Δt a, x_c ← x_c + Δt v. Rotation of an aspherical clump (principal moments not all
   equal) with the angular momentum L and the quaternion q (Yade's exactAsphericalRot):
   T_k ← T_k (1 − λ sgn(T_k ω_k)), A = R(q̄), L_n = L + Δt/2 T, ω_b = (A L_n)/I,
   q_½ = q + Δt/2 q̇(ω_b, q), L ← L + Δt T, ω_b = (A L)/I, q' = q + Δt q̇(ω_b, q_½),
   ω = q'·ω_b, q = q'/|q'| (Omelyan-like, Yade's leapfrogAsphericalRotate); a spherical clump
   turns like a sphere (α = T/I damped as a, ω ← ω + Δt α, q ← rot(|ω|Δt, ω/|ω|) q).
3. The members are placed: x_i = x_c + q·relPos_i, v_i = v_c + ω × (x_i − x_c), ω_i = ω.
   (The sphere leapfrog runs over the member rows too; step 3 overwrites what it wrote.)

Storage: SoA of the owned clumps (``id``, ``pos``, ``vel``, ``angvel``, ``angmom``, ``ori``
(w, x, y, z), ``mass``, ``inertia`` (principal), ``aspherical``; ``force``/``torque`` the member
sums of the last step) and their members as CSR (``mptr``; ``mgid`` ascending within a clump,
``relpos`` in the principal frame; ``mrow`` the member rows, remapped at every neighbour rebuild
by `attach`). Checkpoint tables: ``clumps`` (key ``id``) and ``clump_members`` (key ``gid``).
Units: m, s, kg, N; quaternions unit, body → global.
"""
from math import cos, sin, sqrt

import numpy as np
from numba import njit, prange

from ..kernels import kernel
from ..vec import cross3, dot3

CLUMP_FLOATS = {"pos": 3, "vel": 3, "angvel": 3, "angmom": 3, "ori": 4, "mass": 1, "inertia": 3}
CLUMP_INTS = ("id", "aspherical")
CLUMP_TABLE = "clumps"
MEMBER_TABLE = "clump_members"


@njit(inline="always", cache=True)
def _sign(x):
    return (x > 0.0) * 1.0 - (x < 0.0) * 1.0


@njit(inline="always", cache=True)
def _qrot(w, x, y, z, vx, vy, vz):
    """Eigen's q·v: uv = 2 (qv × v); v + w uv + qv × uv (q need not be normalised)."""
    ux, uy, uz = cross3(x, y, z, vx, vy, vz)
    ux = ux + ux
    uy = uy + uy
    uz = uz + uz
    cx, cy, cz = cross3(x, y, z, ux, uy, uz)
    return (vx + w * ux) + cx, (vy + w * uy) + cy, (vz + w * uz) + cz


@njit(inline="always", cache=True)
def _dot_q(w0, w1, w2, qw, qx, qy, qz):
    """NewtonIntegrator::DotQ(ω_body, Q) as (w, x, y, z)."""
    return ((-qx * w0 - qy * w1 - qz * w2) / 2.0, (qw * w0 - qz * w1 + qy * w2) / 2.0,
            (qz * w0 + qw * w1 - qx * w2) / 2.0, (-qy * w0 + qx * w1 + qw * w2) / 2.0)


@kernel()
def sum_member_forces(nc, mptr, mrow, cpos, force, torque, pos, cforce, ctorque):
    """Clump::addForceTorqueFromMembers: cforce/ctorque of every clump from its members."""
    for c in prange(nc):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        tx = 0.0
        ty = 0.0
        tz = 0.0
        for k in range(mptr[c], mptr[c + 1]):
            b = mrow[k]
            ax, ay, az = cross3(pos[b, 0] - cpos[c, 0], pos[b, 1] - cpos[c, 1], pos[b, 2] - cpos[c, 2],
                                force[b, 0], force[b, 1], force[b, 2])
            fx += force[b, 0]
            fy += force[b, 1]
            fz += force[b, 2]
            tx += torque[b, 0] + ax
            ty += torque[b, 1] + ay
            tz += torque[b, 2] + az
        cforce[c, 0] = fx
        cforce[c, 1] = fy
        cforce[c, 2] = fz
        ctorque[c, 0] = tx
        ctorque[c, 1] = ty
        ctorque[c, 2] = tz


@njit(inline="always", cache=True)
def rotation_matrix(qw, qx, qy, qz):
    """Eigen's Quaternion::toRotationMatrix of q = (w, x, y, z), as its 9 entries row by row."""
    tx = 2.0 * qx
    ty = 2.0 * qy
    tz = 2.0 * qz
    twx = tx * qw
    twy = ty * qw
    twz = tz * qw
    txx = tx * qx
    txy = ty * qx
    txz = tz * qx
    tyy = ty * qy
    tyz = tz * qy
    tzz = tz * qz
    return (1.0 - (tyy + tzz), txy - twz, txz + twy, txy + twz, 1.0 - (txx + tzz), tyz - twx, txz - twy, tyz + twx,
            1.0 - (txx + tyy))


@njit(inline="always", cache=True)
def normalised(qw, qx, qy, qz):
    """q / |q| (Eigen's Quaternion::normalize)."""
    qn = sqrt((qx * qx + qy * qy) + (qz * qz + qw * qw))
    return qw / qn, qx / qn, qy / qn, qz / qn


@njit(inline="always", cache=True)
def aspherical_rotate(qw, qx, qy, qz, angmom, tx0, ty0, tz0, angvel, inertia, damping, dt):
    """Yade's leapfrogAsphericalRotate (exactAsphericalRot) of one body: orientation q (w, x, y, z,
    body = principal frame → global), angular momentum ``angmom`` [3] (global, updated in place),
    torque (tx0, ty0, tz0) [N·m] Cundall-damped against the last ``angvel`` [3] [rad/s], principal
    ``inertia`` [3] [kg·m²]; returns the new q (not normalised) and ω [rad/s] (module docstring)."""
    t0 = tx0 * (1.0 - damping * _sign(tx0 * angvel[0]))
    t1 = ty0 * (1.0 - damping * _sign(ty0 * angvel[1]))
    t2 = tz0 * (1.0 - damping * _sign(tz0 * angvel[2]))
    # A = R(conj(q))
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = rotation_matrix(qw, -qx, -qy, -qz)
    h = dt / 2.0
    l0 = angmom[0] + h * t0
    l1 = angmom[1] + h * t1
    l2 = angmom[2] + h * t2
    w0 = dot3(a00, a01, a02, l0, l1, l2) / inertia[0]
    w1 = dot3(a10, a11, a12, l0, l1, l2) / inertia[1]
    w2 = dot3(a20, a21, a22, l0, l1, l2) / inertia[2]
    dw, dx, dy, dz = _dot_q(w0, w1, w2, qw, qx, qy, qz)
    hw = qw + h * dw
    hx = qx + h * dx
    hy = qy + h * dy
    hz = qz + h * dz
    l0 = angmom[0] + dt * t0
    l1 = angmom[1] + dt * t1
    l2 = angmom[2] + dt * t2
    angmom[0] = l0
    angmom[1] = l1
    angmom[2] = l2
    w0 = dot3(a00, a01, a02, l0, l1, l2) / inertia[0]
    w1 = dot3(a10, a11, a12, l0, l1, l2) / inertia[1]
    w2 = dot3(a20, a21, a22, l0, l1, l2) / inertia[2]
    dw, dx, dy, dz = _dot_q(w0, w1, w2, hw, hx, hy, hz)
    qw = qw + dt * dw
    qx = qx + dt * dx
    qy = qy + dt * dy
    qz = qz + dt * dz
    ox, oy, oz = _qrot(qw, qx, qy, qz, w0, w1, w2)
    return qw, qx, qy, qz, ox, oy, oz


@kernel()
def leapfrog_clumps(nc, cpos, cvel, cangvel, cangmom, cori, cmass, cinertia, casph, cforce, ctorque, mptr, mrow,
                    relpos, pos, vel, angvel, gravity, damping, dt):
    """NewtonIntegrator on every clump, then Clump::moveMembers (see the module docstring)."""
    for c in prange(nc):
        m = cmass[c]
        for k in range(3):
            a = cforce[c, k] / m + gravity[k]
            a *= 1.0 - damping * _sign(a * (cvel[c, k] + 0.5 * dt * a))
            cvel[c, k] += dt * a
        for k in range(3):
            cpos[c, k] += cvel[c, k] * dt
        qw = cori[c, 0]
        qx = cori[c, 1]
        qy = cori[c, 2]
        qz = cori[c, 3]
        if casph[c]:
            qw, qx, qy, qz, ox, oy, oz = aspherical_rotate(qw, qx, qy, qz, cangmom[c], ctorque[c, 0], ctorque[c, 1],
                                                           ctorque[c, 2], cangvel[c], cinertia[c], damping, dt)
            cangvel[c, 0] = ox
            cangvel[c, 1] = oy
            cangvel[c, 2] = oz
        else:  # leapfrogSphericalRotate
            for k in range(3):
                a = ctorque[c, k] / cinertia[c, k]
                a *= 1.0 - damping * _sign(a * (cangvel[c, k] + 0.5 * dt * a))
                cangvel[c, k] += dt * a
            ox = cangvel[c, 0]
            oy = cangvel[c, 1]
            oz = cangvel[c, 2]
            w2 = dot3(ox, oy, oz, ox, oy, oz)
            if w2 != 0.0:
                wn = sqrt(w2)
                half = 0.5 * (wn * dt)
                s = sin(half)
                rw = cos(half)
                rx = s * (ox / wn)
                ry = s * (oy / wn)
                rz = s * (oz / wn)
                qw, qx, qy, qz = (rw * qw - rx * qx - ry * qy - rz * qz, rw * qx + rx * qw + ry * qz - rz * qy,
                                  rw * qy + ry * qw + rz * qx - rx * qz, rw * qz + rz * qw + rx * qy - ry * qx)
        qw, qx, qy, qz = normalised(qw, qx, qy, qz)
        cori[c, 0] = qw
        cori[c, 1] = qx
        cori[c, 2] = qy
        cori[c, 3] = qz
        ox = cangvel[c, 0]
        oy = cangvel[c, 1]
        oz = cangvel[c, 2]
        for k in range(mptr[c], mptr[c + 1]):
            b = mrow[k]
            rx, ry, rz = _qrot(qw, qx, qy, qz, relpos[k, 0], relpos[k, 1], relpos[k, 2])
            px = cpos[c, 0] + rx
            py = cpos[c, 1] + ry
            pz = cpos[c, 2] + rz
            pos[b, 0] = px
            pos[b, 1] = py
            pos[b, 2] = pz
            vx, vy, vz = cross3(ox, oy, oz, px - cpos[c, 0], py - cpos[c, 1], pz - cpos[c, 2])
            vel[b, 0] = cvel[c, 0] + vx
            vel[b, 1] = cvel[c, 1] + vy
            vel[b, 2] = cvel[c, 2] + vz
            angvel[b, 0] = ox
            angvel[b, 1] = oy
            angvel[b, 2] = oz


@njit(cache=True)
def drop_same_clump(pi, pj, row_clump):
    """The candidate pairs (pi, pj) without those whose two rows are members of one rigid clump
    (``row_clump[row]`` = its clump id, -1 for any other row); the order is kept."""
    keep = 0
    for p in range(pi.shape[0]):
        c = row_clump[pi[p]]
        if c < 0 or c != row_clump[pj[p]]:
            pi[keep] = pi[p]
            pj[keep] = pj[p]
            keep += 1
    return pi[:keep], pj[:keep]


@njit(cache=True)
def add_member_stiffness(n_local, ptr, rows, state, kn, ks, out):
    """out[b] += Σ (k_n + k_s) over the real contact rows of each owned body b (CSR ptr/rows)."""
    for b in range(n_local):
        for k in range(ptr[b], ptr[b + 1]):
            p = rows[k]
            if state[p] == 1:
                out[b] += kn[p] + ks[p]


@njit(cache=True)
def clump_dt(nc, mptr, mrow, cpos, pos, radius, kmember, cmass, cinertia):
    """sqrt(min over clumps of M/K_t and I_min/K_r) [s]: K_t = Σ (k_n + k_s) over the members'
    contacts bounds the clump's stiffness in any direction, K_r = Σ (k_n + k_s) (|x_i − x_c| + r_i)²
    its rotational stiffness (every contact force at the farthest point of its member); inf
    without contacts."""
    best = np.inf
    for c in range(nc):
        kt = 0.0
        kr = 0.0
        for k in range(mptr[c], mptr[c + 1]):
            b = mrow[k]
            dx = pos[b, 0] - cpos[c, 0]
            dy = pos[b, 1] - cpos[c, 1]
            dz = pos[b, 2] - cpos[c, 2]
            lever = sqrt(dx * dx + dy * dy + dz * dz) + radius[b]
            kt += kmember[b]
            kr += kmember[b] * lever * lever
        if kt > 0.0:
            best = min(best, cmass[c] / kt)
            best = min(best, min(cinertia[c, 0], min(cinertia[c, 1], cinertia[c, 2])) / kr)
    return sqrt(best)


class Clumps:
    """The rigid clumps owned by this rank and their members (see the module docstring).

    ``extent`` [m]: the largest distance of a member centre from its clump's centre over all
    clumps of the scene (the same on every rank; the slab halo widens by twice it)."""

    def __init__(self, extent):
        self.extent = float(extent)
        self.set_rows(empty_clump_table(), empty_member_table())

    # ------------------------------------------------------------------ rows
    def set_rows(self, clumps, members):
        """Hold exactly these clumps (a ``clumps`` table) and their members (``clump_members``):
        clumps sorted by id, members by (clump, gid)."""
        order = np.argsort(np.asarray(clumps["id"], np.int64), kind="stable")
        for k in CLUMP_INTS:
            setattr(self, k, np.ascontiguousarray(np.asarray(clumps[k], np.int64)[order]))
        for k, w in CLUMP_FLOATS.items():
            a = np.asarray(clumps[k], np.float64).reshape(len(order), w) if w > 1 else np.asarray(clumps[k], np.float64)
            setattr(self, k, np.ascontiguousarray(a[order]))
        self.n = len(order)
        self.force = np.zeros((self.n, 3))
        self.torque = np.zeros((self.n, 3))
        mc = np.asarray(members["clump"], np.int64)
        mg = np.asarray(members["gid"], np.int64)
        morder = np.lexsort((mg, mc))
        self.mclump, self.mgid = mc[morder], mg[morder]
        self.relpos = np.ascontiguousarray(np.asarray(members["relpos"], np.float64).reshape(-1, 3)[morder])
        idx = np.searchsorted(self.id, self.mclump)
        held = idx < self.n
        held[held] = self.id[idx[held]] == self.mclump[held]
        if not held.all():
            raise ValueError(f"clump members: gid {int(self.mgid[~held][0])} belongs to clump "
                             f"{int(self.mclump[~held][0])}, which this rank does not hold")
        counts = np.bincount(idx, minlength=self.n).astype(np.int64)
        self.mptr = np.zeros(self.n + 1, np.int64)
        np.cumsum(counts, out=self.mptr[1:])
        self.mrow = np.full(len(self.mgid), -1, np.int64)
        self.row_clump = np.full(0, -1, np.int64)

    def table(self):
        """(clumps, clump_members): copies of the owned rows as checkpoint tables."""
        clumps = {k: getattr(self, k).copy() for k in (*CLUMP_INTS, *CLUMP_FLOATS)}
        members = {"gid": self.mgid.copy(), "clump": self.mclump.copy(), "relpos": self.relpos.copy()}
        return clumps, members

    def keep(self, mask):
        """Keep the clumps where ``mask`` is true (with their members)."""
        clumps, members = self.table()
        mine = np.isin(members["clump"], clumps["id"][mask])
        self.set_rows({k: v[mask] for k, v in clumps.items()}, {k: v[mine] for k, v in members.items()})

    def add(self, clumps, members):
        """Add clumps (tables of rows this rank did not hold, e.g. arriving by migration)."""
        old_c, old_m = self.table()
        self.set_rows(
            {
                k: np.concatenate([old_c[k], np.asarray(clumps[k], old_c[k].dtype).reshape((-1,) + old_c[k].shape[1:])])
                for k in old_c
            },
            {
                k: np.concatenate(
                    [old_m[k], np.asarray(members[k], old_m[k].dtype).reshape((-1,) + old_m[k].shape[1:])]
                )
                for k in old_m
            },
        )

    def attach(self, p):
        """Map the members to their rows after the owned rows changed (migration, reordering)
        and set ``row_clump`` [n_total] (clump id of the members' rows, -1 elsewhere)."""
        nl = p.n_local
        gids = p.gid[:nl]
        order = np.argsort(gids, kind="stable")
        at = np.searchsorted(gids[order], self.mgid)
        at = np.minimum(at, max(nl - 1, 0))
        if len(self.mgid) and (nl == 0 or np.any(gids[order][at] != self.mgid)):
            missing = self.mgid[(nl == 0) | (gids[order][at] != self.mgid)][0] if nl else self.mgid[0]
            raise RuntimeError(f"clumps: member gid {int(missing)} is not held with its clump on this rank")
        self.mrow = np.ascontiguousarray(order[at]) if len(self.mgid) else np.zeros(0, np.int64)
        self.row_clump = np.full(p.n_total, -1, np.int64)
        self.row_clump[self.mrow] = self.mclump

    def centre_coordinate(self, p, axis):
        """[n_local] coordinate along ``axis`` that decides the owner of each owned row: its own
        for a sphere, its clump's centre for a member (rows as at the last `attach`)."""
        x = p.pos[: p.n_local, axis].copy()
        if len(self.mrow):
            x[self.mrow] = np.repeat(self.pos[:, axis], np.diff(self.mptr))
        return x

    def pack(self, mask, dest):
        """Rows of the clumps where ``mask`` is true, addressed to ``dest`` (migration): (ints
        [n, 1 + CLUMP_INTS], floats [n, Σ CLUMP_FLOATS], member ints [m, 3] = dest, gid, clump,
        member floats [m, 3] = relpos)."""
        clumps, members = self.table()
        n = int(np.count_nonzero(mask))
        ci = np.concatenate([np.asarray(dest, np.int64)[mask][:, None]]
                            + [clumps[k][mask].reshape(n, 1) for k in CLUMP_INTS], axis=1)
        cf = np.concatenate([clumps[k][mask].reshape(n, w) for k, w in CLUMP_FLOATS.items()], axis=1)
        pick = np.isin(members["clump"], clumps["id"][mask])
        mdest = np.repeat(np.asarray(dest, np.int64), np.diff(self.mptr))[pick]
        mi = np.stack([mdest, members["gid"][pick], members["clump"][pick]], axis=1)
        return ci, cf, mi, members["relpos"][pick].reshape(-1, 3)

    # ------------------------------------------------------------------ per step
    def sum_forces(self, p):
        sum_member_forces(self.n, self.mptr, self.mrow, self.pos, p.force, p.torque, p.pos, self.force, self.torque)

    def integrate(self, p, gravity, damping, dt):
        leapfrog_clumps(self.n, self.pos, self.vel, self.angvel, self.angmom, self.ori, self.mass, self.inertia,
                        self.aspherical, self.force, self.torque, self.mptr, self.mrow, self.relpos, p.pos, p.vel,
                        p.angvel, gravity, damping, dt)

    def stiffness_dt(self, p, kmember):
        """The clumps' mass–spring time step [s] (`clump_dt`) from ``kmember`` [n_local], the
        Σ (k_n + k_s) of each owned body's contacts."""
        return clump_dt(self.n, self.mptr, self.mrow, self.pos, p.pos, p.radius, kmember, self.mass, self.inertia)

    # ------------------------------------------------------------------ diagnostics
    def energy(self, gravity, dt):
        """(kinetic, rotational, potential) [J] per owned clump: ½ M v², ½ ω·L (aspherical) or
        ½ Σ I_k ω_k², −M g·x at the start of the step."""
        ke = 0.5 * self.mass * np.einsum("ij,ij->i", self.vel, self.vel)
        w, lm = self.angvel, self.angmom
        kr = np.where(self.aspherical == 1, 0.5 * np.einsum("ij,ij->i", w, lm),
                      0.5 * np.einsum("ij,ij->i", self.inertia * w, w))
        pe = -self.mass * ((self.pos - self.vel * dt) @ np.asarray(gravity, np.float64))
        return ke, kr, pe

    def net_forces(self, gravity):
        """[n, 3] F + M g of every owned clump (the unbalanced-force observable)."""
        return self.force + self.mass[:, None] * np.asarray(gravity, np.float64)


def empty_clump_table():
    out = {k: np.zeros(0, np.int64) for k in CLUMP_INTS}
    out.update({k: np.zeros((0, w)) if w > 1 else np.zeros(0) for k, w in CLUMP_FLOATS.items()})
    return out


def empty_member_table():
    return {"gid": np.zeros(0, np.int64), "clump": np.zeros(0, np.int64), "relpos": np.zeros((0, 3))}


def unpack_clumps(ci, cf, mi, mf):
    """Inverse of `Clumps.pack` (without the destination column): (clumps, clump_members)."""
    clumps = {k: ci[:, 1 + c].astype(np.int64) for c, k in enumerate(CLUMP_INTS)}
    at = 0
    for k, w in CLUMP_FLOATS.items():
        clumps[k] = cf[:, at: at + w].copy() if w > 1 else cf[:, at].copy()
        at += w
    members = {"gid": mi[:, 1].astype(np.int64), "clump": mi[:, 2].astype(np.int64), "relpos": mf.reshape(-1, 3)}
    return clumps, members


def extent_of(members):
    """Largest |relPos| [m] of a ``clump_members`` table (0 if empty)."""
    rp = np.asarray(members["relpos"], np.float64).reshape(-1, 3)
    return float(np.sqrt(np.einsum("ij,ij->i", rp, rp)).max()) if len(rp) else 0.0
