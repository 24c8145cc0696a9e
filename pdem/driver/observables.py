"""Global scalar observables of a running simulation, reduced so that they do not depend on
the rank count (exact sums, max/min reductions).

- unbalanced force ratio: mean over free bodies (a rigid clump is one body) of |F + m g| divided
  by the mean contact force magnitude (Yade's ``unbalancedForce``) [-]
- wall forces: total force of the spheres on each wall [N] (exact sums over contacts)
- top of the bed: max over spheres of z + r [m]
- the largest overlap of any real contact over the smaller radius of its pair [-]
- rigid boxes: force of the spheres on each box [N] (exact sums) and centre [m]
"""
import numpy as np

from ..diagnostics import max_overlap_ratio as _max_overlap_ratio
from ..state import DOF_ALL


def wall_forces(sim):
    """[n_walls, 3] total force exerted by the spheres on each wall [N] (exact sums)."""
    kind = sim.kind("sphere_wall")
    return np.zeros((len(sim.walls), 3)) if kind is None else kind.totals(sim.comm)


def unbalanced_force(sim):
    """Yade's unbalanced force ratio: mean |net force| on the free owned bodies (gravity
    included) over the mean |contact force| [-]; 1 when there are no contacts."""
    p = sim.particles
    nl = p.n_local
    free = p.blocked[:nl] != DOF_ALL
    if sim.clumps is not None:  # a rigid clump is one body: |F + M g| of the clump, not of its members
        free &= sim.clumps.row_clump[:nl] < 0
    net = p.force[:nl][free] + p.mass[:nl][free, None] * sim.gravity
    if sim.clumps is not None:
        net = np.concatenate([net, sim.clumps.net_forces(sim.gravity)])
    body = np.linalg.norm(net, axis=1)
    mags = [np.linalg.norm(kind.contacts.force[kind.owned_rows(nl)], axis=1) for kind in sim.kinds]
    mags = np.concatenate(mags) if mags else np.zeros(0)
    n_body = sim.comm.allreduce_sum_int(len(body))
    n_cont = sim.comm.allreduce_sum_int(len(mags))
    if n_cont == 0 or n_body == 0:
        return 1.0
    mean_body = sim.comm.exact_sum(body) / n_body
    mean_contact = sim.comm.exact_sum(mags) / n_cont
    return mean_body / mean_contact if mean_contact > 0 else 1.0


def bed_top(sim):
    p = sim.particles
    nl = p.n_local
    local = float(np.max(p.pos[:nl, 2] + p.radius[:nl])) if nl else -np.inf
    return sim.comm.allreduce_max(local)


def max_overlap_ratio(sim):
    """The largest overlap / smaller radius over every contact of every rank [-] (0 without contacts)."""
    return sim.comm.allreduce_max(_max_overlap_ratio(sim)[0])


def box_forces(sim):
    """[n_boxes, 3] total force of the spheres on each rigid box [N] at the last force computation
    (an exact sum over all ranks: identical bits on any rank count)."""
    if sim.boxes is None:
        return np.zeros((0, 3))
    return sim.boxes.contact_force.copy()


def box_positions(sim):
    """[n_boxes, 3] centre of each rigid box [m] (replicated: the same on every rank)."""
    if sim.boxes is None:
        return np.zeros((0, 3))
    return sim.boxes.center.copy()
