"""pdem's rigid clumps and cohesive bonds vs real Yade 2023.02a (data/clump_*.json, bond_*.json;
NOTES.md "Clumps", "Cohesive bonds", "Facts for the implementer").

- Construction: mass, centre, principal moments, orientation quaternion and members' relPos of
  100 random clumps, 30 clumps whose radius has pow(r, 2) != r*r and the drop clump (Yade's
  discretization 0, and 5, 10, 20 = pdem's "grid" mass model): bit-identical.
- clump_drop (damping 0), clump_drop_damped (0.3), clump_spin (free, angular momentum about a
  non-principal axis): every record bit-identical (members' pos, vel, angVel, force, torque;
  the clump's pos, vel, angVel, angMom, ori and member-summed force and torque; every wall
  contact's forces, overlap, normal, kn, ks, tan φ). Each member has at most one contact, so the
  summation order cannot matter (YADE_MODEL.md §10).
- bond_stiffness: kn, ks, tan φ, normal and shear adhesion of CohFrictPhys (and kn, ks of
  FrictPhys) for 100 random pairs: bit-identical.
- bond_tension, bond_shear, bond_dynamic (pdem's bond with stress_free=False = Yade's
  setCohesionNow bond, loaded by its initial overlap): every record bit-identical (bodies, and
  the interaction's normal and shear force, overlap, normal, kn, ks, tan φ, adhesions), so the
  tensile break (867), the shear break under compression (1158) and under tension (899/900) come
  at Yade's iterations. pdem makes the bond when the scene is built, Yade in iteration 1 (the
  same state after it); at iteration 0 Yade lists no interaction, so that record's interaction
  list is not compared.
"""
import numpy as np
import pytest
import yade_json

from pdem import Scene
from pdem.bodies.clump_properties import clump_properties
from pdem.contact import cohesive, linear

pytestmark = pytest.mark.validate

MEMBER = (("pos", "pos"), ("vel", "vel"), ("angVel", "angvel"), ("force", "force"), ("torque", "torque"))
CLUMP = (("pos", "pos"), ("vel", "vel"), ("angVel", "angvel"), ("angMom", "angmom"), ("force", "force"),
         ("torque", "torque"))


def quat(q):
    return [q["w"], q["x"], q["y"], q["z"]]


def construction_errors(rec, density, label):
    members = [(m["centre"], m["radius"]) for m in rec["member_inputs"]]
    d = rec.get("discretization", 0)
    got = clump_properties([c for c, _ in members], [r for _, r in members], density,
                           "grid" if d > 0 else "members", d)
    bad = [f"{label} {k}" for k, want in (("mass", [rec["mass"]]), ("pos", rec["pos"]), ("inertia", rec["inertia"]),
                                          ("ori", quat(rec["ori"])))
           if list(np.atleast_1d(got[k])) != list(want)]
    for mid, rp in zip(rec["memberIds"], got["rel_pos"]):
        if list(rp) != rec["members"][str(mid)]["relPos"]:
            bad.append(f"{label} relPos {mid}")
    if got["aspherical"] != rec["aspherical"]:
        bad.append(f"{label} aspherical")
    return bad


def test_clump_construction_bitwise():
    d = yade_json.load("clump_construction")
    rho = d["materials"][0]["density"]
    bad = []
    for name in ("random", "pow2", "drop"):
        for k, rec in enumerate(d[name]):
            bad += construction_errors(rec, rho, f"{name}[{k}] d={rec.get('discretization', 0)}")
    assert {r["discretization"] for r in d["drop"]} == {0, 5, 10, 20}
    assert len(d["random"]) == 100 and len(d["pow2"]) == 30
    assert not bad, bad[:10]


def clump_scene(d):
    """The JSON's clump scene through the public API: (scene, {Yade member id: gid}, clump body)."""
    sc = Scene(dt=d["dt"], damping=d["damping"], gravity=d["gravity"])
    mats = {
        m["id"]: sc.material(
            density=m["density"], young=m["young"], poisson=m["poisson"], friction_angle=m["frictionAngle"]
        )
        for m in sorted(d["materials"], key=lambda m: m["id"])
    }
    bodies = sorted(d["bodies"], key=lambda b: b["id"])
    for b in bodies:
        if b["kind"] == "wall":
            sc.add_wall(b["axis"], b["position"], mats[b["material"]], sense=b["sense"])
    clump = next(b for b in bodies if b["kind"] == "clump")
    members = [b for b in bodies if b["kind"] == "sphere"]
    assert all(b["clumpId"] == clump["id"] for b in members)
    sc.add_clump([b["pos"] for b in members], [b["radius"] for b in members], mats[members[0]["material"]],
                 vel=clump["vel"], angvel=clump["angVel"], angmom=clump["angMom"])
    return sc, {b["id"]: k for k, b in enumerate(members)}, clump


@pytest.mark.parametrize("case", ["clump_drop", "clump_drop_damped", "clump_spin"])
def test_clump_scene_bitwise(case):
    d = yade_json.load(case)
    sc, gid_of, clump = clump_scene(d)
    sim = sc.build()
    assert sim.dt == d["dt"]
    walls = {b["id"]: ("wall", 0) for b in d["bodies"] if b["kind"] == "wall"}
    c0 = sim.clumps_table()
    for k, want in (("mass", [clump["mass"]]), ("pos", clump["pos"]), ("inertia", clump["inertia"]),
                    ("ori", quat(clump["ori"]))):
        assert list(np.atleast_1d(c0[k][0])) == list(want), k
    n_contact = 0
    for rec in d["records"]:
        sim.run(rec["iter"] - sim.step)
        p = sim.particles
        row = yade_json.rows_by_gid(sim)
        c = sim.clumps_table()
        bad = []
        for bid, bs in rec["bodies"].items():
            if int(bid) == clump["id"]:
                bad += [f"clump {y}" for y, q in CLUMP if not np.array_equal(c[q][0], bs[y])]
                if not np.array_equal(c["ori"][0], quat(bs["ori"])):
                    bad.append("clump ori")
            else:
                k = row[gid_of[int(bid)]]
                bad += [f"member {bid} {y}" for y, q in MEMBER if not np.array_equal(getattr(p, q)[k], bs[y])]
        got = yade_json.real_contacts(sim, gid_of, walls)
        want = {(i["id1"], i["id2"]): i for i in rec["interactions"]}
        if set(got) != set(want):
            bad.append(f"contacts {sorted(got)} != {sorted(want)}")
        else:
            for key, i in want.items():
                bad += [f"contact {key} {f}" for f in ("normalForce", "shearForce", "normal", "penetrationDepth", "kn",
                                                        "ks", "tangensOfFrictionAngle")
                        if not np.array_equal(got[key][f], i[f])]
        n_contact += bool(want)
        assert not bad, f"{case} O.iter {rec['iter']}: not bit-identical to Yade: {bad[:6]}"
    assert sim.step == d["records"][-1]["iter"]
    assert n_contact > 50 or case == "clump_spin"


def test_bond_stiffness_bitwise():
    d = yade_json.load("bond_stiffness")
    bad = []
    for k, (pair, coh, fr) in enumerate(zip(d["pairs"], d["CohFrictPhys"], d["FrictPhys"])):
        a, b = pair["a"], pair["b"]
        props = np.array([[m["young"], m["poisson"], m["frictionAngle"], m["normalCohesion"], m["shearCohesion"]]
                          for m in (a, b)])
        params, history = cohesive.bond_rows(props, [0], [1], [coh["refR1"]], [coh["refR2"]], [0.0], False)
        got = {"kn": params[0, 0], "ks": params[0, 1], "tangensOfFrictionAngle": params[0, 2],
               "normalAdhesion": history[0, cohesive.ADH_N], "shearAdhesion": history[0, cohesive.ADH_T]}
        bad += [f"pair {k} CohFrictPhys {f}" for f, v in got.items() if v != coh[f]]
        kn, ks, tphi = linear.stiffnesses.py_func(a["young"], a["poisson"], a["frictionAngle"], fr["refR1"],
                                                  b["young"], b["poisson"], b["frictionAngle"], fr["refR2"])
        bad += [f"pair {k} FrictPhys {f}" for f, v in (("kn", kn), ("ks", ks), ("tangensOfFrictionAngle", tphi))
                if v != fr[f]]
    assert len(d["pairs"]) == 100
    assert not bad, bad[:10]


def bond_scene(d):
    """The JSON's two bonded spheres (sphere 1 blocked with a velocity, or both free)."""
    sc = Scene(dt=d["dt"], damping=d["damping"], gravity=d["gravity"], law="cohesive", allow_initial_overlap=True)
    mats = {m["id"]: sc.material(density=m["density"], young=m["young"], poisson=m["poisson"],
                                 friction_angle=m["frictionAngle"], normal_cohesion=m["normalCohesion"],
                                 shear_cohesion=m["shearCohesion"])
            for m in sorted(d["materials"], key=lambda m: m["id"])}
    assert all(m["fragile"] and not m["momentRotationLaw"] for m in d["materials"])
    bodies = sorted(d["bodies"], key=lambda b: b["id"])
    sc.add_spheres([b["pos"] for b in bodies], [b["radius"] for b in bodies], [mats[b["material"]] for b in bodies],
                   fixed=[b["fixed"] for b in bodies], vel=[b["vel"] for b in bodies],
                   angvel=[b["angVel"] for b in bodies])
    sc.add_bonds([[0, 1]], stress_free=False)
    return sc, bodies


BOND = (("normalForce", "normal_force"), ("shearForce", "shear_force"), ("penetrationDepth", "overlap"),
        ("normal", "normal"), ("kn", "kn"), ("ks", "ks"), ("tangensOfFrictionAngle", "tan_phi"),
        ("normalAdhesion", "normal_adhesion"), ("shearAdhesion", "shear_adhesion"), ("unp", "unp"))


@pytest.mark.parametrize("case, events", [("bond_tension", {"deleted": 867}),
                                          ("bond_shear", {"cohesion_broken": 1158}),
                                          ("bond_dynamic", {"cohesion_broken": 899, "deleted": 900})])
def test_bond_scene_bitwise(case, events):
    d = yade_json.load(case)
    assert {e["event"]: e["iter"] for e in d["interaction_events"] if e["event"] != "created"} == events
    sc, bodies = bond_scene(d)
    sim = sc.build()
    yade_json.set_yade_mass(sim, d, {b["id"]: b["id"] for b in bodies})
    seen = set()
    for rec in d["records"]:
        sim.run(rec["iter"] - sim.step)
        p = sim.particles
        row = yade_json.rows_by_gid(sim)
        bad = [f"body {bid} {y}" for bid, bs in rec["bodies"].items() for y, q in MEMBER
               if not np.array_equal(getattr(p, q)[row[int(bid)]], bs[y])]
        c = sim.contacts("sphere_sphere")
        if rec["iter"] > 0:
            if len(c["gid1"]) != len(rec["interactions"]):
                bad.append(f"{len(c['gid1'])} contacts, Yade {len(rec['interactions'])}")
            elif len(c["gid1"]):
                i = rec["interactions"][0]
                bad += [f"bond {y}" for y, q in BOND if not np.array_equal(c[q][0], i[y])]
                assert (c["created"][0], i["iterMadeReal"]) == (0, 0)
                seen.add("broken" if i["cohesionBroken"] else "intact")
            else:
                seen.add("deleted")
        assert not bad, f"{case} O.iter {rec['iter']}: not bit-identical to Yade: {bad[:6]}"
    assert "intact" in seen and ("deleted" in seen or "broken" in seen), seen
