"""What a running simulation can tell about itself, and the blow-up check.

- `energy`: mechanical energy [J] of the owned free bodies (rigid clumps as one body each) and
  the contacts (kinetic, rotational, gravitational potential −m g·x, elastic from the law, and
  their total synchronised to the positions), as exact global sums; `kinetic_energy` its kinetic
  and rotational part alone (for records written often).
- `contacts_per_particle`, `max_overlap_ratio`, `free_bodies`: real contacts per body; the largest
  overlap over the smaller radius of the pair, over all ranks [-]; the owned rows that move as
  bodies of their own (the driver's observables and the guard use these).
- `check_stability`: stop with `InstabilityError` naming the cause if the state is not finite,
  an overlap exceeds ``max_overlap_ratio`` of the smaller radius (`check_overlap`, also the
  guard's every-step test), or the mechanical energy grew without external work (a time step
  above the critical one).
Every reduction goes through the domain's communicator, so results do not depend on the rank
count. Physics here never knows its rank.
"""
import numpy as np

from ..errors import InstabilityError
from ..settings import AUTO
from ..bodies.state import DOF_ALL


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
    """Mechanical energy [J] at x_n, the positions of the last force computation: kinetic and
    rotational ½ m v² and ½ I ω² of the velocities after the step (v_{n+1/2}), potential −m g·x_n,
    elastic from the law, and ``total``, synchronised to x_n.

    The leapfrog's velocities live half a step after its positions, so K(v_{n+1/2}) + U(x_n) is
    off by about (h/2) F·v, which swings with every hard contact. ``total`` instead takes for
    the kinetic part ½ m v_{n−1/2}·v_{n+1/2} = ½ m v_{n+1/2}² − (h/2) m a_n·v_{n+1/2} (a_n the
    last step's acceleration as the integrator formed it, h its Δt; the same for spins), the
    quantity the leapfrog conserves exactly under linear forces (its "shadow" energy), so that
    a growth of ``total`` is an instability, not the half-step offset. Before the first step
    (h unknown) the state is taken as it is, without correction."""
    p = sim.particles
    nl = p.n_local
    free, m, v, w, inertia, ke, kr = _kinetic_terms(sim)
    h = sim.last_dt or 0.0
    # potential energy at the positions the overlaps were computed from (start of the step)
    x_start = p.pos[:nl][free] - v * h
    pe = -m * (x_start @ sim.gravity)
    if sim.clumps is not None:
        cke, ckr, cpe = sim.clumps.energy(sim.gravity, h)
        ke, kr, pe = np.concatenate([ke, cke]), np.concatenate([kr, ckr]), np.concatenate([pe, cpe])
    el = []
    for kind in sim.kinds:
        c = kind.contacts
        rows = kind.owned_rows(nl)
        el.append(sim.law.elastic_energy(c.params[rows], c.history[rows], c.overlap[rows]))
    el = np.concatenate(el) if el else np.zeros(0)
    sync = np.zeros(len(m))
    if h > 0.0:
        blocked = p.blocked[:nl][free]
        a = _step_acceleration(p.force[:nl][free] / m[:, None] + sim.gravity, v, blocked, 0, sim.damping, h)
        alpha = _step_acceleration(p.torque[:nl][free] / inertia[:, None], w, blocked, 3, sim.damping, h)
        sync = -0.5 * h * (m * np.einsum("ij,ij->i", a, v) + inertia * np.einsum("ij,ij->i", alpha, w))
    s = sim.comm.exact_sum
    out = {"kinetic": s(ke), "rotational": s(kr), "potential": s(pe), "elastic": s(el)}
    out["total"] = s(np.concatenate([ke, kr, pe, el, sync]))
    return out


def kinetic_energy(sim):
    """Kinetic plus rotational energy [J] of the velocities after the step: ``energy(sim)``'s
    ``kinetic + rotational`` (the same bits) without its other terms (collective)."""
    _, _, _, _, _, ke, kr = _kinetic_terms(sim)
    if sim.clumps is not None:
        cke, ckr, _ = sim.clumps.energy(sim.gravity, sim.last_dt or 0.0)
        ke, kr = np.concatenate([ke, cke]), np.concatenate([kr, ckr])
    return sim.comm.exact_sum(ke) + sim.comm.exact_sum(kr)


def free_bodies(sim):
    """bool per owned row: the body moves freely (not fully blocked) and is not a rigid clump's
    member (a clump counts as one body: `pdem.bodies.clumps`)."""
    nl = sim.particles.n_local
    free = sim.particles.blocked[:nl] != DOF_ALL
    if sim.clumps is not None:
        free &= sim.clumps.row_clump[:nl] < 0
    return free


def _kinetic_terms(sim):
    """(free, m, v, ω, I, ½ m v², ½ I ω²) of this rank's free bodies (a clump's members excluded)."""
    p = sim.particles
    nl = p.n_local
    free = free_bodies(sim)
    m = p.mass[:nl][free]
    v = p.vel[:nl][free]
    w = p.angvel[:nl][free]
    inertia = p.inertia[:nl][free]
    return (free, m, v, w, inertia, 0.5 * m * np.einsum("ij,ij->i", v, v),
            0.5 * inertia * np.einsum("ij,ij->i", w, w))


def _step_acceleration(a, v, blocked, shift, damping, h):
    """The acceleration the integrator applied in the last step (`pdem.integrator`): a = F/m + g
    (``a`` given), blocked components 0, Cundall's damping with the mid-step velocity estimated
    from the velocity after the step."""
    a = np.where((blocked[:, None] >> (np.arange(3) + shift)) & 1, 0.0, a)
    if damping > 0.0:
        a = a * (1.0 - damping * np.sign(a * (v - 0.5 * h * a)))
    return a


def max_overlap_ratio(sim):
    """The largest overlap over the smaller radius of its pair, over every contact of every rank
    [-] (0 without contacts; collective)."""
    return sim.comm.allreduce_max(_worst_overlap_here(sim)[0])


def _worst_overlap_here(sim):
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


def agree(comm, value, text):
    """``text`` of the rank with the largest ``value`` (the lowest such rank): the same line on
    every rank (collective)."""
    best = comm.allreduce_max(float(value))
    root = int(comm.allreduce_min(comm.rank if value == best else comm.size))
    return comm.bcast(text if comm.rank == root else None, root=min(root, comm.size - 1))


def worst_overlap(sim):
    """"overlap R of the smaller radius between body gid G and X" of the largest overlap over all
    ranks: the same text on every rank (collective)."""
    ratio, gi, other = _worst_overlap_here(sim)
    return agree(sim.comm, ratio, f"overlap {ratio:.3g} of the smaller radius between body gid {gi} and {other}")


def dt_cause(sim, cause):
    """"(dt = X s): CAUSE" closing an instability message; for a fixed Δt (``simulation.dt``)
    above the step dt = "auto" would take in this state, that is named as the cause instead
    (collective: every rank calls it with the same state and gets the same text)."""
    text = f"(dt = {sim.dt:.3e} s)"
    if sim.settings.dt != AUTO:
        from ..timestep import stable_dt

        stable = stable_dt(sim)
        if np.isfinite(stable) and sim.dt > stable:
            return (f"{text}: the time step fixed by simulation.dt is {sim.dt / stable:.3g} times the one dt = "
                    f"\"auto\" takes here ({stable:.3e} s): too large for the stiffnesses present; lower it or use "
                    "dt = \"auto\"")
    return f"{text}: {cause}"


def check_finite(sim):
    """Raise `InstabilityError` naming the body (lowest gid) if a position or velocity is not
    finite (collective)."""
    p = sim.particles
    nl = p.n_local
    bad = ~np.isfinite(p.pos[:nl]).all(axis=1) | ~np.isfinite(p.vel[:nl]).all(axis=1)
    first_bad = int(p.gid[:nl][bad].min()) if bad.any() else -1
    if sim.comm.any_flag(bool(bad.any())):
        gid = int(-sim.comm.allreduce_max(-first_bad if first_bad >= 0 else -2**62))
        raise InstabilityError(
            f"step {sim.step}: non-finite position or velocity of body gid {gid} (dt = {sim.dt:.3e} s): "
            "the time step is too large for the stiffness, or an input is not finite")


def check_overlap(sim, worst, cause):
    """Raise `InstabilityError` naming the worst overlap and ``cause`` if ``worst`` (the largest
    overlap ratio, already reduced over the ranks) exceeds the scene's ``max_overlap_ratio``
    (collective when it raises)."""
    if worst > sim.max_overlap_ratio:
        raise InstabilityError(f"step {sim.step}: {worst_overlap(sim)} exceeds max_overlap_ratio = "
                               f"{sim.max_overlap_ratio} " + dt_cause(sim, cause))


def check_stability(sim):
    """Raise `InstabilityError` (one line: step, cause, body, Δt; the same on every rank) if the
    run has blown up or lost bodies (`pdem.checks.guard.Guard.check_domain`)."""
    check_finite(sim)
    sim.guard.check_domain(sim)
    check_overlap(sim, max_overlap_ratio(sim), "time step too large or load too high for the stiffness")
    if sim.settings.energy_check and not sim.moving_boundaries:
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
                f"(kinetic+elastic {scale:.3e} J, before {ref[1]:.3e} J) "
                + dt_cause(sim, "numerical instability, the time step exceeds the critical value for the contact "
                                "stiffness"))
        ref[0] = min(ref[0], e["total"])  # dissipation lowers the reference, nothing raises it
        ref[1] = max(ref[1], scale)
