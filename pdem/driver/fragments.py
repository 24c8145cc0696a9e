"""Fragment records in the results file: ``/fragments/<label>`` (`pdem.format.schema.write_fragments`).

`FragmentRecorder` writes the fragments of the running simulation (`pdem.bodies.fragments.fragments`:
connected components over intact bonds and rigid clumps) on a schedule (every ``every`` steps,
label ``fragment_label(step)``) or at named stages (`record(sim, "peak")`). A scene or a plain
run (run.fragments_every) schedules it. Every rank calls it (the computation is collective);
rank 0 writes. A resumed run writes a record of the same label again (replaced).

The group attributes: ``density`` [kg/m³] (of the grains' material: the sieve diameter of a
fragment is (6 m/(π ρ))^(1/3)) and ``member_radius_min`` [m]; both default to what the scene
has: the density of the clump members' material (it must be one) and their smallest radius.
With ``bonds`` a record also holds the intact bonds (attribute ``n_bonds``; the track's records).
"""
import numpy as np

from ..format.schema import fragment_label, write_fragments

from ..errors import InputError
from ..bodies.fragments import fragments


class FragmentRecorder:
    """Writes fragment records of a simulation into the results file ``path``."""

    def __init__(self, path, comm, every=0, density=None, member_radius_min=None, bonds=False):
        self.path = path
        self.comm = comm
        self.every = int(every)
        self.bonds = bonds  # write the intact bonds as the record's attribute n_bonds
        self.density = density
        self.member_radius_min = member_radius_min
        self.last = None  # what the last record found (rank 0)

    def on_step(self, sim):
        """Record if the step is on the schedule."""
        if self.every and sim.step % self.every == 0:
            self.record(sim, fragment_label(sim.step))

    def _density(self, sim):
        p = sim.particles
        mine = np.unique(p.material[: p.n_local][p.clump[: p.n_local] >= 0]).astype(np.int64)
        mats = np.unique(self.comm.allgather_rows(mine))
        if len(mats) != 1:
            raise InputError("fragments: the clump members have no single material; give the recorder the "
                             "grains' density")
        return float(sim.materials.density()[mats[0]])

    def record(self, sim, label):
        """Write the fragments now as ``/fragments/<label>`` (collective); returns the record's
        fragments on rank 0, None elsewhere."""
        density = self.density if self.density is not None else self._density(sim)
        f = fragments(sim)
        if self.comm.rank == 0:
            rmin = self.member_radius_min if self.member_radius_min is not None else f["member_radius_min"]
            write_fragments(self.path, label, f["n_members"], f["mass"], step=sim.step, time=sim.time,
                            density=density, member_radius_min=rmin, clump=f["clump"], replace=True,
                            n_bonds=f["n_bonds"] if self.bonds else None)
            self.last = f
        return f
