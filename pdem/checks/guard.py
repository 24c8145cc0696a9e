"""Runaway guard: a run that tunnels, shoots bodies away or leaves its domain stops, naming why.

What is checked, and when (every check raises `InstabilityError`, exit status 4, with one line
naming the step, the body and the cause; the line is the same on every rank):

- every step (`check_step`, from values the step computes anyway and reduced in the one
  collective of the neighbour-rebuild test, so it costs no extra communication):
  * the largest displacement of a body in the last step, |v|·Δt, over its radius must not
    exceed `STEP_FRACTION` (0.25): a body moving faster crosses a contact in fewer steps than
    the contact law needs to stop it (it tunnels through a wall, a facet or another sphere);
  * the largest overlap the force loops saw in the step, over the smaller radius, must not
    exceed the scene's ``max_overlap_ratio`` (default 0.5). With the displacement bound, an
    overlap cannot pass from below the limit to beyond a radius in one step, so no contact,
    however short, goes through unseen;
- every ``check_interval`` steps (`check_domain`, from `pdem.checks.diagnostics.check_stability`): no
  body may be behind a wall it started in front of (its centre more than its radius beyond the
  plane: it went through), nor outside the declared domain box (``simulation.domain``);
- at build (`check_initial_overlaps`): no sphere may start overlapping a wall, a facet or a box
  (as for sphere pairs in `pdem.build.scene`), nor start behind a one-sided wall, unless the scene
  sets ``allow_initial_overlap``.

The domain of a scene: the half-spaces in front of its walls (a one-sided wall's side; a
two-sided wall's side where every sphere starts), intersected with the declared box if any;
sides that neither close are open. Physics here never knows its rank: every decision is a
reduction over the domain's communicator.
"""
from functools import cache

import numpy as np
from numba import njit

from .. import vec
from ..contact import geometry as geometry_module
from ..contact.geometry import CONTACT
from .diagnostics import agree, check_finite, check_overlap, dt_cause
from ..errors import InstabilityError
from ..kernels import specialize

STEP_FRACTION = 0.25  # largest displacement per step over the body's radius [-]


class Guard:
    """The runaway checks of one simulation: ``wall_side[k]`` is the side (+1, -1) of wall k
    where the spheres belong (0: not checked); ``box`` the declared domain [[lo], [hi]] or None."""

    def __init__(self, wall_side=(), box=None):
        self.wall_side = np.asarray(wall_side, np.int64)
        self.box = None if box is None else np.asarray(box, np.float64).reshape(2, 3)

    @classmethod
    def for_scene(cls, walls, pos, box=None):
        """Sides of ``walls`` from their sense, or for two-sided walls the side where every
        sphere centre of ``pos`` (all spheres of the scene) starts."""
        side = []
        for k in range(len(walls)):
            s = int(walls.sense[k])
            if s == 0 and len(pos):
                d = pos[:, int(walls.axis[k])] - float(walls.position[k])
                s = 1 if np.all(d > 0) else (-1 if np.all(d < 0) else 0)
            side.append(s)
        return cls(side, box)

    # ------------------------------------------------------------------ every step
    def check_step(self, sim, step_ratio, overlap_ratio):
        """Stop if a body moved more than STEP_FRACTION of its radius in the last step or an
        overlap passed max_overlap_ratio (both already reduced over the ranks)."""
        if not step_ratio <= STEP_FRACTION:
            if not np.isfinite(step_ratio):  # max_motion reports a NaN or inf as inf
                check_finite(sim)
            p = sim.particles
            nl = p.n_local
            speed = np.linalg.norm(p.vel[:nl], axis=1) if nl else np.zeros(0)
            ratio = speed * sim.dt / p.radius[:nl] if nl else np.zeros(0)
            k = int(np.argmax(ratio)) if nl else -1
            what = (f"body gid {int(p.gid[k])} at {_xyz(p.pos[k])} m moves {ratio[k]:.3g} of its radius per step "
                    f"(|v| = {speed[k]:.4g} m/s, r = {p.radius[k]:.4g} m)") if nl else ""
            what = agree(sim.comm, ratio[k] if nl else -1.0, what)
            cause = ("the initial velocity is too high for the time step" if sim.step == 0 else
                     "numerical instability or a speed too high for the time step")
            raise InstabilityError(
                f"step {sim.step}: {what}, more than {STEP_FRACTION} "
                + dt_cause(sim, f"a contact this fast is crossed before the contact law can stop it (tunnelling): "
                                f"{cause}; lower dt or the speed"))
        check_overlap(sim, overlap_ratio, "numerical instability (the time step exceeds the critical value for the "
                                          "contact stiffness) or a load or speed too high for the stiffness")

    # ------------------------------------------------------------------ every check_interval steps
    def check_domain(self, sim):
        """Stop if a body is behind a wall it belongs in front of, or outside the declared box."""
        p = sim.particles
        nl = p.n_local
        pos, r = p.pos[:nl], p.radius[:nl]
        what = ""
        walls = sim.walls
        for k in np.flatnonzero(self.wall_side):
            a = int(walls.axis[k])
            behind = (pos[:, a] - walls.position[k]) * self.wall_side[k] < -r
            if behind.any():
                b = int(np.flatnonzero(behind)[0])
                what = (f"body gid {int(p.gid[b])} at {_xyz(pos[b])} m went through wall {_name(walls.names[k])} "
                        f"({'xyz'[a]} = {walls.position[k]:.6g} m)")
                break
        if not what and self.box is not None:
            out = np.any((pos < self.box[0]) | (pos > self.box[1]), axis=1)
            if out.any():
                b = int(np.flatnonzero(out)[0])
                what = (f"body gid {int(p.gid[b])} at {_xyz(pos[b])} m left the domain {self.box[0].tolist()}.."
                        f"{self.box[1].tolist()} m")
        if sim.comm.any_flag(bool(what)):
            what = agree(sim.comm, 1.0 if what else -1.0, what)
            raise InstabilityError(f"step {sim.step}: {what} "
                                   + dt_cause(sim, "the run has lost bodies; a time step too large, a speed or load "
                                                   "too high for the stiffness"))


def _name(name):
    """A boundary as a message names it: its index as is, a given name quoted."""
    return name if name.isdigit() else repr(name)


def _xyz(x):
    return "(" + ", ".join(f"{float(v):.4g}" for v in x) + ")"


# ---------------------------------------------------------------------------- at build
def first_overlaps(n, pi, pj, pos, radius, other_f, other_i):
    """(largest overlap [m], its row) of candidate rows [0, n) as a new contact would see them."""
    worst = 0.0
    row = -1
    for p in range(n):
        status, _, _, _, pen = GEOM_CONTACT(True, pi[p], pj[p], pos, radius, other_f, other_i)  # noqa: F821
        if status == CONTACT and pen > worst:
            worst = pen
            row = p
    return worst, row


@cache
def _first_overlaps(geometry):
    return specialize(first_overlaps, f"first_overlaps__{geometry.name}", {"GEOM_CONTACT": geometry.contact},
                      sources=(geometry_module, vec))


@njit(cache=True)
def _behind_walls(pos, n, axis, position, sense):
    """(row, wall) of the first sphere whose centre is on the wrong side of a one-sided wall."""
    for s in range(n):
        for w in range(axis.shape[0]):
            if sense[w] != 0 and (pos[s, axis[w]] - position[w]) * sense[w] < 0.0:
                return s, w
    return -1, -1


def check_initial_overlaps(sim):
    """Stop with one line (InputError, every rank) if a sphere starts overlapping a wall, a facet
    or a box, or behind a one-sided wall (collective)."""
    from ..errors import InputError

    p = sim.particles
    what, worst = "", 0.0
    if len(sim.walls):
        s, w = _behind_walls(p.pos, p.n_local, sim.walls.axis.copy(), sim.walls.position.copy(), sim.walls.sense.copy())
        if s >= 0:
            worst = np.inf
            what = (f"body gid {int(p.gid[s])} at {_xyz(p.pos[s])} m starts behind the one-sided wall "
                    f"{_name(sim.walls.names[w])}")
    for kind in sim.kinds[1:]:
        if what:
            break
        c = kind.contacts
        other_f, other_i = kind.kernel_arrays()
        pen, row = _first_overlaps(kind.geometry)(c.n, c.i, c.j, p.pos, p.radius, other_f, other_i)
        if row >= 0 and pen > 1e-9 * p.radius[c.i[row]]:  # not rounding of a sphere placed touching
            s, b = int(c.i[row]), int(c.j[row])
            worst = pen / p.radius[s]
            what = (
                f"body gid {int(p.gid[s])} overlaps {kind.name.split('_', 1)[1]} {_name(kind.boundary.names[b])} by "
                f"{pen:.3e} m ({100 * worst:.0f} % of its radius) at the start"
            )
    if sim.comm.any_flag(bool(what)):
        what = agree(sim.comm, worst if what else -1.0, what)
        raise InputError(f"spheres: {what}; move it or set allow_initial_overlap = true")
