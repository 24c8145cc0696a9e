#!/usr/bin/env python3
"""Independent re-implementation of LIGGGHTS 3.8.0 Hertz-Mindlin for two free spheres, from NOTES.md.

    python3 hertz_mindlin_reference.py [data/oblique_impact.json ...] [--reset-history-at-separation] [--perturb-ulp]

Re-runs the scene stored in each JSON (bodies, materials, dt, model settings) step by step with plain
Python floats, in the same operation order as the LIGGGHTS source (see NOTES.md §2-§5), and compares
every dumped step: positions, velocities, angular velocities, forces, torques of both atoms and the
stored tangential history of the contact. Prints the maximum relative difference per quantity
(|a-b| / max|b| over the run, per component family) and the number of bit-identical values.
Exit status 0 if the worst relative difference is below 1e-9 (it is exactly 0 for all four cases).
--reset-history-at-separation (not LIGGGHTS) and --perturb-ulp (initial vx of the last body + 1 ulp) are
diagnostics: they show what a code that deletes the history at separation, or one that rounds differently,
should expect against these references.
Needs only the Python standard library.
"""
import json
import math
import sys
from pathlib import Path

MY_PI = 3.14159265358979323846           # LAMMPS math_const.h (== math.pi)
SQRT_FIVE_OVER_SIX = 0.91287092917527685576161630466800355658790782499663875  # normal_model_hertz.h
INERTIA = 0.4                            # fix_nve_sphere.cpp


# ---------------------------------------------------------------- material (global_properties.cpp)
def y_eff(Yi, Yj, vi, vj):
    # createYeff: 1./((1.-pow(vi,2.))/Yi+(1.-pow(vj,2.))/Yj); pow(x,2.) is exactly x*x
    return 1. / ((1. - vi * vi) / Yi + (1. - vj * vj) / Yj)


def g_eff(Yi, Yj, vi, vj):
    # createGeff: 1./(2.*(2.-vi)*(1.+vi)/Yi+2.*(2.-vj)*(1.+vj)/Yj)
    return 1. / (2. * (2. - vi) * (1. + vi) / Yi + 2. * (2. - vj) * (1. + vj) / Yj)


def beta_eff(e):
    # createCoeffRestLog + createBetaEff: log(e) / sqrt(pow(log(e),2.)+pow(M_PI,2.))
    le = math.log(e)
    return le / math.sqrt(le * le + MY_PI * MY_PI)


def sphere_mass(radius, density):
    # atom_vec_sphere.cpp data_atom: 4.0*MY_PI/3.0 * radius*radius*radius * density (left to right)
    return 4.0 * MY_PI / 3.0 * radius * radius * radius * density


# ---------------------------------------------------------------- one pair (pair_gran_base.h + models)
def pair_force(xi, xj, vi, vj, wi, wj, radi, radj, mi, mj, shear, P, dt, update_history=True):
    """Force/torque on i and j of a touching pair, or None if not touching.

    shear (list of 3) is the contact history, updated in place like LIGGGHTS does.
    Returns (Fi, Fj, Ti, Tj, info)."""
    delx = xi[0] - xj[0]
    dely = xi[1] - xj[1]
    delz = xi[2] - xj[2]
    rsq = delx * delx + dely * dely + delz * delz
    radsum = radi + radj
    if not rsq < radsum * radsum:
        return None
    r = math.sqrt(rsq)
    rinv = 1.0 / r
    enx, eny, enz = delx * rinv, dely * rinv, delz * rinv
    meff = mi * mj / (mi + mj)
    # --- surface_model_default.h
    vr1, vr2, vr3 = vi[0] - vj[0], vi[1] - vj[1], vi[2] - vj[2]
    vn = vr1 * enx + vr2 * eny + vr3 * enz
    vt1, vt2, vt3 = vr1 - vn * enx, vr2 - vn * eny, vr3 - vn * enz
    deltan = radsum - r
    cri = radi - 0.5 * deltan
    crj = radj - 0.5 * deltan
    wr1 = (cri * wi[0] + crj * wj[0]) * rinv
    wr2 = (cri * wi[1] + crj * wj[1]) * rinv
    wr3 = (cri * wi[2] + crj * wj[2]) * rinv
    vtr1 = vt1 - (delz * wr2 - dely * wr3)
    vtr2 = vt2 - (delx * wr3 - delz * wr1)
    vtr3 = vt3 - (dely * wr1 - delx * wr2)
    # --- normal_model_hertz.h
    reff = radi * radj / (radi + radj)
    sqrtval = math.sqrt(reff * deltan)
    Sn = 2. * P["Yeff"] * sqrtval
    St = 8. * P["Geff"] * sqrtval
    kn = 4. / 3. * P["Yeff"] * sqrtval
    kt = St
    gamman = -2. * SQRT_FIVE_OVER_SIX * P["betaeff"] * math.sqrt(Sn * meff)
    gammat = -2. * SQRT_FIVE_OVER_SIX * P["betaeff"] * math.sqrt(St * meff) if P["tangential_damping"] else 0.0
    kn /= 1.0   # force->nktv2p, 1 in SI
    kt /= 1.0
    Fn_damping = -gamman * vn
    Fn_contact = kn * deltan
    Fn = Fn_damping + Fn_contact
    if P["limitForce"] and Fn < 0.0:
        Fn = 0.0
    Fi = [0.0 + Fn * enx, 0.0 + Fn * eny, 0.0 + Fn * enz]
    Fj = [0.0 + -Fi[0], 0.0 + -Fi[1], 0.0 + -Fi[2]]
    # --- tangential_model_history.h
    if update_history:
        shear[0] += vtr1 * dt
        shear[1] += vtr2 * dt
        shear[2] += vtr3 * dt
        rsht = shear[0] * enx + shear[1] * eny + shear[2] * enz
        shear[0] -= rsht * enx
        shear[1] -= rsht * eny
        shear[2] -= rsht * enz
    shrmag = math.sqrt(shear[0] * shear[0] + shear[1] * shear[1] + shear[2] * shear[2])
    xmu = P["mu"]
    Ft1, Ft2, Ft3 = -(kt * shear[0]), -(kt * shear[1]), -(kt * shear[2])
    Ft_shear = kt * shrmag
    Ft_friction = xmu * abs(Fn)
    slip = Ft_shear > Ft_friction
    if slip:
        if shrmag != 0.0:
            ratio = Ft_friction / Ft_shear
            Ft1 *= ratio
            Ft2 *= ratio
            Ft3 *= ratio
            if update_history:
                shear[0] = -Ft1 / kt
                shear[1] = -Ft2 / kt
                shear[2] = -Ft3 / kt
        else:
            Ft1 = Ft2 = Ft3 = 0.0
    else:
        Ft1 -= gammat * vtr1
        Ft2 -= gammat * vtr2
        Ft3 -= gammat * vtr3
    tor1 = eny * Ft3 - enz * Ft2
    tor2 = enz * Ft1 - enx * Ft3
    tor3 = enx * Ft2 - eny * Ft1
    Ti = [0.0 + -cri * tor1, 0.0 + -cri * tor2, 0.0 + -cri * tor3]
    Tj = [0.0 + -crj * tor1, 0.0 + -crj * tor2, 0.0 + -crj * tor3]
    Fi = [Fi[0] + Ft1, Fi[1] + Ft2, Fi[2] + Ft3]
    Fj = [Fj[0] + -Ft1, Fj[1] + -Ft2, Fj[2] + -Ft3]
    # --- rolling_model_cdt.h (pair branch)
    if P["rolling"] == "cdt":
        rmu = P["rmu"]
        w1, w2, w3 = wi[0] - wj[0], wi[1] - wj[1], wi[2] - wj[2]
        wmag = math.sqrt(w1 * w1 + w2 * w2 + w3 * w3)
        if wmag > 0.:
            s = rmu * kn * deltan * reff / wmag
            rt = [w1 * s, w2 * s, w3 * s]
            d = rt[0] * enx + rt[1] * eny + rt[2] * enz
            rt = [rt[0] - enx * d, rt[1] - eny * d, rt[2] - enz * d]
            Ti = [Ti[0] - rt[0], Ti[1] - rt[1], Ti[2] - rt[2]]
            Tj = [Tj[0] + rt[0], Tj[1] + rt[1], Tj[2] + rt[2]]
    elif P["rolling"] not in ("", "off", None):
        raise NotImplementedError(P["rolling"])
    info = {"deltan": deltan, "Fn": Fn, "kn": kn, "kt": kt, "gamman": gamman, "gammat": gammat, "slip": slip,
            "vn": vn}
    return Fi, Fj, Ti, Tj, info


# ---------------------------------------------------------------- sphere - primitive plane (fix_wall_gran.cpp)
def plane_force(x, v, w, radi, mi, dim, pos, hist, P, dt, update_history=True):
    """Force/torque of a primitive plane wall (xplane/yplane/zplane at coordinate pos, velocity 0) on a sphere.

    hist (list of 3) is the per-atom wall history, zeroed here when not touching. Returns (F, T, info) or None."""
    # primitive_wall_definitions.h Plane<dim>::resolveContact
    delta = [0.0, 0.0, 0.0]
    if x[dim] > pos:
        delta[dim] = pos - x[dim]
        dn = x[dim] - pos - radi
    else:
        delta[dim] = pos - x[dim]
        dn = pos - x[dim] - radi
    if not dn <= 0:             # post_force_primitive: deltan > 0 -> history zeroed, no force
        hist[0] = hist[1] = hist[2] = 0.0
        return None
    sd = -dn                     # sidata.deltan
    dlx, dly, dlz = -delta[0], -delta[1], -delta[2]   # sidata.delta (wall -> sphere centre)
    # fix_wall_gran_base.h compute_force
    r = radi - sd
    rinv = 1.0 / r
    enx, eny, enz = dlx * rinv, dly * rinv, dlz * rinv
    radsum = radi
    meff = mi
    # surface_model_default.h, wall branch (v_j = wall velocity = 0)
    vr1, vr2, vr3 = v[0] - 0.0, v[1] - 0.0, v[2] - 0.0
    vn = vr1 * enx + vr2 * eny + vr3 * enz
    vt1, vt2, vt3 = vr1 - vn * enx, vr2 - vn * eny, vr3 - vn * enz
    deltan = radsum - r          # recomputed; replaces sidata.deltan after the rotation term
    cr = radi - 0.5 * sd         # uses the deltan of resolveContact
    wr1, wr2, wr3 = cr * w[0] * rinv, cr * w[1] * rinv, cr * w[2] * rinv
    vtr1 = vt1 - (dlz * wr2 - dly * wr3)
    vtr2 = vt2 - (dlx * wr3 - dlz * wr1)
    vtr3 = vt3 - (dly * wr1 - dlx * wr2)
    # normal_model_hertz.h with reff = radi, Yeff/Geff/betaeff of (sphere type, wall type)
    reff = radi
    sqrtval = math.sqrt(reff * deltan)
    Sn = 2. * P["Yeff"] * sqrtval
    St = 8. * P["Geff"] * sqrtval
    kn = 4. / 3. * P["Yeff"] * sqrtval
    kt = St
    gamman = -2. * SQRT_FIVE_OVER_SIX * P["betaeff"] * math.sqrt(Sn * meff)
    gammat = -2. * SQRT_FIVE_OVER_SIX * P["betaeff"] * math.sqrt(St * meff) if P["tangential_damping"] else 0.0
    kn /= 1.0
    kt /= 1.0
    Fn = -gamman * vn + kn * deltan
    if P["limitForce"] and Fn < 0.0:
        Fn = 0.0
    Fn_ = Fn * 1.0               # area_ratio
    F = [0.0 + Fn_ * enx, 0.0 + Fn_ * eny, 0.0 + Fn_ * enz]
    # tangential_model_history.h (identical to the pair case)
    shear = hist
    if update_history:
        shear[0] += vtr1 * dt
        shear[1] += vtr2 * dt
        shear[2] += vtr3 * dt
        rsht = shear[0] * enx + shear[1] * eny + shear[2] * enz
        shear[0] -= rsht * enx
        shear[1] -= rsht * eny
        shear[2] -= rsht * enz
    shrmag = math.sqrt(shear[0] * shear[0] + shear[1] * shear[1] + shear[2] * shear[2])
    Ft1, Ft2, Ft3 = -(kt * shear[0]), -(kt * shear[1]), -(kt * shear[2])
    Ft_shear = kt * shrmag
    Ft_friction = P["mu"] * abs(Fn)
    slip = Ft_shear > Ft_friction
    if slip:
        if shrmag != 0.0:
            ratio = Ft_friction / Ft_shear
            Ft1 *= ratio
            Ft2 *= ratio
            Ft3 *= ratio
            if update_history:
                shear[0] = -Ft1 / kt
                shear[1] = -Ft2 / kt
                shear[2] = -Ft3 / kt
        else:
            Ft1 = Ft2 = Ft3 = 0.0
    else:
        Ft1 -= gammat * vtr1
        Ft2 -= gammat * vtr2
        Ft3 -= gammat * vtr3
    tor1 = eny * Ft3 - enz * Ft2
    tor2 = enz * Ft1 - enx * Ft3
    tor3 = enx * Ft2 - eny * Ft1
    T = [0.0 + (-cr * tor1) * 1.0, 0.0 + (-cr * tor2) * 1.0, 0.0 + (-cr * tor3) * 1.0]
    F = [F[0] + Ft1 * 1.0, F[1] + Ft2 * 1.0, F[2] + Ft3 * 1.0]
    return F, T, {"deltan": deltan, "Fn": Fn, "slip": slip}


# ---------------------------------------------------------------- integration (fix_nve_sphere.cpp, verlet.cpp)
def run(bodies, Ppair, dt, nsteps, sink, gravity=None, walls=(), skin=None, reset_on_separation=False):
    """Velocity Verlet of fix nve/sphere for 1 or 2 spheres.

    Ppair: contact parameters of the pair bodies[0] (LIGGGHTS i) - bodies[1] (j), if there are two.
    gravity: (magnitude, (dx, dy, dz)) as in 'fix gravity MAG vector dx dy dz', added after the pair forces.
    walls: list of (dim, position, P) primitive planes, added after gravity in this order (fix order).
    skin: neighbour skin; a neighbour-list rebuild (any atom moved more than skin/2 since the last one,
    checked every step after initial_integrate: neigh_modify delay 0 every 1 check yes) drops the pair's
    history unless the pair overlaps at that moment (NOTES §4.6). None: no rebuild logic.
    reset_on_separation: NOT LIGGGHTS; zero the pair history whenever the pair does not overlap (what a code
    that deletes a contact at separation does), to measure the effect of LIGGGHTS's stale history.
    sink(step, x, v, w, f, t, hist, infos) is called at step 0 (setup) and after every step."""
    n = len(bodies)
    x = [list(b["pos"]) for b in bodies]
    v = [list(b["vel"]) for b in bodies]
    w = [list(b["omega"]) for b in bodies]
    rad = [b["radius"] for b in bodies]
    m = [b["mass"] for b in bodies]
    f = [[0.0] * 3 for _ in bodies]
    t = [[0.0] * 3 for _ in bodies]
    hist = {"pair": [0.0, 0.0, 0.0]}
    for k in range(len(walls)):
        for i in range(n):
            hist[("wall", k, i)] = [0.0, 0.0, 0.0]
    dtv = dt
    dtf = 0.5 * dt * 1.0                       # force->ftm2v = 1 in SI
    dtfrotate = dtf / INERTIA
    if gravity is not None:                    # fix_gravity.cpp set_acceleration
        mag, (gx, gy, gz) = gravity
        length = math.sqrt(gx * gx + gy * gy + gz * gz)
        acc = (mag * (gx / length), mag * (gy / length), mag * (gz / length))

    def forces(update_history):
        infos = {}
        for k in range(n):                     # force_clear
            f[k] = [0.0, 0.0, 0.0]
            t[k] = [0.0, 0.0, 0.0]
        if n == 2:                             # pair->compute
            res = pair_force(x[0], x[1], v[0], v[1], w[0], w[1], rad[0], rad[1], m[0], m[1], hist["pair"], Ppair,
                             dt, update_history)
            # no overlap: LIGGGHTS calls neither surfacesIntersect nor surfacesClose (contact_distance_factor 1);
            # the stale history stays until the next neighbour rebuild (NOTES). The spheres here touch once.
            if res is None and reset_on_separation:
                hist["pair"][:] = [0.0, 0.0, 0.0]
            if res is not None:
                Fi, Fj, Ti, Tj, infos["pair"] = res
                for c in range(3):
                    f[0][c] += 1.0 * Fi[c]
                    t[0][c] += 1.0 * Ti[c]
                    f[1][c] += 1.0 * Fj[c]
                    t[1][c] += 1.0 * Tj[c]
        if gravity is not None:                # post_force, fix order: gravity first
            for k in range(n):
                massone = m[k] * 1.0
                for c in range(3):
                    f[k][c] += massone * acc[c]
        for kw, (dim, pos, P) in enumerate(walls):
            for k in range(n):
                res = plane_force(x[k], v[k], w[k], rad[k], m[k], dim, pos, hist[("wall", kw, k)], P, dt,
                                  update_history)
                if res is not None:
                    F, T, infos[("wall", kw, k)] = res
                    for c in range(3):
                        f[k][c] += F[c]
                        t[k][c] += T[c]
        return infos

    xhold = [list(p) for p in x]               # Neighbor::build at setup
    triggersq = 0.25 * skin * skin if skin is not None else None
    infos = forces(update_history=False)       # setup(): shearupdate = 0
    sink(0, x, v, w, f, t, hist, infos)
    for step in range(1, nsteps + 1):
        for k in range(n):                     # initial_integrate
            dtfm = dtf / (m[k] * 1.0)
            for c in range(3):
                v[k][c] += dtfm * f[k][c]
            for c in range(3):
                x[k][c] += dtv * v[k][c]
            dtirotate = dtfrotate / (rad[k] * rad[k] * m[k])
            for c in range(3):
                w[k][c] += dtirotate * t[k][c]
        if triggersq is not None:              # Neighbor::decide / check_distance, then rebuild
            moved = False
            for k in range(n):
                dx, dy, dz = x[k][0] - xhold[k][0], x[k][1] - xhold[k][1], x[k][2] - xhold[k][2]
                moved |= dx * dx + dy * dy + dz * dz > triggersq
            if moved:
                xhold = [list(p) for p in x]
                if n == 2:
                    dx, dy, dz = x[0][0] - x[1][0], x[0][1] - x[1][1], x[0][2] - x[1][2]
                    if not dx * dx + dy * dy + dz * dz < (rad[0] + rad[1]) * (rad[0] + rad[1]):
                        hist["pair"][:] = [0.0, 0.0, 0.0]
        infos = forces(update_history=True)
        for k in range(n):                     # final_integrate
            dtfm = dtf / (m[k] * 1.0)
            for c in range(3):
                v[k][c] += dtfm * f[k][c]
            dtirotate = dtfrotate / (rad[k] * rad[k] * m[k])
            for c in range(3):
                w[k][c] += dtirotate * t[k][c]
        sink(step, x, v, w, f, t, hist, infos)


# ---------------------------------------------------------------- comparison with a JSON
def contact_params(mat, ti, tj, rolling=""):
    """Per-type-pair parameters from the JSON's 'materials' (types are 1-based as in LIGGGHTS)."""
    Y, nu = mat["youngsModulus"], mat["poissonsRatio"]
    i, j = ti - 1, tj - 1
    return {"Yeff": y_eff(Y[i], Y[j], nu[i], nu[j]), "Geff": g_eff(Y[i], Y[j], nu[i], nu[j]),
            "betaeff": beta_eff(mat["coefficientRestitution"][i][j]), "mu": mat["coefficientFriction"][i][j],
            "rmu": mat.get("coefficientRollingFriction", [[0.0] * len(Y)] * len(Y))[i][j],
            "tangential_damping": True, "limitForce": False, "rolling": "cdt" if "cdt" in rolling else ""}


def compare(path, reset_on_separation=False, perturb_ulp=False):
    J = json.loads(Path(path).read_text())
    if perturb_ulp:     # round-off sensitivity: last body's initial vx moved by one ulp
        J["bodies"][-1]["vel"][0] = math.nextafter(J["bodies"][-1]["vel"][0], math.inf)
    mat = J["materials"]
    rolling = J["model_settings"]["rolling"]
    bodies = []
    for b in J["bodies"]:
        mass = sphere_mass(b["radius"], b["density"])
        assert mass == b["mass"], (mass, b["mass"])     # same formula as LIGGGHTS, bit-identical
        assert b["radius"] == 0.5 * b["diameter_in_data_file"]
        bodies.append(b)
    n = len(bodies)
    Ppair = contact_params(mat, bodies[0]["type"], bodies[1]["type"], rolling) if n == 2 else None
    gravity = None
    if any(J["gravity"]):
        gravity = (9.81, (0.0, 0.0, -1.0))
        assert J["gravity"] == [0.0, 0.0, -9.81]
    walls = []
    if "wall" in J:
        W = J["wall"]
        types = {b["type"] for b in bodies}
        assert len(types) == 1
        walls.append(("xyz".index(W["primitive"][0]), W["position"], contact_params(mat, bodies[0]["type"], W["type"])))
    steps = J["steps"]
    idx = {s: k for k, s in enumerate(steps)}
    ids = [str(b["id"]) for b in bodies]
    ref = J["atoms"]
    fams = ["pos", "vel", "omega", "force", "torque"]
    maxdiff = {(a, q): 0.0 for a in ids for q in fams}
    scale = {(a, q): max(abs(c) for row in ref[a][q] for c in row) or 1.0 for a in ids for q in fams}
    C = J.get("contact")
    cidx = {s: k for k, s in enumerate(C["steps"])} if C else {}
    shear_diff = ov_diff = 0.0
    shear_scale = max(abs(c) for row in C["shear"] for c in row) if C else 1.0
    ov_scale = max(C["overlap"]) if C else 1.0
    nequal = ntotal = 0
    first_diff = {}
    stats = {"slip": 0, "stick": 0, "neg": 0, "steps": 0}

    def sink(step, x, v, w, f, t, hist, infos):
        nonlocal shear_diff, ov_diff, nequal, ntotal
        if step > 0:
            for info in infos.values():
                stats["steps"] += 1
                stats["slip" if info["slip"] else "stick"] += 1
                stats["neg"] += info["Fn"] < 0
        if step not in idx:
            return
        k = idx[step]
        mine = {"pos": x, "vel": v, "omega": w, "force": f, "torque": t}
        for a in range(n):
            for q in fams:
                r = ref[ids[a]][q][k]
                for c in range(3):
                    d = abs(mine[q][a][c] - r[c])
                    ntotal += 1
                    nequal += d == 0.0
                    if d > 0 and (ids[a], q) not in first_diff:
                        first_diff[(ids[a], q)] = step
                    maxdiff[(ids[a], q)] = max(maxdiff[(ids[a], q)], d)
        if "wall" in J and n == 1 and step > 0:
            # LIGGGHTS's own check of the order: dumped force == (0 + m g) + stored wall force, bit for bit
            wf = ref["1"]["wall_force"][k]
            tot = [(0.0 + m0g[c]) + wf[c] for c in range(3)]
            assert tot == ref["1"]["force"][k], (step, tot, ref["1"]["force"][k])
        if step in cidx:
            r = C["shear"][cidx[step]]
            sh = hist["pair"]
            shear_diff = max(shear_diff, *(abs(sh[c] - r[c]) for c in range(3)))
            xi, xj = x[0], x[1]
            d0, d1, d2 = xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]   # compute pair/gran/local 'delta'
            ov = bodies[0]["radius"] + bodies[1]["radius"] - math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            ov_diff = max(ov_diff, abs(ov - C["overlap"][cidx[step]]))

    m0g = [bodies[0]["mass"] * 1.0 * a for a in (9.81 * (0.0 / 1.0), 9.81 * (0.0 / 1.0), 9.81 * (-1.0 / 1.0))]
    run(bodies, Ppair, J["dt"], steps[-1], sink, gravity, walls, J.get("neighbor_skin"), reset_on_separation)
    if C:
        span = f"contact {C['steps'][0]}..{C['steps'][-1]}"
    elif "pair_touching_dumped" in J:
        span = f"pair touching (dumped) {J['pair_touching_dumped']}"
    else:
        span = f"wall contacts {J['wall_contacts']}"
    print(f"== {J['case']}  ({Path(path).name}; {len(steps)} dumped steps, {span})"
          f"{'  [variant: pair history reset at separation, NOT LIGGGHTS]' if reset_on_separation else ''}"
          f"{'  [variant: initial vx of the last body + 1 ulp]' if perturb_ulp else ''}")
    for name, P in ([("pair", Ppair)] if Ppair else []) + [(f"wall {k}", Wk[2]) for k, Wk in enumerate(walls)]:
        print(f"   {name}: Yeff {P['Yeff']!r}  Geff {P['Geff']!r}  betaeff {P['betaeff']!r}  mu {P['mu']!r}")
    print(f"   contact steps {stats['steps']}: Coulomb-capped (slip) {stats['slip']}, stick {stats['stick']}, "
          f"Fn < 0 (damping pull) {stats['neg']}")
    worst = 0.0
    for (a, q), d in maxdiff.items():
        rel = d / scale[(a, q)]
        worst = max(worst, rel)
        print(f"   atom {a} {q:6s}: max |diff| {d:.3e}  (rel. to max |value| {scale[(a, q)]:.3e}: {rel:.3e})"
              f"{'  first diff at step ' + str(first_diff[(a, q)]) if (a, q) in first_diff else '  bit-identical'}")
    if C:
        print(f"   contact shear history: max |diff| {shear_diff:.3e} (rel {shear_diff / shear_scale:.3e}); "
              f"overlap: max |diff| {ov_diff:.3e} (rel {ov_diff / ov_scale:.3e})")
        worst = max(worst, shear_diff / shear_scale)
    print(f"   {nequal}/{ntotal} dumped atom values bit-identical; worst relative difference {worst:.3e}")
    return worst


def main(argv):
    d = Path(__file__).resolve().parent.parent / "data"
    reset = "--reset-history-at-separation" in argv
    perturb = "--perturb-ulp" in argv
    args = [a for a in argv[1:] if not a.startswith("--")]
    paths = args or [str(d / f) for f in ("oblique_impact.json", "oblique_impact_cdt.json", "wall_impact.json",
                                          "recontact.json")]
    worst = max(compare(p, reset, perturb) for p in paths)
    return 0 if worst < 1e-9 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
