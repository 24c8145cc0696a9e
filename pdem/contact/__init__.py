"""Contact laws (one module per law) and geometries; `LAWS` names the laws a scene can select.

A law module provides: ``NAME``; ``N_PARAMS`` (per-contact parameters fixed at creation, Yade's
Ip2) and ``HISTORY`` (per-contact columns carried from step to step); ``MOMENT`` (whether
``force`` returns a rolling/twisting moment); ``MATERIAL_KEYS`` (material key -> (what is
allowed, test); a material's law properties are these keys, in this order); ``PWAVE_KEY`` (the
modulus key of the P-wave time-step estimate, or None) and ``FRICTION_KEY`` (or None); the
njit-inline ``ip2(props, ma, mb, ra, rb, m1, m2, params, p)`` and ``force(...)`` called by the
generated pair loop (`pdem.contact.loops`); and the numpy-level ``stiffness(params, history,
overlap) -> (kn, ks)`` (time step), ``elastic_energy(params, history, overlap)`` (energy check),
``contact_forces(params, history, overlap, normal) -> (normal force, shear force)`` and
``PARAM_NAMES`` (name -> parameter column) for `Simulation.contacts`, and, with a friction key,
``set_friction(n, mat_i, mat_j, props, params)``. ``STIFFNESS_KEYS``: the material keys the
law's stiffnesses are proportional to (a preparation at reduced stiffness scales them:
`stiffness_keys`, `Simulation.scale_stiffness`).

Added for the viscous and Hertz–Mindlin laws (issue 12):

- ``CONTACT_POINT_VELOCITY``: if true, the loop passes the relative velocity at the contact point
  without Yade's ratcheting factor α (`geometry` ``contact_velocity``), so ``vn`` is the true
  approach velocity (negative while approaching) that a dashpot needs; false keeps Yade's
  (linear law, bit for bit).
- ``PAIR_KEYS`` and ``combine(key, a, b)``: material keys that may be set per pair of materials
  (`pdem.build.materials.MaterialTable.set_pair`; unset pairs get ``combine``); ``ip2`` reads them from
  the pair columns of ``props`` (`pdem.build.materials.pair_column`).
- ``dt_stiffness(params, history, overlap) -> (kn, ks)``: what the automatic time step sees;
  a damped law raises its stiffness by 1/(sqrt(1+η²) − η)² (the damped critical step) and a
  rolling law adds its rolling stiffness (`pdem.timestep`).
- ``pwave_modulus(values, radius)``: the modulus [Pa] of the P-wave step of each body from its
  material's ``PWAVE_KEY`` value (E itself, or k_n/r for a law whose materials give stiffness).
- ``force`` gets ``wrx, wry, wrz`` = ω2 − ω1 (relative spin) and returns the moment on body 1;
  with ``MOMENT`` the loop applies it as a couple (+m on body 1, −m on body 2).

Optional (a law without them behaves as if they were absent/False): ``TENSILE`` and the
njit-inline ``holds(p, fresh, pen, params, history)`` (real contacts with negative overlap live
on while ``holds``; see `pdem.contact.loops`), ``CONTACT_POINT_LEVER`` (torques about the
contact point), ``STIFFNESS_PARAMS`` (the parameter columns proportional to ``STIFFNESS_KEYS``,
for `Simulation.scale_stiffness` with ``rescale_existing``), ``HISTORY_NAMES`` (name -> history column, also reported by
`Simulation.contacts`) and, for laws with bonds, ``bond_rows(props, mat1, mat2, r1, r2, pen,
stress_free) -> (params, history)``, ``bond_strengths(props, mat) -> (c_N, c_T)`` and
``intact(params, history) -> bool mask`` (`pdem.bodies.bonds`, `pdem.bodies.fragments`).

A law may build its ``ip2`` and ``force`` from the shared sub-models of
`pdem.contact.submodels` (pair stiffness, frictional Ip2, shear spring, Coulomb cap, rolling
resistance) instead of writing them again.

A new law is its own module plus one line in `LAWS` (or `register_law(module)` at run time, as
tests/unit/test_law_plugin.py does). Importing this package compiles nothing.
"""
from importlib import import_module
from types import ModuleType

from ..errors import InputError

LAWS = {"linear": "pdem.contact.linear", "viscous": "pdem.contact.viscous",
        "hertz_mindlin": "pdem.contact.hertz_mindlin", "cohesive": "pdem.contact.cohesive"}
REQUIRED = ("NAME", "N_PARAMS", "HISTORY", "MOMENT", "MATERIAL_KEYS", "PWAVE_KEY", "FRICTION_KEY", "ip2", "force",
            "stiffness", "elastic_energy", "contact_forces", "PARAM_NAMES", "CONTACT_POINT_VELOCITY", "PAIR_KEYS",
            "combine", "dt_stiffness", "pwave_modulus", "STIFFNESS_KEYS")


def register_law(module):
    """Make a law module selectable by its ``NAME``; returns the module."""
    missing = [k for k in REQUIRED if not hasattr(module, k)]
    if missing:
        raise InputError(f"law {getattr(module, 'NAME', module)!r}: lacks {', '.join(missing)}")
    LAWS[module.NAME] = module
    return module


def get_law(name):
    """The law module called ``name`` (or ``name`` itself if it is a module)."""
    if isinstance(name, ModuleType):
        return register_law(name)
    if name not in LAWS:
        raise InputError(f"simulation.law = {name!r}: unknown contact law; known: {', '.join(sorted(LAWS))}")
    law = LAWS[name]
    if isinstance(law, str):
        law = LAWS[name] = import_module(law)
    return law


def stiffness_keys(law=None):
    """The material keys a stiffness is proportional to: the ``STIFFNESS_KEYS`` of ``law`` (a name
    or module), or, without one, their union over every registered law (sorted)."""
    if law is not None:
        return tuple(get_law(law).STIFFNESS_KEYS)
    return tuple(sorted({k for name in list(LAWS) for k in get_law(name).STIFFNESS_KEYS}))
