"""The linear frictional model exactly as Yade 2023.02a computes it (YADE_MODEL.md §3–5).

Yade: ``Ig2_Sphere_Sphere_ScGeom``, ``Ig2_Wall_Sphere_ScGeom``, ``Ig2_Facet_Sphere_ScGeom``
(geometry, ScGeom::precompute), ``Ip2_FrictMat_FrictMat_FrictPhys`` (parameters, once per contact),
``Law2_ScGeom_FrictPhys_CundallStrack`` (forces). Thesis ch. 3 and appendix A; Cundall & Strack
(1979) Géotechnique 29(1):47–65, doi:10.1680/geot.1979.29.1.47.

Per contact: parameters ``[kn [N/m], ks [N/m], tan φ]`` (Ip2, fixed at creation) and history
``[Fs_x, Fs_y, Fs_z [N], n_x, n_y, n_z]`` (shear force in global axes, normal of the previous step).
Each loop writes the force and torques of every candidate pair into the pair's own row
(race-free under ``prange``); `pdem.forces` sums them per body in a fixed order.
"""
from math import sqrt, tan

from numba import njit, prange

from ..kernels import kernel

from ..vec import cross3, dot3

N_PARAMS = 3
HISTORY_WIDTH = 6


@njit(inline="always", cache=True)
def ip2(e_a, nu_a, phi_a, r_a, e_b, nu_b, phi_b, r_b):
    """kn = 2 E_a R_a E_b R_b/(E_a R_a + E_b R_b), ks the same with E·ν, tan(min φ) (§4)."""
    kna = e_a * r_a
    knb = e_b * r_b
    ksa = kna * nu_a
    ksb = knb * nu_b
    kn = ((2.0 * kna) * knb) / (kna + knb)
    ks = ((2.0 * ksa) * ksb) / (ksa + ksb)
    return kn, ks, tan(min(phi_a, phi_b))


@njit(cache=True)
def set_friction(n, mat_i, mat_j, phi, params):
    """params[:n, 2] = tan(min φ) of each contact's two materials (Ip2's friction, the same tan)."""
    for k in range(n):
        params[k, 2] = tan(min(phi[mat_i[k]], phi[mat_j[k]]))


@njit(inline="always", cache=True)
def _clear(p, state, history, force, torque_i, torque_j, overlap):
    state[p] = 0
    for c in range(HISTORY_WIDTH):
        history[p, c] = 0.0
    for c in range(3):
        force[p, c] = 0.0
        torque_i[p, c] = 0.0
        torque_j[p, c] = 0.0
    overlap[p] = 0.0


@njit(inline="always", cache=True)
def law2(p, fresh, nx, ny, nz, pen, six, siy, siz, ox, oy, oz, tx, ty, tz, params, history):
    """CundallStrack: rotate the stored shear force, add −ks·Δu_s, cap at |Fn| tan φ (§5).

    Returns f = −Fn − Fs, the force on body 1 [N]; updates the history row."""
    kn = params[p, 0]
    ks = params[p, 1]
    tphi = params[p, 2]
    knp = kn * max(pen, 0.0)
    fnx = knp * nx
    fny = knp * ny
    fnz = knp * nz
    if fresh:
        fsx = 0.0
        fsy = 0.0
        fsz = 0.0
    else:
        fsx = history[p, 0]
        fsy = history[p, 1]
        fsz = history[p, 2]
        cx, cy, cz = cross3(fsx, fsy, fsz, ox, oy, oz)
        fsx -= cx
        fsy -= cy
        fsz -= cz
        cx, cy, cz = cross3(fsx, fsy, fsz, tx, ty, tz)
        fsx -= cx
        fsy -= cy
        fsz -= cz
    fsx -= ks * six
    fsy -= ks * siy
    fsz -= ks * siz
    max_fs2 = dot3(fnx, fny, fnz, fnx, fny, fnz) * (tphi * tphi)
    fs2 = dot3(fsx, fsy, fsz, fsx, fsy, fsz)
    if fs2 > max_fs2:
        ratio = sqrt(max_fs2) / sqrt(fs2)
        fsx *= ratio
        fsy *= ratio
        fsz *= ratio
    history[p, 0] = fsx
    history[p, 1] = fsy
    history[p, 2] = fsz
    history[p, 3] = nx
    history[p, 4] = ny
    history[p, 5] = nz
    return -fnx - fsx, -fny - fsy, -fnz - fsz


@njit(inline="always", cache=True)
def _axes(fresh, p, history, nx, ny, nz, w_x, w_y, w_z, dt):
    """ScGeom::precompute: orthonormal_axis = n_old × n, twist_axis = (dt/2 n_old·(ω1+ω2)) n_old."""
    if fresh:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    px = history[p, 3]
    py = history[p, 4]
    pz = history[p, 5]
    ox, oy, oz = cross3(px, py, pz, nx, ny, nz)
    angle = dt * 0.5 * dot3(px, py, pz, w_x, w_y, w_z)
    return ox, oy, oz, angle * px, angle * py, angle * pz


@kernel()
def sphere_sphere_forces(n, pi, pj, state, params, history, force, torque_i, torque_j, overlap,
                         pos, vel, angvel, radius, material, young, poisson, friction, dt):
    """Forces of all sphere–sphere candidates (Yade Ig2_Sphere_Sphere_ScGeom, noRatch)."""
    for p in prange(n):
        i = pi[p]
        j = pj[p]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        r1 = radius[i]
        r2 = radius[j]
        d2 = dot3(dx, dy, dz, dx, dy, dz)
        fresh = state[p] == 0
        rs = r1 + r2
        if fresh and rs * rs - d2 < 0.0:
            continue  # a row with state 0 is already clear (ContactList.replace, _clear)
        dist = sqrt(d2)
        nx = dx / dist
        ny = dy / dist
        nz = dz / dist
        pen = rs - dist
        if pen < 0.0:
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        if fresh:
            ma = material[i]
            mb = material[j]
            kn, ks, tphi = ip2(young[ma], poisson[ma], friction[ma], r1, young[mb], poisson[mb], friction[mb], r2)
            params[p, 0] = kn
            params[p, 1] = ks
            params[p, 2] = tphi
            state[p] = 1
        ox, oy, oz, tx, ty, tz = _axes(fresh, p, history, nx, ny, nz, angvel[i, 0] + angvel[j, 0],
                                       angvel[i, 1] + angvel[j, 1], angvel[i, 2] + angvel[j, 2], dt)
        # relative velocity of 2 w.r.t. 1, avoidGranularRatcheting (full radii, factor alpha)
        alpha = rs / (rs - pen)
        ax = (vel[j, 0] - vel[i, 0]) * alpha
        ay = (vel[j, 1] - vel[i, 1]) * alpha
        az = (vel[j, 2] - vel[i, 2]) * alpha
        bx, by, bz = cross3(angvel[j, 0], angvel[j, 1], angvel[j, 2], (-r2) * nx, (-r2) * ny, (-r2) * nz)
        cx, cy, cz = cross3(angvel[i, 0], angvel[i, 1], angvel[i, 2], r1 * nx, r1 * ny, r1 * nz)
        rvx = ax + bx - cx
        rvy = ay + by - cy
        rvz = az + bz - cz
        dn = dot3(nx, ny, nz, rvx, rvy, rvz)
        rvx = rvx - dn * nx
        rvy = rvy - dn * ny
        rvz = rvz - dn * nz
        fx, fy, fz = law2(p, fresh, nx, ny, nz, pen, rvx * dt, rvy * dt, rvz * dt, ox, oy, oz, tx, ty, tz,
                          params, history)
        force[p, 0] = fx
        force[p, 1] = fy
        force[p, 2] = fz
        mx, my, mz = cross3(nx, ny, nz, fx, fy, fz)
        l1 = r1 - 0.5 * pen
        l2 = r2 - 0.5 * pen
        torque_i[p, 0] = l1 * mx
        torque_i[p, 1] = l1 * my
        torque_i[p, 2] = l1 * mz
        torque_j[p, 0] = l2 * mx
        torque_j[p, 1] = l2 * my
        torque_j[p, 2] = l2 * mz
        overlap[p] = pen


@kernel()
def sphere_wall_forces(n, ps, pw, state, params, history, force, torque_i, torque_j, overlap,
                       pos, vel, angvel, radius, material, young, poisson, friction,
                       wall_axis, wall_sense, wall_pos, wall_vel, wall_material, dt):
    """Forces of sphere–wall candidates (Yade Ig2_Wall_Sphere_ScGeom; wall = body 1).

    ``force`` is the force on the sphere (−f); ``torque_i`` the torque on the sphere."""
    for p in prange(n):
        s = ps[p]
        w = pw[p]
        a = wall_axis[w]
        r = radius[s]
        dist = pos[s, a] - wall_pos[w]
        fresh = state[p] == 0
        if fresh and abs(dist) > r:
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        pen = -(abs(dist) - r)
        if pen < 0.0:
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        sense = wall_sense[w]
        sign = (1.0 if dist > 0.0 else -1.0) if sense == 0 else (1.0 if sense == 1 else -1.0)
        nx = sign if a == 0 else 0.0
        ny = sign if a == 1 else 0.0
        nz = sign if a == 2 else 0.0
        # Ip2, relative velocity and Law2 of a sphere on a flat boundary (the same lines are in
        # sphere_box_forces). Written out on purpose: a shared inline helper that took the arrays
        # and passed them on to _axes/law2 cost ~20 atomic reference-count updates per contact
        # (numba keeps them across nested inlined calls) and made this loop 5x slower.
        if fresh:
            mw = wall_material[w]
            ms = material[s]
            kn, ks, tphi = ip2(young[mw], poisson[mw], friction[mw], r, young[ms], poisson[ms], friction[ms], r)
            params[p, 0] = kn
            params[p, 1] = ks
            params[p, 2] = tphi
            state[p] = 1
        ox, oy, oz, tx, ty, tz = _axes(fresh, p, history, nx, ny, nz, angvel[s, 0], angvel[s, 1], angvel[s, 2], dt)
        rs = r + r
        alpha = rs / (rs - pen)
        ax = (vel[s, 0] - wall_vel[w, 0]) * alpha
        ay = (vel[s, 1] - wall_vel[w, 1]) * alpha
        az = (vel[s, 2] - wall_vel[w, 2]) * alpha
        bx, by, bz = cross3(angvel[s, 0], angvel[s, 1], angvel[s, 2], (-r) * nx, (-r) * ny, (-r) * nz)
        rvx = ax + bx
        rvy = ay + by
        rvz = az + bz
        dn = dot3(nx, ny, nz, rvx, rvy, rvz)
        rvx = rvx - dn * nx
        rvy = rvy - dn * ny
        rvz = rvz - dn * nz
        fx, fy, fz = law2(p, fresh, nx, ny, nz, pen, rvx * dt, rvy * dt, rvz * dt, ox, oy, oz, tx, ty, tz,
                          params, history)
        force[p, 0] = -fx
        force[p, 1] = -fy
        force[p, 2] = -fz
        mx, my, mz = cross3(nx, ny, nz, fx, fy, fz)
        l2 = r - 0.5 * pen
        torque_i[p, 0] = l2 * mx
        torque_i[p, 1] = l2 * my
        torque_i[p, 2] = l2 * mz
        overlap[p] = pen


@kernel()
def sphere_facet_forces(n, ps, pf, state, params, history, force, torque_i, torque_j, overlap,
                        pos, vel, angvel, radius, material, young, poisson, friction,
                        facet_geom, facet_vel, facet_material, dt):
    """Forces of sphere–facet candidates (Yade Ig2_Facet_Sphere_ScGeom, facet = body 1, no
    ratcheting correction; face, edge and vertex contacts). ``facet_geom`` rows are laid out
    by `pdem.facets.FACET_COLUMNS`."""
    for p in prange(n):
        s = ps[p]
        f = pf[p]
        g = facet_geom[f]
        r = radius[s]
        clx = pos[s, 0] - g[0]
        cly = pos[s, 1] - g[1]
        clz = pos[s, 2] - g[2]
        nfx = g[3]
        nfy = g[4]
        nfz = g[5]
        big_l = dot3(nfx, nfy, nfz, clx, cly, clz)
        if big_l < 0.0:
            nfx = -nfx
            nfy = -nfy
            nfz = -nfz
            big_l = -big_l
        fresh = state[p] == 0
        if fresh and big_l > r:
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        cpx = clx - big_l * nfx
        cpy = cly - big_l * nfy
        cpz = clz - big_l * nfz
        # edge normals ne_k at g[6 + 3k], icr at g[15], vertex unit vectors vu_k at g[16 + 3k], lengths vl_k at g[25 + k]
        bm = dot3(g[6], g[7], g[8], cpx, cpy, cpz)
        m = 0
        for k in range(1, 3):
            q = dot3(g[6 + 3 * k], g[7 + 3 * k], g[8 + 3 * k], cpx, cpy, cpz)
            if q > bm:
                bm = q
                m = k
        icr = g[15]
        if bm < icr:
            pen = r - big_l
            nn = sqrt(dot3(nfx, nfy, nfz, nfx, nfy, nfz))
            nx = nfx / nn
            ny = nfy / nn
            nz = nfz / nn
        else:
            cpx = cpx + g[6 + 3 * m] * (icr - bm)
            cpy = cpy + g[7 + 3 * m] * (icr - bm)
            cpz = cpz + g[8 + 3 * m] * (icr - bm)
            mp = 2 if m - 1 < 0 else m - 1
            if dot3(cpx, cpy, cpz, g[6 + 3 * mp], g[7 + 3 * mp], g[8 + 3 * mp]) > icr:
                cpx = g[16 + 3 * m] * g[25 + m]
                cpy = g[17 + 3 * m] * g[25 + m]
                cpz = g[18 + 3 * m] * g[25 + m]
            else:
                m = 0 if m + 1 > 2 else m + 1
                if dot3(cpx, cpy, cpz, g[6 + 3 * m], g[7 + 3 * m], g[8 + 3 * m]) > icr:
                    cpx = g[16 + 3 * m] * g[25 + m]
                    cpy = g[17 + 3 * m] * g[25 + m]
                    cpz = g[18 + 3 * m] * g[25 + m]
            nx = clx - cpx
            ny = cly - cpy
            nz = clz - cpz
            nn = sqrt(dot3(nx, ny, nz, nx, ny, nz))
            nx /= nn
            ny /= nn
            nz /= nn
            pen = r - nn
        if not (pen > 0.0 or not fresh):
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        if pen < 0.0:  # real contact that opened: Law2 deletes it
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        if fresh:
            mf = facet_material[f]
            ms = material[s]
            kn, ks, tphi = ip2(young[mf], poisson[mf], friction[mf], 2.0 * r, young[ms], poisson[ms], friction[ms], r)
            params[p, 0] = kn
            params[p, 1] = ks
            params[p, 2] = tphi
            state[p] = 1
        ox, oy, oz, tx, ty, tz = _axes(fresh, p, history, nx, ny, nz, angvel[s, 0], angvel[s, 1], angvel[s, 2], dt)
        lever = r - 0.5 * pen
        # contact point x2 - (r - pen/2) n, then its offset from the sphere centre (Yade's order)
        c2x = (pos[s, 0] - lever * nx) - pos[s, 0]
        c2y = (pos[s, 1] - lever * ny) - pos[s, 1]
        c2z = (pos[s, 2] - lever * nz) - pos[s, 2]
        wx, wy, wz = cross3(angvel[s, 0], angvel[s, 1], angvel[s, 2], c2x, c2y, c2z)
        rvx = (vel[s, 0] + wx) - facet_vel[f, 0]
        rvy = (vel[s, 1] + wy) - facet_vel[f, 1]
        rvz = (vel[s, 2] + wz) - facet_vel[f, 2]
        dn = dot3(nx, ny, nz, rvx, rvy, rvz)
        rvx = rvx - dn * nx
        rvy = rvy - dn * ny
        rvz = rvz - dn * nz
        fx, fy, fz = law2(p, fresh, nx, ny, nz, pen, rvx * dt, rvy * dt, rvz * dt, ox, oy, oz, tx, ty, tz,
                          params, history)
        force[p, 0] = -fx
        force[p, 1] = -fy
        force[p, 2] = -fz
        mx, my, mz = cross3(nx, ny, nz, fx, fy, fz)
        torque_i[p, 0] = lever * mx
        torque_i[p, 1] = lever * my
        torque_i[p, 2] = lever * mz
        overlap[p] = pen


@kernel()
def sphere_box_forces(n, ps, pb, state, params, history, force, torque_i, torque_j, overlap,
                      pos, vel, angvel, radius, material, young, poisson, friction,
                      box_center, box_half, box_vel, box_material, dt):
    """Forces of sphere–box candidates (axis-aligned rigid box = body 1, like a wall).

    Geometry: the closest point q of the box to the sphere centre x (clamp per axis);
    outside, n = (x − q)/|x − q| and pen = r − |x − q| (face, edge or corner contact); with the
    centre inside the box, the exit through the nearest face: n = ±e_a, pen = r + (h_a − |x_a − c_a|).
    Parameters as for walls (radius1 = radius2 = r: kn = 2 E_b r E_s r/(E_b r + E_s r)),
    relative velocity with the ratcheting factor α = 2r/(2r − pen) and the box velocity as v1
    (the box does not rotate). ``force`` is the force on the sphere (−f), ``torque_i`` the
    torque on the sphere (lever r − pen/2)."""
    for p in prange(n):
        s = ps[p]
        b = pb[p]
        r = radius[s]
        dx = pos[s, 0] - box_center[b, 0]
        dy = pos[s, 1] - box_center[b, 1]
        dz = pos[s, 2] - box_center[b, 2]
        hx = box_half[b, 0]
        hy = box_half[b, 1]
        hz = box_half[b, 2]
        ex = dx - min(max(dx, -hx), hx)
        ey = dy - min(max(dy, -hy), hy)
        ez = dz - min(max(dz, -hz), hz)
        fresh = state[p] == 0
        if ex != 0.0 or ey != 0.0 or ez != 0.0:
            dist = sqrt(dot3(ex, ey, ez, ex, ey, ez))
            if fresh and dist > r:
                _clear(p, state, history, force, torque_i, torque_j, overlap)
                continue
            nx = ex / dist
            ny = ey / dist
            nz = ez / dist
            pen = r - dist
        else:
            # centre inside: leave through the nearest face (ties: x before y before z)
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
        if pen < 0.0:
            _clear(p, state, history, force, torque_i, torque_j, overlap)
            continue
        # the plane-contact lines of sphere_wall_forces (see there why they are not shared)
        if fresh:
            mb = box_material[b]
            ms = material[s]
            kn, ks, tphi = ip2(young[mb], poisson[mb], friction[mb], r, young[ms], poisson[ms], friction[ms], r)
            params[p, 0] = kn
            params[p, 1] = ks
            params[p, 2] = tphi
            state[p] = 1
        ox, oy, oz, tx, ty, tz = _axes(fresh, p, history, nx, ny, nz, angvel[s, 0], angvel[s, 1], angvel[s, 2], dt)
        rs = r + r
        alpha = rs / (rs - pen)
        ax = (vel[s, 0] - box_vel[b, 0]) * alpha
        ay = (vel[s, 1] - box_vel[b, 1]) * alpha
        az = (vel[s, 2] - box_vel[b, 2]) * alpha
        bx, by, bz = cross3(angvel[s, 0], angvel[s, 1], angvel[s, 2], (-r) * nx, (-r) * ny, (-r) * nz)
        rvx = ax + bx
        rvy = ay + by
        rvz = az + bz
        dn = dot3(nx, ny, nz, rvx, rvy, rvz)
        rvx = rvx - dn * nx
        rvy = rvy - dn * ny
        rvz = rvz - dn * nz
        fx, fy, fz = law2(p, fresh, nx, ny, nz, pen, rvx * dt, rvy * dt, rvz * dt, ox, oy, oz, tx, ty, tz,
                          params, history)
        force[p, 0] = -fx
        force[p, 1] = -fy
        force[p, 2] = -fz
        mx, my, mz = cross3(nx, ny, nz, fx, fy, fz)
        l2 = r - 0.5 * pen
        torque_i[p, 0] = l2 * mx
        torque_i[p, 1] = l2 * my
        torque_i[p, 2] = l2 * mz
        overlap[p] = pen
