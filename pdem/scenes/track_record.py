"""Records of a track section under traffic, in the kind "track" layout of `pdem.format.schema`.

- `PassageTracker` follows every sleeper through the passages of a load program: settlement
  (positive down, from the sleeper's centre at the start of traffic [m]), its largest value in
  the passage (peak) and its value when the passage ends (permanent). A passage ends at the
  first step at or after its nominal end; its peak instant is the first step at or after the
  nominal peak (the first axle over the middle sleeper, or mid-cycle). With ``loads = True`` (the
  rail as a beam) it also follows the largest load [N, downward] on every sleeper in the
  passage: the rail's share of the wheels as the beam and the bed distribute it. And the
  passage's energy ledger: the work of the loads on the sleepers [J] and the change of the
  mechanical energy of sleepers and ballast [J] (`mechanical_energy`) over the passage; their
  difference is what the bed (damping, friction, the viscous law) dissipated, zero for an
  elastic undamped bed but for the integrator's error. The work is the leapfrog's own: with
  the energies at the positions x_n of the force computations, the step from x_k to x_{k+1}
  does ½ (F_k + F_{k+1})·(x_{k+1} − x_k) (F the load and its moment, x the position and the
  turn: `Boxes.load_step`), the quantity by which the leapfrog's synchronised energy changes.
  Plain data, JSON state for checkpoints; fed every step with the replicated sleeper positions
  (identical on every rank), so every rank takes the same decisions.
- `TrackWriter` writes ``/series`` (`pdem.format.schema.TRACK_SERIES`) and the per-sleeper rows
  of ``/track`` (settlement [m], ballast force on the sleeper, positive up [N]) together, one
  row of each per sample, and ``/passages`` (peak, permanent settlement and the gap under each
  sleeper, `observables.box_gaps`; with the beam the peak load on each sleeper, ``load_peak``).
  After a restart it cuts ``/series`` and ``/track`` to the rows written up to the checkpoint
  and ``/passages`` to the passages closed by then.
- `write_force_record` writes ``/forces/<label>``: the normal force of every sleeper–ballast
  contact (with its sleeper) and the force of every ballast–ballast contact
  (`observables.contact_force_samples`).

Only rank 0 writes; the others go through the same calls (the collectives inside them).
"""
import h5py
import numpy as np
from ..format import schema

from ..driver import observables
from ..driver.results import series_writer

EVERY = 10  # samples buffered before /series and /track are written


class PassageTracker:
    """Peak and permanent settlement of every sleeper per passage.

    ``ends[p]``, ``peaks[p]`` [s]: nominal end and peak instant of passage p (0-based);
    passage 0 starts where tracking starts."""

    def __init__(self, ends, peaks, reference, loads=False):
        self.ends = [float(t) for t in ends]
        self.peaks = [float(t) for t in peaks]
        self.reference = [float(z) for z in reference]  # sleeper centre heights at the start [m]
        self.p = 0  # the open passage
        self.t_start = None
        self.peak = None
        self.peak_seen = False
        self.load_peak = [0.0] * len(self.reference) if loads else None  # [N] in the open passage
        self.work = 0.0  # [J] of the loads in the open passage
        self.energy0 = None  # [J] mechanical energy when the open passage's ledger started
        self.last_step = None  # ([n, 6] load, [n, 6] displacement) of the step before (`account`)

    @property
    def done(self):
        return self.p >= len(self.ends)

    def settlement(self, z):
        """Settlement [m] of every sleeper from its centre heights z [m] (positive down)."""
        return np.array([r - float(x) for r, x in zip(self.reference, z)])

    def start(self, t, settlement):
        self.t_start = float(t)
        self.peak = [float(s) for s in settlement]
        self.peak_seen = False

    def update(self, t, settlement, load=None):
        """Feed one step (``load`` [N]: on every sleeper, if loads are followed); returns the
        events it completes: "peak" (the peak instant of the open passage is reached) and/or
        "end" (the passage is over; then ``closed()`` gives its row and the next passage opens
        at this step)."""
        events = []
        if self.done:
            return events
        self.peak = [max(a, float(b)) for a, b in zip(self.peak, settlement)]
        if self.load_peak is not None:
            self.load_peak = [max(a, float(b)) for a, b in zip(self.load_peak, load)]
        if not self.peak_seen and t >= self.peaks[self.p]:
            self.peak_seen = True
            events.append("peak")
        if t >= self.ends[self.p]:
            events.append("end")
        return events

    def account(self, sim):
        """Feed the energy ledger one step n (load F_n, displacement Δx_n): the work of the step
        before, ½ (F_{n−1} + F_n)·Δx_{n−1} (numpy over the replicated arrays: the same bits on
        every rank; collective on the first call: it measures the energy at x_n the ledger
        starts from)."""
        load, moved = sim.boxes.load_step(sim.last_dt)
        if self.energy0 is None:
            self.energy0 = mechanical_energy(sim)
        else:
            before, step = self.last_step
            self.work += float(np.sum(0.5 * (before + load) * step))
        self.last_step = (load, moved)

    def close(self, t, settlement, energy):
        """The row of the open passage ending at t: (t_start, t_end, peak, permanent, load peak
        or None, {"load_work", "energy_change"} [J] with ``energy`` [J] the mechanical energy
        now); opens the next one."""
        ledger = {"load_work": self.work, "energy_change": energy - self.energy0}
        self.work, self.energy0 = 0.0, energy
        row = (self.t_start, float(t), np.array(self.peak), np.asarray(settlement, float).copy(),
               None if self.load_peak is None else np.array(self.load_peak), ledger)
        self.p += 1
        self.start(t, settlement)
        if self.load_peak is not None:
            self.load_peak = [0.0] * len(self.load_peak)
        return row

    def state(self):
        out = {"ends": self.ends, "peaks": self.peaks, "reference": self.reference, "p": self.p,
               "t_start": self.t_start, "peak": self.peak, "peak_seen": self.peak_seen, "work": self.work,
               "energy0": self.energy0,
               "last_step": None if self.last_step is None else [a.tolist() for a in self.last_step]}
        return out if self.load_peak is None else {**out, "load_peak": self.load_peak}

    @classmethod
    def restore(cls, state):
        tr = cls(state["ends"], state["peaks"], state["reference"], loads="load_peak" in state)
        tr.p, tr.t_start, tr.peak, tr.peak_seen = int(state["p"]), state["t_start"], state["peak"], state["peak_seen"]
        tr.load_peak = state.get("load_peak")
        # a checkpoint from before the ledger: it starts at the first step after the restart
        tr.work, tr.energy0, last = state.get("work", 0.0), state.get("energy0"), state.get("last_step")
        tr.last_step = None if last is None else tuple(np.array(a, float) for a in last)
        return tr


def mechanical_energy(sim):
    """Mechanical energy [J] of the ballast (`pdem.checks.diagnostics.energy`'s ``total``: kinetic,
    rotational, gravitational and elastic, synchronised to the positions) and of the sleepers
    (`Boxes.energy`) (collective)."""
    return sim.energy()["total"] + sim.boxes.energy(sim.gravity, sim.last_dt)


def sleeper_sample(sim, tracker):
    """(/series row, settlement [n], force [n]) of the sleepers now (collective: energy and
    contacts are reduced over ranks)."""
    bx = sim.boxes
    s = tracker.settlement(bx.center[:, 2])
    force = bx.contact_force[:, 2].copy()
    e = sim.energy()
    load = 0.0
    ballast = 0.0
    for k in range(len(bx)):
        load += float(bx.load_force[k] @ bx.direction[k])
        ballast += float(force[k])
    row = {"step": sim.step, "time": sim.time, "dt": sim.dt, "applied_load": load, "ballast_force": ballast,
           "mean_settlement": float(np.sum(s) / len(s)), "kinetic_energy": e["kinetic"] + e["rotational"],
           "contacts_per_particle": sim.contacts_per_particle()}
    return row, s, force


def end_heights(boxes):
    """[n, 2] height z [m] of the middle of each box's base edge at its two ends along its own y
    axis (lo: local (0, −h_y, −h_z), hi: (0, h_y, −h_z)), the box turned by its rotation."""
    out = np.zeros((len(boxes), 2))
    for k in range(len(boxes)):
        h = boxes.half[k]
        for e, sign in enumerate((-1.0, 1.0)):
            out[k, e] = boxes.center[k, 2] + boxes.rotation[k, 2] @ np.array([0.0, sign * h[1], -h[2]])
    return out


def tilts(boxes):
    """[n, 2] tilt [rad] of each box about x (across the track: its hi end up is positive) and
    about y (along the track), from its rotation R (box → global): atan2(R_zy, R_zz) and
    atan2(−R_zx, R_zz), the angles of R = R_y R_x that tilt the box's z axis."""
    r = boxes.rotation
    return np.stack([np.arctan2(r[:, 2, 1], r[:, 2, 2]), np.arctan2(-r[:, 2, 0], r[:, 2, 2])], axis=1)


class TrackWriter:
    """``/series`` + ``/track`` rows and ``/passages`` of a results file (rank 0 writes).

    ``restart_step`` None starts the groups afresh (removing ``/track``, ``/passages`` and
    ``/forces`` of an earlier attempt); else the rows after that step and the passages after
    ``passages_done`` are cut."""

    def __init__(self, path, sleeper_x, comm, restart_step=None, passages_done=0):
        self.path = path
        self.active = comm.rank == 0
        self.series = series_writer(path, schema.TRACK_SERIES, comm, restart_step=restart_step, every=10**9)
        self.rows_s, self.rows_f = [], []
        if not self.active:
            return
        if restart_step is None:
            with h5py.File(path, "a") as f:
                for g in (schema.TRACK, schema.PASSAGES, schema.FORCES):
                    if g in f:
                        del f[g]
            schema.write_track(path, sleeper_x)
        else:
            cut_track(path, self.series.rows, passages_done)

    def append(self, row, settlement, force):
        self.series.append(row)
        if self.active:
            self.rows_s.append(np.asarray(settlement, float))
            self.rows_f.append(np.asarray(force, float))
            if len(self.rows_s) >= EVERY:
                self.flush()

    def flush(self):
        """Write the buffered rows of /series and /track (they stay the same length)."""
        self.series.flush()
        if self.active and self.rows_s:
            schema.append_track_rows(self.path, np.array(self.rows_s), np.array(self.rows_f))
            self.rows_s, self.rows_f = [], []

    def passage(self, t_start, t_end, peak, permanent, gap, load_peak=None, **more):
        if self.active:
            self.flush()
            schema.append_passages(self.path, t_start, t_end, peak, permanent, gap, load_peak=load_peak, **more)

    def close(self):
        self.flush()
        self.series.close()


def cut_track(path, n_rows, n_passages):
    """Cut ``/track`` rows to ``n_rows`` (the rows of /series kept) and ``/passages`` to
    ``n_passages`` (a run resumed from a checkpoint)."""
    with h5py.File(path, "a") as f:
        if schema.TRACK in f:
            for name in ("settlement", "force"):
                ds = f[schema.TRACK][name]
                ds.resize(min(ds.shape[0], n_rows), axis=0)
        if schema.PASSAGES in f:
            g = f[schema.PASSAGES]
            for name in g:
                ds = g[name]
                ds.resize(min(ds.shape[0], n_passages), axis=0)


def write_force_record(path, label, sim):
    """``/forces/<label>`` of the contacts now (collective; rank 0 writes, replacing a record of
    the same label written before a restart)."""
    forces = observables.contact_force_samples(sim)
    if sim.comm.rank == 0:
        schema.write_forces(path, label, step=sim.step, time=sim.time, replace=True, **forces)
