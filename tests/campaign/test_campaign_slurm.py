"""The SLURM job-array script of a campaign, run without a scheduler: fake ``srun``, ``scontrol``
and ``sbatch`` shell scripts on PATH, SLURM_ARRAY_TASK_ID etc. in the environment (``launcher =
"srun"``: the fake srun stands in for the allocation); and the single-run template
jobs/templates/slurm.sbatch, the same template, run with the venv's mpiexec.

The fake srun logs its arguments and plays pdem for the member it was given (``--out DIR``):
per call, the next action of FAKE_PLAN_<member>: an exit status, ``wait`` (until SIGUSR1/SIGTERM,
then exit 3 as pdem does after its checkpoint) or ``exec`` (run the real ``pdem run``)."""
import json
import os
import signal
import subprocess
import sys

import h5py

import pytest

from campaign_helpers import ROOT, pdem_campaign, write_campaign
from factories import TINY_DEPOSITION
from pdem.campaign.slurm import run_script
from pdem_cli import needs_mpiexec, signal_when

FAKE_SRUN = r"""#!/usr/bin/env bash
echo "srun $*" >> "$FAKE_LOG"
while [[ "$1" == --* ]]; do shift; done
cmd=("$@"); out=""
for ((i = 0; i < ${#cmd[@]}; i++)); do [ "${cmd[$i]}" = "--out" ] && out="${cmd[$((i + 1))]}"; done
n=$(( $(cat "$out/fake_calls" 2>/dev/null || echo 0) + 1 )); echo "$n" > "$out/fake_calls"
plan_var="FAKE_PLAN_$(basename "$out" | tr -c 'A-Za-z0-9\n' '_')"
plan=(${!plan_var:-0}); action="${plan[$((n - 1))]:-0}"
case "$action" in
  exec) exec "${cmd[@]}" ;;
  wait) trap 'echo "step 100: stop signal received"; exit 3' USR1 TERM
        touch "$out/fake_waiting"; while true; do sleep 0.05; done ;;
  4) echo "pdem: unstable: fake instability"; exit 4 ;;
  *) echo "fake pdem run: exit $action"; exit "$action" ;;
esac
"""
FAKE_SCONTROL = '#!/usr/bin/env bash\necho "scontrol $*" >> "$FAKE_LOG"\n'
FAKE_SBATCH = '#!/usr/bin/env bash\necho "sbatch $*" >> "$FAKE_LOG"\necho "Submitted batch job 4242"\n'

CAMPAIGN = """
[set]
"run.steps" = 2000
[seeds]
values = [1, 2, 3]
[slurm]
time = "0-02:00:00"
partition = "short"
account = "ballast"
signal_lead = 240
max_running = 2
launcher = "srun"
launcher_args = ["--mpi=pmi2"]
options = ["--mem-per-cpu=2G", "--constraint=cpu"]
"""


def fake_bin(tmp_path):
    b = tmp_path / "fakebin"
    b.mkdir()
    for name, text in (("srun", FAKE_SRUN), ("scontrol", FAKE_SCONTROL), ("sbatch", FAKE_SBATCH)):
        (b / name).write_text(text)
        (b / name).chmod(0o755)
    return b


def slurm_env(tmp_path, task, **plans):
    env = dict(os.environ, PATH=f"{tmp_path / 'fakebin'}:{os.environ['PATH']}", FAKE_LOG=str(tmp_path / "fake.log"),
               SLURM_ARRAY_JOB_ID="77", SLURM_ARRAY_TASK_ID=str(task), SLURM_JOB_ID=str(100 + task),
               SLURM_SUBMIT_DIR=str(tmp_path), OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    env.update({f"FAKE_PLAN_{k}": v for k, v in plans.items()})
    return env


def fake_log(tmp_path):
    p = tmp_path / "fake.log"
    return p.read_text().splitlines() if p.exists() else []


def make_script(tmp_path):
    p = write_campaign(tmp_path, CAMPAIGN, head="ranks = 2\nthreads = 3")
    r = pdem_campaign("slurm", p)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "runs" / "camp"
    return p, out, out / "campaign.sbatch"


def test_script_passes_bash_n_and_asks_for_the_resources(tmp_path, tiny):
    p, out, script = make_script(tmp_path)
    assert subprocess.run(["bash", "-n", str(script)]).returncode == 0
    text = script.read_text()
    for line in ("#SBATCH --array=0-2%2", "#SBATCH --ntasks=2", "#SBATCH --cpus-per-task=3",
                 "#SBATCH --time=0-02:00:00", "#SBATCH --signal=B:USR1@240", "#SBATCH --requeue",
                 "#SBATCH --partition=short", "#SBATCH --account=ballast", "#SBATCH --mem-per-cpu=2G",
                 "#SBATCH --constraint=cpu", f"#SBATCH --output={out}/slurm/%A_%a.out"):
        assert line in text.splitlines(), line
    assert "export NUMBA_NUM_THREADS=3 OMP_NUM_THREADS=1" in text
    assert (out / "slurm").is_dir() and (out / "seed-3" / "scene.toml").exists()
    # writing it again changes nothing; --submit hands it to sbatch
    before = script.stat().st_mtime_ns
    fake_bin(tmp_path)
    r = pdem_campaign("slurm", p, "--submit", env=slurm_env(tmp_path, 0))
    assert r.returncode == 0 and "Submitted batch job 4242" in r.stdout
    assert fake_log(tmp_path) == [f"sbatch {script}"] and script.stat().st_mtime_ns == before


def run_task(script, env, timeout=600):
    return subprocess.run(["bash", str(script)], capture_output=True, text=True, env=env, timeout=timeout)


def test_array_task_requeue_on_exit_3_and_resume(tmp_path, tiny):
    _, out, script = make_script(tmp_path)
    fake_bin(tmp_path)
    # task 1 = seed-2: pdem stops with exit 3 (checkpointed): the task requeues itself
    r = run_task(script, slurm_env(tmp_path, 1, seed_2="3 0"))
    assert r.returncode == 3, r.stdout + r.stderr
    log = fake_log(tmp_path)
    assert log[0].startswith("srun --ntasks=2 --cpus-per-task=3 --mpi=pmi2 ") and log[0].endswith(
        f"-m pdem run {out}/seed-2/scene.toml --out {out}/seed-2")
    assert log[1] == "scontrol requeue 77_1"
    st = pdem_campaign("status", out)
    assert "seed-2  stopped     3" in st.stdout and "seed-1  pending" in st.stdout
    # the requeued task runs the same command again: pdem resumes and finishes; no requeue
    r = run_task(script, slurm_env(tmp_path, 1, seed_2="3 0"))
    assert r.returncode == 0, r.stdout + r.stderr
    assert len(fake_log(tmp_path)) == 3 and fake_log(tmp_path)[2].startswith("srun ")
    # once more (e.g. the whole array resubmitted): a done member is skipped without srun
    r = run_task(script, slurm_env(tmp_path, 1))
    assert r.returncode == 0 and "already done" in r.stdout and len(fake_log(tmp_path)) == 3
    rec = json.loads((out / "seed-2" / "run.json").read_text())
    assert [a["exit"] for a in rec["attempts"]] == [3, 0]
    assert [a["slurm_job"] for a in rec["attempts"]] == ["77_1", "77_1"] and rec["attempts"][0]["launcher"] == "srun"
    assert rec["attempts"][0]["ranks"] == 2 and rec["attempts"][0]["threads"] == 3
    assert rec["core_s"] == rec["attempts"][0]["core_s"] + rec["attempts"][1]["core_s"]
    # a failing member: its status, no requeue
    r = run_task(script, slurm_env(tmp_path, 0, seed_1="4"))
    assert r.returncode == 4 and not any(x.startswith("scontrol") for x in fake_log(tmp_path)[3:])
    assert "pdem: unstable: fake instability" in pdem_campaign("status", out).stdout
    # an index beyond the members
    r = run_task(script, slurm_env(tmp_path, 3))
    assert r.returncode == 2 and "the campaign has 3 members" in r.stderr


def test_usr1_at_the_wall_time_is_forwarded_and_requeues(tmp_path, tiny):
    _, out, script = make_script(tmp_path)
    fake_bin(tmp_path)
    status, text = signal_when(["bash", str(script)], (out / "seed-3" / "fake_waiting").exists,
                               signal.SIGUSR1, env=slurm_env(tmp_path, 2, seed_3="wait 0"))  # --signal=B:USR1@240
    assert status == 3, text
    assert "requeueing array task 77_2" in text and fake_log(tmp_path)[-1] == "scontrol requeue 77_2"
    assert "step 100: stop signal received" in (out / "seed-3" / "pdem.log").read_text()


def test_real_pdem_through_srun_stops_and_resumes(tmp_path, tiny):
    """The fake srun runs the real ``pdem run`` (1 rank): USR1 -> checkpoint, exit 3, requeue; the
    requeued task resumes from the checkpoint and finishes. (20 000 steps: the signal passes
    through the fake srun and the member runner, and 2000 tiny steps can end before it arrives.)"""
    p = write_campaign(tmp_path, '[set]\n"run.steps" = 20000\n[seeds]\nvalues = [5]\n[slurm]\nlauncher = "srun"\n')
    assert pdem_campaign("slurm", p).returncode == 0
    out = tmp_path / "runs" / "camp"
    script = out / "campaign.sbatch"
    fake_bin(tmp_path)
    env = slurm_env(tmp_path, 0, seed_5="exec exec")
    log = out / "seed-5" / "pdem.log"
    status, text = signal_when(["bash", str(script)], lambda: log.exists() and "step      100" in log.read_text(),
                               signal.SIGUSR1, env=env)
    assert status == 3, text
    assert fake_log(tmp_path)[-1] == "scontrol requeue 77_0"
    r = run_task(script, env)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "resuming from" in log.read_text()
    with h5py.File(out / "seed-5" / "results.h5") as f:
        assert f["series"]["step"][-1] == 20000
    assert sys.executable in script.read_text()


def test_one_template_the_venvs_mpiexec_and_the_numba_cache_beside_the_runs(tmp_path, tiny):
    """jobs/templates/slurm.sbatch is `run_script()`; a campaign's default script launches like it."""
    assert (ROOT / "jobs" / "templates" / "slurm.sbatch").read_text() == run_script()
    p = write_campaign(tmp_path, "[seeds]\nvalues = [1]\n")
    assert pdem_campaign("slurm", p).returncode == 0
    text = (tmp_path / "runs" / "camp" / "campaign.sbatch").read_text()
    assert '"$PYTHON" -m pdem campaign member "$CAMPAIGN_DIR" "$member" --launcher mpiexec &' in text.splitlines()
    assert 'export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-$CAMPAIGN_DIR/.numba_cache}"' in text.splitlines()
    assert 'export NUMBA_CACHE_DIR="${NUMBA_CACHE_DIR:-$(dirname "$OUT")/.numba_cache}"' in run_script().splitlines()
    assert "export NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1 MPLBACKEND=Agg" in text.splitlines()
    trap = "trap 'kill -USR1 $pid 2>/dev/null' USR1"
    assert trap in text.splitlines() and trap in run_script().splitlines()


@needs_mpiexec
@pytest.mark.slow
def test_single_run_template_runs_on_the_allocations_ranks(tmp_path):
    """The template with SLURM's variables set and a fake scontrol: the venv's mpiexec starts
    SLURM_NTASKS = 2 ranks, and numba's cache goes to the run folder's parent (compiled anew)."""
    fake_bin(tmp_path)
    (tmp_path / "tiny.toml").write_text(TINY_DEPOSITION)
    env = {k: v for k, v in slurm_env(tmp_path, 0).items() if k != "NUMBA_CACHE_DIR"}
    env.update(SLURM_NTASKS="2", SCENE="tiny.toml", OUT="runs/t", PDEM_PYTHON=sys.executable,
               PYTHONPATH=os.pathsep.join(sys.path))
    r = subprocess.run(["bash", str(ROOT / "jobs" / "templates" / "slurm.sbatch")], capture_output=True, text=True,
                       env=env, cwd=tmp_path, timeout=900)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "on 2 rank(s)" in r.stdout and (tmp_path / "runs" / "t" / "results.h5").exists()
    assert any((tmp_path / "runs" / ".numba_cache").iterdir()) and fake_log(tmp_path) == []
