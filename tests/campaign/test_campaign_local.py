"""The local runner on tiny members (50 spheres, a few hundred to 20 000 steps, 1 rank each, two at
a time): a failing member does not stop the others; SIGTERM to the runner stops the running
members with a checkpoint (exit 3), a second ``campaign run`` resumes them, and every member's
results.h5 equals that of an uninterrupted campaign bit for bit."""
import json
import os
import signal
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from campaign_helpers import ROOT, pdem_campaign, write_campaign
from pdem_cli import signal_when


def states(out):
    r = pdem_campaign("status", out, "--json")
    assert r.returncode == 0, r.stderr
    return {x["name"]: x for x in json.loads(r.stdout)}


def test_a_failing_member_does_not_stop_the_others(tmp_path, tiny):
    p = write_campaign(tmp_path, """
[[case]]
name = "a"
"deposition.seed" = 1
[[case]]
name = "bad"
"simulation.max_overlap_ratio" = 1e-6
[[case]]
name = "b"
"deposition.seed" = 2
""", head="[local]\ncores = 2")
    r = pdem_campaign("run", p)
    assert r.returncode == 1, r.stdout + r.stderr
    out = tmp_path / "runs" / "camp"
    st = states(out)
    assert {n: s["state"] for n, s in st.items()} == {"a": "done", "bad": "failed", "b": "done"}
    assert st["bad"]["exit"] == 4 and st["bad"]["message"].startswith("pdem: unstable: step ")
    assert "bad: FAILED, exit 4" in r.stdout and "pdem: unstable" in r.stdout
    for name in ("a", "b"):
        rec = json.loads((out / name / "run.json").read_text())
        assert rec["exit"] == 0 and rec["attempts"][0]["ranks"] == 1 and rec["attempts"][0]["threads"] == 1
        assert rec["wall_s"] > 0 and rec["core_s"] == rec["wall_s"]
        # the CPU time of the member's process, measured by the runner: one process, one thread
        assert 0 < rec["cpu_s"] <= 1.1 * rec["wall_s"] + 0.5
        with h5py.File(out / name / "results.h5") as f:
            assert f["series"]["step"][-1] == 400
    # again: nothing to run (done skipped, failed skipped); with --retry-failed the failed one runs again
    r2 = pdem_campaign("run", p)
    assert r2.returncode == 1 and "2 done, 0 to run" in r2.stdout and "1 failed (skipped" in r2.stdout
    assert states(out)["bad"]["attempts"] == 1
    r3 = pdem_campaign("run", p, "--retry-failed")
    assert r3.returncode == 1 and states(out)["bad"]["attempts"] == 2 and states(out)["a"]["attempts"] == 1


def steps_logged(logs):
    """Every log shows a progress line of pdem's step loop (its signal handlers are in); the first
    members compile the kernels (minutes on a fresh numba cache of a loaded machine)."""
    return all(p.exists() and any(line.startswith("step ") and " t = " in line for line in p.read_text().splitlines())
               for p in logs)


def series(path):
    with h5py.File(path) as f:
        return {k: f["series"][k][()] for k in f["series"]}


def test_sigterm_then_resume_gives_the_uninterrupted_results(tmp_path, tiny):
    """(20 000 steps per member: at 2000 both running members could finish before SIGTERM.)"""
    p = write_campaign(tmp_path, """
[set]
"run.steps" = 20000
"run.checkpoint_every" = 5000
[seeds]
values = [1, 2, 3]
""", head="[local]\ncores = 2")
    out = tmp_path / "runs" / "camp"
    env = dict(os.environ, OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    # SIGTERM to the runner only: it forwards to the members
    status, text = signal_when([sys.executable, "-m", "pdem", "campaign", "run", str(p)],
                               lambda: steps_logged([out / "seed-1" / "pdem.log", out / "seed-2" / "pdem.log"]),
                               signal.SIGTERM, cwd=ROOT, env=env)
    assert status == 3, text
    assert "SIGTERM received: stopping 2 running member(s)" in text
    st = states(out)
    # the two running members stop (a member may just have finished its few seconds of steps when
    # the signal came: then it is done); the third never started
    stopped = [n for n in ("seed-1", "seed-2") if st[n]["state"] == "stopped"]
    assert stopped and all(st[n]["state"] in ("stopped", "done") for n in ("seed-1", "seed-2"))
    assert st["seed-3"]["state"] == "pending"
    for n in stopped:
        assert st[n]["exit"] == 3
        ckpts = sorted((out / n / "checkpoints").glob("ckpt_*.h5"))
        assert ckpts and int(ckpts[-1].stem.split("_")[1]) < 20000
    r = pdem_campaign("run", p)
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"{1 + len(stopped)} to run ({len(stopped)} resume from a checkpoint)" in r.stdout
    for n in stopped:
        assert "resuming from" in (out / n / "pdem.log").read_text()
        assert states(out)[n]["attempts"] == 2
    # the same campaign uninterrupted, in another directory
    ref = tmp_path / "ref"
    r = pdem_campaign("run", p, "--out", ref)
    assert r.returncode == 0, r.stdout + r.stderr
    for n in ("seed-1", "seed-2", "seed-3"):
        got, want = series(out / n / "results.h5"), series(ref / n / "results.h5")
        assert sorted(got) == sorted(want) and want["step"][-1] == 20000
        for k in want:
            assert got[k].dtype == want[k].dtype and np.array_equal(got[k], want[k]), (n, k)
            assert got[k].tobytes() == want[k].tobytes(), (n, k)
    assert Path(ref / "seed-1" / "scene.toml").read_text() == Path(out / "seed-1" / "scene.toml").read_text()


def test_two_rank_member_stops_and_resumes(tmp_path, tiny):
    """A member on 2 ranks (the venv's mpiexec): SIGTERM to the runner reaches the ranks through
    their process group; exit 3, then the same command resumes it to the end. (20 000 steps: 1000
    steps of the tiny scene took under a second on 2 ranks, and the member finished before the
    signal reached it.)"""
    p = write_campaign(tmp_path, '[set]\n"run.steps" = 20000\n[seeds]\nvalues = [7]\n', head="ranks = 2")
    out = tmp_path / "runs" / "camp"
    env = dict(os.environ, OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    status, text = signal_when([sys.executable, "-m", "pdem", "campaign", "run", str(p), "--cores", "2"],
                               lambda: steps_logged([out / "seed-7" / "pdem.log"]), signal.SIGTERM, cwd=ROOT, env=env)
    assert status == 3, text
    log = (out / "seed-7" / "pdem.log").read_text()
    assert "mpiexec -n 2 " in log and "on 2 rank(s)" in log and "stop signal received" in log
    assert states(out)["seed-7"]["state"] == "stopped"
    r = pdem_campaign("run", p)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "resuming from" in (out / "seed-7" / "pdem.log").read_text()
    rec = json.loads((out / "seed-7" / "run.json").read_text())
    assert [a["exit"] for a in rec["attempts"]] == [3, 0] and rec["attempts"][1]["ranks"] == 2
    assert rec["core_s"] == pytest.approx(2 * rec["wall_s"], abs=0.01)
    assert all(a["cpu_s"] > 0 for a in rec["attempts"])  # mpiexec's tree: both ranks' CPU time
