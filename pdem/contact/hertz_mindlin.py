"""Hertz–Mindlin with viscous damping from the coefficient of restitution, as LIGGGHTS 3.8 and
EDEM compute it (SPEC.md 1.4): ``pair_style gran model hertz tangential history`` with optional
``rolling_friction cdt``.

Formulas (tests/validation/liggghts_reference/NOTES.md §1, §3, §5, §6, read from the LIGGGHTS
source; Hertz 1882, Mindlin 1949, damping after Tsuji et al. 1992 Powder Technol. 71:239 and
the EDEM theory guide). Material keys: ``young`` E [Pa], ``poisson`` ν [-] in (−1, 0.5],
``restitution`` e [-] in (0, 1], ``friction`` μ [-], ``rolling_friction`` μ_r [-] (0: off).
Per contact (i = body 1, j = body 2):

- E* = 1/((1 − ν_i²)/E_i + (1 − ν_j²)/E_j), G* = 1/(2(2 − ν_i)(1 + ν_i)/E_i + 2(2 − ν_j)(1 + ν_j)/E_j),
  β = ln e / sqrt(ln² e + π²) (≤ 0), R* = r_i r_j/(r_i + r_j), m* = m_i m_j/(m_i + m_j); against a
  boundary (a half-space) R* = r and m* = m of the sphere. e, μ, μ_r are ``PAIR_KEYS``: set per
  pair of materials (`pdem.build.materials.MaterialTable.set_pair`, LIGGGHTS's ``peratomtypepair``),
  otherwise the smaller of the two materials' values.
- With overlap δ: S_n = 2E* sqrt(R*δ), S_t = 8G* sqrt(R*δ) (Mindlin's no-slip tangential
  stiffness), k_n = 4/3 E* sqrt(R*δ), γ_n = −2 sqrt(5/6) β sqrt(S_n m*), γ_t = −2 sqrt(5/6) β
  sqrt(S_t m*).
- F_n = k_n δ − γ_n v_n (v_n < 0 approaching); LIGGGHTS's default (``limitForce off``): at the end
  of an impact the damping may pull (F_n < 0).
- Tangential displacement ξ (history, the "total" form): ξ ← ξ + v_t Δt, then projected onto the
  current tangent plane; F_t = S_t ξ. If S_t |ξ| > μ |F_n|: F_t scaled to μ |F_n| and ξ = F_t/S_t
  (no damping while slipping); else F_t += γ_t v_t. v_t: tangential relative velocity at the
  contact point, lever arms r − δ/2 (``CONTACT_POINT_VELOCITY``).
- Rolling friction ``cdt``: w = ω_1 − ω_2, torque μ_r k_n δ R* w/|w| with its normal part removed,
  on body 1 (opposite on body 2).
Force on body 1: −F_n n + F_t (n from body 1 to body 2; ξ and v_t of body 2 relative to body 1).

Differences from LIGGGHTS that remain (measured in tests/validation/liggghts_reference):
pdem deletes a contact when it opens (LIGGGHTS keeps a pair's stale history until the next
neighbour rebuild, NOTES §4), and integrates with Yade's leapfrog (the same positions and
half-step velocities as LIGGGHTS's velocity Verlet, rounded differently). Parameters
``[E*, G*, β, μ, μ_r, R*, m*]``; history ``[ξ (3) [m], F_n [N]]`` (F_n for reporting).
Time step: `dt_stiffness` is (S_n, S_t) raised by 1/(sqrt(1 + η²) − η)², η = sqrt(5/6)|β| the
damping ratio; the P-wave step uses E.
"""
from math import inf, log, pi, sqrt

import numpy as np
from numba import njit

from ..vec import dot3
from .submodels import rolling_constant_torque, tangential

NAME = "hertz_mindlin"
N_PARAMS = 7
HISTORY = 4
MOMENT = True
CONTACT_POINT_VELOCITY = True
MATERIAL_KEYS = {
    "young": ("a finite number > 0 [Pa]", lambda v: v > 0.0),
    "poisson": ("in (-1, 0.5]", lambda v: -1.0 < v <= 0.5),
    "restitution": ("in (0, 1]", lambda v: 0.0 < v <= 1.0),
    "friction": ("a finite number >= 0 (Coulomb's mu)", lambda v: v >= 0.0),
    "rolling_friction": ("a finite number >= 0 (0: no rolling friction)", lambda v: v >= 0.0),
}
PAIR_KEYS = ("restitution", "friction", "rolling_friction")
PARAM_NAMES = {"young_eff": 0, "shear_eff": 1, "beta": 2, "friction": 3, "rolling_friction": 4, "radius_eff": 5,
               "mass_eff": 6}
PWAVE_KEY = "young"
FRICTION_KEY = "friction"
STIFFNESS_KEYS = ("young",)  # E* and G* are proportional to E
SQRT_FIVE_OVER_SIX = 0.91287092917527685576  # LIGGGHTS normal_model_hertz.h
_NK = len(MATERIAL_KEYS)
_NPK = len(PAIR_KEYS)


def combine(key, a, b):
    """Value of a pair key for two materials whose pair is not set: the smaller."""
    return min(a, b)


@njit(inline="always", cache=True)
def beta_of(e):
    """β = ln e / sqrt(ln² e + π²) (LIGGGHTS createBetaEff); 0 for e = 1."""
    le = log(e)
    return le / sqrt(le * le + pi * pi)


@njit(inline="always", cache=True)
def ip2(props, ma, mb, ra, rb, m1, m2, params, p):
    """Parameters of a new contact between materials ma (body 1) and mb (body 2)."""
    yi = props[ma, 0]
    vi = props[ma, 1]
    yj = props[mb, 0]
    vj = props[mb, 1]
    base = _NK + mb * _NPK
    params[p, 0] = 1. / ((1. - vi * vi) / yi + (1. - vj * vj) / yj)
    params[p, 1] = 1. / (2. * (2. - vi) * (1. + vi) / yi + 2. * (2. - vj) * (1. + vj) / yj)
    params[p, 2] = beta_of(props[ma, base])
    params[p, 3] = props[ma, base + 1]
    params[p, 4] = props[ma, base + 2]
    if m1 == inf:  # body 1 is a boundary: a half-space
        params[p, 5] = rb
        params[p, 6] = m2
    else:
        params[p, 5] = ra * rb / (ra + rb)
        params[p, 6] = m1 * m2 / (m1 + m2)


@njit(inline="always", cache=True)
def force(p, fresh, nx, ny, nz, pen, vn, six, siy, siz, ox, oy, oz, tx, ty, tz, wrx, wry, wrz, dt, params,
          history):
    """Hertz normal force with damping, Mindlin tangential force (total form) with Coulomb's
    cap, constant rolling torque. Returns the force and the moment on body 1."""
    yeff = params[p, 0]
    geff = params[p, 1]
    beta = params[p, 2]
    mu = params[p, 3]
    rmu = params[p, 4]
    reff = params[p, 5]
    meff = params[p, 6]
    sqrtval = sqrt(reff * pen)
    sn = 2. * yeff * sqrtval
    st = 8. * geff * sqrtval
    kn = 4. / 3. * yeff * sqrtval
    kt = st
    gamman = -2. * SQRT_FIVE_OVER_SIX * beta * sqrt(sn * meff)
    gammat = -2. * SQRT_FIVE_OVER_SIX * beta * sqrt(st * meff)
    fn = -gamman * vn + kn * pen  # LIGGGHTS: Fn_damping + Fn_contact with vn = (v_i − v_j)·e_n
    if fresh:
        xx = xy = xz = 0.0
    else:
        xx = history[p, 0]
        xy = history[p, 1]
        xz = history[p, 2]
    xx += six
    xy += siy
    xz += siz
    _, xx, xy, xz = tangential(xx, xy, xz, nx, ny, nz)
    shrmag = sqrt(dot3(xx, xy, xz, xx, xy, xz))
    ftx = kt * xx
    fty = kt * xy
    ftz = kt * xz
    ft_friction = mu * abs(fn)
    if kt * shrmag > ft_friction:
        if shrmag != 0.0:
            ratio = ft_friction / (kt * shrmag)
            ftx *= ratio
            fty *= ratio
            ftz *= ratio
            xx = ftx / kt
            xy = fty / kt
            xz = ftz / kt
        else:
            ftx = fty = ftz = 0.0
    else:
        g = gammat / dt  # v_t = Δu_t/Δt
        ftx += g * six
        fty += g * siy
        ftz += g * siz
    history[p, 0] = xx
    history[p, 1] = xy
    history[p, 2] = xz
    history[p, 3] = fn
    # moment on body 1: −μ_r k_n δ R* (ω1 − ω2)/|ω1 − ω2|, its normal part removed
    mx, my, mz = rolling_constant_torque(wrx, wry, wrz, nx, ny, nz, rmu, kn, pen, reff)
    return -fn * nx + ftx, -fn * ny + fty, -fn * nz + ftz, mx, my, mz


# ---------------------------------------------------------------------------- numpy side
def stiffness(params, history, overlap):
    """(S_n, S_t) [N/m]: the tangent normal stiffness dF_n/dδ = 2E* sqrt(R*δ) and Mindlin's
    8G* sqrt(R*δ), per contact row."""
    root = np.sqrt(params[:, 5] * np.maximum(overlap, 0.0))
    return 2.0 * params[:, 0] * root, 8.0 * params[:, 1] * root


def damping_ratio(params):
    """η = sqrt(5/6)|β| [-] of each contact's dashpot (γ_n/(2 sqrt(S_n m*)))."""
    return SQRT_FIVE_OVER_SIX * np.abs(params[:, 2])


def dt_stiffness(params, history, overlap):
    """(S_n, S_t) divided by (sqrt(1 + η²) − η)²: the damped critical step."""
    eta = damping_ratio(params)
    factor = 1.0 / (np.sqrt(1.0 + eta * eta) - eta) ** 2
    kn, kt = stiffness(params, history, overlap)
    return kn * factor, kt * factor


def pwave_modulus(values, radius):
    """Young's modulus [Pa] per body: the material's ``young``."""
    return values


def contact_forces(params, history, overlap, normal):
    """(total normal force F_n n, tangential elastic force S_t ξ) [N] per contact row, on body 2
    (the damping part of the shear force is not stored)."""
    _, kt = stiffness(params, history, overlap)
    return history[:, 3:4] * normal, -kt[:, None] * history[:, :3]


def elastic_energy(params, history, overlap):
    """8/15 E* sqrt(R*) δ^(5/2) + ½ S_t |ξ|² [J] per contact row."""
    d = np.maximum(overlap, 0.0)
    _, kt = stiffness(params, history, overlap)
    return (8.0 / 15.0) * params[:, 0] * np.sqrt(params[:, 5]) * d ** 2.5 + 0.5 * kt * np.einsum(
        "ij,ij->i", history[:, :3], history[:, :3])


@njit(cache=True)
def set_friction(n, mat_i, mat_j, props, params):
    """params[:n, 3] = μ of each contact's pair of materials."""
    for k in range(n):
        params[k, 3] = props[mat_i[k], _NK + mat_j[k] * _NPK + 1]  # materials.pair_column
