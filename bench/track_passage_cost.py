"""Cost of one passage of a track run at full stiffness, measured here and projected to P ranks.

    python -m bench.track_passage_cost bed PREPARED SCENE OUT.h5
    mpiexec -n 2 python -m pdem run SCENE_WITH_BED --out RUN_2 --steps S    (and -n 1 ... RUN_1, a check)
    python -m bench.track_passage_cost cost SCENE --run2 RUN_2 [--run1 RUN_1] [--ranks 1 2 8 64 256] [--json F]

A full-stiffness track (E_k = 2.8e11 Pa) steps at Δt ~ 1e-6 s, so its preparation alone is
millions of steps. The cost of a traffic step does not depend on the stiffness (the same
spheres, contacts and code), only the number of steps does, so it is measured on a bed that
needs no preparation at full stiffness:

``bed``: a copy of PREPARED (the ``prepared.h5`` of the same track at scaled stiffness) that the
full-stiffness scene SCENE accepts as its ``[traffic] prepared``: its record of the scene file is
replaced by SCENE's, which must describe the same track (the ``[track]`` tables equal, one line
and exit 2 otherwise). Nothing else changes: the contacts carried from the soft bed keep their
stiffness and new ones get the full stiffness. **For timing only**: the bed is not in
equilibrium at full stiffness (a few hundred steps of 1e-6 s move it by nothing measurable),
and its settlement means nothing. The traffic's Δt is computed afresh from SCENE's materials and
rail (`pdem.timestep`, with the pads' checks), as in a real run.

``cost``: from the ``scaling.json`` of a 2-rank run of SCENE from that bed (``pdem run
--steps``: a few hundred traffic steps or more) and the Δt in its checkpoint,

    steps per passage   n_p = period / Δt     (period of `pdem.boundaries.loads.AxleTrain`: the
                                                first axle from x_from to x_to, the last axle's
                                                offset, at ``speed``, plus ``rest_time``) [-]
    measured, 2 ranks   t_2 = pdem's timers (the slower rank) / steps  [s/step]
                        core-hours per passage = 2 t_2 n_p / 3600
    projected, P ranks  t(P) = f + t_model(N, P)      [s/step]

t_model is `bench.scaling_model.track_step` (docs/scaling.md "Track section": compute b c N/P +
c_g g, ghost messages, packing u g + o, the sleepers' allreduce), calibrated on the 2-rank run:
c from its compute (timers neighbours + contacts + integration per step = b c N/2 + c_g g with
c_g = c/2, g its ghosts), the imbalance b and halo from its ``loads``, α, β of
``bench/pingpong.json`` and the packing's u, o of ``bench/track_scaling.json`` (measured for the
large track; per ghost and per step, so they carry over). f is its time per step outside the
compute and communication timers ("output", "other": the rail beam's solve, the sleepers' loads
and records, the step loop's Python): work that does not shrink with P, kept whole on every rank
(so the projection is pessimistic where it is parallel in fact). ``--calibrate 1`` takes c and f
from the 1-rank run instead (all its compute is c N), the halo and imbalance still from the
2-rank run: on a machine shared with other jobs the 2-rank run waits for its partner, and a
1-rank run with one numba thread (NUMBA_NUM_THREADS=1) is the cleaner measure of the work per
step. The measured communication
(waiting for the other rank included) is not in the model, which has the messages and packing
only. A 1-rank run (``--run1``) is printed beside the model's t(1) as a check. P_max = L/h (L
the track's length, h the halo): slabs thinner than the halo are not possible, and such rows
are marked so. ``--sleepers K``: the same model for the same cross-section and train over K
sleepers (N = n_x K a bodies, n_x measured; a passage longer by (K a - L)/speed), for rank
counts a short track cannot take. Units: [s], [m], [N]; hours as printed.
"""
import argparse
import json
import os
import shutil
import sys
import tempfile
import tomllib
from pathlib import Path

HERE = Path(__file__).resolve().parent
COMPUTE = ("neighbours", "contacts", "integration")


class BadInput(Exception):
    """One line naming what is wrong (exit 2)."""


def make_bed(prepared, scene, out):
    """Write the copy of ``prepared`` that ``scene`` accepts as ``[traffic] prepared`` (above)."""
    from pdem.io.checkpoint import CheckpointError, read_checkpoint, write_checkpoint
    from pdem.parallel.comm import SerialComm

    try:
        tables, meta = read_checkpoint(prepared)
    except CheckpointError as exc:
        raise BadInput(f"PREPARED = {str(prepared)!r}: {exc}") from None
    text = Path(scene).read_text()
    there = tomllib.loads(meta["scene_file"]).get("track", {})
    here = tomllib.loads(text).get("track", {})
    for k in sorted(set(there) | set(here)):
        if there.get(k) != here.get(k):
            raise BadInput(f"SCENE = {str(scene)!r}: track.{k} = {here.get(k, '(absent)')!r}, the prepared bed's "
                           f"{there.get(k, '(absent)')!r}: not the same track")
    meta = {**meta, "scene_file": text, "scene_path": str(scene)}
    with tempfile.TemporaryDirectory(dir=Path(out).parent) as tmp:
        written = write_checkpoint(tmp, int(meta["step"]), tables, meta, SerialComm(), keep=None)
        shutil.move(written, out)
    return Path(out)


def passage_period(scene):
    """(period of one passage [s], track length [m], passages, speed [m/s]) of the scene file's traffic."""
    from pdem.scenes.track import make_train, profile, track_settings, traffic_settings

    doc = tomllib.loads(Path(scene).read_text())
    c = track_settings(doc)
    t = traffic_settings(doc, c)
    if t is None or t["program"] != "axles":
        raise BadInput(f"SCENE = {str(scene)!r}: needs [traffic] program = 'axles' (trains with a period)")
    return make_train(t, c, 0.0).period, profile(c)["length"], int(t["passages"]), float(t["speed"])


def run_dt(run):
    """Δt of the newest checkpoint of a run [s] (the traffic's, after `pdem run --steps`)."""
    from pdem.io.checkpoint import list_checkpoints, read_checkpoint

    found = list_checkpoints(Path(run) / "checkpoints")
    if not found:
        raise BadInput(f"RUN = {str(run)!r}: no checkpoint (run it with pdem run --steps)")
    return float(read_checkpoint(found[-1][1])[1]["dt"])


def cost(scene, run2, ranks, passages=None, run1=None, sleepers=(), calibrate=2):
    """The measured and projected cost of a passage (module docstring) as a dict."""
    from bench.scaling_model import track_step

    period, length, n_passages, speed = passage_period(scene)
    passages = passages or n_passages
    r2 = json.loads((Path(run2) / "scaling.json").read_text())
    if r2["ranks"] != 2:
        raise BadInput(f"--run2 must be a 2-rank run (got {r2['ranks']} ranks)")
    r1 = None if run1 is None else json.loads((Path(run1) / "scaling.json").read_text())
    if r1 is not None and r1["ranks"] != 1:
        raise BadInput(f"--run1 must be a 1-rank run (got {r1['ranks']} ranks)")
    dt = run_dt(run2)
    if r1 is not None and run_dt(run1) != dt:
        raise BadInput(f"the two runs stepped at different Δt ({run_dt(run1):.6g}, {dt:.6g} s): not the same scene")
    ld = r2["loads"]
    pp = json.loads((HERE / "pingpong.json").read_text())["sendrecv"]
    stored = json.loads((HERE / "track_scaling.json").read_text())["inputs"]
    n, steps2 = r2["bodies"], r2["steps"]
    m = {"n_x": n / r2["track_length"], "spacing": r2["spacing"], "g2": max(ld["ghosts"]), "b": ld["imbalance"],
         "h": ld["halo"], "alpha": pp["alpha_s"], "beta": pp["beta_B_per_s"], "u": stored["u"], "o": stored["o"]}
    timers = r2["timers_max_s"]
    compute2 = sum(timers[k] for k in COMPUTE) / steps2
    if calibrate == 2:
        c_body = compute2 / (m["b"] * n / 2 + 0.5 * m["g2"])  # compute2 = b c N/2 + c_g g, c_g = c/2
        f = (timers["output"] + timers["other"]) / steps2
    elif r1 is None:
        raise BadInput("--calibrate 1 needs --run1 (the 1-rank run the model is calibrated on)")
    else:  # the 1-rank run: all its compute is c N
        c_body = sum(r1["timers_max_s"][k] for k in COMPUTE) / r1["steps"] / n
        f = (r1["timers_max_s"]["output"] + r1["timers_max_s"]["other"]) / r1["steps"]
    t2 = r2["timers_total_max_s"] / steps2
    n_p = period / dt
    p_max = int(length / m["h"])

    def t_model(P, N=n):
        return f + track_step(m, N, P, m["alpha"], m["beta"], c=c_body)[0]

    def table(N, n_steps, p_limit):
        return [{"P": P, "t_step": t_model(P, N), "possible": P <= p_limit,
                 "efficiency": t_model(1, N) / (P * t_model(P, N)),
                 "wall_h_per_passage": t_model(P, N) * n_steps / 3600,
                 "core_h_per_passage": P * t_model(P, N) * n_steps / 3600,
                 "wall_h_run": t_model(P, N) * n_steps * passages / 3600,
                 "core_h_run": P * t_model(P, N) * n_steps * passages / 3600} for P in ranks]

    rows = table(n, n_p, p_max)
    longer = []  # the same cross-section and train over K sleepers: N = n_x K a, the first axle K - K0 spacings further
    for k in sleepers:
        L = k * m["spacing"]
        period_k = period + (L - length) / speed
        longer.append({"sleepers": k, "length": L, "bodies": m["n_x"] * L, "period": period_k,
                       "steps_per_passage": period_k / dt, "P_max": int(L / m["h"]),
                       "rows": table(m["n_x"] * L, period_k / dt, int(L / m["h"]))})
    return {"scene": str(scene), "runs": [None if run1 is None else str(run1), str(run2)], "bodies": n, "dt": dt,
            "period": period, "steps_per_passage": n_p, "passages": passages, "track_length": length,
            "halo": m["h"], "P_max": p_max, "c_body": c_body, "f_fixed": f,
            "t1": None if r1 is None else r1["timers_total_max_s"] / r1["steps"], "t1_model": t_model(1),
            "t2": t2, "t2_model": t_model(2), "compute2": compute2, "comm2": timers["communication"] / steps2,
            "steps_measured": [None if r1 is None else r1["steps"], steps2],
            "uptime": [None if r1 is None else r1.get("uptime"), r2.get("uptime")],
            "measured_2_ranks": {"steps_per_s": 1.0 / t2, "wall_h_per_passage": t2 * n_p / 3600,
                                 "core_h_per_passage": 2 * t2 * n_p / 3600},
            "alpha": m["alpha"], "beta": m["beta"], "u": m["u"], "o": m["o"], "b": m["b"], "ghosts_2": m["g2"],
            "calibrated_on": calibrate, "rows": rows, "longer": longer}


def cost_lines(r):
    """The cost as text (what the campaign header and docs/track.md quote)."""
    lines = [f"scene {r['scene']}: {r['bodies']} bodies, Δt = {r['dt']:.4g} s, a passage {r['period']:.4g} s = "
             f"{r['steps_per_passage']:.0f} steps; track {r['track_length']:g} m, halo {r['halo'] * 1e3:.1f} mm: "
             f"P_max = L/h = {r['P_max']}",
             f"measured on 2 ranks ({r['steps_measured'][1]} steps, load average {r['uptime'][1]}): "
             f"{r['t2'] * 1e3:.2f} ms/step = {r['measured_2_ranks']['steps_per_s']:.0f} steps/s (compute "
             f"{r['compute2'] * 1e3:.2f}, communication {r['comm2'] * 1e3:.2f}, the rest {r['f_fixed'] * 1e3:.2f} "
             f"ms/step; model {r['t2_model'] * 1e3:.2f} ms/step: c = {r['c_body'] * 1e9:.0f} ns per body-step, "
             f"calibrated on the {r['calibrated_on']}-rank run)"
             + ("" if r["t1"] is None else f"; 1 rank ({r['steps_measured'][0]} steps, load average {r['uptime'][0]}): "
                f"{r['t1'] * 1e3:.2f} ms/step, model {r['t1_model'] * 1e3:.2f}"),
             f"measured, 2 ranks: {r['measured_2_ranks']['wall_h_per_passage']:.2f} h and "
             f"{r['measured_2_ranks']['core_h_per_passage']:.2f} core-h per passage",
             f"{'P':>5} {'t/step ms':>10} {'E':>6} {'wall h/passage':>15} {'core-h/passage':>15} "
             f"{'wall h, ' + str(r['passages']) + ' passages':>22} {'core-h, all':>12}"]
    lines += _row_lines(r["rows"])
    for t in r["longer"]:
        lines += [f"the same track with {t['sleepers']} sleepers ({t['length']:g} m, {t['bodies']:.0f} bodies, "
                  f"a passage {t['period']:.4g} s = {t['steps_per_passage']:.0f} steps, P_max = {t['P_max']}), "
                  "modelled:",
                  *_row_lines(t["rows"])]
    return lines


def _row_lines(rows):
    return [f"{w['P']:>5} {w['t_step'] * 1e3:>10.3f} {w['efficiency']:>6.2f} {w['wall_h_per_passage']:>15.3f} "
            f"{w['core_h_per_passage']:>15.2f} {w['wall_h_run']:>22.2f} {w['core_h_run']:>12.1f}"
            + ("" if w["possible"] else "   slab thinner than the halo: not possible") for w in rows]


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python -m bench.track_passage_cost", allow_abbrev=False)
    sub = ap.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("bed", help="the scaled prepared bed as the full-stiffness scene's prepared bed (timing only)")
    b.add_argument("prepared", type=Path)
    b.add_argument("scene", type=Path)
    b.add_argument("out", type=Path)
    c = sub.add_parser("cost", help="steps, time and core-hours per passage, measured and projected")
    c.add_argument("scene", type=Path)
    c.add_argument("--run2", type=Path, required=True, help="a 2-rank run of SCENE from the bed (pdem run --steps)")
    c.add_argument("--run1", type=Path, help="a 1-rank run of the same: its time per step is printed beside the "
                   "model's (a check)")
    c.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 8, 16, 32, 64, 256])
    c.add_argument("--calibrate", type=int, choices=(1, 2), default=2,
                   help="the run whose compute and fixed time per step calibrate the model (default 2: --run2)")
    c.add_argument("--passages", type=int, help="passages of the whole run (default: the scene's)")
    c.add_argument("--sleepers", type=int, nargs="+", default=[], metavar="K",
                   help="also model the same track with K sleepers (the same cross-section and train)")
    c.add_argument("--json", type=Path, help="write the numbers there")
    a = ap.parse_args(argv)
    from pdem.errors import InputError

    try:
        if a.cmd == "bed":
            print(f"wrote {make_bed(a.prepared, a.scene, a.out)} (timing only: see bench/track_passage_cost.py)")
            return 0
        if any(p < 1 for p in a.ranks):
            raise BadInput(f"--ranks {a.ranks}: rank counts must be >= 1")
        if any(k < 1 for k in a.sleepers):
            raise BadInput(f"--sleepers {a.sleepers}: sleeper counts must be >= 1")
        r = cost(a.scene, a.run2, a.ranks, a.passages, run1=a.run1, sleepers=a.sleepers, calibrate=a.calibrate)
    except (BadInput, InputError, OSError) as exc:  # one line, exit 2
        print(f"bench.track_passage_cost: error: {exc}", file=sys.stderr)
        return 2
    print("\n".join(cost_lines(r)))
    if a.json:
        a.json.write_text(json.dumps(r, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    sys.exit(main())
