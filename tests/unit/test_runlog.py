"""The run's text log (`pdem.driver.runlog`) and the whole-run ETA of the progress lines
(`pdem.driver.runloop.eta_text`)."""
import sys

import pytest

from pdem.driver import runlog
from pdem.driver.runloop import eta_text


@pytest.fixture
def logged():
    yield
    runlog.stop()


def test_the_log_holds_what_the_terminal_showed_and_resumes_append(tmp_path, capsys, logged):
    runlog.start(["run", "scene.toml"])
    print("before the output folder is known")  # held, then written when the folder is
    runlog.attach(tmp_path, fresh=True)
    print("stage 1/2 pour")
    sys.stderr.write("pdem: a warning\n")
    runlog.log_only("step 100  ETA 3 s")  # a progress line while a bar is drawn: the log only
    runlog.stop()
    shown = capsys.readouterr()
    assert "step 100" not in shown.out and "stage 1/2 pour" in shown.out and "a warning" in shown.err
    lines = (tmp_path / "log.txt").read_text().splitlines()
    assert lines[0].startswith("# pdem ") and lines[0].endswith("pdem run scene.toml")
    assert lines[1:] == ["before the output folder is known", "stage 1/2 pour", "pdem: a warning",
                         "step 100  ETA 3 s"]

    runlog.start(["run", "scene.toml"])  # a resumed run appends
    runlog.attach(tmp_path, fresh=False)
    print("resuming")
    runlog.stop()
    lines = (tmp_path / "log.txt").read_text().splitlines()
    assert len(lines) == 7 and lines[5].startswith("# pdem ") and lines[6] == "resuming"

    runlog.start(["run", "scene.toml", "--fresh"])  # --fresh starts the log over
    runlog.attach(tmp_path, fresh=True)
    runlog.stop()
    assert len((tmp_path / "log.txt").read_text().splitlines()) == 1


def test_each_line_is_on_disk_when_printed(tmp_path, logged):
    runlog.start(["run"])
    runlog.attach(tmp_path, fresh=True)
    print("line one")
    assert (tmp_path / "log.txt").read_text().splitlines()[-1] == "line one"  # before stop: flushed


def test_without_a_logged_run_nothing_changes(tmp_path):
    stdout = sys.stdout
    runlog.attach(tmp_path, fresh=True)
    runlog.log_only("x")
    assert sys.stdout is stdout and not (tmp_path / "log.txt").exists()


def test_eta_of_the_whole_run():
    # 0.01 s a step, 100 steps left in this stage, at dt = 1e-3 s
    assert eta_text(0.01, 100, False) == "ETA 1 s"
    assert eta_text(0.01, 100, True) == "ETA \u2264 1 s"  # this stage may end earlier
    # then a stage of exactly 2 s (2000 steps, 20 s) and one of at most 1 s (10 s)
    assert eta_text(0.01, 100, False, [(2.0, True)], dt=1e-3) == "ETA 21 s"
    assert eta_text(0.01, 100, False, [(2.0, True), (1.0, False)], dt=1e-3) == "ETA \u2264 31 s"
    # a later stage of unknown length: a lower bound only, of the stages that are sure to run
    assert eta_text(0.01, 100, False, [(2.0, True), (None, False)], dt=1e-3) == "ETA \u2265 21 s"
    assert eta_text(0.01, 100, True, [(None, False)], dt=1e-3) == "ETA \u2265 0 s"
