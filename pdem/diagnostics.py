"""What a running simulation can tell about itself, and the blow-up check.

- `energy`: mechanical energy [J] of the owned free bodies (rigid clumps as one body each) and
  the contacts (kinetic, rotational, gravitational potential −m g·x, elastic from the law), as
  exact global sums.
- `contacts_per_particle`, `max_overlap_ratio`: real contacts per body; the largest overlap over
  the smaller radius of the pair [-].
- `check_stability`: stop with `InstabilityError` naming the cause if the state is not finite,
  an overlap exceeds ``max_overlap_ratio`` of the smaller radius, or the mechanical energy grew
  without external work (a time step above the critical one).
Every reduction goes through the domain's communicator, so results do not depend on the rank
count. Physics here never knows its rank.
"""
import numpy as np

from .errors import InstabilityError
from .state import DOF_ALL


def contacts_per_particle(sim):
    """Real contacts per owned body (sphere pairs counted for both bodies, boundaries once)."""
    p = sim.particles
    n = 0
    for kind in sim.kinds:
        rows = kind.contacts.real_rows()
        for side in kind.body_rows(rows):
            n += np.count_nonzero(side < p.n_local)
    n_tot = sim.comm.allreduce_sum_int(int(n))
    bodies = sim.comm.allreduce_sum_int(p.n_local)
    return n_tot / max(bodies, 1)


def energy(sim):
    """Mechanical energy [J]: kinetic, rotational, potential, elastic and their total."""
    p = sim.particles
    nl = p.n_local
    free = p.blocked[:nl] != DOF_ALL
    if sim.clumps is not None:  # a rigid clump counts as one body, not as its members
        free &= sim.clumps.row_clump[:nl] < 0
    m = p.mass[:nl][free]
    v = p.vel[:nl][free]
    w = p.angvel[:nl][free]
    ke = 0.5 * m * np.einsum("ij,ij->i", v, v)
    kr = 0.5 * p.inertia[:nl][free] * np.einsum("ij,ij->i", w, w)
    # potential energy at the positions the overlaps were computed from (start of the step)
    x_start = p.pos[:nl][free] - v * sim.dt
    pe = -m * (x_start @ sim.gravity)
    if sim.clumps is not None:
        cke, ckr, cpe = sim.clumps.energy(sim.gravity, sim.dt)
        ke, kr, pe = np.concatenate([ke, cke]), np.concatenate([kr, ckr]), np.concatenate([pe, cpe])
    el = []
    for kind in sim.kinds:
        c = kind.contacts
        rows = kind.owned_rows(nl)
        el.append(sim.law.elastic_energy(c.params[rows], c.history[rows], c.overlap[rows]))
    el = np.concatenate(el) if el else np.zeros(0)
    s = sim.comm.exact_sum
    out = {"kinetic": s(ke), "rotational": s(kr), "potential": s(pe), "elastic": s(el)}
    out["total"] = out["kinetic"] + out["rotational"] + out["potential"] + out["elastic"]
    return out


def max_overlap_ratio(sim):
    """(ratio, gid, other): the largest overlap divided by the smaller radius of the pair on this
    rank, the gid of the pair's particle and how the second body is named."""
    p = sim.particles
    worst = (0.0, -1, -1)
    for kind in sim.kinds:
        c = kind.contacts
        if c.n == 0:
            continue
        rows = np.arange(c.n)
        ratio = c.overlap[: c.n] / kind.min_radius(p.radius, rows)
        k = int(np.argmax(ratio))
        if ratio[k] > worst[0]:
            worst = (float(ratio[k]), int(p.gid[c.i[k]]), kind.other_name(p.gid, k))
    return worst


def check_stability(sim):
    """Raise `InstabilityError` (one line: step, cause, body, Δt) if the run has blown up."""
    p = sim.particles
    nl = p.n_local
    bad = ~np.isfinite(p.pos[:nl]).all(axis=1) | ~np.isfinite(p.vel[:nl]).all(axis=1)
    first_bad = int(p.gid[:nl][bad].min()) if bad.any() else -1
    if sim.comm.any_flag(bool(bad.any())):
        gid = int(-sim.comm.allreduce_max(-first_bad if first_bad >= 0 else -2**62))
        raise InstabilityError(
            f"step {sim.step}: non-finite position or velocity of body gid {gid} (dt = {sim.dt:.3e} s): "
            "the time step is too large for the stiffness, or an input is not finite")
    ratio, gi, other = max_overlap_ratio(sim)
    worst = sim.comm.allreduce_max(ratio)
    if worst > sim.max_overlap_ratio:
        where = f" between body gid {gi} and {other}" if ratio == worst else ""
        raise InstabilityError(
            f"step {sim.step}: overlap {worst:.3g} of the smaller radius{where} exceeds max_overlap_ratio = "
            f"{sim.max_overlap_ratio} (dt = {sim.dt:.3e} s): time step too large or load too high for the stiffness")
    if sim.energy_check and not sim.moving_boundaries:
        e = energy(sim)
        scale = e["kinetic"] + e["rotational"] + e["elastic"]
        if sim.energy_reference is None:
            sim.energy_reference = [e["total"], scale]
            return
        ref = sim.energy_reference
        growth = e["total"] - ref[0]
        tolerance = 0.5 * ref[1] + 1e-9 * (abs(ref[0]) + abs(e["potential"]))
        if growth > tolerance:
            raise InstabilityError(
                f"step {sim.step}: mechanical energy grew by {growth:.3e} J without external work "
                f"(kinetic+elastic {scale:.3e} J, before {ref[1]:.3e} J; dt = {sim.dt:.3e} s): numerical "
                "instability, the time step exceeds the critical value for the contact stiffness")
        ref[0] = min(ref[0], e["total"])  # dissipation lowers the reference, nothing raises it
        ref[1] = max(ref[1], scale)
