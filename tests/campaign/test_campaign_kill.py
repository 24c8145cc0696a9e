"""A campaign disturbed every way at once, then run again: one member killed with ``kill -9``
mid-run (after its first checkpoint), the runner stopped by SIGTERM while another member runs,
one member already finished. The second ``campaign run`` must leave the finished member's files
untouched (not run, not rewritten), resume the killed member from its checkpoint (exit 137 counts
as stopped, `pdem.campaign.record.EXIT_KILLED`) and the stopped one from its stop checkpoint, and
every member's results must equal those of the same campaign run undisturbed, bit for bit.

Tiny members (50 spheres, 1 rank each, two at a time on --cores 2): "a" 400 steps, "b" and "c"
20 000 steps with a checkpoint every 2000.
"""
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

from pdem.format.campaign import RUN

pytestmark = pytest.mark.slow  # three campaigns of 40 000 steps in all, each

CAMPAIGN = """
[set]
"run.checkpoint_every" = 2000
[[case]]
name = "a"
"deposition.seed" = 1
[[case]]
name = "b"
"deposition.seed" = 2
"run.steps" = 20000
[[case]]
name = "c"
"deposition.seed" = 3
"run.steps" = 20000
"""


def last_attempt(d):
    try:
        return json.loads((d / RUN).read_text())["attempts"][-1]
    except (FileNotFoundError, json.JSONDecodeError, KeyError, IndexError):
        return None


def logged_steps(d):
    log = d / "pdem.log"
    return log.exists() and any(x.startswith("step ") and " t = " in x for x in log.read_text().splitlines())


def member_pid(d):
    """The pid of the `pdem run` process of member directory ``d`` (from /proc)."""
    scene = str((d / "scene.toml").resolve())
    for p in Path("/proc").iterdir():
        if p.name.isdigit():
            try:
                argv = (p / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if scene.encode() in argv and b"pdem" in argv:
                return int(p.name)
    return None


def series(path):
    with h5py.File(path) as f:
        return {k: f["series"][k][()] for k in f["series"]}


def test_member_killed_runner_stopped_then_resumed(tmp_path, tiny):
    p = write_campaign(tmp_path, CAMPAIGN)
    out = tmp_path / "runs" / "camp"
    a, b, c = (out / n for n in "abc")
    killed = []

    def disturb():
        """Kill b (-9) once a is done and b has a checkpoint; then stop the runner once b's kill is
        recorded and c runs its step loop (its signal handlers are in)."""
        if not killed:
            done = (last_attempt(a) or {}).get("exit") == 0
            if done and list((b / "checkpoints").glob("ckpt_*.h5")) and (pid := member_pid(b)):
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
            return False
        return (last_attempt(b) or {}).get("exit") is not None and logged_steps(c)

    env = dict(os.environ, OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    status, text = signal_when([sys.executable, "-m", "pdem", "campaign", "run", str(p), "--cores", "2"], disturb,
                               signal.SIGTERM, cwd=ROOT, env=env)
    assert status == 3, text
    assert "b: killed (SIGKILL; the next run resumes it from its checkpoint), exit 137" in text, text
    assert "SIGTERM received: stopping 1 running member(s)" in text, text
    st = {x["name"]: x for x in json.loads(pdem_campaign("status", out, "--json").stdout)}
    assert {n: st[n]["state"] for n in "abc"} == {"a": "done", "b": "stopped", "c": "stopped"}, st
    assert st["b"]["exit"] == 137 and "killed by SIGKILL" in st["b"]["message"]
    assert st["c"]["exit"] == 3
    b_ckpt = sorted((b / "checkpoints").glob("ckpt_*.h5"))[-1]
    finished = {f: (f.read_bytes(), f.stat().st_mtime_ns) for f in a.rglob("*") if f.is_file() and f.name != ".lock"}

    r = pdem_campaign("run", p, "--cores", "2")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "1 done, 2 to run (2 resume from a checkpoint)" in r.stdout, r.stdout
    assert f"resuming from {b_ckpt}" in (b / "pdem.log").read_text()
    assert "resuming from" in (c / "pdem.log").read_text()
    # the finished member was neither run again nor rewritten
    after = {f: (f.read_bytes(), f.stat().st_mtime_ns) for f in a.rglob("*") if f.is_file() and f.name != ".lock"}
    assert after == finished
    assert len(json.loads((a / RUN).read_text())["attempts"]) == 1
    assert [x["exit"] for x in json.loads((b / RUN).read_text())["attempts"]] == [137, 0]

    ref = tmp_path / "ref"
    r = pdem_campaign("run", p, "--out", ref, "--cores", "2")
    assert r.returncode == 0, r.stdout + r.stderr
    for n in "abc":
        got, want = series(out / n / "results.h5"), series(ref / n / "results.h5")
        assert sorted(got) == sorted(want) and want["step"][-1] == (400 if n == "a" else 20000)
        for k in want:
            assert got[k].dtype == want[k].dtype and got[k].tobytes() == want[k].tobytes(), (n, k)
            assert np.array_equal(got[k], want[k]), (n, k)
