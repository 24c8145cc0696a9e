"""Pair loops generated from a (geometry, law) pair: the contact forces of one contact kind.

`make_pair_loop(geometry, law)` returns the `pdem.kernels.Kernel` of `pair_forces` with its
placeholders bound to the geometry's Ig2 functions (`pdem.contact.geometry`) and the law's Ip2
and Law2 (`pdem.contact.linear` and siblings, composed of `pdem.contact.submodels`); it is cached
per pair for the process (and by numba on disk). Adding a law writes no loop: its module provides `ip2`, `force` and the
constants, and `pdem.contact.LAWS` names it.

Per candidate row p (bodies i, j) of a contact list, in Yade's order (YADE_MODEL.md §1, §3–5):
Ig2 at the positions of the start of the step → if the pair is not in contact, skip it, or
clear the row of a contact that opened → Ip2 once, when the contact is new (parameters, and the
creation step in the last parameter column) → ScGeom::precompute: orthonormal axis n_old × n and
twist axis (Δt/2 n_old·(ω1+ω2)) n_old from the normal stored in the geometry's history columns,
relative velocity (Yade's, with the ratcheting factor; or at the contact point without it for a
law with ``CONTACT_POINT_VELOCITY``), its normal part vn passed on and removed, Δu_s = v_t Δt →
Law2 → outputs: the overlap per row; for a boundary the force and torque on the sphere per row;
for a pair of particles, (f, torque on body 1) into body 1's *slot* and (−f, torque on body 2)
into body 2's slot. A slot is a body's entry in its incidence list (`pdem.contact.neighbors.
build_incidence`, partners by gid; −1 for a ghost body), so the per-body sum (`pdem.contact.forces`) reads
its slots in order, contiguously, instead of gathering pair rows (2–2.5× faster at 50k).

Two optional law constants change the loop (pruned at compile time): ``TENSILE`` (a law with
bonds, `pdem.contact.cohesive`): a real contact whose overlap became negative is not deleted by
the loop; the law's ``holds(p, fresh, pen, params, history)`` decides, after Ip2, whether the
contact lives on this step (Yade's Law2 deletes the interaction and applies no force);
``CONTACT_POINT_LEVER``: torques (cp − x1) × f on body 1 and −(cp − x2) × f on body 2 with the
geometry's contact point (Law2_ScGeom6D_CohFrictPhys_CohesionMoment) instead of CundallStrack's
(r − pen/2) n × f. Rows and slots are written only by their own row's iteration (race-free
under ``prange``); `pdem.contact.forces` sums them per body in a fixed order. The loop returns the
largest overlap over the smaller radius of its contacts [-] (a max reduction: read by the
runaway guard, `pdem.checks.guard`, every step).

The geometry and law functions take scalars and at most plain arrays they index themselves:
an inline helper that passed arrays on to further inline helpers cost ~20 atomic reference-count
updates per contact and made the wall loop 5x slower (measured when this was written by hand).
"""
from functools import lru_cache

from numba import njit, prange

from .. import vec
from ..kernels import specialize
from ..vec import cross3, dot3
from . import geometry as geometry_module
from . import submodels
from .geometry import OPEN, SKIP
from .submodels import tangential

NORMAL_COLUMNS = 3  # the geometry's history: the normal of the previous step


def pair_forces(n, pi, pj, state, params, history, force, torque, overlap, slot, slot_f, slot_t, pos, vel, angvel,
                radius, material, mass, props, other_f, other_i, dt, step):
    """Forces of candidate rows [0, n) of one contact kind (placeholders bound by make_pair_loop);
    returns the largest overlap over the smaller radius [-] of the rows in contact."""
    worst = 0.0
    for p in prange(n):
        i = pi[p]
        j = pj[p]
        fresh = state[p] == 0
        status, nx, ny, nz, pen = GEOM_CONTACT(fresh, i, j, pos, radius, other_f, other_i)  # noqa: F821
        if status == SKIP:
            continue  # a row with state 0 is already clear (ContactList.replace)
        drop = status == OPEN and not LAW_TENSILE  # noqa: F821  (Law2 deletes an opened contact)
        if not drop:
            if fresh:
                ma, mb, ra, rb, m1, m2 = GEOM_IP2_ARGS(i, j, radius, material, mass, other_f, other_i)  # noqa: F821
                LAW_IP2(props, ma, mb, ra, rb, m1, m2, params, p)  # noqa: F821
                params[p, LAW_N_PARAMS] = step  # noqa: F821
                state[p] = 1
            drop = LAW_TENSILE and not LAW_HOLDS(p, fresh, pen, params, history)  # noqa: F821  (the law deletes it)
        if drop:  # clear the row (and its slots): a row with state 0 is clear
            state[p] = 0
            for c in range(history.shape[1]):
                history[p, c] = 0.0
            if GEOM_TWO_PARTICLES:  # noqa: F821
                for s in (slot[p, 0], slot[p, 1]):
                    if s >= 0:
                        for c in range(3):
                            slot_f[s, c] = 0.0
                            slot_t[s, c] = 0.0
            else:
                for c in range(3):
                    force[p, c] = 0.0
                    torque[p, c] = 0.0
            overlap[p] = 0.0
            continue
        wsx, wsy, wsz, wrx, wry, wrz = GEOM_SPINS(i, j, angvel)  # noqa: F821
        if fresh:
            ox = oy = oz = tx = ty = tz = 0.0
        else:
            px = history[p, LAW_HISTORY]  # noqa: F821
            py = history[p, LAW_HISTORY + 1]  # noqa: F821
            pz = history[p, LAW_HISTORY + 2]  # noqa: F821
            ox, oy, oz = cross3(px, py, pz, nx, ny, nz)
            angle = dt * 0.5 * dot3(px, py, pz, wsx, wsy, wsz)
            tx = angle * px
            ty = angle * py
            tz = angle * pz
        if LAW_CONTACT_POINT:  # noqa: F821  (compile-time constant: one branch is compiled)
            rvx, rvy, rvz = GEOM_CONTACT_VELOCITY(i, j, nx, ny, nz, pen, pos, vel, angvel, radius, other_f)  # noqa: F821
        else:
            rvx, rvy, rvz = GEOM_RELATIVE_VELOCITY(i, j, nx, ny, nz, pen, pos, vel, angvel, radius, other_f)  # noqa: F821
        dn, rvx, rvy, rvz = tangential(rvx, rvy, rvz, nx, ny, nz)  # vn and the tangential part
        fx, fy, fz, mx, my, mz = LAW_FORCE(p, fresh, nx, ny, nz, pen, dn, rvx * dt, rvy * dt, rvz * dt,  # noqa: F821
                                           ox, oy, oz, tx, ty, tz, wrx, wry, wrz, dt, params, history)
        history[p, LAW_HISTORY] = nx  # noqa: F821
        history[p, LAW_HISTORY + 1] = ny  # noqa: F821
        history[p, LAW_HISTORY + 2] = nz  # noqa: F821
        if LAW_CONTACT_POINT_LEVER:  # noqa: F821  (T1 = (cp − x1) × f, T2 = −(cp − x2) × f)
            cpx, cpy, cpz = GEOM_CONTACT_POINT(i, j, nx, ny, nz, pen, pos, radius, other_f)  # noqa: F821
            ax, ay, az = cross3(cpx - pos[i, 0], cpy - pos[i, 1], cpz - pos[i, 2], fx, fy, fz)
            if GEOM_TWO_PARTICLES:  # noqa: F821
                t1x, t1y, t1z = ax, ay, az
                bx, by, bz = cross3(cpx - pos[j, 0], cpy - pos[j, 1], cpz - pos[j, 2], fx, fy, fz)
                t2x, t2y, t2z = -bx, -by, -bz
            else:  # the sphere (row i) is body 2
                t1x = t1y = t1z = 0.0
                t2x, t2y, t2z = -ax, -ay, -az
        else:  # CundallStrack's sphericalBodies branch: T = (r − pen/2) n × f on both
            cx, cy, cz = cross3(nx, ny, nz, fx, fy, fz)
            l1, l2 = GEOM_LEVERS(i, j, pen, radius)  # noqa: F821
            t1x = l1 * cx
            t1y = l1 * cy
            t1z = l1 * cz
            t2x = l2 * cx
            t2y = l2 * cy
            t2z = l2 * cz
        if GEOM_TWO_PARTICLES:  # noqa: F821  (into the slots of the owned bodies: f on 1, -f on 2)
            if LAW_MOMENT:  # noqa: F821  (a couple: +m on body 1, -m on body 2)
                t1x += mx
                t1y += my
                t1z += mz
                t2x -= mx
                t2y -= my
                t2z -= mz
            s = slot[p, 0]
            if s >= 0:
                slot_f[s, 0] = fx
                slot_f[s, 1] = fy
                slot_f[s, 2] = fz
                slot_t[s, 0] = t1x
                slot_t[s, 1] = t1y
                slot_t[s, 2] = t1z
            s = slot[p, 1]
            if s >= 0:
                slot_f[s, 0] = -fx
                slot_f[s, 1] = -fy
                slot_f[s, 2] = -fz
                slot_t[s, 0] = t2x
                slot_t[s, 1] = t2y
                slot_t[s, 2] = t2z
        else:
            force[p, 0] = -fx
            force[p, 1] = -fy
            force[p, 2] = -fz
            torque[p, 0] = t2x
            torque[p, 1] = t2y
            torque[p, 2] = t2z
            if LAW_MOMENT:  # noqa: F821
                torque[p, 0] -= mx
                torque[p, 1] -= my
                torque[p, 2] -= mz
        overlap[p] = pen
        r_min = min(radius[i], radius[j]) if GEOM_TWO_PARTICLES else radius[i]  # noqa: F821
        worst = max(worst, pen / r_min)
    return worst


@njit(inline="always", cache=True)
def _always(p, fresh, pen, params, history):
    return True


@lru_cache(maxsize=None)
def make_pair_loop(geometry, law):
    """The compiled `pair_forces` of ``geometry`` (a `pdem.contact.geometry` class) and ``law``
    (a law module)."""
    bindings = {
        "GEOM_CONTACT": geometry.contact,
        "GEOM_IP2_ARGS": geometry.ip2_args,
        "GEOM_SPINS": geometry.spins,
        "GEOM_RELATIVE_VELOCITY": geometry.relative_velocity,
        "GEOM_CONTACT_VELOCITY": geometry.contact_velocity,
        "GEOM_LEVERS": geometry.levers,
        "GEOM_TWO_PARTICLES": geometry.TWO_PARTICLES,
        "GEOM_CONTACT_POINT": geometry.contact_point,
        "LAW_IP2": law.ip2,
        "LAW_FORCE": law.force,
        "LAW_N_PARAMS": law.N_PARAMS,
        "LAW_HISTORY": law.HISTORY,
        "LAW_MOMENT": law.MOMENT,
        "LAW_CONTACT_POINT": law.CONTACT_POINT_VELOCITY,
        # optional parts of the protocol (laws without bonds need not define them)
        "LAW_TENSILE": getattr(law, "TENSILE", False),
        "LAW_HOLDS": getattr(law, "holds", _always),
        "LAW_CONTACT_POINT_LEVER": getattr(law, "CONTACT_POINT_LEVER", False),
    }
    return specialize(pair_forces, f"{geometry.name}__{law.NAME}", bindings,
                      sources=(geometry_module, law, vec, submodels))
