"""The wheel as a user gets it: built from a copy of the sources (nothing written into the checkout),
installed into a fresh venv, then ``pdem --version`` and a scene end to end, run from outside the
checkout.

Building needs setuptools >= 77 (pyproject.toml): this interpreter's if it has one, else a build
venv with the setuptools that requirements.lock pins (from the package index or pip's cache: a
clean clone builds offline once `make venv` installed the lock).

- `test_wheel_installs_and_runs_a_scene`: the wheel's contents; installed with ``--no-deps`` into a
  venv that borrows this interpreter's site-packages (a .pth line, added as a plain path: its own
  .pth files, such as one pointing at a checkout, are not processed); a tiny plain scene.
- `test_clean_venv_with_the_mpi_extra_runs_the_box_test_on_2_ranks`: ``pip install WHEEL[mpi]``
  into an empty venv, every dependency from the package index at the versions of
  requirements.lock, then ``mpiexec -n 2 pdem run jobs/box_test.toml --steps 300`` (the venv's
  own mpiexec, from the mpich wheel): exit 0, a checkpoint at step 300, OUT/log.txt.
- `test_clean_venv_without_extras_finishes_with_a_note`: ``pip install WHEEL`` (no extras): a
  plain scene runs serially and ends with exit 0 and one line naming the missing package of the
  post-processing; ``python -m pdem_analysis`` says which package it needs, exit 2.
The two clean-venv tests are skipped when no package index answers (a machine without one).
"""
import os
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from importlib.util import find_spec
from pathlib import Path

import pytest

import pdem.cli
import pdem.format.run
from factories import TINY_DEPOSITION
from pdem.version import __version__

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "pdem", "analysis")
BUILD_SETUPTOOLS = (77, 0)  # pyproject.toml [build-system]


def locked(name):
    """The version requirements.lock pins for ``name``."""
    for line in (ROOT / "requirements.lock").read_text().splitlines():
        if line.lower().startswith(f"{name.lower()}=="):
            return line.split("==")[1].strip()
    raise AssertionError(f"requirements.lock pins no {name}")


def _this_python_builds():
    if find_spec("setuptools") is None:
        return False
    import setuptools

    return tuple(int(x) for x in setuptools.__version__.split(".")[:2]) >= BUILD_SETUPTOOLS


def _pip(python, *args, timeout=1800):
    return subprocess.run([str(python), "-m", "pip", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def builder(tmp_path):
    """A Python that can build the wheel: this one, or a venv with the locked setuptools
    (pytest.skip if it cannot be installed: no package index and nothing cached)."""
    if _this_python_builds():
        return Path(sys.executable)
    venv = tmp_path / "build-venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    r = _pip(venv / "bin" / "python", "install", "-q", f"setuptools=={locked('setuptools')}")
    if r.returncode != 0:
        pytest.skip(f"setuptools=={locked('setuptools')} cannot be installed here: {r.stderr.strip()[-300:]}")
    return venv / "bin" / "python"


def build_wheel(tmp_path):
    src = tmp_path / "src"
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            src.mkdir(exist_ok=True)
            shutil.copy(ROOT / name, src / name)
    r = _pip(builder(tmp_path), "wheel", src, "--no-deps", "--no-build-isolation", "--no-index",
             "-w", tmp_path / "dist", timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    (wheel,) = (tmp_path / "dist").glob("pdem-*.whl")
    return wheel


def fresh_venv(tmp_path, wheel):
    """A venv without system site-packages; the wheel installed without dependencies."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=300)
    py = venv / "bin" / "python"
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "--no-deps", "--no-index",
                        str(wheel)], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    purelib = subprocess.run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                             capture_output=True, text=True, check=True).stdout.strip()
    Path(purelib, "zz_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    return venv


def clean_venv(tmp_path, wheel, extras=""):
    """An empty venv (with pip) and ``pip install WHEEL[extras]``, the dependencies from the
    package index at requirements.lock's versions (pytest.skip if no index answers)."""
    venv = tmp_path / f"venv{extras or '-plain'}"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    r = _pip(venv / "bin" / "python", "install", "-q", "--only-binary", ":all:", "-c", ROOT / "requirements.lock",
             f"{wheel}{'[' + extras + ']' if extras else ''}")
    if r.returncode != 0 and ("No matching distribution" in r.stderr or "Could not find" in r.stderr
                              or "NewConnectionError" in r.stderr):
        pytest.skip(f"the dependencies cannot be installed here (no package index?): {r.stderr.strip()[-300:]}")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return venv


def user_env(tmp_path):
    """The environment of a user: no PYTHONPATH into this checkout, one thread, a numba cache."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1", MPLBACKEND="Agg", NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    return env


@pytest.mark.slow
def test_wheel_installs_and_runs_a_scene(tmp_path):
    wheel = build_wheel(tmp_path)
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"pdem", "pdem_analysis", f"pdem-{__version__}.dist-info"}, tops
    assert "pdem_analysis/__main__.py" in names
    assert {f"pdem-{__version__}.dist-info/LICENSE", f"pdem-{__version__}.dist-info/licenses/LICENSE"} & set(names)
    meta = zipfile.ZipFile(wheel).read(f"pdem-{__version__}.dist-info/METADATA").decode()
    for dep in ("numba", "h5py", "rich", "matplotlib", "mpi4py", "meshio", "ruff"):
        assert f"Requires-Dist: {dep}" in meta, dep
    packages = {p.parent.relative_to(ROOT).as_posix() for p in (ROOT / "pdem").rglob("__init__.py")}
    assert packages <= {n.rsplit("/", 1)[0] for n in names}, "a pdem sub-package is missing from the wheel"

    venv = fresh_venv(tmp_path, wheel)
    env = user_env(tmp_path)
    work = tmp_path / "work"
    work.mkdir()

    def run(*cmd):
        return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=900, env=env, cwd=work)

    r = run(venv / "bin" / "pdem", "--version")
    assert r.returncode == 0 and r.stdout.strip() == f"pdem {__version__}", r.stdout + r.stderr
    r = run(venv / "bin" / "python", "-c", "import pdem, pdem_analysis; print(pdem.__file__, pdem_analysis.__file__)")
    assert r.stdout.count(str(venv)) == 2, r.stdout + r.stderr
    assert run(venv / "bin" / "python", "-c", "import analysis").returncode != 0
    assert run(venv / "bin" / "python", "-m", "pdem_analysis", "--help").returncode == 0
    (work / "tiny.toml").write_text(TINY_DEPOSITION)
    r = run(venv / "bin" / "pdem", "run", "tiny.toml", "--out", "out")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert (work / "out" / "results.h5").exists()


@pytest.mark.slow
def test_clean_venv_with_the_mpi_extra_runs_the_box_test_on_2_ranks(tmp_path):
    venv = clean_venv(tmp_path, build_wheel(tmp_path), "mpi")
    work = tmp_path / "work"
    work.mkdir()
    shutil.copy(ROOT / "jobs" / "box_test.toml", work / "box_test.toml")
    r = subprocess.run([venv / "bin" / "mpiexec", "-n", "2", venv / "bin" / "pdem", "run", "box_test.toml", "--out",
                        "out", "--steps", "300"], capture_output=True, text=True, timeout=1800, env=user_env(tmp_path),
                       cwd=work)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "on 2 rank(s)" in r.stdout and "Traceback" not in r.stderr
    assert (work / "out" / "checkpoints" / "ckpt_000000000300.h5").exists()
    log = (work / "out" / "log.txt").read_text()
    assert "on 2 rank(s)" in log and "stopped at step 300" in log


@pytest.mark.slow
def test_clean_venv_without_extras_finishes_with_a_note(tmp_path):
    venv = clean_venv(tmp_path, build_wheel(tmp_path))
    work = tmp_path / "work"
    work.mkdir()
    (work / "tiny.toml").write_text(TINY_DEPOSITION)
    env = user_env(tmp_path)

    def run(*cmd):
        return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=1800, env=env, cwd=work)

    assert run(venv / "bin" / "python", "-c", "import mpi4py").returncode != 0  # really without the extras
    r = run(venv / "bin" / "pdem", "run", "tiny.toml", "--out", "out")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    notes = [line for line in r.stdout.splitlines() if "post-processing skipped" in line]
    assert len(notes) == 1 and "matplotlib" in notes[0] and "Traceback" not in r.stderr, r.stdout + r.stderr
    assert "Section" in r.stdout.split(notes[0])[1]  # the timing table the summary would have shown
    assert (work / "out" / "results.h5").exists() and (work / "out" / "log.txt").exists()
    r = run(venv / "bin" / "python", "-m", "pdem_analysis", "summary", "out")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "matplotlib" in r.stderr, r.stderr


def test_post_processing_without_matplotlib_is_a_note_not_a_failure(monkeypatch, capsys, tmp_path):
    def no_matplotlib(name):
        raise ModuleNotFoundError("No module named 'matplotlib'", name="matplotlib")

    monkeypatch.setattr(pdem.format.run, "read_run_info", lambda out: {"kind": "box_test"})
    monkeypatch.setattr(pdem.cli, "import_module", no_matplotlib)
    pdem.cli.post_process(tmp_path)
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "post-processing skipped" in out and "package matplotlib" in out


def test_version_option(capsys):
    with pytest.raises(SystemExit) as exc:
        pdem.cli.main(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out == f"pdem {__version__}\n"
