"""bench/track_passage_cost.py: the cost of a passage from measured runs, against hand arithmetic.

The period of a passage of jobs/track_tilt_large.toml comes from its keys by the formula of
docs/track.md ("Loads": the first axle from x_from = x_0 - 3π/4 L to x_to = x_last + 3π/4 L,
L = (4 EI a / k_d)^(1/4), the last axle's offset, at the speed, plus the rest), not from pdem;
the steps per passage, time per step, the model's calibration (c from the 2-rank compute) and the
core-hours are then the division and products the module's docstring states, on hand-made
scaling.json records and checkpoints with a known Δt.
Bad input: one line, exit 2.
"""
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from bench.track_passage_cost import main, make_bed
from pdem.io.checkpoint import read_checkpoint, write_checkpoint
from pdem.parallel.comm import SerialComm

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "jobs" / "track_tilt_large.toml"
DT = 2.0e-4


def checkpoint(directory, scene_text, dt=DT, step=100):
    tables = {"particles": {"gid": np.arange(3, dtype=np.int64), "pos": np.arange(9.0).reshape(3, 3)}}
    meta = {"step": step, "time": 1.5, "dt": dt, "keys": {"particles": ["gid"]}, "scene_file": scene_text,
            "track": {"stage": 4, "started": False}}
    return write_checkpoint(directory, step, tables, meta, SerialComm(), keep=None)


def scaling(run, ranks, steps, total, compute, bodies=4000):
    run.mkdir(parents=True, exist_ok=True)
    comm = 0.1 * ranks
    other = total - sum(compute) - comm
    rec = {"scene": "track", "ranks": ranks, "bodies": bodies, "steps": steps, "rebuilds": steps // 20,
           "wall_s": total, "spacing": 0.3, "track_length": 2.4, "sleepers": 8, "bodies_per_metre": bodies / 2.4,
           "radius": 0.025, "radius_spread": 0.3,
           "timers_max_s": {"neighbours": compute[0], "contacts": compute[1], "integration": compute[2],
                            "communication": comm, "output": other / 2, "other": other / 2},
           "timers_total_max_s": total, "uptime": [1.0, 1.0, 1.0],
           "loads": {"ghosts": [400, 380], "halo": 0.075, "imbalance": 1.05, "work": [1.0, 1.0],
                     "owned": [bodies // 2, bodies // 2]}}
    (run / "scaling.json").write_text(json.dumps(rec))
    checkpoint(run / "checkpoints", "x")


def test_cost_of_a_passage_by_hand(tmp_path, capsys):
    doc = tomllib.loads(SCENE.read_text())
    tr, t = doc["track"], doc["traffic"]
    length = (4 * t["rail_bending_stiffness"] * tr["spacing"] / 6.0e7) ** 0.25  # k_d: the default rail seat
    x0, x_last = 0.5 * tr["spacing"], (tr["sleepers"] - 0.5) * tr["spacing"]
    period = ((x_last - x0 + 2 * 0.75 * math.pi * length + t["axles"][-1]) / t["speed"] + t["rest_time"])
    scaling(tmp_path / "r1", 1, 400, 8.0, (2.0, 4.0, 1.0))
    scaling(tmp_path / "r2", 2, 400, 5.0, (1.0, 2.0, 0.5))
    out = tmp_path / "cost.json"
    assert main(["cost", str(SCENE), "--run2", str(tmp_path / "r2"), "--run1", str(tmp_path / "r1"),
                 "--ranks", "1", "2", "64", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["period"] == pytest.approx(period, rel=1e-12)
    assert r["steps_per_passage"] == pytest.approx(period / DT, rel=1e-12)
    # the 2-rank compute (1 + 2 + 0.5 s over 400 steps) = b c N/2 + c/2 g: b = 1.05, N = 4000, g = 400
    c = 3.5 / 400 / (1.05 * 4000 / 2 + 400 / 2)
    assert r["c_body"] == pytest.approx(c, rel=1e-12)
    assert r["f_fixed"] == pytest.approx((5.0 - 3.5 - 0.2) / 400, rel=1e-12)
    assert r["t2"] == pytest.approx(5.0 / 400) and r["t1"] == pytest.approx(8.0 / 400)
    assert r["measured_2_ranks"]["core_h_per_passage"] == pytest.approx(2 * 5.0 / 400 * period / DT / 3600, rel=1e-12)
    one, two, many = r["rows"]
    t1 = (5.0 - 3.5 - 0.2) / 400 + c * 4000  # P = 1: the fixed part and all the compute, no messages
    assert one["t_step"] == pytest.approx(t1, rel=1e-12) and one["efficiency"] == pytest.approx(1.0)
    assert one["core_h_run"] == pytest.approx(t1 * period / DT * t["passages"] / 3600, rel=1e-12)
    assert two["t_step"] > r["f_fixed"] + c * (1.05 * 2000 + 200)  # + the messages and the packing
    assert r["P_max"] == int(2.4 / 0.075) and not many["possible"] and two["possible"]
    assert "not possible" in capsys.readouterr().out
    # calibrated on the 1-rank run: c = its compute (2 + 4 + 1 s over 400 steps) / N, f its output + other
    assert main(["cost", str(SCENE), "--run2", str(tmp_path / "r2"), "--run1", str(tmp_path / "r1"),
                 "--calibrate", "1", "--ranks", "1", "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    assert r["c_body"] == pytest.approx(7.0 / 400 / 4000, rel=1e-12)
    assert r["f_fixed"] == pytest.approx((8.0 - 7.0 - 0.1) / 400, rel=1e-12)
    assert r["rows"][0]["t_step"] == pytest.approx(7.9 / 400, rel=1e-12)


def test_bed_takes_the_scene_and_keeps_the_bodies(tmp_path, capsys):
    prepared = checkpoint(tmp_path / "prep", SCENE.read_text())
    full = tmp_path / "full.toml"
    full.write_text(SCENE.read_text().replace("young = 2.8e6", "young = 2.8e11"))
    out = make_bed(prepared, full, tmp_path / "bed.h5")
    (t0, m0), (t1, m1) = read_checkpoint(prepared), read_checkpoint(out)
    assert m1["scene_file"] == full.read_text() and m1["step"] == m0["step"] and m1["dt"] == m0["dt"]
    for col in t0["particles"]:
        np.testing.assert_array_equal(t0["particles"][col], t1["particles"][col])


def test_bad_input_one_line_exit_2(tmp_path, capsys):
    prepared = checkpoint(tmp_path / "prep", SCENE.read_text())
    other = tmp_path / "other.toml"
    other.write_text(SCENE.read_text().replace("sleepers = 8", "sleepers = 6"))
    cases = [(["bed", str(prepared), str(other), str(tmp_path / "b.h5")], "track.sleepers = 6"),
             (["bed", str(tmp_path / "none.h5"), str(SCENE), str(tmp_path / "b.h5")], "PREPARED"),
             (["cost", str(SCENE), "--run2", str(tmp_path / "r2"), "--ranks", "0"], "--ranks [0]"),
             (["cost", str(SCENE), "--run2", str(tmp_path / "r2"), "--calibrate", "1"], "--calibrate 1 needs --run1")]
    scaling(tmp_path / "r1", 2, 400, 8.0, (2.0, 4.0, 1.0))  # a 2-rank run given as the 1-rank one
    scaling(tmp_path / "r2", 2, 400, 5.0, (1.0, 2.0, 0.5))
    cases.append((["cost", str(SCENE), "--run1", str(tmp_path / "r1"), "--run2", str(tmp_path / "r2")],
                  "--run1 must be a 1-rank run"))
    scaling(tmp_path / "r3", 1, 400, 8.0, (2.0, 4.0, 1.0))
    cases.append((["cost", str(SCENE), "--run2", str(tmp_path / "r3")], "--run2 must be a 2-rank run"))
    for argv, what in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and what in err, err
