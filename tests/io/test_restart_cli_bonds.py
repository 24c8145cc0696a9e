"""`pdem run` of a bonded oedometer (jobs/oedometer_ci.toml: breakable clumps whose members are held
by cohesive bonds, a staged run: pour, refill, vibrate, settle, load) stopped by SIGTERM mid-run on
2 ranks and resumed on another rank count gives the uninterrupted serial run's bits: every
dataset of results.h5 (the series, the fragment records) and the final checkpoint's tables
(bodies, clumps, members, contacts with the bond history), compared as tests/tools/compare_h5.py
does.

Two stops: one sent from outside once the refill stage's checkpoint exists (it lands mid-stage,
at the next stop poll), resumed on 3 ranks; and one sent by the run to itself (tests/tools/
inject_fault.py, kind SIGTERM) 50 steps before the step at which the reference ends a stage (a
multiple of 100: the stop poll and the stage's end test fall on the same step; the stage ends, the
next poll stops the run), resumed on 1 rank.
"""
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from pdem_cli import MPIEXEC, needs_mpiexec, pdem_cmd, run_pdem, signal_when

from factories import OEDOMETER_CI_JOB
from pdem.io.checkpoint import list_checkpoints

pytestmark = [needs_mpiexec, pytest.mark.slow]  # four oedometers of 13 000 steps

TOOLS = Path(__file__).resolve().parents[1] / "tools"
_spec = importlib.util.spec_from_file_location("compare_h5", TOOLS / "compare_h5.py")
compare_h5 = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(compare_h5)


def assert_same_run(ref, got):
    """results.h5 and the final checkpoint (but its meta: it records the rank count) bit for bit."""
    bad, n = compare_h5.compare_files(ref / "results.h5", got / "results.h5")
    assert not bad and n > 10, bad
    (step, want), (step_got, have) = (list_checkpoints(d / "checkpoints")[-1] for d in (ref, got))
    assert step == step_got
    bad, n = compare_h5.compare_files(want, have, skip=("meta",))
    assert not bad and n > 10, bad


@pytest.fixture(scope="module")
def ref(tmp_path_factory):
    base = tmp_path_factory.mktemp("restart_cli_bonds")
    scene = base / "oedometer.toml"
    shutil.copy(OEDOMETER_CI_JOB, scene)
    run_pdem(1, scene, base / "ref")
    return base, scene


def test_sigterm_mid_stage_on_2_resumed_on_3(ref):
    base, scene = ref
    out = base / "stopped"
    status, text = signal_when(pdem_cmd(2, scene, out), lambda: len(list_checkpoints(out / "checkpoints")) >= 2,
                               signal.SIGTERM)
    assert status == 3 and "stop signal received" in text, text[-3000:]
    stop_step = list_checkpoints(out / "checkpoints")[-1][0]
    assert stop_step not in {s for s, _ in list_checkpoints(base / "ref" / "checkpoints")}  # mid-stage
    r = run_pdem(3, scene, out)
    assert f"at step {stop_step}" in r.stdout
    assert_same_run(base / "ref", out)


def test_sigterm_on_a_stage_end_step_on_2_resumed_on_1(ref):
    base, scene = ref
    ends = [s for s, _ in list_checkpoints(base / "ref" / "checkpoints")]
    step = next(s for s in ends[1:] if s % 100 == 0)  # a stage ends on a stop-poll step
    out = base / "stopped_at_end"
    cmd = [str(MPIEXEC), "-n", "2", sys.executable, str(TOOLS / "inject_fault.py"), "-1", str(step - 50), "SIGTERM",
           "--", "run", str(scene), "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False,
                       env=dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1"))
    text = r.stdout
    assert r.returncode == 3 and "stop signal received" in text, text[-3000:] + r.stderr[-3000:]
    # the stage ended on that step as in the reference (its end test before the stop poll), and the
    # run stopped at the next poll, inside the next stage (it used to stop inside the ended stage)
    assert f"step {step}: checkpoint" in text and "(end of stage" in text.split(f"step {step}: checkpoint")[1]
    assert f"step {step + 100}: stop signal received" in text, text[-3000:]
    r = run_pdem(1, scene, out)
    assert "resuming from" in r.stdout
    assert_same_run(base / "ref", out)
