"""Sub-models the contact laws are composed of, each written once (as LAMMPS GRANULAR composes a
pair style from normal, damping, tangential and rolling sub-models).

All are njit-inline: a law calls them from its ``ip2``/``force`` and numba inlines them into
the generated pair loop (`pdem.contact.loops`, whose cache key covers this module), so a law
built from them computes the same floating-point operations in the same order as one that
writes them out.

- Ip2 (material pair → contact parameters): `pair_stiffness`, the series combination 2ab/(a+b)
  of two materials' stiffnesses (Yade's FrictPhys k_n and k_s, the viscous law's k_n, k_s and
  k_θ); `frictional_ip2`, the Ip2 of a law whose materials are (E [Pa], ν [-], φ [rad]) and whose
  parameters are [k_n, k_s, tan φ] (linear, cohesive); `set_tan_friction`, its friction column
  again after a friction change.
- Tangential: `shear_spring`, Yade's incremental shear spring that the stored shear force
  follows the contact's rotation with (linear, cohesive, viscous).
- Vectors at a contact: `tangential`, a vector's normal component and its part in the tangent
  plane (the pair loop's relative velocity, the viscous law's relative spin, Hertz–Mindlin's
  tangential displacement and rolling torque); `capped`, a vector scaled down to a largest
  norm (the viscous law's Coulomb shear and its rolling moment).
- Rolling resistance (Ai et al. (2011) Powder Technol. 206:269–282): `rolling_spring`, an
  elastic–plastic rolling and twisting spring (model type C without the dashpot: the viscous
  law), `rolling_constant_torque`, a torque of constant magnitude against the relative spin
  (model type A, LIGGGHTS's ``rolling_friction cdt``: Hertz–Mindlin).
"""
from math import sqrt, tan

from numba import njit

from ..vec import dot3, scgeom_rotate


# ---------------------------------------------------------------------------- Ip2
@njit(inline="always", cache=True)
def pair_stiffness(a, b):
    """2ab/(a + b): the stiffness of two springs of 2a and 2b in series [as a, b]; a for equal
    materials; 0 if both are 0 (a, b >= 0)."""
    return (2.0 * a * b) / (a + b) if a + b > 0.0 else 0.0


def frictional_ip2(stiffnesses):
    """The Ip2 ``ip2(props, ma, mb, ra, rb, m1, m2, params, p)`` of a frictional law: material
    columns (E, ν, φ) of body 1 (ma, radius ra) and body 2 (mb, rb) through ``stiffnesses(E_a,
    ν_a, φ_a, r_a, E_b, ν_b, φ_b, r_b) -> (k_n, k_s, tan φ)`` into parameters [k_n, k_s, tan φ]."""

    @njit(inline="always")
    def ip2(props, ma, mb, ra, rb, m1, m2, params, p):
        kn, ks, tphi = stiffnesses(props[ma, 0], props[ma, 1], props[ma, 2], ra, props[mb, 0], props[mb, 1],
                                   props[mb, 2], rb)
        params[p, 0] = kn
        params[p, 1] = ks
        params[p, 2] = tphi

    return ip2


@njit(cache=True)
def set_tan_friction(n, mat_i, mat_j, props, params):
    """params[:n, 2] = tan(min φ) of each contact's two materials (a `frictional_ip2` law's
    friction, the same tan as its Ip2)."""
    for k in range(n):
        params[k, 2] = tan(min(props[mat_i[k], 2], props[mat_j[k], 2]))


# ---------------------------------------------------------------------------- vectors at a contact
@njit(inline="always", cache=True)
def tangential(x, y, z, nx, ny, nz):
    """(v·n, v − (v·n) n): the normal component of v and its part in the plane normal to n."""
    d = dot3(x, y, z, nx, ny, nz)
    return d, x - d * nx, y - d * ny, z - d * nz


@njit(inline="always", cache=True)
def capped(x, y, z, cap):
    """v scaled to the norm ``cap`` if |v| > cap (|v|² > cap², ratio cap/|v|), else v."""
    v2 = dot3(x, y, z, x, y, z)
    if v2 > cap * cap:
        ratio = cap / sqrt(v2)
        return x * ratio, y * ratio, z * ratio
    return x, y, z


# ---------------------------------------------------------------------------- tangential
@njit(inline="always", cache=True)
def shear_spring(fresh, fx, fy, fz, ox, oy, oz, tx, ty, tz, ks, dux, duy, duz):
    """Yade's incremental shear spring (CundallStrack): the stored shear force F_s [N] (zero on
    a ``fresh`` contact) follows the contact's rotation (`pdem.vec.scgeom_rotate`), minus
    k_s Δu_s (Δu_s the tangential displacement of the step [m]); not yet capped."""
    if fresh:
        fx = 0.0
        fy = 0.0
        fz = 0.0
    else:
        fx, fy, fz = scgeom_rotate(fx, fy, fz, ox, oy, oz, tx, ty, tz)
    return fx - ks * dux, fy - ks * duy, fz - ks * duz


# ---------------------------------------------------------------------------- rolling resistance
@njit(inline="always", cache=True)
def rolling_spring(fresh, mrx, mry, mrz, mt, ox, oy, oz, tx, ty, tz, wrx, wry, wrz, nx, ny, nz, kr, dt, mcap):
    """Elastic–plastic rolling and twisting springs: the stored rolling moment M_r (follows the
    contact's rotation, `pdem.vec.scgeom_rotate`; zero and M_t zero on a ``fresh`` contact) plus
    k_θ ω_r Δt, ω_r the in-plane part of the relative spin ω2 − ω1, capped at |M_r| <= ``mcap``;
    the twisting moment M_t plus k_θ ω_t Δt, ω_t = (ω2 − ω1)·n, capped at |M_t| <= ``mcap``.
    Returns (M_r, M_t) [N·m], the moments on body 1."""
    if fresh:
        mrx = mry = mrz = 0.0
        mt = 0.0
    else:
        mrx, mry, mrz = scgeom_rotate(mrx, mry, mrz, ox, oy, oz, tx, ty, tz)
    wn, rx, ry, rz = tangential(wrx, wry, wrz, nx, ny, nz)
    mrx += kr * rx * dt
    mry += kr * ry * dt
    mrz += kr * rz * dt
    mt += kr * wn * dt
    mrx, mry, mrz = capped(mrx, mry, mrz, mcap)
    if abs(mt) > mcap:
        mt = mcap if mt > 0.0 else -mcap
    return mrx, mry, mrz, mt


@njit(inline="always", cache=True)
def rolling_constant_torque(wrx, wry, wrz, nx, ny, nz, mu_r, kn, pen, reff):
    """LIGGGHTS's ``cdt``: a torque of norm μ_r k_n δ R* [N·m] along ω2 − ω1 (the relative spin),
    its normal part removed: the moment on body 1, against the rolling of body 1 relative to
    body 2; zero for μ_r = 0 or without relative spin."""
    mx = my = mz = 0.0
    if mu_r > 0.0:
        wmag = sqrt(dot3(wrx, wry, wrz, wrx, wry, wrz))
        if wmag > 0.0:
            s = mu_r * kn * pen * reff / wmag
            _, mx, my, mz = tangential(wrx * s, wry * s, wrz * s, nx, ny, nz)
    return mx, my, mz
