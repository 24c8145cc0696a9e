"""A toy second contact law for tests/unit/test_law_plugin.py: the linear law without the
Coulomb cap (the shear spring never slides). It lives outside pdem/ on purpose: adding a law
touches no engine file, it is a module with the law protocol (`pdem.contact`) and a
`register_law` call (or one line in `pdem.contact.LAWS`)."""
import numpy as np
from numba import njit

from pdem.contact.linear import (  # noqa: F401  (reused as they are)
    CONTACT_POINT_VELOCITY, PAIR_KEYS, STIFFNESS_KEYS, combine, contact_forces, dt_stiffness, elastic_energy, ip2,
    pwave_modulus, stiffness)
from pdem.vec import cross3

NAME = "linear_uncapped"
N_PARAMS = 3
HISTORY = 3
MOMENT = False
MATERIAL_KEYS = {
    "young": ("a finite number > 0 [Pa]", lambda v: v > 0.0),
    "poisson": ("a finite number >= 0", lambda v: v >= 0.0),
    "friction_angle": ("in [0, pi/2) rad (stored, not used)", lambda v: 0.0 <= v < np.pi / 2),
}
PARAM_NAMES = {"kn": 0, "ks": 1}
PWAVE_KEY = "young"
FRICTION_KEY = None


@njit(inline="always", cache=True)
def force(p, fresh, nx, ny, nz, pen, vn, six, siy, siz, ox, oy, oz, tx, ty, tz, wrx, wry, wrz, dt, params, history):
    """Fn = kn pen n; Fs rotated with the contact, minus ks Δu_s, never capped."""
    kn = params[p, 0]
    ks = params[p, 1]
    knp = kn * max(pen, 0.0)
    if fresh:
        fsx = fsy = fsz = 0.0
    else:
        fsx, fsy, fsz = history[p, 0], history[p, 1], history[p, 2]
        cx, cy, cz = cross3(fsx, fsy, fsz, ox, oy, oz)
        fsx, fsy, fsz = fsx - cx, fsy - cy, fsz - cz
        cx, cy, cz = cross3(fsx, fsy, fsz, tx, ty, tz)
        fsx, fsy, fsz = fsx - cx, fsy - cy, fsz - cz
    fsx -= ks * six
    fsy -= ks * siy
    fsz -= ks * siz
    history[p, 0] = fsx
    history[p, 1] = fsy
    history[p, 2] = fsz
    return -knp * nx - fsx, -knp * ny - fsy, -knp * nz - fsz, 0.0, 0.0, 0.0
