"""No hung jobs, no silent nonsense: how `pdem run` ends under faults and bad input, on 1 and 2
ranks (subprocesses through the real command line; docs/reliability.md).

- an exception on ONE rank (RuntimeError, MemoryError, OSError, an instability seen by one
  rank) while the other waits in a collective: the job ends (the subprocess timeout would kill a
  hung one and fail the test) with the failure's status, the line printed once;
- bad input and errors every rank raises: printed once, status 2;
- runaway runs (a shot into a wall, dt = 1 s): status 4 naming the body, never 0;
- too many ranks for the slabs: status 2 with the largest usable count;
- ranks launched on different scene files or arguments (an MPMD launch): status 2 at start,
  one line naming the rank, never a hang;
- a run whose requested length no run could reach (run.steps, --steps, a stage's end time):
  status 2 at start, one line naming the field;
- output failures: --out a file or under a file, its checkpoints folder unusable, a damaged
  results.h5 on resume (refused on every rank together), a full disk (status 5, one line, never
  a segfault);
- a campaign file or its base scene that is a folder or not text: status 2, one line.
Fault injection: tests/tools/inject_fault.py (the real CLI with one rank's step raising).
"""
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from pdem_cli import MPIEXEC

ROOT = Path(__file__).resolve().parents[2]
INJECT = ROOT / "tests" / "tools" / "inject_fault.py"
HUNG_AFTER = 300  # s: a job still running after this is hung (they end in seconds: a guard, not a timing)

SCENE = """
[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]

[run]
steps = 200
progress_every = 0
output_every = 50

[materials.ballast]
density = 2600.0
young = 2.8e7
poisson = 0.3
friction_angle = 0.5

[deposition]
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.4, 0.1, 0.3]
count = 120
radius = 0.01
seed = 1
material = "ballast"
walls_material = "ballast"
"""

SHOT = """
[simulation]
dt = "auto"
damping = 0.0
gravity = [0.0, 0.0, 0.0]

[run]
steps = 2000
progress_every = 0

[materials.ballast]
density = 2600.0
young = 2.8e7
poisson = 0.3
friction_angle = 0.5

[[walls]]
axis = "x"
position = 0.0
material = "ballast"

[[spheres]]
pos = [[0.05, 0.0, 0.0], [0.3, 0.0, 0.0]]
radius = 0.01
material = "ballast"
vel = [[-100.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
"""


def run(n_ranks, argv, tmp_path, env=None, tool=None, timeout=HUNG_AFTER):
    """(returncode, stdout, stderr) of ``pdem ARGV`` (or the fault tool) on n_ranks; a run that
    has not ended after ``timeout`` seconds is killed and the test fails (TimeoutExpired)."""
    cmd = [sys.executable] + ([str(INJECT), *tool, "--"] if tool else ["-m", "pdem"]) + list(argv)
    if n_ranks > 1:
        cmd = [str(MPIEXEC), "-n", str(n_ranks)] + cmd
    return run_cmd(cmd, tmp_path, env, timeout)


def run_cmd(cmd, tmp_path, env=None, timeout=HUNG_AFTER):
    """(returncode, stdout, stderr) of ``cmd`` in ``tmp_path``, killed after ``timeout`` s (TimeoutExpired)."""
    e = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1", **(env or {}))
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=e, cwd=tmp_path, check=False)
    return r.returncode, r.stdout, r.stderr


def scene(tmp_path, text=SCENE, name="scene.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def pdem_lines(err):
    return [x for x in err.splitlines() if x.startswith("pdem: ")]


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """One short run first, so that numba's cache holds the kernels before the guarded runs (a
    cold cache compiles for minutes on a loaded machine)."""
    d = tmp_path_factory.mktemp("warm")
    rc, _, err = run(1, ["run", str(scene(d)), "--out", "out", "--steps", "100"], d, timeout=900)
    assert rc == 0, err[-2000:]


@pytest.mark.parametrize("n_ranks", [1, 2])
@pytest.mark.parametrize("kind, status, words", [
    ("RuntimeError", 1, ["internal error", "RuntimeError", "injected fault"]),
    ("MemoryError", 5, ["out of memory"]),
    ("OSError", 5, ["injected I/O error"]),
    ("Instability", 4, ["unstable", "injected instability"]),
])
def test_exception_on_one_rank_ends_the_job(warm, tmp_path, n_ranks, kind, status, words):
    """The fault on the last rank at step 60; the other rank waits in the next collective. The
    job must end (one still running after HUNG_AFTER is killed: TimeoutExpired) with the status of
    the failure and its line once. The grace time is 5 s here (PDEM_FAILURE_GRACE_S; default 10 s)."""
    s = scene(tmp_path)
    rc, out, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path, tool=[str(n_ranks - 1), "60", kind],
                       env={"PDEM_FAILURE_GRACE_S": "5"})
    assert rc == status, (rc, out[-2000:], err[-3000:])
    lines = pdem_lines(err)
    assert len(lines) == 1, err[-3000:]
    for w in words:
        assert w in lines[0], lines
    if n_ranks > 1:
        assert f"on rank 1 of {n_ranks}" in lines[0]
    if kind != "RuntimeError":  # only a bug (internal error) shows its traceback
        assert "Traceback" not in err


@pytest.mark.parametrize("n_ranks", [1, 2])
@pytest.mark.parametrize("edit, words", [
    (("young = 2.8e7", "young = true"), ["young", "True", "> 0"]),
    (("damping = 0.3", "damping = 0.3\nallow_initial_overlap = \"false\""), ["allow_initial_overlap", "true or false"]),
    (("progress_every = 0", "progress_every = 0\ncheckpoint_every_s = \"abc\""), ["checkpoint_every_s", "'abc'"]),
    (("progress_every = 0", "progress_every = 0\ncheckpoint_every_s = nan"), ["checkpoint_every_s", "nan"]),
    (("progress_every = 0", "progress_every = 0\nsnapshot_contacts = 1"), ["snapshot_contacts = 1", "true or false"]),
    (("seed = 1", "seed = -1"), ["deposition.seed", "-1"]),
])
def test_bad_input_once_status_2(tmp_path, n_ranks, edit, words):
    s = scene(tmp_path, SCENE.replace(*edit))
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path)
    assert rc == 2, (rc, err[-2000:])
    lines = pdem_lines(err)
    assert len(lines) == 1 and "Traceback" not in err, err[-2000:]
    for w in words:
        assert w in lines[0], lines


@pytest.mark.parametrize("n_ranks", [1, 2, 3])
def test_output_directory_problems(tmp_path, n_ranks):
    """--out a file, under a file, /dev/null; its checkpoints/ a file or a folder that cannot be
    created: status 2 and one line naming the path at start (the checkpoints folder was found
    only at the first checkpoint, after the work, as a failed write: status 5)."""
    s = scene(tmp_path)
    (tmp_path / "afile").write_text("x")
    (tmp_path / "ck_file").mkdir()
    (tmp_path / "ck_file" / "checkpoints").write_text("x")
    (tmp_path / "ck_link").mkdir()
    (tmp_path / "ck_link" / "checkpoints").symlink_to("/proc/self/no-such-folder")  # a folder nobody can create
    for out, words in (
        ("afile", ["--out afile", "not a directory"]),
        ("afile/sub", ["--out afile/sub", "Not a directory"]),
        ("/dev/null", ["--out /dev/null", "not a directory"]),
        ("ck_file", ["--out ck_file: its checkpoints folder ck_file/checkpoints exists and is not a directory"]),
        ("ck_link", ["--out ck_link: its checkpoints folder ck_link/checkpoints cannot be created or written"]),
    ):
        rc, out_text, err = run(n_ranks, ["run", str(s), "--out", out], tmp_path)
        lines = pdem_lines(err)
        assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (out, rc, err[-2000:])
        assert "step" not in out_text  # found at start, before the scene is built or a step is made
        for w in words:
            assert w in lines[0], lines


@pytest.mark.parametrize("n_ranks", [2, 3])
@pytest.mark.parametrize("differ, words", [
    ("file", ["read a different scene file"]),
    ("args", ["was given different arguments"]),
])
def test_ranks_that_disagree_on_their_input_stop_at_start(tmp_path, n_ranks, differ, words):
    """An MPMD launch (mpiexec -n N-1 pdem run A : -n 1 pdem run B): the last rank reads another
    scene file (another seed: it would build other spheres and the ranks would wait on each
    other forever) or is given another --steps. Every rank stops at start: status 2, one line
    naming that rank; a hung job is killed after HUNG_AFTER (TimeoutExpired fails the test)."""
    a = scene(tmp_path)
    b = scene(tmp_path, SCENE.replace("seed = 1", "seed = 2"), name="other.toml")
    pdem = [sys.executable, "-m", "pdem", "run"]
    last = [str(b), "--out", "out"] if differ == "file" else [str(a), "--out", "out", "--steps", "150"]
    cmd = [str(MPIEXEC), "-n", str(n_ranks - 1), *pdem, str(a), "--out", "out", ":", "-n", "1", *pdem, *last]
    rc, _, err = run_cmd(cmd, tmp_path)
    lines = pdem_lines(err)
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (rc, err[-2000:])
    assert f"ranks disagree on their input: rank {n_ranks - 1} " in lines[0], lines
    for w in words:
        assert w in lines[0], lines
    assert not (tmp_path / "out").exists()  # stopped before any work


@pytest.mark.parametrize("n_ranks", [1, 2, 3])
@pytest.mark.parametrize("how", ["run.steps", "--steps", "stage"])
def test_absurd_run_length_refused_at_start(tmp_path, n_ranks, how):
    """10**15 steps (centuries at any step cost: pdem.driver.preflight.MAX_STEPS) asked by
    run.steps, by --steps, or by a stage's end (the oedometer's pour settles up to 1e12 s):
    status 2, one line naming the field, before any step (a plain run: before its output)."""
    from factories import oedometer_ci_doc, toml_text

    s = scene(tmp_path, SCENE.replace("steps = 200", "steps = 1000000000000000") if how == "run.steps" else SCENE)
    extra, words = [], [f"{how} = 1000000000000000: 1e+15 steps would take at least 317 years"]
    if how == "--steps":
        extra = ["--steps", "1000000000000000"]
    elif how == "stage":
        s = scene(tmp_path, toml_text(oedometer_ci_doc(settle_max_time=1e12)))
        # refused first by the plausible range of the key (pdem/scenes/common/bounds.py), before the
        # stage's projected length (driver/preflight.check_run_length) would be
        words = ["oedometer.settle_max_time = 1000000000000.0", "plausible range 0 .. 1000 s"]
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out", *extra], tmp_path)
    lines = pdem_lines(err)
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (rc, err[-2000:])
    for w in words:
        assert w in lines[0], lines
    assert how == "stage" or not (tmp_path / "out").exists()


def test_negative_steps_refused(tmp_path):
    s = scene(tmp_path)
    rc, _, err = run(2, ["run", str(s), "--out", "out", "--steps", "-5"], tmp_path)
    assert rc == 2 and pdem_lines(err) == [
        "pdem: error: --steps = -5: must be an integer >= 0 (the total steps of the run)"
    ]


@pytest.mark.parametrize("command", ["expand", "run", "status"])
def test_campaign_file_or_base_scene_a_folder_or_binary(tmp_path, command):
    """`pdem campaign run DIR`, a binary campaign file, a base scene that is a folder or binary:
    one line naming the file, status 2, no traceback (were a traceback each)."""
    folder = tmp_path / "folder"
    folder.mkdir()
    (tmp_path / "binary.toml").write_bytes(bytes(range(256)))
    (tmp_path / "base_folder.toml").write_text('[campaign]\nbase = "folder"\n[seeds]\nvalues = [1]\n')
    (tmp_path / "base_binary.toml").write_text('[campaign]\nbase = "binary.toml"\n[seeds]\nvalues = [1]\n')
    cases = [("binary.toml", "binary.toml: not a text file in UTF-8 (a TOML campaign file is)"),
             ("base_folder.toml", f"campaign.base = 'folder': {folder}: is a directory, not a base scene file"),
             ("base_binary.toml", "campaign.base = 'binary.toml': ")]
    if command != "status":  # status reads a folder as a campaign's folder (its campaign.json)
        cases.append(("folder", "folder: is a directory, not a campaign file"))
    for name, words in cases:
        rc, _, err = run(1, ["campaign", command, name], tmp_path)
        assert rc == 2 and "Traceback" not in err, (name, rc, err[-2000:])
        assert pdem_lines(err) == [err.strip()] and words in err, (name, err)


@pytest.mark.parametrize("n_ranks", [1, 2])
def test_shot_into_wall_stops_with_status_4(tmp_path, n_ranks):
    """A sphere at 100 m/s towards a soft wall (E 2.8e7, no damping) would tunnel through it: the
    run stops with status 4 naming the body, never exits 0."""
    s = scene(tmp_path, SHOT)
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path)
    lines = pdem_lines(err)
    assert rc == 4 and len(lines) == 1, (rc, err[-2000:])
    assert "body gid 0" in lines[0] and "tunnelling" in lines[0], lines


@pytest.mark.parametrize("n_ranks", [1, 2])
def test_deposition_with_dt_1s_stops_with_status_4(tmp_path, n_ranks):
    s = scene(tmp_path, SCENE.replace('dt = "auto"', "dt = 1.0"))
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path)
    lines = pdem_lines(err)
    assert rc == 4 and len(lines) == 1, (rc, err[-2000:])
    assert "step 1:" in lines[0] and "of its radius per step" in lines[0], lines


def test_too_many_ranks_named_before_any_work(tmp_path):
    """A scene 0.1 m long on x with a halo of ~0.022 m takes at most 4 slabs: 5 ranks are refused
    with that number (no ValueError traceback from the ghost layer)."""
    s = scene(tmp_path, SCENE.replace("box_hi = [0.4, 0.1, 0.3]", "box_hi = [0.11, 0.1, 0.6]"))
    rc, _, err = run(5, ["run", str(s), "--out", "out"], tmp_path)
    lines = pdem_lines(err)
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (rc, err[-2000:])
    assert "5 ranks: too many" in lines[0] and "use at most 3 ranks" in lines[0], lines


@pytest.mark.parametrize("n_ranks", [1, 2])
def test_damaged_results_file_on_resume_refused_by_every_rank(tmp_path, n_ranks):
    s = scene(tmp_path)
    rc, _, err = run(1, ["run", str(s), "--out", "out", "--steps", "100"], tmp_path)
    assert rc == 0, err[-2000:]
    (tmp_path / "out" / "results.h5").write_bytes(b"\0garbage" * 100)
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path)
    lines = pdem_lines(err)
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (rc, err[-2000:])
    assert "results.h5" in lines[0] and "move it aside" in lines[0], lines
    # moved aside as the line says: the run continues from the checkpoint with a new file
    (tmp_path / "out" / "results.h5").rename(tmp_path / "out" / "results.h5.damaged")
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path)
    assert rc == 0, err[-2000:]


@pytest.mark.parametrize("n_ranks", [1, 2])
def test_no_space_at_the_first_write(tmp_path, n_ranks):
    """A full disk at the first results write (a free-space floor no disk has): status 5 and one
    line naming the file, before HDF5 is ever handed the failing write."""
    s = scene(tmp_path)
    rc, _, err = run(n_ranks, ["run", str(s), "--out", "out"], tmp_path, env={"PDEM_MIN_FREE_BYTES": str(10**18)})
    lines = pdem_lines(err)
    assert rc == 5 and len(lines) == 1 and "Traceback" not in err, (rc, err[-2000:])
    assert "no space left" in lines[0] and "results.h5" in lines[0], lines


@pytest.fixture
def small_disk(tmp_path):
    """A 400 KiB tmpfs (needs root: mount). Skipped, with the reason, where it cannot be mounted."""
    d = tmp_path / "disk"
    d.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(d)], capture_output=True, text=True,
                       check=False)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs to fill ({r.stderr.strip() or 'mount failed'}); "
                    "test_no_space_at_the_first_write covers the path")
    yield d
    subprocess.run(["umount", str(d)], check=False)


@pytest.mark.parametrize("n_ranks", [1, 2])
def test_disk_full_mid_run(tmp_path, small_disk, n_ranks):
    """A real full file system mid-run (checkpoints every 100 steps fill 400 KiB): status 5, one
    line, no HDF5 traceback, no segfault; the checkpoints written before are intact."""
    s = scene(tmp_path, SCENE.replace("steps = 200", "steps = 3000").replace(
        "output_every = 50", "output_every = 1\ncheckpoint_every = 100\ncheckpoint_keep = 0"))
    rc, out, err = run(n_ranks, ["run", str(s), "--out", str(small_disk / "o")], tmp_path,
                       env={"PDEM_MIN_FREE_BYTES": "100000"})
    lines = pdem_lines(err)
    assert rc == 5 and len(lines) == 1, (rc, out[-1000:], err[-3000:])
    assert "No space left" in lines[0] or "no space left" in lines[0], lines
    assert "Traceback" not in err and "Segmentation" not in err
    from pdem.io.checkpoint import list_checkpoints, verify_checkpoint

    written = list_checkpoints(small_disk / "o" / "checkpoints")
    assert written
    for _, p in written:
        verify_checkpoint(p)
