"""Yade's cohesive frictional law (breakable bonds) exactly as Yade 2023.02a computes it
(YADE_MODEL.md §6; tests/validation/yade_reference/NOTES.md "Facts for the implementer").

Yade: ``Ip2_CohFrictMat_CohFrictMat_CohFrictPhys`` (parameters, once per contact) and
``Law2_ScGeom6D_CohFrictPhys_CohesionMoment`` with ``momentRotationLaw = False`` (no bending or
twisting moments), fragile bonds (Yade's default). Thesis 3.3 (eq. 3.34) and 4.5; SPEC 1.2.
The geometry (normal, overlap, relative velocity, ScGeom axes) is `pdem.contact.geometry`'s.

Material keys: ``young`` E [Pa], ``poisson`` ν [-] (k_s/k_n as in the linear law),
``friction_angle`` φ [rad], ``normal_cohesion`` c_N [Pa] and ``shear_cohesion`` c_T [Pa]
(>= 0; a bond needs both > 0 on both materials; 0 for a material that never bonds, e.g. steel).

Per contact: parameters ``[kn [N/m], ks [N/m], tan φ]`` and law history ``[Fs_x, Fs_y, Fs_z
[N], Fn [N], a_N [N], a_T [N], u_p [m]]``: the shear force in global axes, the normal force
magnitude applied in the last step (Yade's normalForce = Fn·n; 0 after a shear break under
tension), the normal and shear adhesions (0: no bond) and the reference overlap u_p (Yade's unp).

- Ip2 (a new contact, never bonded): kn = 2 E_a R_a E_b R_b/(E_a R_a + E_b R_b) and ks the same
  with E·ν, evaluated left to right as Yade's CohFrictPhys does (the linear law's FrictPhys order
  differs in the last bit); ks = 0 if ν_a or ν_b is 0; tan φ = tan(min φ_a, φ_b).
- Bonds are made at set-up (`bond_rows`, between the members of a breakable clump): a_N = min(c_N)
  r_min², a_T = min(c_T) r_min² (r_min the smaller radius), u_p = the overlap when made (stress
  free, SPEC 1.2) or 0 (Yade's setCohesionNow: the initial overlap pushes).
- Law2: Fn = kn (pen − u_p); if −Fn > a_N the contact is deleted, no force this step (a tensile
  break; a contact without bond is deleted as soon as Fn < 0). Fs rotated with the contact,
  minus ks Δu_s; if |Fs| > max(0, a_T + Fn tan φ): an intact bond breaks for good (a_N = a_T = 0,
  cap max(0, Fn tan φ)), Fs scaled to the cap and, under tension, the normal force is 0 this
  step. f = −Fn n − Fs on body 1, at the contact point: torques (cp − x1) × f and −(cp − x2) × f
  (`CONTACT_POINT_LEVER`).
- `scale_bonds`: every bond's a_N, a_T times a factor (a preparation step, not Yade's law).
- Stiffness for the time step: kn, ks. Elastic energy: ½ kn (pen − u_p)² + ½ |Fs|²/ks.
"""
from math import sqrt, tan

import numpy as np
from numba import njit

from ..vec import dot3
from . import linear
from .submodels import frictional_ip2, set_tan_friction, shear_spring

NAME = "cohesive"
N_PARAMS = 3
HISTORY = 7
MOMENT = False
TENSILE = True  # a bonded contact lives on with negative overlap; `holds` decides
CONTACT_POINT_LEVER = True
CONTACT_POINT_VELOCITY = False  # Yade's relative velocity (ratcheting factor), as the linear law
PAIR_KEYS = ()  # no per-pair values: every parameter comes from the two materials
MATERIAL_KEYS = {
    "young": ("a finite number > 0 [Pa]", lambda v: v > 0.0),
    "poisson": ("a finite number >= 0 (it is k_s/k_n)", lambda v: v >= 0.0),
    "friction_angle": ("in [0, pi/2) rad", lambda v: 0.0 <= v < np.pi / 2),
    "normal_cohesion": ("a finite number >= 0 [Pa] (0: never bonds)", lambda v: v >= 0.0),
    "shear_cohesion": ("a finite number >= 0 [Pa] (0: never bonds)", lambda v: v >= 0.0),
}
PARAM_NAMES = {"kn": 0, "ks": 1, "tan_phi": 2}
FN, ADH_N, ADH_T, UNP = 3, 4, 5, 6  # history columns
HISTORY_NAMES = {"normal_adhesion": ADH_N, "shear_adhesion": ADH_T, "unp": UNP}
PWAVE_KEY = "young"
FRICTION_KEY = "friction_angle"
STIFFNESS_KEYS = ("young",)


@njit(inline="always", cache=True)
def stiffnesses(e_a, nu_a, phi_a, r_a, e_b, nu_b, phi_b, r_b):
    """CohFrictPhys: kn = 2.0*Ea*Da*Eb*Db/(Ea*Da + Eb*Db), ks likewise with V, left to right."""
    kn = (((2.0 * e_a) * r_a) * e_b) * r_b / ((e_a * r_a) + (e_b * r_b))
    if nu_a == 0.0 or nu_b == 0.0:
        ks = 0.0
    else:
        ks = (((((2.0 * e_a) * r_a) * nu_a) * e_b) * r_b) * nu_b / (((e_a * r_a) * nu_a) + ((e_b * r_b) * nu_b))
    return kn, ks, tan(min(phi_a, phi_b))


ip2 = frictional_ip2(stiffnesses)  # parameters of a new (unbonded) contact between materials ma and mb


@njit(inline="always", cache=True)
def holds(p, fresh, pen, params, history):
    """False if Law2 deletes the contact this step: −kn (pen − u_p) > a_N (fragile)."""
    fn = params[p, 0] * (pen - history[p, UNP])
    return not (-fn > history[p, ADH_N])


@njit(inline="always", cache=True)
def force(p, fresh, nx, ny, nz, pen, vn, six, siy, siz, ox, oy, oz, tx, ty, tz, wrx, wry, wrz, dt, params,
          history):
    """Law2_ScGeom6D_CohFrictPhys_CohesionMoment without moments (the contact holds: `holds`).

    Returns f = −Fn n − Fs, the force on body 1 [N], and no moment; updates the history."""
    kn = params[p, 0]
    ks = params[p, 1]
    tphi = params[p, 2]
    fn = kn * (pen - history[p, UNP])
    applied = fn
    fsx, fsy, fsz = shear_spring(fresh, history[p, 0], history[p, 1], history[p, 2], ox, oy, oz, tx, ty, tz, ks, six,
                                 siy, siz)
    max_fs = max(0.0, history[p, ADH_T] + fn * tphi)
    fs = sqrt(dot3(fsx, fsy, fsz, fsx, fsy, fsz))
    if fs > max_fs:
        if history[p, ADH_N] > 0.0 or history[p, ADH_T] > 0.0:  # an intact bond breaks (fragile)
            history[p, ADH_N] = 0.0
            history[p, ADH_T] = 0.0
            max_fs = max(0.0, fn * tphi)
        ratio = max_fs / fs
        fsx = ratio * fsx
        fsy = ratio * fsy
        fsz = ratio * fsz
        if fn < 0.0:
            applied = 0.0
    history[p, 0] = fsx
    history[p, 1] = fsy
    history[p, 2] = fsz
    history[p, FN] = applied
    return -(applied * nx) - fsx, -(applied * ny) - fsy, -(applied * nz) - fsz, 0.0, 0.0, 0.0


# ---------------------------------------------------------------------------- numpy side
# params[:, :2] are kn, ks as in the linear law: the same time-step stiffness (no damping, no
# rolling), P-wave modulus (the material's young) and no per-pair keys
stiffness = linear.stiffness
dt_stiffness = linear.dt_stiffness
pwave_modulus = linear.pwave_modulus
combine = linear.combine


def contact_forces(params, history, overlap, normal):
    """(normal force Fn·n, shear force Fs) [N] per contact row: Yade's normalForce and
    shearForce (forces on body 2)."""
    return history[:, FN][:, None] * normal, history[:, :3].copy()


def elastic_energy(params, history, overlap):
    """½ kn (pen − u_p)² + ½ |Fs|²/ks [J] per contact row (shear part 0 where ks = 0)."""
    kn, ks = params[:, 0], params[:, 1]
    fs2 = np.einsum("ij,ij->i", history[:, :3], history[:, :3])
    shear = np.divide(fs2, ks, out=np.zeros_like(fs2), where=ks > 0)
    return 0.5 * kn * (overlap - history[:, UNP]) ** 2 + 0.5 * shear


def max_stretch(params, history):
    """[m] per contact row: how far the centres can move apart beyond contact before the
    contact breaks, a_N/kn − u_p (the neighbour list must keep such pairs)."""
    return history[:, ADH_N] / params[:, 0] - history[:, UNP]


def intact(params, history):
    """bool per contact row: the contact is a bond that has not broken."""
    return (history[:, ADH_N] > 0.0) | (history[:, ADH_T] > 0.0)


set_friction = set_tan_friction  # params[:n, 2] = tan(min φ) of each contact's two materials, as Ip2


@njit(cache=True)
def _bond_rows(props, mat1, mat2, r1, r2, pen, stress_free, params, history):
    for k in range(mat1.shape[0]):
        ip2(props, mat1[k], mat2[k], r1[k], r2[k], 0.0, 0.0, params, k)
        r = min(r1[k], r2[k])
        history[k, ADH_N] = min(props[mat1[k], 3], props[mat2[k], 3]) * (r * r)
        history[k, ADH_T] = min(props[mat1[k], 4], props[mat2[k], 4]) * (r * r)
        history[k, UNP] = pen[k] if stress_free else 0.0


def bond_rows(props, mat1, mat2, r1, r2, pen, stress_free):
    """(params [n, N_PARAMS], law history [n, HISTORY]) of bonds made now between spheres of
    materials mat1/mat2 (body 1 = the lower gid), radii r1/r2 [m] and overlap pen [m]: Ip2's
    parameters and a_N = min(c_N) r_min², a_T = min(c_T) r_min², u_p = pen if ``stress_free``
    else 0, Fs = 0."""
    n = len(mat1)
    params = np.zeros((n, N_PARAMS))
    history = np.zeros((n, HISTORY))
    _bond_rows(np.ascontiguousarray(props, np.float64), np.asarray(mat1, np.int64), np.asarray(mat2, np.int64),
               np.asarray(r1, np.float64), np.asarray(r2, np.float64), np.asarray(pen, np.float64),
               bool(stress_free), params, history)
    return params, history


def scale_bonds(n, history, factor):
    """a_N and a_T of the bonds among the first ``n`` contacts times ``factor`` [-] (a broken bond
    keeps 0): the thesis's preparation (4.5) holds its grains with a tenfold adhesion while the
    initial overlaps push the members apart, then returns it (factor 10, then 1/10; the round
    trip is within one ulp of the strength)."""
    history[:n, ADH_N] *= factor
    history[:n, ADH_T] *= factor


def bond_strengths(props, mat):
    """(c_N, c_T) [Pa] of materials ``mat`` (indices)."""
    return props[mat, 3], props[mat, 4]
