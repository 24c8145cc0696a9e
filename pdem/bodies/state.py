"""Particle state: spheres as structure-of-arrays, owned entries first, then ghosts.

Owns the per-body arrays and their capacity. Rows ``[0, n_local)`` are the bodies this rank
integrates; rows ``[n_local, n_local + n_ghost)`` are read-only copies of neighbours' bodies
(filled by ``pdem.parallel``). Every body has a global id ``gid`` that never changes: contacts,
checkpoints and all ordering decisions use it, never the row. Rows are storage only: owned rows
are permuted into spatial order at every neighbour rebuild (`permute_local`), so nothing may
keep a row index across a rebuild.

Units: pos [m], vel [m/s], angvel [rad/s], force [N], torque [N·m], radius [m], mass [kg],
inertia [kg·m²] (a sphere's scalar moment 2/5·m·r², Yade's ``utils.sphere``).
``blocked`` is a bit mask of blocked degrees of freedom: bits 0–2 translations x, y, z, bits 3–5
rotations; 63 means fixed. A blocked body still moves with its (prescribed) velocity.
``clump`` is the id of the clump the sphere belongs to (a rigid clump, `pdem.bodies.clumps`, or a
breakable clump whose members are held by bonds), -1 for a sphere that never was in a clump.
Imports nothing from pdem but numpy.
"""
import numpy as np

DOF_ALL = 63

# name -> (dtype, trailing shape); the columns every body has and that migrate with it
FIELDS = {
    "gid": (np.int64, ()),
    "pos": (np.float64, (3,)),
    "vel": (np.float64, (3,)),
    "angvel": (np.float64, (3,)),
    "radius": (np.float64, ()),
    "mass": (np.float64, ()),
    "inertia": (np.float64, ()),
    "material": (np.int64, ()),
    "blocked": (np.int64, ()),
    "clump": (np.int64, ()),
}
# value of a column a table may lack (tables written before the column existed)
FIELD_DEFAULTS = {"clump": -1}
# accumulators and bookkeeping that are rebuilt, never stored or sent
SCRATCH = {
    "force": (np.float64, (3,)),
    "torque": (np.float64, (3,)),
    "pos_at_rebuild": (np.float64, (3,)),
}


def with_defaults(cols):
    """``cols`` (a dict of FIELDS columns) with the columns of `FIELD_DEFAULTS` it lacks filled in."""
    missing = [k for k in FIELD_DEFAULTS if k not in cols]
    if not missing:
        return cols
    n = len(cols["gid"])
    out = dict(cols)
    for k in missing:
        dtype, shape = FIELDS[k]
        out[k] = np.full((n,) + shape, FIELD_DEFAULTS[k], dtype)
    return out


# what a ghost needs every step (pdem.parallel sends these)
GHOST_STEP_FIELDS = ("pos", "vel", "angvel")


class Particles:
    """Spheres in structure-of-arrays layout with geometric growth of the capacity."""

    def __init__(self, capacity=16):
        self.n_local = 0
        self.n_ghost = 0
        self.capacity = 0
        for name, (dtype, shape) in {**FIELDS, **SCRATCH}.items():
            setattr(self, name, np.zeros((0,) + shape, dtype))
        self.reserve(capacity)

    @property
    def n_total(self):
        return self.n_local + self.n_ghost

    def reserve(self, capacity):
        """Grow every array to at least `capacity` rows (factor 1.5), keeping the contents."""
        if capacity <= self.capacity:
            return
        new_cap = max(capacity, int(self.capacity * 1.5) + 16)
        for name, (dtype, shape) in {**FIELDS, **SCRATCH}.items():
            old = getattr(self, name)
            new = np.zeros((new_cap,) + shape, dtype)
            new[: old.shape[0]] = old
            setattr(self, name, new)
        self.capacity = new_cap

    def append_local(self, rows):
        """Append owned bodies from a dict of column arrays (FIELDS); ghosts must be empty."""
        assert self.n_ghost == 0, "append owned bodies before ghosts are attached"
        n = len(rows["gid"])
        self.reserve(self.n_local + n)
        sl = slice(self.n_local, self.n_local + n)
        for name in FIELDS:
            getattr(self, name)[sl] = rows[name]
        self.pos_at_rebuild[sl] = self.pos[sl]
        self.n_local += n

    def remove_local(self, mask):
        """Drop the owned bodies where ``mask[:n_local]`` is true and drop every ghost.

        The kept owned rows stay in their order and compact at ``[0, n_local)``; every array
        (FIELDS and SCRATCH) is moved with them. Used by migration (`pdem.parallel`)."""
        m = np.asarray(mask[: self.n_local], bool)
        keep = np.flatnonzero(~m)
        if keep.size < self.n_local:  # (at most rebuilds nobody leaves: then nothing moves)
            first = int(np.argmax(m))  # the rows before the first removed one stay in place
            for name in {**FIELDS, **SCRATCH}:
                arr = getattr(self, name)
                arr[first : keep.size] = np.take(arr, keep[first:], axis=0)
        self.n_local = int(keep.size)
        self.n_ghost = 0

    def permute_local(self, order):
        """Reorder the owned rows: new row k is old row ``order[k]`` (a permutation of
        ``[0, n_local)``); every array (FIELDS and SCRATCH) is moved, ghost rows are untouched.
        Used at neighbour rebuilds to store bodies in spatial order (`pdem.simulation`)."""
        nl = self.n_local
        order = np.asarray(order, np.int64)
        assert order.shape == (nl,)
        for name in {**FIELDS, **SCRATCH}:
            arr = getattr(self, name)
            arr[:nl] = np.take(arr[:nl], order, axis=0)  # 3x faster than arr[order] on [n, 3]

    def set_ghosts(self, rows):
        """Replace the ghost rows by the bodies of a dict of FIELDS columns (copies of other
        ranks' bodies), stored after the owned rows; ``pos_at_rebuild`` is set to ``pos``."""
        n = len(rows["gid"])
        self.reserve(self.n_local + n)
        sl = slice(self.n_local, self.n_local + n)
        for name in FIELDS:
            getattr(self, name)[sl] = rows[name]
        self.pos_at_rebuild[sl] = self.pos[sl]
        self.force[sl] = 0.0
        self.torque[sl] = 0.0
        self.n_ghost = n

    def columns(self, rows=None):
        """Copy of the FIELDS columns of the given rows (default: all owned rows)."""
        if rows is None:
            rows = slice(0, self.n_local)
        return {name: getattr(self, name)[rows].copy() for name in FIELDS}

    def bytes_per_particle(self):
        """Memory of the per-body arrays divided by the bodies held [B]."""
        total = sum(getattr(self, n).nbytes for n in {**FIELDS, **SCRATCH})
        return total / max(self.n_total, 1)
