"""The viscous contact law with rolling resistance of the blast-layer paper (SPEC.md 1.3).

Szklennik, "Prognoza redukcji ciśnienia wybuchu warstwą materiału ziarnistego", Biuletyn WAT
65(3), 2016, section 2.2 (eqs. 1–8, after Rojek 2007 and Widuliński et al. 2009); rolling
resistance as in Iwashita & Oda (1998) J. Eng. Mech. 124(3):285–292 and Ai et al. (2011) Powder
Technol. 206:269–282 (model type C without the dashpot: an elastic–plastic rolling spring).
The geometry (normal, overlap, relative velocity at the contact point, without Yade's
ratcheting factor: ``CONTACT_POINT_VELOCITY``) is `pdem.contact.geometry`'s.

Material keys: ``kn`` k_n [N/m], ``ks`` k_s [N/m], ``damping_ratio`` ζ [-] in [0, 1) (the paper's
"c_n = 0.2"), ``friction`` μ [-], ``rolling_stiffness`` k_θ [N·m/rad], ``rolling_coefficient`` β
[-] (0: no rolling resistance). A pair of materials gets k = 2 k_a k_b/(k_a + k_b) for k_n, k_s
and k_θ (a pair of equal materials gets the material's value; a plate or wall of the grains'
stiffness gives the grains' contact stiffness), and for the ``PAIR_KEYS`` ζ (mean), μ and β
(smaller) unless the pair is set (`pdem.build.materials.MaterialTable.set_pair`).

Per contact, with m* = m1 m2/(m1 + m2) (m* = m of the sphere against a boundary) and
r_min the smaller radius:

- c_cr = 2 sqrt(m* k_n), c_n = ζ c_cr (eqs. 3–4);
- F_n = max(k_n g + c_n v_n, 0), g the overlap and v_n the approach velocity (eqs. 1–2: no
  tension, the total normal force is never negative);
- F_s ← R(F_s) + k_s v_s Δt, |F_s| ≤ μ F_n (eqs. 5–7); R rotates the stored force with the
  contact as Yade does (`pdem.contact.linear`);
- rolling: M_r ← R(M_r) + k_θ ω_r Δt with ω_r the in-plane part of the relative spin ω2 − ω1,
  |M_r| ≤ f F_n with f = β r_min (eq. 8); twisting (about the normal): M_t ← M_t + k_θ ω_t Δt,
  ω_t = (ω2 − ω1)·n, |M_t| ≤ f F_n: the paper computes the two separately;
- force on body 1: −F_n n − F_s; moment on body 1: M_r + M_t n (body 2 gets the opposite couple).

Parameters ``[kn, ks, cn [N·s/m], mu, k_theta [N·m/rad], f [m], zeta, r_min [m]]``; history
``[Fs (3) [N], M_r (3) [N·m], M_t [N·m], F_n [N]]`` (F_n, the total normal force of the last
step, only for reporting). Time step (eq. 10): Δt_c = (2/ω_max)(sqrt(1 + η²) − η) — `dt_stiffness`
raises k_n and k_s by 1/(sqrt(1 + ζ²) − ζ)², so pdem's global-stiffness step is the damped one,
and adds k_θ/r_min² to k_s for the rolling springs; `critical_step` is eq. 10 itself.
Elastic energy: ½ k_n g² + ½ |F_s|²/k_s + ½ (|M_r|² + M_t²)/k_θ.
"""
from math import inf, sqrt

import numpy as np
from numba import njit

from .submodels import capped, pair_stiffness, rolling_spring, shear_spring

NAME = "viscous"
N_PARAMS = 8
HISTORY = 8
MOMENT = True
CONTACT_POINT_VELOCITY = True
MATERIAL_KEYS = {
    "kn": ("a finite number > 0 [N/m]", lambda v: v > 0.0),
    "ks": ("a finite number >= 0 [N/m]", lambda v: v >= 0.0),
    "damping_ratio": ("in [0, 1) (c_n / c_cr)", lambda v: 0.0 <= v < 1.0),
    "friction": ("a finite number >= 0 (Coulomb's mu)", lambda v: v >= 0.0),
    "rolling_stiffness": ("a finite number >= 0 [N m/rad]", lambda v: v >= 0.0),
    "rolling_coefficient": ("a finite number >= 0 (beta: f = beta r_min; 0: no rolling resistance)",
                            lambda v: v >= 0.0),
}
PAIR_KEYS = ("damping_ratio", "friction", "rolling_coefficient")
PARAM_NAMES = {"kn": 0, "ks": 1, "cn": 2, "friction": 3, "rolling_stiffness": 4, "rolling_lever": 5,
               "damping_ratio": 6, "r_min": 7}
PWAVE_KEY = "kn"
FRICTION_KEY = "friction"
STIFFNESS_KEYS = ("kn", "ks", "rolling_stiffness")
_NK = len(MATERIAL_KEYS)
_NPK = len(PAIR_KEYS)


def combine(key, a, b):
    """Value of a pair key for two materials whose pair is not set: ζ the mean, μ and β the
    smaller."""
    return 0.5 * (a + b) if key == "damping_ratio" else min(a, b)


@njit(inline="always", cache=True)
def reduced_mass(m1, m2):
    """m1 m2/(m1 + m2) [kg]; the finite one if the other is a boundary (inf)."""
    if m1 == inf:
        return m2
    if m2 == inf:
        return m1
    return m1 * m2 / (m1 + m2)


@njit(inline="always", cache=True)
def ip2(props, ma, mb, ra, rb, m1, m2, params, p):
    """Parameters of a new contact between materials ma (body 1) and mb (body 2)."""
    kn = pair_stiffness(props[ma, 0], props[mb, 0])
    base = _NK + mb * _NPK
    zeta = props[ma, base]
    params[p, 0] = kn
    params[p, 1] = pair_stiffness(props[ma, 1], props[mb, 1])
    params[p, 2] = zeta * (2.0 * sqrt(reduced_mass(m1, m2) * kn))
    params[p, 3] = props[ma, base + 1]
    params[p, 4] = pair_stiffness(props[ma, 4], props[mb, 4])
    r_min = min(ra, rb)
    params[p, 5] = props[ma, base + 2] * r_min
    params[p, 6] = zeta
    params[p, 7] = r_min


@njit(inline="always", cache=True)
def force(p, fresh, nx, ny, nz, pen, vn, six, siy, siz, ox, oy, oz, tx, ty, tz, wrx, wry, wrz, dt, params,
          history):
    """Normal spring–dashpot without tension, incremental Coulomb shear, rolling and twisting
    springs capped at f F_n. Returns the force and the moment on body 1; updates the history."""
    kn = params[p, 0]
    ks = params[p, 1]
    cn = params[p, 2]
    mu = params[p, 3]
    kr = params[p, 4]
    lever = params[p, 5]
    fn = max(kn * pen - cn * vn, 0.0)  # vn < 0 while approaching
    # shear: F_s on body 2 (Yade's shearForce convention), body 1 gets -F_s
    fsx, fsy, fsz = shear_spring(fresh, history[p, 0], history[p, 1], history[p, 2], ox, oy, oz, tx, ty, tz, ks, six,
                                 siy, siz)
    fsx, fsy, fsz = capped(fsx, fsy, fsz, mu * fn)
    # rolling (in-plane part of ω2 − ω1) and twisting (normal part), moments on body 1
    mrx, mry, mrz, mt = rolling_spring(fresh, history[p, 3], history[p, 4], history[p, 5], history[p, 6], ox, oy, oz,
                                       tx, ty, tz, wrx, wry, wrz, nx, ny, nz, kr, dt, lever * fn)
    history[p, 0] = fsx
    history[p, 1] = fsy
    history[p, 2] = fsz
    history[p, 3] = mrx
    history[p, 4] = mry
    history[p, 5] = mrz
    history[p, 6] = mt
    history[p, 7] = fn
    return (-fn * nx - fsx, -fn * ny - fsy, -fn * nz - fsz, mrx + mt * nx, mry + mt * ny, mrz + mt * nz)


# ---------------------------------------------------------------------------- numpy side
def stiffness(params, history, overlap):
    """(kn, ks) [N/m] per contact row."""
    return params[:, 0], params[:, 1]


def damped_factor(eta):
    """sqrt(1 + η²) − η: the damped critical step over the undamped 2/ω (eq. 10)."""
    eta = np.asarray(eta, np.float64)
    return np.sqrt(1.0 + eta * eta) - eta


def critical_step(k_max, m_min, eta):
    """The paper's eq. 10: Δt_c = (2/ω_max)(sqrt(1 + η²) − η), ω_max = sqrt(k_max/m_min) [s]."""
    return float(2.0 / sqrt(k_max / m_min) * damped_factor(eta))


def dt_stiffness(params, history, overlap):
    """(kn, ks) for the time step: divided by (sqrt(1 + ζ²) − ζ)² (the damped critical step),
    k_s plus k_θ/r_min² (the rolling and twisting springs on the rotational degrees of freedom)."""
    factor = 1.0 / damped_factor(params[:, 6]) ** 2
    r_min = params[:, 7]
    roll = np.divide(params[:, 4], r_min * r_min, out=np.zeros(len(r_min)), where=r_min > 0)
    return params[:, 0] * factor, (params[:, 1] + roll) * factor


def pwave_modulus(values, radius):
    """k_n/r [Pa]: the Young's modulus for which a pair of equal spheres has k_n (Yade's k_n = E r)."""
    return np.asarray(values, np.float64) / np.asarray(radius, np.float64)


def contact_forces(params, history, overlap, normal):
    """(total normal force F_n n, shear force F_s) [N] per contact row, forces on body 2."""
    return history[:, 7:8] * normal, history[:, :3].copy()


def elastic_energy(params, history, overlap):
    """½ k_n g² + ½ |F_s|²/k_s + ½ (|M_r|² + M_t²)/k_θ [J] per contact row."""
    kn, ks, kr = params[:, 0], params[:, 1], params[:, 4]
    fs2 = np.einsum("ij,ij->i", history[:, :3], history[:, :3])
    m2 = np.einsum("ij,ij->i", history[:, 3:6], history[:, 3:6]) + history[:, 6] ** 2
    shear = np.divide(fs2, ks, out=np.zeros_like(fs2), where=ks > 0)
    roll = np.divide(m2, kr, out=np.zeros_like(m2), where=kr > 0)
    return 0.5 * kn * overlap ** 2 + 0.5 * shear + 0.5 * roll


@njit(cache=True)
def set_friction(n, mat_i, mat_j, props, params):
    """params[:n, 3] = μ of each contact's pair of materials."""
    for k in range(n):
        params[k, 3] = props[mat_i[k], _NK + mat_j[k] * _NPK + 1]  # materials.pair_column
