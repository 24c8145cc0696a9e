"""The track prepared in the thesis's order (`[track] procedure = "refill"`, thesis 6.1: vibrate,
cut at the sleeper base, place the sleeper, refill, vibrate again, cut above the sleeper top).

Pieces: the refill's rectangles (`refill_areas`) cover the bed's plan less the sleepers'
footprints exactly once (their areas add up to it; sample points in the footprints lie in no
rectangle, the others in one), whole and half track; a procedure not offered is refused in one
line.

End to end: the reduced track of `test_track` with procedure "refill" on 1 rank runs the stages
pour, vibrate, settle, refill, vibrate_again, settle_again, traffic; each count its log reports is
recomputed from the checkpoints (the spheres above bed_depth at the end of settle, the new
spheres of the refill, all with gids never used before, the spheres outside the bed's shape at
the end of vibrate_again); the sleepers rest on the refilled bed before the traffic; the same
scene on 2 ranks gives the same bits. The default procedure keeps its stages (test_track's runs
check its bits).
"""
import copy
import re
import tomllib

import numpy as np
import pytest

from pdem.errors import InputError
from pdem.io.checkpoint import list_checkpoints, read_checkpoint
from pdem.scenes.track import outside_bed, profile, refill_areas, sleeper_boxes, track_settings
from pdem_cli import needs_mpiexec, run_pdem
from test_track import DOC, SCENE, assert_same_files

REFILL = SCENE.replace("vibration_time = 0.05\n", 'vibration_time = 0.05\nprocedure = "refill"\n')
STAGES = ("pour", "vibrate", "settle", "refill", "vibrate_again", "settle_again", "traffic")


def settings(**track):
    d = copy.deepcopy(DOC)
    d["track"].update(track)
    return track_settings(d)


@pytest.mark.parametrize("half", [False, True])
def test_the_refill_covers_the_plan_less_the_sleepers_once(half):
    c = settings(half=half, sleepers=3)
    g = profile(c)
    areas = refill_areas(c)
    centres, hb = sleeper_boxes(c)
    plan = g["length"] * (g["y_toe"] - g["y_lo"])
    footprints = len(centres) * 4 * hb[0] * hb[1]
    assert sum((hi[0] - lo[0]) * (hi[1] - lo[1]) for lo, hi in areas) == pytest.approx(plan - footprints, rel=1e-12)
    rng = np.random.default_rng(0)
    xy = rng.uniform([0.0, g["y_lo"]], [g["length"], g["y_toe"]], (4000, 2))
    covered = sum(((xy >= lo) & (xy < hi)).all(axis=1).astype(int) for lo, hi in areas)
    in_sleeper = np.zeros(len(xy), bool)
    for ctr in centres:
        in_sleeper |= (np.abs(xy - ctr[:2]) < hb[:2]).all(axis=1)
    assert in_sleeper.any() and (~in_sleeper).any()
    assert np.all(covered[in_sleeper] == 0) and np.all(covered[~in_sleeper] == 1)


def test_a_procedure_not_offered_is_refused_in_one_line():
    with pytest.raises(InputError, match=r"^track\.procedure = 'thesis': must be one of 'cut', 'refill'") as e:
        settings(procedure="thesis")
    assert "\n" not in str(e.value)
    assert settings()["procedure"] == "cut"


def stage_end(out, name):
    """The tables of the checkpoint written at the end of stage ``name`` (the next stage not
    started)."""
    for _, path in list_checkpoints(out / "checkpoints"):
        tables, meta = read_checkpoint(path)
        if meta["track"]["stage"] == STAGES.index(name) + 1 and not meta["track"]["started"]:
            return tables
    raise AssertionError(f"no checkpoint at the end of stage {name} in {out}")


@pytest.mark.slow
def test_the_thesis_order_runs_and_its_counts_come_from_the_files(tmp_path):
    scene = tmp_path / "refill.toml"
    scene.write_text(REFILL)
    r = run_pdem(1, scene, tmp_path / "r1")
    assert f"stages {', '.join(STAGES)}" in r.stdout
    c = track_settings(tomllib.loads(REFILL))
    settled, refilled, vibrated, final = (stage_end(tmp_path / "r1", name) for name in
                                          ("settle", "refill", "vibrate_again", "settle_again"))
    p = lambda t: t["particles"]  # noqa: E731
    # the cut at the sleeper base, by the spheres' tops
    above = p(settled)["pos"][:, 2] + p(settled)["radius"] > c["bed_depth"]
    cut, poured = map(int, re.search(r"bed_depth = [\d.]+ m \((\d+) spheres\), placed the sleepers, poured (\d+) "
                                     r"spheres around them", r.stdout).groups())
    assert cut == int(above.sum()) > 0
    kept = p(settled)["gid"][~above]
    new = np.setdiff1d(p(refilled)["gid"], kept)
    assert len(p(refilled)["gid"]) == len(kept) + poured and len(new) == poured > 0
    assert new.min() > p(settled)["gid"].max()  # the removed spheres' gids are not used again
    assert "boxes" in refilled and len(refilled["boxes"]["center"]) == c["sleepers"]
    assert "facets" not in refilled and "facets" not in vibrated and "facets" in final  # slopes at the last cut
    # the last cut, to the bed's shape, after the second vibration
    shaped = int(re.search(r"cut the bed to its shape \((\d+) spheres", r.stdout).group(1))
    assert shaped == int(outside_bed(c, p(vibrated)["pos"], p(vibrated)["radius"]).sum()) > 0
    assert len(p(final)["gid"]) == len(p(vibrated)["gid"]) - shaped
    # the sleepers rest on the refilled bed: below their placement, not through it
    base = final["boxes"]["center"][:, 2] - sleeper_boxes(c)[1][2]
    assert np.all(base < c["bed_depth"]) and np.all(base > 0.5 * c["bed_depth"])


@pytest.mark.slow
@needs_mpiexec
def test_the_thesis_order_gives_the_same_bits_on_2_ranks(tmp_path):
    scene = tmp_path / "refill.toml"
    scene.write_text(REFILL)
    run_pdem(1, scene, tmp_path / "r1")
    run_pdem(2, scene, tmp_path / "r2")
    assert_same_files(tmp_path / "r1", tmp_path / "r2")
