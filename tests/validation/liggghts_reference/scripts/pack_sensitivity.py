#!/usr/bin/env python3
"""How far LIGGGHTS's own pack_settle trajectory moves under round-off-size changes.

    python3 pack_sensitivity.py BASE_RUNDIR      (BASE_RUNDIR: where in.pack_settle was run)

Runs in.pack_settle twice more in scratch directories: (a) x of atom 1 moved by one ulp
(math.nextafter upwards) in the data file, (b) on 2 MPI ranks ('processors 2 1 1', mpirun -np 2), which
changes the force summation order. Writes data/pack_settle_sensitivity.json with, for every record, the
largest distance between corresponding atoms' positions and velocities (against the base run), and each
run's kinetic energy and contact number. This is the floor for any other code's agreement on this scene.
"""
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import lig_dump

HERE = Path(__file__).resolve().parent


def dump_rows(run):
    return [lig_dump.by_id(s) for s in lig_dump.read_dump(Path(run) / "pack_atoms.dump")]


def stats(base, other):
    out = []
    for A, B in zip(base, other):
        dx = max(math.dist([A[i]["x"], A[i]["y"], A[i]["z"]], [B[i]["x"], B[i]["y"], B[i]["z"]]) for i in A)
        dv = max(math.dist([A[i]["vx"], A[i]["vy"], A[i]["vz"]], [B[i]["vx"], B[i]["vy"], B[i]["vz"]]) for i in A)
        out.append((dx, dv))
    return out


def ke(rows):
    return sum(0.5 * r["mass"] * (r["vx"] ** 2 + r["vy"] ** 2 + r["vz"] ** 2) for r in rows.values())


def main(base_run):
    base = dump_rows(base_run)
    work = Path(tempfile.mkdtemp(prefix="liggghts-sens-"))
    lines = (HERE / "pack_settle.data").read_text().split("\n")
    for k, l in enumerate(lines):
        t = l.split()
        if len(t) == 7 and t[0] == "1":
            t[4] = repr(math.nextafter(float(t[4]), 1.0))
            lines[k] = " ".join(t)
            break
    (work / "ulp.data").write_text("\n".join(lines))
    (work / "ulp").mkdir()
    subprocess.run(["liggghts", "-in", str(HERE / "in.pack_settle"), "-var", "data", str(work / "ulp.data"),
                    "-screen", "none"], cwd=work / "ulp", check=True)
    deck = (HERE / "in.pack_settle").read_text().replace("processors      1 1 1", "processors      2 1 1")
    (work / "in.np2").write_text(deck)
    (work / "np2").mkdir()
    subprocess.run(["mpirun", "--allow-run-as-root", "--bind-to", "none", "-np", "2", "liggghts", "-in",
                    str(work / "in.np2"), "-var", "data", str(HERE / "pack_settle.data"), "-screen", "none"],
                   cwd=work / "np2", check=True)
    ulp, np2 = dump_rows(work / "ulp"), dump_rows(work / "np2")
    su, sn = stats(base, ulp), stats(base, np2)
    steps = [s["step"] for s in lig_dump.read_dump(Path(base_run) / "pack_atoms.dump")]
    recs = []
    for k, st in enumerate(steps):
        recs.append({"step": st,
                     "one_ulp": {"max_dpos": su[k][0], "max_dvel": su[k][1], "ke_translational": ke(ulp[k]),
                                 "n_pair_contacts": int(sum(r["c_cpa"] for r in ulp[k].values())) // 2},
                     "two_ranks": {"max_dpos": sn[k][0], "max_dvel": sn[k][1], "ke_translational": ke(np2[k]),
                                   "n_pair_contacts": int(sum(r["c_cpa"] for r in np2[k].values())) // 2},
                     "base": {"ke_translational": ke(base[k]),
                              "n_pair_contacts": int(sum(r["c_cpa"] for r in base[k].values())) // 2}})
    out = {"case": "pack_settle_sensitivity",
           "what": "LIGGGHTS pack_settle vs itself: (one_ulp) atom 1 x moved by one ulp in the data file; "
                   "(two_ranks) same input on 2 MPI ranks (processors 2 1 1). max_dpos/max_dvel = largest "
                   "|x - x_base| / |v - v_base| over all atoms at that record; ke_translational = sum 0.5 m v^2 "
                   "from the dump; n_pair_contacts = sum(contact/atom)/2.",
           "records": recs}
    dst = HERE.parent / "data" / "pack_settle_sensitivity.json"
    dst.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {dst}; scratch {work}")
    for r in recs[::4] + ([recs[-1]] if (len(recs) - 1) % 4 else []):
        print(f"{r['step']:6d}  1ulp: dpos {r['one_ulp']['max_dpos']:.2e} dvel {r['one_ulp']['max_dvel']:.2e}   "
              f"2 ranks: dpos {r['two_ranks']['max_dpos']:.2e} dvel {r['two_ranks']['max_dvel']:.2e}")


if __name__ == "__main__":
    main(sys.argv[1])
