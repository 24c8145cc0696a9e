"""Contact kinds: the table of the kinds of contact a scene has, one entry per kind.

A kind binds a geometry (`pdem.contact.geometry`) to the bodies it concerns, its `ContactList`
(candidate rows with parameters and history), its candidate search at neighbour rebuilds, its
generated force loop (`pdem.contact.loops`, geometry × the scene's law) and the per-body sums
(`pdem.contact.forces`). Everything that walks over contacts (the step, the time step, diagnostics,
observables, migration between slabs, checkpoints) iterates `Simulation.kinds`, so a new kind is
one class here and one line in `make_kinds`.

Order of `make_kinds` (sphere pairs, walls, facets, boxes, rotating boxes, box members) is the order
in which each body's force is summed: partners by gid, then walls, facets and boxes by index (`pdem.contact.forces`).
Checkpoint tables are named ``contacts/<kind name>``.
"""
import numpy as np

from . import forces, neighbors
from ..bodies.clumps import drop_same_clump
from .store import KEY_SHIFT_SPHERE, ContactList, index_pair_keys, sphere_pair_keys
from .geometry import (PeriodicSphereSphere, SphereBox, SphereFacet, SphereMember, SphereOrientedBox, SphereSphere,
                       SphereWall)
from .loops import NORMAL_COLUMNS, make_pair_loop

_NO_ROWS_F = np.zeros((0, 1))
_NO_ROWS_I = np.zeros((0, 1), np.int64)
_NO_SLOTS = np.zeros((0, 2), np.int32)
_NO_SLOT_ROWS = np.zeros((0, 3))


class ContactKind:
    """One kind of contact. ``ptr``/``rows``: per owned body (CSR), its contact rows in the
    order its force is summed."""

    sphere_pair = False  # key = gid_i << 32 | gid_j (else gid << 20 | boundary index)
    boundary = None  # the Walls, Facets or Boxes container

    def __init__(self, geometry, law):
        self.name = geometry.name
        self.geometry = geometry
        self.law = law
        self.contacts = ContactList(law.N_PARAMS + 1, law.HISTORY + NORMAL_COLUMNS,
                                    row_outputs=not geometry.TWO_PARTICLES)
        self.loop = make_pair_loop(geometry, law)
        self.ptr = np.zeros(1, np.int64)
        self.rows = np.zeros(0, np.int32)
        self.worst_overlap = 0.0  # largest overlap / smaller radius of the last compute [-]

    @property
    def normal_column(self):
        """First history column of the contact normal (the geometry's columns follow the law's)."""
        return self.law.HISTORY

    def compute(self, sim):
        """Run the force loop over every candidate row."""
        p, c = sim.particles, self.contacts
        other_f, other_i = self.kernel_arrays()
        slot, slot_f, slot_t = self.slot_arrays()
        self.worst_overlap = self.loop(c.n, c.i, c.j, c.state, c.params, c.history, c.force, c.torque, c.overlap, slot,
                                       slot_f, slot_t, p.pos, p.vel, p.angvel, p.radius, p.material, p.mass, sim.props,
                                       other_f, other_i, sim.dt, sim.step)

    def slot_arrays(self):
        """(slot, slot_f, slot_t) of the pair loop: empty for a boundary kind."""
        return _NO_SLOTS, _NO_SLOT_ROWS, _NO_SLOT_ROWS

    def row_force(self, rows):
        """[len(rows), 3] force on the first body of each contact row [N]."""
        return self.contacts.force[rows]

    def bytes(self):
        """Memory of the contact rows and the per-body incidence (CSR) of this kind [B]."""
        return self.contacts.bytes() + self.ptr.nbytes + self.rows.nbytes

    def owned_rows(self, n_local):
        """Real contact rows counted by this rank (each contact once over all ranks)."""
        return self.contacts.real_rows()

    def body_rows(self, rows):
        """Rows of the particles in the contact rows ``rows`` (one array per particle side)."""
        return (self.contacts.i[rows],)

    def min_radius(self, radius, rows):
        """Smaller particle radius of each contact row [m]."""
        return radius[self.contacts.i[rows]]

    def other_name(self, gid, row):
        """How a message names the second body of contact row ``row``."""
        return f"{self.name.split('_', 1)[1]} {int(self.contacts.j[row])}"


class SpherePairs(ContactKind):
    sphere_pair = True

    def __init__(self, law, geometry=SphereSphere):
        super().__init__(geometry, law)
        self.slot = _NO_SLOTS  # per pair row: incidence entries of body 1 and body 2 (-1: a ghost)
        self.slot_f = _NO_SLOT_ROWS  # per incidence entry: force [N] and torque [N·m] on its body
        self.slot_t = _NO_SLOT_ROWS

    def rebuild(self, sim, cell):
        p = sim.particles
        pi, pj = neighbors.build_sphere_pairs(p.pos, p.radius, p.gid, p.n_local, p.n_total, sim.skin, cell,
                                              8 * p.n_total + 1000)
        if sim.clumps is not None:  # members of one rigid clump never touch each other
            pi, pj = drop_same_clump(pi, pj, sim.clumps.row_clump)
        self.contacts.replace(pi, pj, sphere_pair_keys(pi, pj, p.gid), key_shift=KEY_SHIFT_SPHERE)
        c = self.contacts
        self.ptr, self.rows, first = neighbors.build_incidence(p.n_local, c.n, c.i, c.j, p.gid)
        self.slot = neighbors.pair_slots(c.n, len(self.rows), self.rows, first)
        self.slot_f = np.zeros((len(self.rows), 3))  # zero: the loop fills the slots of real contacts
        self.slot_t = np.zeros((len(self.rows), 3))

    def kernel_arrays(self):
        return _NO_ROWS_F, _NO_ROWS_I

    def slot_arrays(self):
        return self.slot, self.slot_f, self.slot_t

    def row_force(self, rows):
        """Force on body 1 of each row [N], from its slot (or −1 × body 2's slot: the same bits)."""
        s1, s2 = self.slot[rows, 0], self.slot[rows, 1]
        return np.where((s1 >= 0)[:, None], self.slot_f[np.maximum(s1, 0)], -self.slot_f[np.maximum(s2, 0)])

    def row_torques(self, rows):
        """(torque on body 1, torque on body 2) of each row [N·m] (NaN on a ghost's side)."""
        out = []
        for side in (0, 1):
            s = self.slot[rows, side]
            out.append(np.where((s >= 0)[:, None], self.slot_t[np.maximum(s, 0)], np.nan))
        return tuple(out)

    def add_forces(self, sim):
        """Sets (not adds) every owned body's force and torque: the first sum of a step."""
        p = sim.particles
        forces.sum_sphere_pairs(p.n_local, self.ptr, self.slot_f, self.slot_t, p.force, p.torque)

    def bytes(self):
        return super().bytes() + self.slot.nbytes + self.slot_f.nbytes + self.slot_t.nbytes

    def owned_rows(self, n_local):
        rows = self.contacts.real_rows()
        return rows[self.contacts.i[rows] < n_local]

    def body_rows(self, rows):
        return self.contacts.i[rows], self.contacts.j[rows]

    def min_radius(self, radius, rows):
        return np.minimum(radius[self.contacts.i[rows]], radius[self.contacts.j[rows]])

    def other_name(self, gid, row):
        return str(int(gid[self.contacts.j[row]]))


class PeriodicSpherePairs(SpherePairs):
    """Sphere pairs of a scene with periodic ends (`pdem.parallel.periodic_domain`): candidates
    from the ghosts' image positions, the geometry with their image shifts. On a ring of one
    rank a pair across the ends is found as (i, j') and (i', j): the row whose first body is
    owned is kept and its image end summed into the owned body. Checkpoints call it
    ``sphere_sphere`` as the plain kind."""

    def __init__(self, law):
        super().__init__(law, PeriodicSphereSphere)
        self.name = "sphere_sphere"
        self.image = _NO_ROWS_F
        self.home = None  # one rank: the owned row of each image row (`self_image_home`)

    def rebuild(self, sim, cell):
        p, dom = sim.particles, sim.domain
        nl, nt = p.n_local, p.n_total
        self.image = dom.image
        shifted = p.pos[:nt] + self.image[:nt]
        pi, pj = neighbors.build_sphere_pairs(shifted, p.radius, p.gid, nl, nt, sim.skin, cell, 8 * nt + 1000)
        self.home = home = dom.self_image_home(nl, nt)
        if home is not None:  # one rank: (i', j) is the row (i, j') again
            keep = pi < nl
            pi, pj = pi[keep], pj[keep]
        self.contacts.replace(pi, pj, sphere_pair_keys(pi, pj, p.gid), key_shift=KEY_SHIFT_SPHERE)
        c = self.contacts
        cj = c.j[: c.n] if home is None else home[c.j[: c.n]].astype(c.j.dtype)
        self.ptr, self.rows, first = neighbors.build_incidence(nl, c.n, c.i, cj, p.gid)
        self.slot = neighbors.pair_slots(c.n, len(self.rows), self.rows, first)
        self.slot_f = np.zeros((len(self.rows), 3))
        self.slot_t = np.zeros((len(self.rows), 3))

    def kernel_arrays(self):
        return self.image, _NO_ROWS_I

    def body_rows(self, rows):
        """(body 1, body 2) rows; on one rank an image end is its owned body (counted as on
        several ranks)."""
        i, j = self.contacts.i[rows], self.contacts.j[rows]
        if self.home is None:
            return i, j
        return i, np.where(j >= 0, self.home[np.maximum(j, 0)], j)


class BoundaryContacts(ContactKind):
    """Spheres against replicated boundaries (walls, facets, boxes): candidates per owned sphere
    in boundary index order; the row holds the force on the sphere."""

    def __init__(self, geometry, law, boundary, candidates, body_of=None, n_bodies=None, search=None):
        super().__init__(geometry, law)
        self.boundary = boundary
        self._candidates = candidates
        self._search = boundary.search_arrays if search is None else search  # the candidates' boundary arrays
        # the body each boundary row belongs to (a box member: its box) and how many bodies
        self.body_of = np.arange(len(boundary)) if body_of is None else np.ascontiguousarray(body_of, np.int64)
        self.n_bodies = len(boundary) if n_bodies is None else n_bodies

    def rebuild(self, sim, cell):
        p = sim.particles
        self.ptr, ps, pb = self._candidates(p.pos, p.radius, p.n_local, sim.skin, *self._search())
        self.contacts.replace(ps, pb, index_pair_keys(ps, pb, p.gid))
        self.rows = np.arange(len(ps), dtype=np.int32)

    def kernel_arrays(self):
        return self.boundary.kernel_f, self.boundary.kernel_i

    def add_forces(self, sim):
        p, c = sim.particles, self.contacts
        forces.add_sphere_contacts(p.n_local, self.ptr, c.force, c.torque, p.force, p.torque)

    def totals(self, comm):
        """[n_bodies, 3] total force of the spheres on each boundary body (a box with members: on
        the box) [N]: an exact sum over the contact rows of all ranks (each contact is held by the
        owner of its sphere), so every rank gets the same bits whatever the rank count."""
        c = self.contacts
        accs = forces.boundary_totals_acc(c.n, c.state, c.j, c.force, self.body_of, self.n_bodies)
        return comm.exact_sum_accumulators(accs).reshape(self.n_bodies, 3)

    def stiffness_totals(self, comm):
        """[n_bodies] Σ (k_n + k_s) over each boundary body's real contacts, summed exactly over all
        ranks [N/m]."""
        rows = self.contacts.real_rows()
        kn, ks = self.law.dt_stiffness(self.contacts.params[rows], self.contacts.history[rows],
                                       self.contacts.overlap[rows])
        k = (np.asarray(kn, np.float64) + np.asarray(ks, np.float64)).reshape(-1, 1)
        return comm.exact_sum_groups(k, self.body_of[self.contacts.j[rows]], self.n_bodies).reshape(-1)


class OrientedBoxContacts(BoundaryContacts):
    """Spheres on the rigid boxes with free rotations (`SphereOrientedBox`): also the moment of
    their forces about each box's centre."""

    def __init__(self, law, boxes):
        super().__init__(SphereOrientedBox, law, boxes, neighbors.build_box_candidates,
                         search=boxes.oriented_search_arrays)

    def torques(self, sim):
        """[n_boxes, 3] Σ (x_c − c_b) × f_b [N·m] over each box's real contacts, f_b the force on
        the box at the contact point x_c = x − (r − pen/2) n: per row from the row alone, then an
        exact sum over all ranks (the same bits whatever the rank count)."""
        c, p = self.contacts, sim.particles
        rows = c.real_rows()
        s, b = c.i[rows], c.j[rows]
        normal = c.history[rows, self.normal_column: self.normal_column + 3]
        lever = p.radius[s] - 0.5 * c.overlap[rows]
        arm = (p.pos[s] - lever[:, None] * normal) - self.boundary.center[b]
        return sim.comm.exact_sum_groups(np.cross(arm, -c.force[rows]), b, len(self.boundary))


def make_kinds(law, walls, facets, boxes, periodic=False):
    """The contact kinds of a scene with these boundaries (only those it has), in summation order;
    ``periodic``: sphere pairs across periodic ends (`PeriodicSpherePairs`)."""
    kinds = [PeriodicSpherePairs(law) if periodic else SpherePairs(law)]
    if len(walls):
        kinds.append(BoundaryContacts(SphereWall, law, walls, neighbors.build_wall_candidates))
    if len(facets):
        kinds.append(BoundaryContacts(SphereFacet, law, facets, neighbors.build_facet_candidates))
    if boxes.smooth_count():
        kinds.append(BoundaryContacts(SphereBox, law, boxes, neighbors.build_box_candidates))
    if boxes.oriented_count():  # only a scene with a rotating box has this kind
        kinds.append(OrientedBoxContacts(law, boxes))
    if len(boxes.members):
        kinds.append(BoundaryContacts(SphereMember, law, boxes.members, neighbors.build_member_candidates,
                                      body_of=boxes.members.box, n_bodies=len(boxes)))
    return kinds


def box_kinds(kinds):
    """The kinds among ``kinds`` whose forces act on the rigid boxes (flat faces, rotating boxes, member
    spheres)."""
    return [k for k in kinds if k.name in ("sphere_box", "sphere_oriented_box", "sphere_member")]
