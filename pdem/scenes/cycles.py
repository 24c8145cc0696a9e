"""Per-cycle record of a force-controlled box under a cyclic program (SPEC.md 2.3: sleeper
settlement and force every cycle).

`CycleRecorder` is fed samples ``(t, settlement, force, load)`` in increasing time, typically
every step or every few steps from the run driver (`CycleRecorder.sample_box(sim, box)` reads them
from a simulation). For each cycle k of a `pdem.boundaries.loads.Haversine` program (start t_k = start + k/f,
peak t_k + 1/(2f), end t_k + 1/f) it records, from the first sample at or after each instant:
the settlement at the start, at the peak and at the end, and over the samples in [t_k, t_k+1):
the largest and smallest force of the spheres on the box and of the applied load, the
settlement at the sample of the largest force (``settlement_at_force_max``) and the largest
settlement (``settlement_max``). A record is complete (appended to ``records``) at the first
sample at or after the end of its cycle. All settlements of a recorder are measured from the
same zero (``reference``). A caller may pass ``split`` (a dict of extra values, e.g. the force
on the box's bottom face and on its sides) with the peak sample (`CycleRecorder.at_peak` says
which one it is): it is stored in the record as ``<name>_peak``.

Settlement [m] is the displacement of the box centre along the load direction since a
reference position (positive = moving with the load, e.g. down for a sleeper); force [N] is the
ballast reaction along −direction (positive when the ballast pushes back). Imports only numpy.
"""
from math import isnan

import numpy as np

FIELDS = ("cycle", "t_start", "settlement_start", "settlement_peak", "settlement_end", "force_max", "force_min",
          "load_max", "load_min", "n_samples", "settlement_at_force_max", "settlement_max")


class CycleRecorder:
    """Records one row per completed cycle of `program` (anything with ``start``, ``frequency``,
    ``cycles``)."""

    def __init__(self, program):
        self.start = float(program.start)
        self.frequency = float(program.frequency)
        self.cycles = int(program.cycles)
        self.records = []
        self._k = 0
        self._bounds = self._times(0)  # (start, peak, end) instants of cycle _k
        self._open = None
        self.reference = None  # box centre the settlement is measured from (sample_box)
        self._axes = {}  # box -> (component, sign) of an axis-aligned load direction, or None

    def _times(self, k):
        t0 = self.start + k / self.frequency
        return t0, self.start + (k + 0.5) / self.frequency, self.start + (k + 1) / self.frequency

    def _new(self, k):
        return {"cycle": k, "t_start": self._times(k)[0], "settlement_start": np.nan, "settlement_peak": np.nan,
                "settlement_end": np.nan, "force_max": -np.inf, "force_min": np.inf, "load_max": -np.inf,
                "load_min": np.inf, "n_samples": 0, "settlement_at_force_max": np.nan, "settlement_max": -np.inf}

    def at_peak(self, t):
        """Whether a sample at time t will be the peak sample of the open cycle (the first at or
        after its peak instant): the moment to pass ``split`` to `sample`."""
        if self._k >= self.cycles:
            return False
        t0, tp, t1 = self._bounds
        rec = self._open
        return tp <= t < t1 and (rec is None or isnan(rec["settlement_peak"]))

    def sample(self, t, settlement, force, load=np.nan, split=None):
        """Add one sample; returns the record of a cycle this sample completed, else None.
        ``split``: extra values of the peak sample (see the module docstring)."""
        rec = self._open
        if rec is not None and t < self._bounds[2] and (t < self._bounds[1] or not isnan(rec["settlement_peak"])):
            _accumulate(rec, settlement, force, load)  # inside the open cycle, not at its peak or end
            return None
        done = None
        while self._k < self.cycles:
            t0, tp, t1 = self._bounds
            if t < t0:
                return done
            rec = self._open if self._open is not None else self._new(self._k)
            self._open = rec
            if t >= t1:  # this sample closes the cycle (and may open the next)
                rec["settlement_end"] = settlement
                if isnan(rec["settlement_start"]):
                    rec["settlement_start"] = settlement
                if isnan(rec["settlement_peak"]):
                    rec["settlement_peak"] = settlement
                self.records.append(rec)
                done = rec
                self._open = None
                self._k += 1
                self._bounds = self._times(self._k)
                continue
            if isnan(rec["settlement_start"]):
                rec["settlement_start"] = settlement
            if t >= tp and isnan(rec["settlement_peak"]):
                rec["settlement_peak"] = settlement
                for name, value in (split or {}).items():
                    rec[f"{name}_peak"] = float(value)
            _accumulate(rec, settlement, force, load)
            return done
        return done

    def sample_box(self, sim, box=0, split=None):
        """Sample box `box` of a simulation: settlement from the centre at the first call, force of
        the spheres on the box and applied load, both projected on the load direction."""
        bx = sim.boxes
        if self.reference is None:
            self.reference = bx.center[box].copy()
        if box not in self._axes:
            self._axes[box] = _axis(bx.direction[box])
        axis = self._axes[box]
        if axis is None:
            d = bx.direction[box]
            settlement = float((bx.center[box] - self.reference) @ d)
            force = float(-(bx.contact_force[box] @ d))
            load = float(bx.load_force[box] @ d)
        else:  # the same values as the dot products above (the other products are zeros), without numpy
            k, sign = axis
            settlement = sign * (float(bx.center[box, k]) - float(self.reference[k]))
            force = -(sign * float(bx.contact_force[box, k]))
            load = sign * float(bx.load_force[box, k])
        return self.sample(sim.time, settlement, force, load, split)

    def table(self):
        """The completed records as a dict of numpy columns (``FIELDS`` and the ``split`` names
        given, nan in a record without them)."""
        names = list(FIELDS) + sorted({k for r in self.records for k in r} - set(FIELDS))
        return {k: np.array([r.get(k, np.nan) for r in self.records], np.float64) for k in names}

    def state(self):
        """JSON-able state for a checkpoint (``restore`` is its inverse)."""
        return {"k": self._k, "open": self._open, "records": self.records,
                "reference": None if self.reference is None else self.reference.tolist()}

    def restore(self, state):
        self._k = int(state["k"])
        self._bounds = self._times(self._k)
        blank = self._new(0)  # records of a checkpoint written before a field existed get nan
        self._open = None if state["open"] is None else {**blank, "settlement_max": np.nan, **state["open"]}
        self.records = [{**blank, "settlement_max": np.nan, **r} for r in state["records"]]
        self.reference = None if state["reference"] is None else np.asarray(state["reference"], np.float64)
        return self


def _accumulate(rec, settlement, force, load):
    """Add a sample inside the cycle of ``rec`` to its extremes and count."""
    if force > rec["force_max"]:
        rec["settlement_at_force_max"] = settlement
    rec["force_max"] = max(rec["force_max"], force)
    rec["settlement_max"] = max(rec["settlement_max"], settlement)
    rec["force_min"] = min(rec["force_min"], force)
    if not isnan(load):
        rec["load_max"] = max(rec["load_max"], load)
        rec["load_min"] = min(rec["load_min"], load)
    rec["n_samples"] += 1


def _axis(direction):
    """(component, ±1.0) if ``direction`` is a coordinate axis (one component ±1, the others 0), else None."""
    nz = np.flatnonzero(direction)
    if len(nz) == 1 and abs(float(direction[nz[0]])) == 1.0:
        return int(nz[0]), float(direction[nz[0]])
    return None
