"""pack_settle: LIGGGHTS dumps + log -> data/pack_settle.json (called by convert.py)."""
import json
import re
from pathlib import Path

import lig_dump
import pack_generate
from convert import DATA, HERE, PACK_MATERIALS, liggghts_version, read_data_file

WALLS = [  # fix id, primitive, position, unit normal pointing into the box (= direction of the wall force)
    ("wz0", "zplane", 0.0, [0.0, 0.0, 1.0]),
    ("wx0", "xplane", 0.0, [1.0, 0.0, 0.0]),
    ("wx1", "xplane", 0.06, [-1.0, 0.0, 0.0]),
    ("wy0", "yplane", 0.0, [0.0, 1.0, 0.0]),
    ("wy1", "yplane", 0.06, [0.0, -1.0, 0.0]),
]
WALL_COL = {"wz0": "f_force_wz0[3]", "wx0": "f_force_wx0[1]", "wx1": "f_force_wx1[1]", "wy0": "f_force_wy0[2]",
            "wy1": "f_force_wy1[2]"}


def read_thermo(log):
    rows, cols, on = {}, None, False
    for line in Path(log).read_text().splitlines():
        t = line.split()
        if t[:2] == ["Step", "Atoms"]:
            cols, on = t, True
            continue
        if on:
            if not t or not re.fullmatch(r"\d+", t[0]):
                on = False
                continue
            rows[int(t[0])] = dict(zip(cols, [float(v) for v in t]))
    return rows


def convert(a):
    run = Path(a.run)
    snaps = lig_dump.read_dump(run / "pack_atoms.dump")
    pairs = {p["step"]: p for p in lig_dump.read_dump(run / "pack_pairs.dump")}
    thermo = read_thermo(run / "log.liggghts")
    init = read_data_file(HERE / "pack_settle.data")
    gen = pack_generate.generate()
    first = lig_dump.by_id(snaps[0])
    bodies = []
    for i in sorted(init):
        b = init[i]
        g = gen[i - 1]
        assert g["pos"] == b["pos"] and g["diameter"] == b["diameter"], i
        bodies.append({"id": i, "type": b["type"], "radius": first[i]["radius"], "diameter_in_data_file": b["diameter"],
                       "density": b["density"], "mass": first[i]["mass"], "pos": b["pos"], "vel": b["vel"],
                       "omega": b["omega"]})
    ids = sorted(init)
    records = []
    for s in snaps:
        A = lig_dump.by_id(s)
        th = thermo[s["step"]]
        rec = {"step": s["step"], "time": s["step"] * 1.0e-5,
               "ke_translational": th["KinEng"], "ke_rotational": th["erot"],
               "ke_total": th["KinEng"] + th["erot"],
               "n_pair_contacts": int(round(th["ncpa"])) // 2,
               "n_wall_contacts": {w: sum(1 for i in ids if A[i][WALL_COL[w]] != 0.0) for w, *_ in WALLS},
               "floor_force_on_particles": [th["floor[1]"], th["floor[2]"], th["floor[3]"]]}
        rec["atoms"] = {
            "pos": [[A[i]["x"], A[i]["y"], A[i]["z"]] for i in ids],
            "vel": [[A[i]["vx"], A[i]["vy"], A[i]["vz"]] for i in ids],
            "omega": [[A[i]["omegax"], A[i]["omegay"], A[i]["omegaz"]] for i in ids],
            "force": [[A[i]["fx"], A[i]["fy"], A[i]["fz"]] for i in ids],
            "torque": [[A[i]["tqx"], A[i]["tqy"], A[i]["tqz"]] for i in ids],
            "floor_force": [[A[i]["f_force_wz0[1]"], A[i]["f_force_wz0[2]"], A[i]["f_force_wz0[3]"]] for i in ids],
            "n_pair_contacts": [int(A[i]["c_cpa"]) for i in ids],
        }
        p = pairs.get(s["step"])
        rec["pairs"] = [{"id1": int(r[0]), "id2": int(r[1]), "shear": r[3:6], "overlap": r[6]}
                        for r in (p["rows"] if p else [])]
        assert len(rec["pairs"]) == rec["n_pair_contacts"], (s["step"], len(rec["pairs"]), rec["n_pair_contacts"])
        records.append(rec)
    out = {
        "case": "pack_settle",
        "liggghts": liggghts_version(run),
        "deck": "scripts/in.pack_settle", "data_file": "scripts/pack_settle.data",
        "generator": "scripts/pack_generate.py",
        "generation": {"seed": pack_generate.SEED, "grid": pack_generate.GRID, "z0": pack_generate.Z0,
                       "dz": pack_generate.DZ, "r_min": pack_generate.R_MIN, "r_max": pack_generate.R_MAX,
                       "jitter": pack_generate.JITTER, "layers": pack_generate.N_LAYERS},
        "command": "liggghts -in in.pack_settle -var data pack_settle.data",
        "units": "si", "dt": 1.0e-5, "nsteps": snaps[-1]["step"], "record_every": snaps[1]["step"] - snaps[0]["step"],
        "gravity": [0.0, 0.0, -9.81], "newton": "off", "atom_sort": "off", "neighbor_skin": 0.002,
        "box": {"lo": [0.0, 0.0, 0.0], "hi": [0.06, 0.06, 0.12]},
        "pair_style": "gran model hertz tangential history",
        "wall_model": "fix wall/gran model hertz tangential history primitive type 2 ... store_force yes",
        "model_settings": {"tangential_damping": "on (default)", "limitForce": "off (default)", "rolling": "off"},
        "materials": PACK_MATERIALS,
        "walls": [{"fix": w, "primitive": p, "position": x, "type": 2, "normal_into_box": n} for w, p, x, n in WALLS],
        "fix_order": ["property/global x4", "gravity", "wz0", "wx0", "wx1", "wy0", "wy1", "nve/sphere"],
        "bodies": bodies,
        "ids": ids,
        "records": records,
        "notes": [
            "records[k].atoms.<field>[n] belongs to atom ids[n]; state dumped at the end of step records[k].step "
            "(after final_integrate). force = pair + gravity + all wall forces of that step; torque likewise.",
            "ke_translational = thermo 'ke' (sum 0.5 m v^2), ke_rotational = compute erotate/sphere "
            "(sum 0.5 * 0.4 m r^2 w^2), both from LIGGGHTS at full-step velocities.",
            "n_pair_contacts = sum(compute contact/atom)/2 (pairs with |xi-xj| <= ri+rj); pairs = compute "
            "pair/gran/local (id1 < id2 by local index, here = atom id order since sorting is off): stored "
            "tangential history and overlap r1+r2-|x1-x2|.",
            "n_wall_contacts[w] = number of atoms with a non-zero force from wall fix w (store_force yes); "
            "floor_force_on_particles = sum over atoms of the floor's force on them (the force ON the floor is "
            "its negative); atoms.floor_force per atom.",
            "Bit-level agreement with another code is not expected beyond the first multi-contact collisions: "
            "compare the early records closely and the late ones statistically (KE decay, contact numbers, "
            "floor force ~ total weight minus side-wall friction, final heights).",
        ],
    }
    dst = DATA / "pack_settle.json"
    dst.write_text(json.dumps(out, separators=(",", ":")) + "\n")
    print(f"wrote {dst} ({len(records)} records, steps {records[0]['step']}..{records[-1]['step']})")
