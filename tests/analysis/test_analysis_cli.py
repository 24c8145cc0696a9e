"""The command line: python -m analysis box RUN_DIR|RESULTS.h5 [--out DIR]."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pdem.format.schema import write_results
from analysis.__main__ import main

REPO = Path(__file__).resolve().parents[2]
OUTPUTS = ("loops.png", "settlement.png", "stiffness.png", "summary.txt", "summary.json")


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "analysis", *map(str, args)], cwd=REPO,
                          capture_output=True, text=True, timeout=60)


def test_box_writes_plots_and_summary(box_file, box_record, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["box", str(box_file), "--out", str(out)]) == 0
    for name in OUTPUTS:
        assert (out / name).stat().st_size > 0, name
    for name in OUTPUTS[:3]:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_cycles"] == box_record.n_cycles
    assert summary["cycles_source"] == "file"
    assert summary["fits"]["log"]["a"] == pytest.approx(box_record.a, rel=1e-9)
    assert summary["fits"]["log"]["b"] == pytest.approx(box_record.b, rel=1e-9)
    np.testing.assert_allclose(summary["cycles"]["k_unloading"], box_record.k_unload, rtol=1e-6)
    np.testing.assert_allclose(summary["cycles"]["k_loading"], box_record.k_load, rtol=1e-6)

    text = (out / "summary.txt").read_text()
    assert "S = a + b ln N" in text and "S = S1 N^b" in text
    rows = [line for line in text.splitlines() if line.split()[:1] in (["1"], ["8"])]
    assert len(rows) == 2


def test_detected_cycles_agree_with_table(box_file, box_file_no_cycles, tmp_path):
    for path, out in ((box_file, "a"), (box_file_no_cycles, "b")):
        assert main(["box", str(path), "--out", str(tmp_path / out)]) == 0
    a, b = (json.loads((tmp_path / o / "summary.json").read_text()) for o in "ab")
    assert b["cycles_source"] == "detected"
    for name, values in a["cycles"].items():
        np.testing.assert_allclose(b["cycles"][name], values, rtol=1e-9, err_msg=name)


def test_default_output_directory(box_file):
    assert main(["box", str(box_file)]) == 0
    assert (box_file.parent / "box-analysis" / "summary.json").is_file()


def test_bad_file_exits_2_without_traceback(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_text("not hdf5\n")
    proc = run_cli("box", bad, "--out", tmp_path / "out")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1
    assert str(bad) in proc.stderr and "not an HDF5 file" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


def test_help():
    proc = run_cli("--help")
    assert proc.returncode == 0
    assert "box" in proc.stdout


def test_usage_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["box"])
    assert info.value.code == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert main([]) == 2


def test_no_complete_cycle_exits_2(tmp_path, box_record, box_attrs, capsys):
    series = {k: v[:150] for k, v in box_record.series.items()}  # stops before unloading ends
    path = write_results(tmp_path / "short.h5", series, None, box_attrs)
    assert main(["box", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no complete load cycle" in err


def test_box_of_a_run_folder_writes_into_its_analysis_folder(box_file, tmp_path):
    """``box RUN_DIR`` as the other sub-commands, into RUN_DIR/analysis where pdem run's
    post-processing writes (no second folder beside it); a file of a run folder alike."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "results.h5").write_bytes(box_file.read_bytes())
    (run / "run_info.json").write_text("{}")
    assert main(["box", str(run)]) == 0
    assert (run / "analysis" / "summary.json").is_file()
    assert sorted(p.name for p in run.iterdir()) == ["analysis", "results.h5", "run_info.json"]
    (run / "analysis" / "summary.json").unlink()
    assert main(["box", str(run / "results.h5")]) == 0
    assert (run / "analysis" / "summary.json").is_file()


def test_without_the_analysis_extra_one_line_exit_2(monkeypatch, capsys):
    import analysis.__main__ as cli

    monkeypatch.setattr(cli, "find_spec", lambda name: None if name == "matplotlib" else object())
    assert cli.main(["box", "anything.h5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "matplotlib" in err and "Traceback" not in err
