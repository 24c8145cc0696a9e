#!/usr/bin/env python3
"""Convert the LIGGGHTS dumps of one case into data/<case>.json.

    python3 convert.py oblique_impact RUNDIR [--name oblique_impact_cdt --rollmodel "rolling_friction cdt" --rmu 0.1]
    python3 convert.py wall_impact RUNDIR
    python3 convert.py recontact RUNDIR
    python3 convert.py pack_settle RUNDIR

RUNDIR is the directory the deck was run in (it holds the dumps and log.liggghts).
All floats are written with Python's json (repr), so they round-trip to the printed double.
"""
import argparse
import json
import subprocess
import sys
from pathlib import Path

import lig_dump

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data"

ATOM_FIELDS = (("pos", ("x", "y", "z")), ("vel", ("vx", "vy", "vz")), ("omega", ("omegax", "omegay", "omegaz")),
               ("force", ("fx", "fy", "fz")), ("torque", ("tqx", "tqy", "tqz")))
WALL_FIELD = ("wall_force", ("f_force_wz0[1]", "f_force_wz0[2]", "f_force_wz0[3]"))

PACK_MATERIALS = {"types": {"1": "spheres", "2": "walls"}, "youngsModulus": [5.0e6, 1.0e7],
                  "poissonsRatio": [0.3, 0.25], "coefficientRestitution": [[0.5, 0.6], [0.6, 0.6]],
                  "coefficientFriction": [[0.5, 0.4], [0.4, 0.4]]}
FLOOR = {"fix": "wz0", "command": "fix wz0 all wall/gran model hertz tangential history primitive type 2 zplane 0.0 "
                                  "store_force yes", "primitive": "zplane", "position": 0.0, "type": 2,
         "normal_into_box": [0.0, 0.0, 1.0]}
STATE_NOTE = ("atoms.<id>.<field>[k] is the state dumped at the end of step steps[k] (after final_integrate): "
              "pos x(n), vel v(n), omega w(n); force/torque are the per-atom accumulators of step n, i.e. computed "
              "from x(n) and the half-step velocities v(n-1/2), w(n-1/2) (pair, then gravity, then walls). "
              "Step 0 is the setup state (setup force computation, history not updated).")


def liggghts_version(run):
    head = (Path(run) / "log.liggghts").read_text().splitlines()[0].strip()
    try:
        deb = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "liggghts"], capture_output=True,
                             text=True).stdout.strip()
    except OSError:
        deb = "?"
    return f"{head}; Debian package liggghts {deb}; binary /usr/bin/liggghts"


def vec(d, a, b, c):
    return [d[a], d[b], d[c]]


def read_data_file(path):
    """Atoms and Velocities of a LAMMPS data file (atom_style granular) as exact floats."""
    atoms, vels, sec = {}, {}, None
    for line in Path(path).read_text().splitlines():
        s = line.strip()
        if s in ("Atoms", "Velocities"):
            sec = s
            continue
        if not s or sec is None or not s[0].isdigit():
            continue
        t = s.split()
        if sec == "Atoms":
            atoms[int(t[0])] = {"type": int(t[1]), "diameter": float(t[2]), "density": float(t[3]),
                                "pos": [float(t[4]), float(t[5]), float(t[6])]}
        else:
            vels[int(t[0])] = {"vel": [float(t[1]), float(t[2]), float(t[3])],
                               "omega": [float(t[4]), float(t[5]), float(t[6])]}
    for i, a in atoms.items():
        a.update(vels.get(i, {"vel": [0.0, 0.0, 0.0], "omega": [0.0, 0.0, 0.0]}))
    return atoms


def bodies_of(init, first):
    out = []
    for i in sorted(init):
        b = init[i]
        out.append({"id": i, "type": b["type"], "radius": first[i]["radius"], "diameter_in_data_file": b["diameter"],
                    "density": b["density"], "mass": first[i]["mass"], "pos": b["pos"], "vel": b["vel"],
                    "omega": b["omega"]})
    return out


def per_step(run, dump, data_file, fields):
    snaps = lig_dump.read_dump(Path(run) / dump)
    init = read_data_file(HERE / data_file)
    first = lig_dump.by_id(snaps[0])
    steps = [s["step"] for s in snaps]
    rows = [lig_dump.by_id(s) for s in snaps]
    atoms = {str(i): {k: [vec(r[i], *cols) for r in rows] for k, cols in fields} for i in sorted(init)}
    return bodies_of(init, first), steps, atoms


def write(name, out, msg):
    dst = DATA / f"{name}.json"
    dst.write_text(json.dumps(out, separators=(",", ":")) + "\n")
    print(f"wrote {dst} ({msg})")


def oblique(a):
    bodies, steps, atoms = per_step(a.run, "oblique_atoms.dump", "oblique_impact.data", ATOM_FIELDS)
    cst, shear, overlap, pf, pt = [], [], [], [], []
    for p in lig_dump.read_dump(Path(a.run) / "oblique_pair.dump"):
        if not p["rows"]:
            continue
        assert len(p["rows"]) == 1
        r = p["rows"][0]
        assert (r[0], r[1]) == (1.0, 2.0), r[:2]
        cst.append(p["step"])
        pf.append(r[3:6])
        pt.append(r[6:9])
        shear.append(r[9:12])
        overlap.append(r[12])
    out = {
        "case": a.name,
        "liggghts": liggghts_version(a.run),
        "deck": "scripts/in.oblique_impact", "data_file": "scripts/oblique_impact.data",
        "command": f"liggghts -in in.oblique_impact -var data oblique_impact.data -var rollmodel '{a.rollmodel}' "
                   f"-var rmu {a.rmu}",
        "units": "si", "dt": 1.0e-7, "gravity": [0.0, 0.0, 0.0], "newton": "off", "atom_sort": "off",
        "neighbor_skin": 0.002, "neighbor_builds_during_run": 0,
        "pair_style": ("gran model hertz tangential history " + a.rollmodel).strip(),
        "model_settings": {"tangential_damping": "on (default)", "limitForce": "off (default)",
                           "rolling": a.rollmodel or "off"},
        "materials": {"types": {"1": "spheres"}, "youngsModulus": [1.0e8], "poissonsRatio": [0.3],
                      "coefficientRestitution": [[0.5]], "coefficientFriction": [[0.4]],
                      "coefficientRollingFriction": [[float(a.rmu)]]},
        "bodies": bodies,
        "steps": steps,
        "atoms": atoms,
        "contact": {"id1": 1, "id2": 2, "steps": cst, "shear": shear, "overlap": overlap,
                    "pgl_force": pf, "pgl_torque": pt},
        "notes": [
            STATE_NOTE + " No gravity, no walls: force/torque are the contact force/torque alone.",
            "LIGGGHTS pair i = atom 1, j = atom 2 (local index order, sorting off): normal en = (x1 - x2)/|x1 - x2|.",
            "contact: entries of compute pair/gran/local at the steps where the pair is touching. shear = the "
            "stored tangential history (shearx, sheary, shearz) after the update of that step; overlap = "
            "r1 + r2 - |x1 - x2| at the dump positions; pgl_force/pgl_torque = force/torque on atom id1 "
            "RE-EVALUATED by the compute at dump time with the end-of-step velocities v(n), w(n) and without "
            "history update, so they differ from the applied force (atoms.1.force) in the damping terms. "
            "Use atoms.*.force/torque as the reference contact force.",
        ],
    }
    write(a.name, out, f"{len(steps)} steps, contact steps {cst[0]}..{cst[-1]}")


def wall_contact_ranges(steps, wall_force):
    on = [s for s, wf in zip(steps, wall_force) if wf != [0.0, 0.0, 0.0]]
    out = []
    for s in on:
        if out and steps.index(s) == steps.index(out[-1][1]) + 1:
            out[-1][1] = s
        else:
            out.append([s, s])
    return out


def wall(a):
    bodies, steps, atoms = per_step(a.run, "wall_atoms.dump", "wall_impact.data", ATOM_FIELDS + (WALL_FIELD,))
    cr = wall_contact_ranges(steps, atoms["1"]["wall_force"])
    out = {
        "case": "wall_impact",
        "liggghts": liggghts_version(a.run),
        "deck": "scripts/in.wall_impact", "data_file": "scripts/wall_impact.data",
        "command": "liggghts -in in.wall_impact -var data wall_impact.data",
        "units": "si", "dt": 1.0e-6, "gravity": [0.0, 0.0, -9.81], "newton": "off", "atom_sort": "off",
        "neighbor_skin": 0.002,
        "pair_style": "gran model hertz tangential history",
        "wall": FLOOR,
        "fix_order": ["property/global x4", "gravity", "wz0", "nve/sphere"],
        "model_settings": {"tangential_damping": "on (default)", "limitForce": "off (default)", "rolling": "off"},
        "materials": PACK_MATERIALS,
        "bodies": bodies,
        "steps": steps,
        "atoms": atoms,
        "wall_contacts": cr,
        "notes": [
            STATE_NOTE + " force = (0 + m g) + wall force; wall_force = the floor's force alone (store_force yes); "
                         "torque = wall torque.",
            "wall_contacts: [first, last] dumped step of each run of steps with a non-zero wall force.",
        ],
    }
    write("wall_impact", out, f"{len(steps)} steps, wall contacts {cr}")


def recontact(a):
    bodies, steps, atoms = per_step(a.run, "recontact_atoms.dump", "recontact.data", ATOM_FIELDS + (WALL_FIELD,))
    log = (Path(a.run) / "log.liggghts").read_text()
    builds = int(log.split("Neighbor list builds =")[1].split()[0])
    pair_on = []
    for k, s in enumerate(steps):
        p1, p2 = atoms["1"]["pos"][k], atoms["2"]["pos"][k]
        d2 = sum((p1[c] - p2[c]) ** 2 for c in range(3))
        touch = d2 < (bodies[0]["radius"] + bodies[1]["radius"]) ** 2
        if touch and (not pair_on or pair_on[-1][1] != steps[k - 1]):
            pair_on.append([s, s])
        elif touch:
            pair_on[-1][1] = s
    out = {
        "case": "recontact",
        "liggghts": liggghts_version(a.run),
        "deck": "scripts/in.recontact", "data_file": "scripts/recontact.data",
        "command": "liggghts -in in.recontact -var data recontact.data",
        "units": "si", "dt": 1.0e-6, "gravity": [0.0, 0.0, -9.81], "newton": "off", "atom_sort": "off",
        "neighbor_skin": 0.01, "neigh_modify": "delay 0 (every 1 check yes)", "neighbor_builds_during_run": builds,
        "pair_style": "gran model hertz tangential history",
        "wall": FLOOR,
        "fix_order": ["property/global x4", "gravity", "wz0", "nve/sphere"],
        "model_settings": {"tangential_damping": "on (default)", "limitForce": "off (default)", "rolling": "off"},
        "materials": PACK_MATERIALS,
        "bodies": bodies,
        "steps": steps,
        "atoms": atoms,
        "pair_touching_dumped": pair_on,
        "wall_contacts_atom1": wall_contact_ranges(steps, atoms["1"]["wall_force"]),
        "notes": [
            STATE_NOTE + " wall_force = the floor's force on the atom (store_force yes).",
            "pair_touching_dumped: [first, last] dumped step of each run of dumps with |x1-x2| < r1+r2 "
            "(dumps every 20 steps, so the true first/last contact steps lie within 20 steps before/after).",
            "The second contact starts with the stale tangential history left by the first one (no neighbour "
            "rebuild in between); the single rebuild (atom 2 moved > skin/2) happens while the pair is apart, "
            "so the third contact starts from zero history. hertz_mindlin_reference.py reproduces this bit for "
            "bit; resetting the history at separation instead gives a different trajectory from the 2nd contact on.",
        ],
    }
    write("recontact", out, f"{len(steps)} dumps, pair touching {pair_on}, {builds} neighbour builds")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("case", choices=["oblique_impact", "wall_impact", "recontact", "pack_settle"])
    ap.add_argument("run")
    ap.add_argument("--name")
    ap.add_argument("--rollmodel", default="")
    ap.add_argument("--rmu", default="0.0")
    a = ap.parse_args()
    a.name = a.name or a.case
    if a.case == "oblique_impact":
        oblique(a)
    elif a.case == "wall_impact":
        wall(a)
    elif a.case == "recontact":
        recontact(a)
    else:
        import convert_pack
        convert_pack.convert(a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
