"""Stable time step from the stiffnesses actually present.

- Before contacts exist: the P-wave estimate Δt_p = min_i r_i / sqrt(E_i/ρ_i) (Yade's
  PWaveTimeStep, ρ from the body's mass and volume, fixed spheres included; E is the law's
  ``pwave_modulus`` of its ``PWAVE_KEY`` material property: Young's modulus itself for the
  linear and Hertz–Mindlin laws, k_n/r for the viscous law whose materials give a stiffness).
- Afterwards: a global-stiffness estimate (Yade's GlobalStiffnessTimeStepper). Each body sums
  the stiffness of its real contacts, K_t,a = Σ [k_s + (k_n − k_s) n_a²] and
  K_r,a = Σ k_s (1 − n_a²) ℓ² (ℓ the contact radius), and Δt_k = sqrt(min(m/max_a K_t,a,
  min_a I/K_r,a)). For one degree of freedom the critical step is 2·sqrt(m/k); the sum over a
  body's contacts bounds the coupled system (Gershgorin: ω_max² ≤ 2 K/m), so Δt_k is safe with
  a margin of √2 and a safety factor s ≤ 1 on top (default 0.8, Yade's default). (k_n, k_s) of
  each contact come from the law (`law.dt_stiffness`: the linear law's k_n, k_s; a law with
  viscous damping raises them by 1/(sqrt(1 + η²) − η)², which turns 2/ω into the damped
  critical step (2/ω)(sqrt(1 + η²) − η), and adds its rolling stiffness), the normal from the
  contact's history.
A rigid clump adds its own estimate (`pdem.bodies.clumps.clump_dt`): M/K_t and I_min/K_r with every
member contact's k_n + k_s at its lever from the clump centre (the members' own estimate alone
misses the longer levers). Walls, facets, boxes and stiff materials (steel at 10 E) are all in the sums (every contact
kind of `Simulation.kinds`, in the order forces are summed). The simulation never lets Δt
exceed Δt_p itself (`update_dt`): in a loose cloud the few contacts present allow a long step
that the many contacts formed before the next estimate do not.
"""
from math import pi, sqrt

import numpy as np
from numba import njit

from .bodies.clumps import add_member_stiffness
from .settings import AUTO
from .bodies.state import DOF_ALL


@njit(cache=True)
def pwave_dt(n_local, radius, mass, young):
    """min over bodies of r / sqrt(E/ρ), E [Pa] per body (``young[b]``)."""
    dt = np.inf
    for b in range(n_local):
        r = radius[b]
        rho = mass[b] / (4.0 / 3.0 * pi * r * r * r)
        dt = min(dt, r / sqrt(young[b] / rho))
    return dt


@njit(cache=True)
def add_stiffness(n_local, blocked, radius, ptr, rows, state, kn, ks, history, ncol, kt, kr):
    """kt[b, a] += Σ k_s + (k_n − k_s) n_a², kr[b, a] += Σ k_s (1 − n_a²) r² over the real
    contacts of each free owned body b (rows[ptr[b]:ptr[b+1]] of one contact kind)."""
    for b in range(n_local):
        if blocked[b] == DOF_ALL:
            continue
        lever = radius[b]
        for k in range(ptr[b], ptr[b + 1]):
            p = rows[k]
            if state[p] != 1:
                continue
            n0 = history[p, ncol] * history[p, ncol]
            n1 = history[p, ncol + 1] * history[p, ncol + 1]
            n2 = history[p, ncol + 2] * history[p, ncol + 2]
            kn_p = kn[p]
            ks_p = ks[p]
            kt[b, 0] += ks_p + (kn_p - ks_p) * n0
            kt[b, 1] += ks_p + (kn_p - ks_p) * n1
            kt[b, 2] += ks_p + (kn_p - ks_p) * n2
            kr[b, 0] += ks_p * (n1 + n2) * lever * lever
            kr[b, 1] += ks_p * (n0 + n2) * lever * lever
            kr[b, 2] += ks_p * (n0 + n1) * lever * lever


@njit(cache=True)
def stiffness_dt(n_local, mass, inertia, blocked, kt, kr):
    """sqrt(min over free bodies of m/max_a K_t,a and I/K_r,a); inf when no body has contacts."""
    best = np.inf
    for b in range(n_local):
        if blocked[b] == DOF_ALL:
            continue
        ktm = max(kt[b, 0], max(kt[b, 1], kt[b, 2]))
        if ktm > 0.0:
            best = min(best, mass[b] / ktm)
        for a in range(3):
            if kr[b, a] > 0.0:
                best = min(best, inertia[b] / kr[b, a])
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


def box_turn_dt(boxes, stiffness):
    """sqrt(min over boxes with a free rotation of I_min/(K |h|²)) [s]: K |h|² bounds the
    rotational stiffness (every contact at the farthest point of the box); inf without such a box
    with contacts."""
    best = np.inf
    for b in np.flatnonzero(boxes.rotating):
        if stiffness[b] > 0.0:
            best = min(best, boxes.inertia[b].min() / (stiffness[b] * float(boxes.half[b] @ boxes.half[b])))
    return sqrt(best)


def contact_dt(sim):
    """Δt_k of this rank's owned bodies from the real contacts of every kind [s]."""
    p = sim.particles
    nl = p.n_local
    kt = np.zeros((nl, 3))
    kr = np.zeros((nl, 3))
    kmember = np.zeros(nl) if sim.clumps is not None else None
    for kind in sim.kinds:
        c = kind.contacts
        kn, ks = sim.law.dt_stiffness(c.params[: c.n], c.history[: c.n], c.overlap[: c.n])
        add_stiffness(nl, p.blocked, p.radius, kind.ptr, kind.rows, c.state, kn, ks, c.history, kind.normal_column,
                      kt, kr)
        if kmember is not None:
            add_member_stiffness(nl, kind.ptr, kind.rows, c.state, kn, ks, kmember)
    dt = stiffness_dt(nl, p.mass, p.inertia, p.blocked, kt, kr)
    if kmember is not None:  # a clump turns about its centre: levers up to its extent
        dt = min(dt, sim.clumps.stiffness_dt(p, kmember))
    return dt


def update_dt(sim, force=False, carried=None):
    """Set ``sim.dt`` (its one writer): ``carried`` (a checkpoint's Δt, to continue bit for bit),
    the fixed Δt of ``simulation.dt``, or with dt = `AUTO` (every ``dt_interval`` steps, or with
    ``force``) the smaller of safety·Δt_k and Δt_p over all ranks; the P-wave fraction before
    any contact."""
    if carried is not None:
        sim.dt = float(carried)
    elif sim.settings.dt != AUTO:
        sim.dt = sim.settings.dt
    elif force or sim.step % sim.settings.dt_interval == 0:
        sim.dt = stable_dt(sim)


def stable_dt(sim):
    """The Δt that dt = "auto" takes in the present state [s] (collective): min(safety·Δt_k, Δt_p),
    or pwave_factor·Δt_p before any contact. Also names how far a fixed Δt is above it when a
    run with one blows up (`pdem.checks.diagnostics.dt_cause`)."""
    p = sim.particles
    k_dt = contact_dt(sim)
    for kind in sim.box_kinds:  # the box's own mass–spring step, from the global sum of its contacts
        k = kind.stiffness_totals(sim.comm)
        k_dt = min(k_dt, box_dt(sim.boxes.mass, sim.boxes.blocked, k))
        if kind.name == "sphere_oriented_box":
            k_dt = min(k_dt, box_turn_dt(sim.boxes, k))
    k_dt = sim.comm.allreduce_min(k_dt)
    nl = p.n_local
    young = sim.law.pwave_modulus(sim.materials.column(sim.law.PWAVE_KEY)[p.material[:nl]], p.radius[:nl])
    pw = sim.comm.allreduce_min(pwave_dt(nl, p.radius, p.mass, young))
    # never above the P-wave step itself: a body whose few contacts allow a long step can
    # gain many more within dt_interval steps (a sphere landing on a bed)
    return min(sim.settings.dt_safety * k_dt, pw) if np.isfinite(k_dt) else sim.settings.pwave_factor * pw
