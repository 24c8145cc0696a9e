"""Failure agreement at every collective of pdem: when one rank fails at (on entry to) a collective —
an exception, or its process killed with ``kill -9`` — every rank leaves and the job ends within
seconds, with the status of the one mapping (`pdem.driver.failures.classify`, docs/reliability.md)
and one line naming the rank and the site; never a hang.

Every site of tests/tools/inject_fault.py (`SITES`: the start digest agreement, the output check,
the resume choice, the rebuild test, rebalancing, migration, the ghost-layer rebuild and the ghost
update, exact sums, the time step, the stability check, the stop-signal poll, checkpoint, results
and snapshot writes, and the stage machine's build, decision and end) on 2 and 3 ranks, the failing
rank the last one (the one whose partners wait in the collective); a few on 4 ranks, on rank 0 (the
writer of checkpoints, results and snapshots) and on every rank (then the job ends cleanly, the line
printed once); and SIGKILL of one rank on 2, 3 and 4 ranks (the launcher ends the job: Hydra's
status is the signal number, 9, and it reports the kill). A subprocess still running after
HUNG_AFTER seconds is a hung job (TimeoutExpired fails the test): a hang detector, not a timing.
Small scenes, a few hundred steps; the failing rank waits PDEM_FAILURE_GRACE_S = 3 s for the others
before it aborts the job.
"""
import importlib.util
import re
import signal

import pytest
from pdem_cli import needs_mpiexec
from test_failures_cli import INJECT, SCENE, pdem_lines, run, scene, warm  # noqa: F401 (warm: a fixture)

from factories import oedometer_ci_doc, toml_text

_spec = importlib.util.spec_from_file_location("inject_fault", INJECT)
inject_fault = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(inject_fault)
SITES, STARTUP = inject_fault.SITES, inject_fault.STARTUP

pytestmark = needs_mpiexec

HUNG_AFTER = 120  # s: every case ends in seconds; one still running after this is hung
GRACE = {"PDEM_FAILURE_GRACE_S": "3"}

# the plain scene with every output on (checkpoint, results, snapshot every 50 or 100 steps)
PLAIN = SCENE.replace("steps = 200", "steps = 400").replace(
    "output_every = 50", "output_every = 50\nsnapshot_every = 50\ncheckpoint_every = 100")
STAGED = {"stage-build", "stage-until", "stage-end"}  # sites of the stage machine: the oedometer
PLAIN_SITES = [s for s in SITES if s not in STAGED]

# the exception raised at each site, its status (the documented mapping) and the words of its line:
# every class of the mapping appears at some site
KIND = {
    "step": ("RuntimeError", 1, "internal error: RuntimeError: injected fault"),
    "digest": ("InputError", 2, "error: injected.key = 1"),
    "output": ("OSError", 5, "injected I/O error"),
    "resume": ("CheckpointError", 2, "error: checkpoint ckpt_injected.h5: injected damage"),
    "rebuild": ("Instability", 4, "unstable: step"),
    "rebalance": ("MemoryError", 5, "error: out of memory"),
    "migration": ("RuntimeError", 1, "internal error: RuntimeError: injected fault"),
    "ghost-build": ("MemoryError", 5, "error: out of memory"),
    "ghost": ("RuntimeError", 1, "internal error: RuntimeError: injected fault"),
    "exact-sum": ("Instability", 4, "unstable: step"),
    "timestep": ("RuntimeError", 1, "internal error: RuntimeError: injected fault"),
    "stability": ("Instability", 4, "unstable: step"),
    "stop-poll": ("OSError", 5, "injected I/O error"),
    "checkpoint": ("CheckpointWriteError", 5, "error: writing checkpoint ckpt_injected.h5"),
    "results": ("ENOSPC", 5, "no space left on the device"),
    "results-open": ("ResultsFileError", 2, "error: results file results.h5: injected damage"),
    "snapshot": ("SnapshotWriteError", 5, "error: writing snapshots snapshots.h5"),
    "stage-build": ("InputError", 2, "error: injected.key = 1"),
    "stage-until": ("RuntimeError", 1, "internal error: RuntimeError: injected fault"),
    "stage-end": ("OSError", 5, "injected I/O error"),
}


def test_every_site_has_a_kind():
    assert set(KIND) == set(SITES)


@pytest.fixture(scope="module")
def oedometer(tmp_path_factory):
    """The CI oedometer (breakable clumps: bonds, a staged run) cut short: its pour ends after
    0.01 s (settle_max_time), so the first stage ends within a few hundred steps."""
    d = tmp_path_factory.mktemp("oedometer")
    path = d / "oedometer.toml"
    path.write_text(toml_text(oedometer_ci_doc(settle_min_time=0.0, settle_max_time=0.01)))
    return path


def fault_step(site):
    return 0 if site in STARTUP | {"stage-build"} else 60


def inject(tmp_path, n_ranks, rank, site, kind, scene_path=None):
    """(status, stderr, stdout) of `pdem run` on n_ranks with ``kind`` at ``site`` on ``rank``."""
    s = scene_path or scene(tmp_path, PLAIN)
    rc, out, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path,
                       tool=[str(rank), str(fault_step(site)), f"{kind}@{site}"], env=GRACE, timeout=HUNG_AFTER)
    return rc, err, out


def check_alone(rc, err, n_ranks, rank, site, status, words):
    """One rank failed alone: the job ended with the failure's status and its one line, naming
    the site and the rank; only a bug shows a traceback."""
    assert rc == status, (rc, err[-3000:])
    lines = pdem_lines(err)
    assert len(lines) == 1, err[-3000:]
    assert words in lines[0] and f" at {site} (step " in lines[0], lines
    assert lines[0].endswith(f"(on rank {rank} of {n_ranks}; the job is aborted)"), lines
    assert (status == 1) == ("Traceback" in err), err[-3000:]


@pytest.mark.parametrize("n_ranks", [2, pytest.param(3, marks=pytest.mark.slow)])
@pytest.mark.parametrize("site", PLAIN_SITES)
def test_one_rank_fails_at_a_collective(warm, tmp_path, site, n_ranks):  # noqa: F811
    kind, status, words = KIND[site]
    rc, err, _ = inject(tmp_path, n_ranks, n_ranks - 1, site, kind)
    check_alone(rc, err, n_ranks, n_ranks - 1, site, status, words)


@pytest.mark.slow
@pytest.mark.parametrize("n_ranks", [2, 3])
@pytest.mark.parametrize("site", sorted(STAGED))
def test_one_rank_fails_in_the_stage_machine(oedometer, tmp_path, site, n_ranks):
    kind, status, words = KIND[site]
    rc, err, _ = inject(tmp_path, n_ranks, n_ranks - 1, site, kind, oedometer)
    check_alone(rc, err, n_ranks, n_ranks - 1, site, status, words)


@pytest.mark.parametrize("n_ranks, rank, site", [
    (4, 3, "ghost"), (4, 2, "migration"), (4, 0, "checkpoint"), (4, 3, "exact-sum"),
    (3, 0, "results"), (3, 0, "snapshot"), (2, 0, "checkpoint"), (3, 1, "digest"),
])
def test_other_ranks_and_four_ranks(warm, tmp_path, n_ranks, rank, site):  # noqa: F811
    """Rank 0 (the writer of checkpoints, results and snapshots: the others wait for its
    outcome), a middle rank (both its neighbours wait in the exchange), 4 ranks."""
    kind, status, words = KIND[site]
    rc, err, _ = inject(tmp_path, n_ranks, rank, site, kind)
    check_alone(rc, err, n_ranks, rank, site, status, words)


@pytest.mark.parametrize("n_ranks, site, kind, status, words", [
    (2, "checkpoint", "OSError", 5, "injected I/O error at checkpoint"),
    (3, "digest", "InputError", 2, "error: injected.key = 1: must be injected, at digest"),
    (3, "ghost", "Instability", 4, "unstable: step"),
])
def test_every_rank_fails_at_a_collective(warm, tmp_path, n_ranks, site, kind, status, words):  # noqa: F811
    """Every rank fails at the same collective: they agree (no abort), the line is printed once,
    without a rank, and the job exits with the status."""
    rc, err, _ = inject(tmp_path, n_ranks, -1, site, kind)
    assert rc == status, (rc, err[-3000:])
    lines = pdem_lines(err)
    assert len(lines) == 1 and words in lines[0] and "on rank" not in lines[0], err[-3000:]
    assert "Traceback" not in err


@pytest.mark.parametrize("n_ranks, rank, site", [
    (2, 1, "ghost"), (2, 0, "checkpoint"), (3, 2, "migration"), (3, 1, "exact-sum"), (4, 3, "snapshot"),
    (4, 1, "step"),
])
def test_one_rank_killed(warm, tmp_path, n_ranks, rank, site):  # noqa: F811
    """``kill -9`` of one rank at a collective: nothing of pdem runs on it; the launcher (Hydra)
    sees the process die, ends the others and exits with the signal number (9) — never a hang of
    the others in the collective. (The tool's line names the rank and the site.)"""
    rc, err, out = inject(tmp_path, n_ranks, rank, site, "SIGKILL")
    assert rc == signal.SIGKILL, (rc, err[-3000:])
    said = re.search(rf"inject_fault: rank {rank} \(pid (\d+)\) killed at {site} \(step \d+\)", err)
    assert said, err[-3000:]
    # Hydra's report, on its stdout (the pid it names is a process of the job, not always the killed one)
    assert "BAD TERMINATION" in out and "Killed (signal 9)" in out, out[-3000:]
    assert not pdem_lines(err), err[-3000:]  # nothing of pdem's ran after the kill
