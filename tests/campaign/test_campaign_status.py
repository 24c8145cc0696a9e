"""``pdem campaign status`` on fake member directories, one per state (nothing is run)."""
import json

from campaign_helpers import write_campaign
from pdem.campaign.cli import main as campaign_main
from pdem.campaign.layout import write_campaign as expand_into
from pdem.campaign.record import end_attempt, member_state, start_attempt, take_lock
from pdem.campaign.spec import load_campaign
from pdem.campaign.status import status_rows


def attempt(d, exit_status, log="", wall=10.0, ranks=1, threads=2):
    rec = start_attempt(d, d.name, ranks, threads, "local")
    with open(d / "pdem.log", "a") as fh:
        fh.write(log)
    if exit_status is not None:
        end_attempt(d, rec, exit_status, wall)
    return rec


def test_status_of_each_state(tmp_path, tiny, capsys):
    p = write_campaign(tmp_path, "[seeds]\nvalues = [1, 2, 3, 4, 5, 6, 7]\n")
    camp = load_campaign(p)
    man = expand_into(camp, log=lambda m: None)
    d = {m.name: camp.out / m.name for m in camp.members}
    # done after a stop and a resume: two attempts, costs summed
    attempt(d["seed-1"], 3, "step 1400: stop signal received\n", wall=5.0)
    attempt(d["seed-1"], 0, "wrote results.h5\n", wall=7.0)
    # running: another process holds the lock
    attempt(d["seed-2"], None)
    lock = take_lock(d["seed-2"])
    # stopped on a signal (exit 3)
    attempt(d["seed-3"], 3, "step 900: stop signal received; writing a checkpoint\n")
    # interrupted: an attempt without an end and nobody holding the lock (the runner was killed)
    attempt(d["seed-4"], None)
    # failed: an instability (exit 4) and bad input (exit 2); a later line does not hide the cause
    attempt(d["seed-5"], 0, "old attempt\n")
    attempt(d["seed-5"], 4, "step 300: ...\npdem: unstable: step 300: overlap 0.0023 exceeds max_overlap_ratio\n"
                            "pdem campaign: exit status 4 after 1.0 s\n")
    attempt(d["seed-6"], 2, "pdem: error: checkpoint ckpt_1.h5: damaged\n")
    # seed-7: pending (never started)
    try:
        rows = {r["name"]: r for r in status_rows(camp.out, man)}
        assert {n: r["state"] for n, r in rows.items()} == {
            "seed-1": "done", "seed-2": "running", "seed-3": "stopped", "seed-4": "stopped", "seed-5": "failed",
            "seed-6": "failed", "seed-7": "pending"}
        assert rows["seed-1"]["attempts"] == 2 and rows["seed-1"]["wall_s"] == 12.0
        assert rows["seed-1"]["core_s"] == 24.0 and rows["seed-1"]["exit"] == 0
        assert rows["seed-3"]["exit"] == 3 and "stopped on a signal" in rows["seed-3"]["message"]
        assert "interrupted" in rows["seed-4"]["message"] and rows["seed-4"]["exit"] is None
        assert rows["seed-5"]["message"] == "pdem: unstable: step 300: overlap 0.0023 exceeds max_overlap_ratio"
        assert rows["seed-6"]["message"] == "pdem: error: checkpoint ckpt_1.h5: damaged"
        assert rows["seed-7"]["attempts"] == 0 and rows["seed-7"]["message"] == ""
        # the command line: from the campaign file and from the directory, as a table and as JSON
        assert campaign_main(["status", str(p)]) == 0
        text = capsys.readouterr().out
        assert "7 members: 1 done, 1 running, 2 stopped, 2 failed, 1 pending" in text
        assert "pdem: unstable: step 300" in text
        assert campaign_main(["status", str(camp.out), "--json"]) == 0
        js = json.loads(capsys.readouterr().out)
        assert [r["state"] for r in js] == ["done", "running", "stopped", "stopped", "failed", "failed", "pending"]
    finally:
        lock.close()
    assert member_state(d["seed-2"])[0] == "stopped"  # lock released, no end recorded


def test_status_before_expansion_lists_pending(tmp_path, tiny, capsys):
    p = write_campaign(tmp_path, "[seeds]\nvalues = [1, 2]\n")
    assert campaign_main(["status", str(p)]) == 0
    out = capsys.readouterr().out
    assert "2 members: 0 done, 0 running, 0 stopped, 0 failed, 2 pending" in out
    assert not (tmp_path / "runs").exists()  # status never writes


def test_a_member_killed_by_sigkill_counts_as_stopped(tmp_path):
    """Exit 137 (128 + SIGKILL: kill -9, the OOM killer) is no failure of pdem's: the member's
    checkpoints are whole, so it counts as stopped and the next run resumes it; any other exit
    (e.g. 139, a segfault) is a failure."""
    d = tmp_path / "m"
    d.mkdir()
    attempt(d, 137, "step 300 ...\n")
    state, _, msg = member_state(d)
    assert state == "stopped" and "killed by SIGKILL" in msg and "runs again from its newest checkpoint" in msg
    attempt(d, 139, "step 500 ...\n")
    assert member_state(d)[0] == "failed"
