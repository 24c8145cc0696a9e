"""Helpers shared by the Yade comparison tests: rebuild a pdem scene from a reference JSON
(tests/validation/yade_reference/data, format in NOTES.md) and read pdem's state in Yade's terms.

Yade's ids map to pdem as follows: spheres are added in increasing Yade id, so the k-th sphere of
the JSON gets gid k; walls and facets keep their order (index in `sim.walls` / `sim.facets`).
"""
import json
from pathlib import Path

import numpy as np

from pdem import Scene

DATA = Path(__file__).resolve().parent / "data"


def load(case):
    with open(DATA / f"{case}.json") as fh:
        return json.load(fh)


def build_scene(d):
    """A pdem Scene equivalent to the JSON's Yade scene; returns (scene, {yade id: gid}, {yade id: (kind, index)})."""
    # Yade's scenes start in contact with their wall or facet (a sphere at rest on it, overlap ~1e-7 m)
    sc = Scene(dt=d["dt"], damping=d["damping"], gravity=d["gravity"], allow_initial_overlap=True)
    mats = {}
    for m in sorted(d["materials"], key=lambda m: m["id"]):
        mats[m["id"]] = sc.material(density=m["density"], young=m["young"], poisson=m["poisson"],
                                    friction_angle=m["frictionAngle"])
    bodies = sorted(d["bodies"], key=lambda b: b["id"])
    sph = [b for b in bodies if b["kind"] == "sphere"]
    gids = sc.add_spheres([b["pos"] for b in sph], [b["radius"] for b in sph], [mats[b["material"]] for b in sph],
                          fixed=[b["fixed"] for b in sph], vel=[b["vel"] for b in sph],
                          angvel=[b["angVel"] for b in sph])
    gid_of = {b["id"]: int(g) for b, g in zip(sph, gids)}
    other = {}
    for b in bodies:
        if b["kind"] == "wall":
            assert b["fixed"] and b["vel"] == [0.0, 0.0, 0.0]
            other[b["id"]] = ("wall", sc.add_wall(b["axis"], b["position"], mats[b["material"]], sense=b["sense"]))
        elif b["kind"] == "facet":
            assert b["fixed"] and b["vel"] == [0.0, 0.0, 0.0]
            other[b["id"]] = ("facet", sc.add_facet(b["vertices_input"], mats[b["material"]]))
    return sc, gid_of, other


def rows_by_gid(sim):
    p = sim.particles
    return {int(g): k for k, g in enumerate(p.gid[: p.n_local])}


def set_yade_mass(sim, d, gid_of):
    """Give every sphere Yade's mass and inertia (the JSON's values, i.e. V·ρ with V = (4./3)·π·r**3
    evaluated in Python floats). See test_sphere_mass_inertia_bitwise for why this is needed."""
    row = rows_by_gid(sim)
    p = sim.particles
    for b in d["bodies"]:
        if b["kind"] == "sphere":
            k = row[gid_of[b["id"]]]
            p.mass[k] = b["mass"]
            p.inertia[k] = b["inertia"][0]


def real_contacts(sim, gid_of, other):
    """pdem's real contacts keyed like Yade's interactions (id1, id2) -> dict of Yade-named quantities,
    read through the public API (`Simulation.contacts`).

    Yade: normalForce = kn·pen·n (force on body 2), shearForce = Fs, force on body 1 = −Fn − Fs."""
    yade_of_gid = {g: i for i, g in gid_of.items()}
    ids = {kind: {idx: i for i, (k, idx) in other.items() if k == kind} for kind in ("wall", "facet")}
    out = {}
    for kind in sim.kinds:
        c = sim.contacts(kind.name)
        boundary = kind.name.split("_", 1)[1]
        for q in range(len(c["gid1"])):
            sphere = yade_of_gid[int(c["gid1"][q])]
            if kind.sphere_pair:
                key = (sphere, yade_of_gid[int(c["gid2"][q])])
            else:
                key = (ids[boundary][int(c["index"][q])], sphere)
            out[key] = {"normalForce": c["normal_force"][q], "shearForce": c["shear_force"][q],
                        "penetrationDepth": c["overlap"][q], "normal": c["normal"][q], "kn": c["kn"][q],
                        "ks": c["ks"][q], "tangensOfFrictionAngle": c["tan_phi"][q], "force_on_2": c["force"][q]}
    return out


def rel_err(a, b):
    """max |a − b| / max |b| (0 when both are exactly equal)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if np.array_equal(a, b):
        return 0.0
    s = float(np.max(np.abs(b)))
    return float(np.max(np.abs(a - b))) / (s if s > 0 else 1.0)
