"""The stability map report (`analysis.stability`) on synthetic campaign members with known
answers: energy series built by hand (rise, dissipation and release computed here from their
definitions), run records with each exit status, logs with and without pdem's one-line message,
and NaN planted in a checkpoint, an attribute, a text summary."""
import json
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from analysis.__main__ import main
from pdem.format.schema import write_results
from analysis.stability import energy_balance, judge_campaigns, scan_member

MARK = "=== pdem campaign: attempt"
SHOT = ("pdem: unstable: step 12: body gid 3 at (0.1, 0.2, 0.3) m moves 0.48 of its radius per step (|v| = 100 m/s, "
        "r = 0.01 m), more than 0.25 (dt = 4.7e-05 s): a contact this fast is crossed before the contact law can stop "
        "it (tunnelling): the initial velocity is too high for the time step; lower dt or the speed")

# K, U_el, P per sample: total = [10, 9, 8.5, 8.5]: no rise; 1.5 J dissipated of 10 - 8 = 2 J released
CALM = {"kinetic_energy": [0.0, 2.0, 1.0, 0.5], "elastic_energy": [0.0, 0.0, 0.5, 0.0],
        "potential_energy": [10.0, 7.0, 7.0, 8.0]}
# total = [10, 9, 9.15, 8.9]: rise 0.15 above the minimum 9, S = max(K + U) = 2: 7.5 %
WOBBLY = {"kinetic_energy": [0.0, 2.0, 1.15, 0.9], "elastic_energy": [0.0, 0.0, 0.0, 0.0],
          "potential_energy": [10.0, 7.0, 8.0, 8.0]}
# total = [10, 9, 9.5, 9.5]: rise 0.5 / S 2 = 25 %
GROWING = {"kinetic_energy": [0.0, 2.0, 1.5, 1.5], "elastic_energy": [0.0, 0.0, 0.0, 0.0],
           "potential_energy": [10.0, 7.0, 8.0, 8.0]}


def series(energies, work=None):
    n = len(energies["kinetic_energy"])
    s = {"step": np.arange(n) * 100.0, "time": np.arange(n) * 0.01}
    for k, v in energies.items():
        s[k] = (np.array(v), "J")
    s["total_energy"] = (sum(np.array(v) for v in energies.values()), "J")
    s["contacts_per_particle"] = (np.array([0.0, 1.0, 2.0, 2.5][:n]), "-")
    if work is not None:
        s["external_work"] = (np.array(work), "J")
        s["total_energy"] = (s["total_energy"][0] + np.array(work), "J")
    return s


def member(root, name, exit=0, log="", energies=CALM, external_work=0, work=None, ended=True):
    d = root / name
    d.mkdir(parents=True)
    if exit is not None:
        attempt = {"start": "t0", "end": "t1" if ended else None, "exit": exit if ended else None, "wall_s": 2.0,
                   "core_s": 2.0, "ranks": 1, "threads": 1}
        rec = {"member": name, "attempts": [attempt]}
        (d / "run.json").write_text(json.dumps(rec))
        (d / "pdem.log").write_text(f"{MARK} 1 started t0 on host: 1 rank(s) x 1 thread(s) ===\n"
                                    f"pdem 0.2.0: scene.toml on 1 rank(s)\n{log}\n")
    if energies is not None:
        write_results(d / "results.h5", series(energies, work), None,
                      {"scene": {}, "pdem_version": "test", "kind": "deposition"})
        if external_work is not None:
            with h5py.File(d / "results.h5", "a") as f:
                f.attrs["external_work"] = external_work
    return d


def campaign(root, names, expect=None, name="fake"):
    man = {"format": "pdem-campaign", "version": 1, "name": name, "seed_key": None, "varied": [], "cases": True,
           "analysis": {"expect": expect or {}},
           "members": [{"name": n, "dir": n, "params": {"case": n}, "ranks": 1, "threads": 1} for n in names]}
    (root / "campaign.json").write_text(json.dumps(man))
    return root


def test_energy_balance_known_numbers():
    calm = {k: v[0] for k, v in series(CALM).items() if isinstance(v, tuple)}
    calm.update(step=np.arange(4.0), time=np.arange(4.0))
    b = energy_balance(calm, {"external_work": 0})
    assert b["checked"] and b["ok"] and b["rise"] == 0.0 and b["scale"] == 2.0
    assert b["dissipated"] == pytest.approx(1.5) and b["released"] == pytest.approx(2.0)
    wob = {k: v[0] for k, v in series(WOBBLY).items() if isinstance(v, tuple)}
    wob["step"] = np.array([0, 100, 200, 300])
    b = energy_balance(wob, {"external_work": 0})
    assert b["rise"] == pytest.approx(0.15) and b["rise_ratio"] == pytest.approx(0.075) and b["ok"]
    assert b["rise_step"] == 200
    assert not energy_balance(wob, {"external_work": 0}, tolerance=0.07)["ok"]
    # external work without a record: not checked; a record: checked on E - W
    assert energy_balance(wob, {"external_work": 1}) == {
        "checked": False, "ok": True,
        "reason": "external work (boundaries move or loads act) and no external_work record"}
    assert not energy_balance(wob, {})["checked"]  # unknown: not checked either
    grow = {k: v[0] for k, v in series(GROWING, work=[0.0, 1.0, 3.0, 4.0]).items() if isinstance(v, tuple)}
    grow["step"] = np.arange(4)
    b = energy_balance(grow, {"external_work": 1})
    assert b["checked"] and b["work"] and b["rise"] == pytest.approx(0.5)
    assert energy_balance({"step": np.arange(3), "kinetic_energy": np.ones(3)}, {})["reason"].startswith(
        "no total_energy")


def synthetic(tmp_path):
    root = tmp_path / "camp"
    member(root, "calm")
    member(root, "wobbly", energies=WOBBLY)
    member(root, "growing", energies=GROWING)
    member(root, "shot", exit=4, log=SHOT, energies={k: v[:1] for k, v in CALM.items()})
    member(root, "mute4", exit=4, log="Traceback ...")
    member(root, "bug", exit=1, log="pdem: internal error: ZeroDivisionError: division by zero")
    member(root, "badinput", exit=2, log="pdem: error: simulation.dt = -1: must be 'auto' or a number > 0 [s]")
    d = member(root, "nanckpt")
    (d / "checkpoints").mkdir()
    with h5py.File(d / "checkpoints" / "ckpt_000000000300.h5", "w") as f:
        f["particles/vel"] = np.array([[0.0, np.nan, 1.0], [np.inf, 0.0, 0.0]])
        f.attrs["meta"] = json.dumps({"dt": float("nan")})
    d = member(root, "nantext")
    (d / "summary.txt").write_text("steps: 300\nunbalanced force ratio: nan\ninfo: fine\n")
    member(root, "moving", energies=GROWING, external_work=1)
    member(root, "worked", energies=CALM, external_work=1, work=[0.0, 0.5, 1.0, 1.5])  # E rises by W only
    member(root, "halted", exit=3, log="step 100: stop signal received")
    member(root, "killed", ended=False)
    (root / "never").mkdir(parents=True)
    member(root, "surprise")
    names = ["calm", "wobbly", "growing", "shot", "mute4", "bug", "badinput", "nanckpt", "nantext", "moving",
             "worked", "halted", "killed", "never", "surprise"]
    return campaign(root, names, expect={"calm": "stable", "shot": "stopped", "surprise": "stopped"})


def test_verdicts_of_synthetic_members(tmp_path):
    v = {x.member: x for x in judge_campaigns([synthetic(tmp_path)])}
    assert v["calm"].verdict == "stable" and v["calm"].line.startswith(
        "ran stably (energy balance: the mechanical energy never rose (tolerance 10 %); 1.5 J of the 2 J released "
        "dissipated (75 %); up to 2.5 contacts per particle; 300 steps, 0.03 s)")
    assert v["wobbly"].verdict == "stable" and "rose at most 7.5 % of the largest kinetic+elastic energy 2 J" in \
        v["wobbly"].line
    assert v["growing"].verdict == "FAILED" and v["growing"].line.startswith(
        "FAILED: ran to the end, but the mechanical energy rose by 25 % of the largest kinetic+elastic energy")
    assert "at step 200" in v["growing"].line
    assert v["shot"].verdict == "stopped" and v["shot"].line == "stopped: " + SHOT[len("pdem: unstable: "):]
    assert v["shot"].steps == 0
    assert v["mute4"].verdict == "FAILED"
    assert v["mute4"].line == "FAILED: exit 4, unstable without a message naming the cause"
    assert v["bug"].line == ("FAILED: exit 1, an internal error (a bug): pdem: internal error: ZeroDivisionError: "
                             "division by zero")
    assert v["badinput"].verdict == "FAILED"
    assert v["badinput"].line.startswith("FAILED: exit 2, bad input: pdem: error: ")
    nan = v["nanckpt"]
    assert nan.verdict == "FAILED" and nan.line.startswith("FAILED: 2 NaN and 1 infinite values in its outputs")
    where = {(f, w) for f, w, _, _ in nan.nonfinite}
    assert where == {("checkpoints/ckpt_000000000300.h5", "/ attribute meta"),
                     ("checkpoints/ckpt_000000000300.h5", "/particles/vel")}
    assert v["nantext"].verdict == "FAILED" and v["nantext"].nonfinite[0][:2] == (
        "summary.txt", "line 2: unbalanced force ratio: nan")
    assert v["moving"].verdict == "stable" and "energy balance not checked: external work" in v["moving"].line
    assert v["worked"].verdict == "stable" and "(net of the external work)" in v["worked"].line
    assert "the mechanical energy never rose" in v["worked"].line
    assert v["halted"].verdict == "incomplete" and v["halted"].line.startswith(
        "incomplete: stopped on a signal (exit 3) at step 300; run the campaign again to finish it (so far: energy "
        "balance: the mechanical energy never rose")
    assert v["killed"].verdict == "incomplete" and "no exit status recorded" in v["killed"].line
    assert v["never"].verdict == "pending"
    assert v["surprise"].verdict == "FAILED" and v["surprise"].line.startswith(
        "FAILED: expected to be stopped, but ran stably")
    assert [x.expected for x in v.values()].count(None) == 12


def test_scan_ignores_what_is_not_a_number(tmp_path):
    """Words such as 'info', 'infinitely', 'nano' and a scene's TOML text are not non-finite values."""
    d = member(tmp_path, "m")
    (d / "notes.txt").write_text("info: nano infinitely finite; dt = 'auto'\n")
    with h5py.File(d / "results.h5", "a") as f:
        f.attrs["scene_file"] = "# spheres at rest; nan-free\n[simulation]\ndt = 'auto'\n"
    assert scan_member(d) == []
    (d / "notes.txt").write_text("x = -inf\ny = NaN\n")
    assert [(w, n, i) for _, w, n, i in scan_member(d)] == [("line 1: x = -inf", 0, 1), ("line 2: y = NaN", 1, 0)]


@pytest.fixture
def analysis_cli(capsys):
    """``python -m analysis stability ARGS`` in this process: (exit status, stdout, stderr)."""
    def call(*args):
        capsys.readouterr()
        rc = main(["stability", *map(str, args)])
        out = capsys.readouterr()
        return SimpleNamespace(returncode=rc, stdout=out.out, stderr=out.err)
    return call


def test_report_files_and_exit_status(tmp_path, analysis_cli):
    good = tmp_path / "good"
    member(good, "calm")
    member(good, "shot", exit=4, log=SHOT)
    campaign(good, ["calm", "shot"], expect={"calm": "stable", "shot": "stopped"}, name="good")
    r = analysis_cli(good)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.splitlines()[0] == ("stability map PASSED: 2 members: 1 stable, 1 stopped, 0 FAILED, 0 incomplete, "
                                        "0 pending; no NaN or infinity in any output")
    out = good / "analysis"
    for f in ("stability.txt", "stability.md", "stability.json", "stability.png"):
        assert (out / f).is_file() and str(out / f) in r.stdout
    doc = json.loads((out / "stability.json").read_text())
    assert doc["passed"] and [m["verdict"] for m in doc["members"]] == ["stable", "stopped"]
    md = (out / "stability.md").read_text().splitlines()
    assert md[2].startswith("| campaign | member | verdict |") and len(md) == 6
    # a failing campaign: exit 1, the report still written; two directories need --out
    bad = synthetic(tmp_path)
    r = analysis_cli(bad)
    assert r.returncode == 1 and r.stdout.startswith("stability map FAILED: 15 members: 4 stable, 1 stopped, 7 FAILED, "
                                                     "2 incomplete, 1 pending"), r.stdout + r.stderr
    r = analysis_cli(good, bad)
    assert r.returncode == 2 and r.stderr.strip() == ("python -m analysis: error: several campaign directories: give "
                                                      "--out for the report"), r.stderr
    r = analysis_cli(good, bad, "--out", tmp_path / "both")
    assert r.returncode == 1 and "17 members" in r.stdout.splitlines()[0]
    assert "| good | calm | stable |" in (tmp_path / "both" / "stability.md").read_text()
    r = analysis_cli(tmp_path / "nowhere")
    assert r.returncode == 2 and "not a campaign directory" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_expectations_must_name_cases(tmp_path, analysis_cli):
    root = tmp_path / "c"
    member(root, "calm")
    campaign(root, ["calm"], expect={"calm": "stable", "typo": "stopped"})
    r = analysis_cli(root)
    assert r.returncode == 2 and "expect names cases the campaign does not have: typo" in r.stderr
    campaign(root, ["calm"], expect={"calm": "fine"})
    r = analysis_cli(root)
    assert r.returncode == 2 and 'must map case names to "stable" or "stopped"' in r.stderr
    r = analysis_cli(root, "--tolerance", "-1")
    assert r.returncode == 2 and "--tolerance -1.0: must be a number > 0" in r.stderr
