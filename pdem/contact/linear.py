"""The linear frictional law exactly as Yade 2023.02a computes it (YADE_MODEL.md §4–5).

Yade: ``Ip2_FrictMat_FrictMat_FrictPhys`` (parameters, once per contact, at creation) and
``Law2_ScGeom_FrictPhys_CundallStrack`` (forces). Thesis ch. 3 and appendix A; Cundall & Strack
(1979) Géotechnique 29(1):47–65, doi:10.1680/geot.1979.29.1.47. The geometry (normal, overlap,
relative velocity, ScGeom axes) is `pdem.contact.geometry`'s; this module is only the law.

Material keys: ``young`` E [Pa], ``poisson`` ν [-] (really k_s/k_n), ``friction_angle`` φ [rad].
Per contact: parameters ``[kn [N/m], ks [N/m], tan φ]`` and law history ``[Fs_x, Fs_y, Fs_z]``
[N] (the shear force in global axes).

- kn = 2 E_a R_a E_b R_b/(E_a R_a + E_b R_b), ks the same with E·ν, tan φ = tan(min φ_a, φ_b);
  where Yade gives ks = 0/0 = NaN (ν = 0 on both sides) pdem defines ks = 0 (no shear spring).
- Fn = kn·max(pen, 0)·n; Fs rotated with the contact (orthonormal then twist axis), minus
  ks·Δu_s, capped at |Fn| tan φ; f = −Fn − Fs is the force on body 1.
- Stiffness for the time step: kn, ks. Elastic energy: ½ kn pen² + ½ |Fs|²/ks.
"""
from math import sqrt, tan

import numpy as np
from numba import njit

from ..vec import dot3
from .submodels import frictional_ip2, pair_stiffness, set_tan_friction, shear_spring

NAME = "linear"
N_PARAMS = 3
HISTORY = 3
MOMENT = False  # no rolling or twisting moment
CONTACT_POINT_VELOCITY = False  # Yade's relative velocity (ratcheting factor, full-radius levers)
PAIR_KEYS = ()  # no per-pair values: every parameter comes from the two materials
# material key -> (what is allowed, test)
MATERIAL_KEYS = {
    "young": ("a finite number > 0 [Pa]", lambda v: v > 0.0),
    "poisson": ("a finite number >= 0 (it is k_s/k_n)", lambda v: v >= 0.0),
    "friction_angle": ("in [0, pi/2) rad", lambda v: 0.0 <= v < np.pi / 2),
}
PARAM_NAMES = {"kn": 0, "ks": 1, "tan_phi": 2}
PWAVE_KEY = "young"  # the modulus of the P-wave time step estimate
FRICTION_KEY = "friction_angle"
STIFFNESS_KEYS = ("young",)  # the material keys the stiffness parameters are proportional to
STIFFNESS_PARAMS = [0, 1]    # the parameter columns proportional to them (kn, ks)


@njit(inline="always", cache=True)
def stiffnesses(e_a, nu_a, phi_a, r_a, e_b, nu_b, phi_b, r_b):
    """kn = 2 E_a R_a E_b R_b/(E_a R_a + E_b R_b), ks the same with E·ν, tan(min φ) (§4)."""
    kna = e_a * r_a
    knb = e_b * r_b
    return pair_stiffness(kna, knb), pair_stiffness(kna * nu_a, knb * nu_b), tan(min(phi_a, phi_b))


ip2 = frictional_ip2(stiffnesses)  # parameters of a new contact between materials ma (body 1) and mb (body 2)


@njit(inline="always", cache=True)
def force(p, fresh, nx, ny, nz, pen, vn, six, siy, siz, ox, oy, oz, tx, ty, tz, wrx, wry, wrz, dt, params,
          history):
    """CundallStrack: rotate the stored shear force, add −ks·Δu_s, cap at |Fn| tan φ (§5).

    Returns f = −Fn − Fs, the force on body 1 [N], and the moment on body 1 (none: zeros);
    updates the law history."""
    kn = params[p, 0]
    ks = params[p, 1]
    tphi = params[p, 2]
    knp = kn * max(pen, 0.0)
    fnx = knp * nx
    fny = knp * ny
    fnz = knp * nz
    fsx, fsy, fsz = shear_spring(fresh, history[p, 0], history[p, 1], history[p, 2], ox, oy, oz, tx, ty, tz, ks, six,
                                 siy, siz)
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
    return -fnx - fsx, -fny - fsy, -fnz - fsz, 0.0, 0.0, 0.0


# ---------------------------------------------------------------------------- numpy side
def stiffness(params, history, overlap):
    """(kn, ks) [N/m] per contact row."""
    return params[:, 0], params[:, 1]


dt_stiffness = stiffness  # no damping, no rolling: the time step sees kn, ks as they are


def pwave_modulus(values, radius):
    """Young's modulus [Pa] per body for the P-wave step: the material's ``young`` itself."""
    return values


def combine(key, a, b):
    raise KeyError(key)  # never called: PAIR_KEYS is empty


def contact_forces(params, history, overlap, normal):
    """(normal force kn·max(pen, 0)·n, shear force Fs) [N] per contact row: Yade's
    normalForce and shearForce (forces on body 2)."""
    return (params[:, 0] * np.maximum(overlap, 0.0))[:, None] * normal, history[:, :3].copy()


def elastic_energy(params, history, overlap):
    """½ kn pen² + ½ |Fs|²/ks [J] per contact row (shear part 0 where ks = 0)."""
    kn, ks = params[:, 0], params[:, 1]
    fs2 = np.einsum("ij,ij->i", history[:, :3], history[:, :3])
    shear = np.divide(fs2, ks, out=np.zeros_like(fs2), where=ks > 0)
    return 0.5 * kn * overlap ** 2 + 0.5 * shear


set_friction = set_tan_friction  # params[:n, 2] = tan(min φ) of each contact's two materials
