"""``python -m analysis summary RUN`` on a synthetic run's files (`pdem.format.run`), the stage
table, and the lenient mode of the one reader. The four staged scenes' summaries are checked end
to end by tests/scenes/."""
import h5py
import numpy as np
import pytest

from analysis.__main__ import main
from analysis.run_summary import stage_table
from pdem.format.read import ResultFileError, read_results
from pdem.format.run import RUN_INFO, clear_run_info, read_run_info, scene_facts, write_run_info
from pdem.format.schema import RUN_SERIES, write_results


def plain_run(run_dir):
    """A plain run's results.h5 (5 samples) and its account."""
    t = np.linspace(0.0, 0.01, 5)
    series = {name: (np.linspace(0.0, 1.0, 5) if name != "time" else t, units) for name, units in RUN_SERIES.items()}
    write_results(run_dir / "results.h5", series, None, {"scene": {}, "pdem_version": "0", "kind": "scene"})
    write_run_info(run_dir, summary="scene", title="scene", scene_file="jobs/x.toml", ranks=2, wall_s=1.3,
                   about=["spheres: 7"], stages=[], stage_columns=[], preparation=None, notes=[],
                   timing="TIMING TABLE")


def test_summary_of_a_plain_run(tmp_path, capsys):
    plain_run(tmp_path)
    assert main(["summary", str(tmp_path)]) == 0
    text = (tmp_path / "summary.txt").read_text()
    assert text.splitlines()[:4] == ["scene: jobs/x.toml", "ranks: 2", "wall time: 1.3 s", "spheres: 7"]
    assert text.rstrip().endswith("TIMING TABLE")
    assert (tmp_path / "results.png").stat().st_size > 1000


def test_summary_without_an_account_is_bad_input(tmp_path, capsys):
    assert main(["summary", str(tmp_path)]) == 2
    assert RUN_INFO in capsys.readouterr().err


def test_run_info_round_trip_and_clear(tmp_path):
    assert read_run_info(tmp_path) is None
    write_run_info(tmp_path, summary="scene", ranks=3)
    info = read_run_info(tmp_path)
    assert info["summary"] == "scene" and info["ranks"] == 3 and info["format"] == "pdem-run-info"
    clear_run_info(tmp_path)
    assert read_run_info(tmp_path) is None
    (tmp_path / RUN_INFO).write_text('{"format": "other"}')
    with pytest.raises(ValueError, match="not a pdem-run-info file"):
        read_run_info(tmp_path)


def test_stage_table_columns_and_missing_values():
    rows = [{"stage": "pour", "t_end": 0.5, "step_end": 100, "spheres": 20, "unbalanced_force": 0.01,
             "bed_top": 0.25, "sleeper_z": None, "wall_s": 3.0},
            {"stage": "settle_long_name", "t_end": 1.0, "step_end": 200, "spheres": 20, "unbalanced_force": 0.001,
             "bed_top": 0.24, "sleeper_z": 0.3, "wall_s": 4.0}]
    lines = stage_table(rows, [("sleeper_z", "sleeper centre z [m]", ".4f"), ("balance", "balance", ".3f")])
    assert lines[0].split()[:2] == ["stage", "t_end"] and "sleeper centre z [mm]" in lines[0]  # one length unit
    assert "bed top [mm]" in lines[0] and "[m]" not in lines[0]
    assert lines[1].split() == ["pour", "0.5", "100", "20", "0.01", "250.00", "-", "-", "3.0"]
    assert lines[2].split()[6:] == ["300.00", "-", "4.0"]
    assert len({len(line) for line in lines}) == 1  # aligned


def test_lenient_read_gives_none_where_the_strict_one_raises(tmp_path):
    missing, foreign = tmp_path / "missing.h5", tmp_path / "foreign.h5"
    with h5py.File(foreign, "w") as f:
        f["x"] = [1.0]
    for path in (missing, foreign, tmp_path):
        assert read_results(path, lenient=True) is None
        with pytest.raises(ResultFileError):
            read_results(path)


def test_summary_names_version_date_seeds_and_materials(tmp_path):
    doc = {"materials": {"ballast": {"density": 2600.0, "young": 1.0e7}},
           "deposition": {"seed": 3}, "box_test": {"refill": {"pour_seed": 7}, "seedless": 1}}
    facts = scene_facts(doc)
    assert facts["seeds"] == {"deposition.seed": 3, "box_test.refill.pour_seed": 7}
    assert facts["materials"] == doc["materials"] and facts["finished"].endswith("Z")
    plain_run(tmp_path)
    info = read_run_info(tmp_path)
    write_run_info(tmp_path, **{k: v for k, v in info.items() if k not in ("format", "version")},
                   pdem_version="9.9.9", **facts)
    assert main(["summary", str(tmp_path)]) == 0
    lines = (tmp_path / "summary.txt").read_text().splitlines()
    assert lines[1] == f"pdem 9.9.9, finished {facts['finished']}"
    assert lines[2] == "seeds: deposition.seed = 3, box_test.refill.pour_seed = 7"
    assert lines[3] == "material ballast (SI units): density = 2600, young = 1e+07"
