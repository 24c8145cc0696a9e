"""The settings of a simulation (a scene file's ``[simulation]`` table): one frozen record,
checked and made once by `pdem.build.scene.Scene`, handed to `pdem.simulation.Simulation`.

- ``dt``: `AUTO` (the stable step re-estimated every ``dt_interval`` steps, `pdem.timestep`) or
  a fixed Δt > 0 [s]; ``dt_safety`` (0, 1] the safety factor on the stiffness estimate,
  ``pwave_factor`` (0, 1] the fraction of the P-wave step taken before any contact;
- ``damping``: Cundall's λ_D in [0, 0.99]; ``gravity`` [m/s²];
- ``skin`` [m] (None: a quarter of the mean radius) of the neighbour lists;
- ``check_interval`` [steps] of the blow-up check, ``max_overlap_ratio`` (0, 1] the largest
  overlap over the smaller radius allowed, ``energy_check`` whether the mechanical energy may
  not grow, ``allow_initial_overlap`` whether bodies may start overlapping;
- ``slab_axis`` (0, 1, 2) along which ranks cut the domain; ``law`` the contact law's name;
  ``domain`` [[x, y, z] low, high] [m] the declared box bodies must stay in, or None;
  ``periodic`` (lo, hi) [m] along ``slab_axis``: the track has no ends (a body leaving at hi
  re-enters at lo, contacts across the ends by minimum image: `pdem.parallel.periodic_domain`),
  or None.

A running simulation changes its gravity (shaking), damping and overlap limit as its own state
(`Simulation.gravity`, ...); the settings themselves never change (a different setting is a
new record: `dataclasses.replace`). `as_dict` is the record as the scene's spec (checkpoints,
result files) holds it.
"""
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .build.validate import boolean, number, vectors

AUTO = "auto"  # dt re-estimated from the stiffnesses present (the one sentinel of dt)


@dataclass(frozen=True)
class SimulationSettings:
    dt: object
    damping: float
    gravity: tuple
    skin: object
    dt_safety: float
    dt_interval: int
    pwave_factor: float
    check_interval: int
    max_overlap_ratio: float
    energy_check: bool
    allow_initial_overlap: bool
    slab_axis: int
    law: str
    domain: object = None
    periodic: object = None

    def as_dict(self):
        """The settings as the scene spec holds them (JSON-able; ``domain`` and ``periodic`` only
        when declared)."""
        out = {name: getattr(self, name) for name in self.__dataclass_fields__ if name not in ("domain", "periodic")}
        out["gravity"] = list(self.gravity)
        if self.domain is not None:
            out["domain"] = [list(corner) for corner in self.domain]
        if self.periodic is not None:
            out["periodic"] = list(self.periodic)
        return out


def simulation_settings(*, dt, damping, gravity, skin, dt_safety, dt_interval, pwave_factor, check_interval,
                        max_overlap_ratio, energy_check, allow_initial_overlap, slab_axis, law, domain, periodic=None):
    """The checked `SimulationSettings` (`InputError` with one line naming the first bad value)."""
    if dt != AUTO:
        dt = number("dt", dt, 0.0, lo_open=True, allow="'auto' or a number > 0 [s]")
    checked = dict(
        dt=dt,
        damping=number("damping", damping, 0.0, 0.99, allow="in [0, 0.99] (Cundall's lambda_D)"),
        gravity=tuple(vectors("gravity", gravity, 1)[0].tolist()),
        skin=None if skin is None else number("skin", skin, 0.0, lo_open=True, allow="a length > 0 [m]"),
        dt_safety=number("dt_safety", dt_safety, 0.0, 1.0, lo_open=True, allow="in (0, 1]"),
        dt_interval=number("dt_interval", dt_interval, 1, integer=True, allow="an integer >= 1 [steps]"),
        pwave_factor=number("pwave_factor", pwave_factor, 0.0, 1.0, lo_open=True, allow="in (0, 1]"),
        check_interval=number("check_interval", check_interval, 1, integer=True, allow="an integer >= 1 [steps]"),
        max_overlap_ratio=number("max_overlap_ratio", max_overlap_ratio, 0.0, 1.0, lo_open=True, allow="in (0, 1]"),
        energy_check=boolean("energy_check", energy_check),
        allow_initial_overlap=boolean("allow_initial_overlap", allow_initial_overlap),
    )
    box = None
    if domain is not None:
        box = vectors("domain", domain, 2)
        if not np.all(box[1] > box[0]):
            raise InputError(f"domain = {box.tolist()}: must be [[x, y, z] low, [x, y, z] high] with low < high [m]")
        box = tuple(tuple(corner) for corner in box.tolist())
    if slab_axis not in (0, 1, 2) or isinstance(slab_axis, bool):
        raise InputError(f"slab_axis = {slab_axis!r}: must be 0, 1 or 2 (x, y, z)")
    period = None
    if periodic is not None:
        ends = _ends(periodic)
        period = (float(ends[0]), float(ends[1]))
    return SimulationSettings(**checked, slab_axis=slab_axis, law=law, domain=box, periodic=period)


def _ends(periodic):
    """[lo, hi] [m] of ``periodic``: two finite numbers, lo < hi."""
    msg = f"periodic = {periodic!r}: must be [lo, hi], two numbers with lo < hi [m] along slab_axis"
    if not isinstance(periodic, (list, tuple)) or len(periodic) != 2:
        raise InputError(msg)
    lo = number("periodic[0]", periodic[0], allow="a number [m]")
    hi = number("periodic[1]", periodic[1], allow="a number [m]")
    if not hi > lo:
        raise InputError(msg)
    return lo, hi
