"""Shared pieces of the track scenes' end-to-end tests (tests/scenes/test_track_beam.py,
test_track_tilt.py): a load program run from one prepared bed on 1 and 2 ranks, and the checks
that they and a 3-rank run to a checkpoint, and a 2-rank run resumed in the middle of a passage,
give the same bits."""
import shutil

import numpy as np

from pdem.format.groups import read_track
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem_cli import run_pdem
from run_files import datasets


def prepared_runs(base, prepare_text, scene_of):
    """Prepare the bed of ``prepare_text`` on 1 rank in ``base/bed``, then run the load program
    ``scene_of(bed)`` (the scene file's text starting from that bed) on 1 and 2 ranks (``base/r1``,
    ``base/r2``); returns (scene path, 1-rank result, 2-rank result)."""
    (base / "prepare.toml").write_text(prepare_text)
    run_pdem(1, base / "prepare.toml", base / "bed")
    scene = base / "traffic.toml"
    scene.write_text(scene_of(base / "bed"))
    return scene, run_pdem(1, scene, base / "r1"), run_pdem(2, scene, base / "r2")


def assert_same_results(ref, got, what):
    """Every dataset of two results files bit for bit."""
    a, b = datasets(ref), datasets(got)
    assert sorted(a) == sorted(b), f"{what}: datasets {sorted(set(a) ^ set(b))}"
    for k in a:
        assert np.array_equal(a[k], b[k]), f"/{k} differs ({what})"
    return a


def assert_same_bodies_on_3_ranks(base, scene, step, box_columns=("center",)):
    """``scene`` on 3 ranks ``--steps step`` gives the bodies of the 1-rank run ``base/r1`` at its
    checkpoint of that step: every particle column and the boxes' ``box_columns``."""
    out = base / "steps3"
    run_pdem(3, scene, out, "--steps", str(step))
    name = f"ckpt_{step:012d}.h5"
    got = read_checkpoint(out / "checkpoints" / name)[0]
    ref = read_checkpoint(base / "r1" / "checkpoints" / name)[0]
    for col in ref["particles"]:
        assert np.array_equal(ref["particles"][col], got["particles"][col]), f"step {step}, 3 ranks: particles/{col}"
    for col in box_columns:
        assert np.array_equal(ref["boxes"][col], got["boxes"][col]), f"step {step}, 3 ranks: boxes/{col}"


def assert_resume_in_passage(base, scene, passage=2):
    """A copy of the 2-rank run ``base/r2`` cut back to a checkpoint inside ``passage`` (1-based:
    after the previous passage's end, before this one's) and run again on 2 ranks rewrites the
    records of the 1-rank run ``base/r1`` bit for bit; returns the resumed run's result."""
    out = base / "resume"
    shutil.copytree(base / "r2", out)
    rec = read_track(out / "results.h5").passages
    lo = float(rec["t_end"][passage - 2] if passage > 1 else rec["t_start"][0])
    hi = float(rec["t_end"][passage - 1])
    inside = [s for s, path in list_checkpoints(out / "checkpoints")[:-1]
              if lo < read_checkpoint(path)[1]["time"] < hi]
    assert inside, f"no checkpoint inside passage {passage}"
    mid = inside[len(inside) // 2]
    for s, path in list_checkpoints(out / "checkpoints"):
        if s > mid:
            path.unlink()
    r = run_pdem(2, scene, out)
    assert f"at step {mid} (stage traffic" in r.stdout and "(resumed)" in r.stdout
    assert_same_results(base / "r1" / "results.h5", out / "results.h5", "after the restart")
    return r
