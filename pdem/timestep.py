"""Stable time step from the stiffnesses actually present.

- Before contacts exist: the P-wave estimate Δt_p = min_i r_i / sqrt(E_i/ρ_i) (Yade's
  PWaveTimeStep, ρ from the body's mass and volume, fixed spheres included).
- Afterwards: a global-stiffness estimate (Yade's GlobalStiffnessTimeStepper). Each body sums
  the stiffness of its real contacts, K_t,a = Σ [k_s + (k_n − k_s) n_a²] and
  K_r,a = Σ k_s (1 − n_a²) ℓ² (ℓ the contact radius), and Δt_k = sqrt(min(m/max_a K_t,a,
  min_a I/K_r,a)). For one degree of freedom the critical step is 2·sqrt(m/k); the sum over a
  body's contacts bounds the coupled system (Gershgorin: ω_max² ≤ 2 K/m), so Δt_k is safe with
  a margin of √2 and a safety factor s ≤ 1 on top (default 0.8, Yade's default).
Walls, facets, boxes and stiff materials (steel at 10 E) are all in the sums. The simulation
never lets Δt exceed Δt_p itself (`Simulation.update_dt`): in a loose cloud the few contacts
present allow a long step that the many contacts formed before the next estimate do not.
"""
from math import pi, sqrt

import numpy as np
from numba import njit

DOF_ALL = 63


@njit(cache=True)
def pwave_dt(n_local, radius, mass, material, young):
    dt = np.inf
    for b in range(n_local):
        r = radius[b]
        rho = mass[b] / (4.0 / 3.0 * pi * r * r * r)
        dt = min(dt, r / sqrt(young[material[b]] / rho))
    return dt


@njit(inline="always", cache=True)
def _add(kt, kr, kn, ks, nx, ny, nz, lever):
    n2 = (nx * nx, ny * ny, nz * nz)
    for a in range(3):
        kt[a] += ks + (kn - ks) * n2[a]
    kr[0] += ks * (n2[1] + n2[2]) * lever * lever
    kr[1] += ks * (n2[0] + n2[2]) * lever * lever
    kr[2] += ks * (n2[0] + n2[1]) * lever * lever


@njit(cache=True)
def stiffness_dt(n_local, mass, inertia, blocked, radius, inc_ptr, inc_pair, inc_first, pi_, pj, ss_state, ss_params,
                 ss_hist, w_ptr, w_state, w_params, w_hist, f_ptr, f_state, f_params, f_hist, b_ptr, b_state, b_params,
                 b_hist):
    """sqrt(min over free bodies of m/K) from current contacts; inf when no body has contacts."""
    best = np.inf
    kt = np.zeros(3)
    kr = np.zeros(3)
    for b in range(n_local):
        if blocked[b] == DOF_ALL:
            continue
        kt[:] = 0.0
        kr[:] = 0.0
        for k in range(inc_ptr[b], inc_ptr[b + 1]):
            p = inc_pair[k]
            if ss_state[p] == 1:
                _add(kt, kr, ss_params[p, 0], ss_params[p, 1], ss_hist[p, 3], ss_hist[p, 4], ss_hist[p, 5], radius[b])
        for p in range(w_ptr[b], w_ptr[b + 1]):
            if w_state[p] == 1:
                _add(kt, kr, w_params[p, 0], w_params[p, 1], w_hist[p, 3], w_hist[p, 4], w_hist[p, 5], radius[b])
        for p in range(f_ptr[b], f_ptr[b + 1]):
            if f_state[p] == 1:
                _add(kt, kr, f_params[p, 0], f_params[p, 1], f_hist[p, 3], f_hist[p, 4], f_hist[p, 5], radius[b])
        for p in range(b_ptr[b], b_ptr[b + 1]):
            if b_state[p] == 1:
                _add(kt, kr, b_params[p, 0], b_params[p, 1], b_hist[p, 3], b_hist[p, 4], b_hist[p, 5], radius[b])
        ktm = max(kt[0], max(kt[1], kt[2]))
        if ktm > 0.0:
            best = min(best, mass[b] / ktm)
        for a in range(3):
            if kr[a] > 0.0:
                best = min(best, inertia[b] / kr[a])
    return sqrt(best)


def box_dt(mass, blocked, stiffness):
    """sqrt(min over boxes with a free translation of m/K) [s], K [N/m] the global sum of the
    normal and shear stiffnesses of the box's real contacts (an upper bound of its stiffness
    along any axis); inf if no such box has contacts."""
    best = np.inf
    for b in range(len(mass)):
        if blocked[b] & 7 == 7 or not stiffness[b] > 0.0:
            continue
        best = min(best, mass[b] / stiffness[b])
    return sqrt(best)
