"""The ballast grain of a scene's ``[<scene>.clumps]`` table: one parser for the box test
(`pdem.scenes.box_test`, rigid clumps), the oedometer (`pdem.scenes.oedometer`, rigid or
breakable) and the track section (`pdem.scenes.track`, rigid or breakable).

The table has the keys of a ``[[clumps]]`` grain (`pdem.build.config.CLUMP_KEYS`: ``shape`` and
its ``radii``, ``member_radius``, ``member_spacing`` or ``members`` [m]; ``mass_model``,
``discretization``, ``samples`` of a rigid clump; ``breakable`` and ``stress_free`` of a
breakable one) without those of a cloud (material, box, count, seed, velocity: the scene pours
the grains). A breakable grain's members are free spheres joined by bonds of the cohesive law
(docs/clumps.md), so it needs ``simulation.law = "cohesive"``.

`grain_spec` returns the checked table with ``members`` [k, 3] (member centres about the grain's
centre [m]), ``member_radii`` [k] [m], ``breakable``, ``stress_free``, ``mass_model``,
``discretization`` and ``samples`` filled in; `grain_reach` the radius [m] of the sphere about
the grain's centre that holds it (the circumscribed radius).
"""
import numpy as np

from ...build.config import CLUMP_KEYS, check_keys, grain_shape
from ...build.validate import boolean
from ...errors import InputError

GRAIN_KEYS = CLUMP_KEYS - {"material", "box_lo", "box_hi", "count", "seed", "vel"}  # rigid or breakable
RIGID_GRAIN_KEYS = GRAIN_KEYS - {"breakable", "stress_free"}


def grain_spec(doc, table, label, breakable=True):
    """The checked grain of ``table`` (the scene's ``[<label>]``; one-line InputError naming
    ``label.key``); ``breakable`` False: rigid clumps only (the keys ``breakable`` and
    ``stress_free`` are unknown)."""
    check_keys(label, table, GRAIN_KEYS if breakable else RIGID_GRAIN_KEYS, ("shape",))
    pos, radius = grain_shape(table, label)
    g = dict(table)
    g["breakable"] = boolean(f"{label}.breakable", g.get("breakable", False))
    g["stress_free"] = boolean(f"{label}.stress_free", g.get("stress_free", True))
    law = doc.get("simulation", {}).get("law", "linear")
    if g["breakable"] and law != "cohesive":
        raise InputError(f"{label}.breakable = true: bonds need simulation.law = \"cohesive\", got {law!r}")
    g["members"], g["member_radii"] = pos, radius
    g["mass_model"] = g.get("mass_model", "members")
    g["discretization"] = g.get("discretization", 0)
    g["samples"] = g.get("samples", 0)
    return g


def grain_reach(g):
    """Radius [m] of the smallest sphere about the grain's centre holding all its members."""
    pos, radius = g["members"], g["member_radii"]
    return float(np.max(np.sqrt(np.einsum("ij,ij->i", pos, pos)) + radius))
