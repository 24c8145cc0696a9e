"""The wheel as a user gets it: built from a copy of the sources (nothing written into the checkout),
installed into a fresh venv, then ``pdem --version`` and a tiny plain scene end to end, run from
outside the checkout.

Offline, the fresh venv cannot download numpy, numba, h5py and rich: the wheel goes in with
``--no-deps`` and a .pth line lends the venv this interpreter's site-packages (added as a plain
path: its own .pth files, such as one pointing at a checkout, are not processed). Building needs
setuptools with ``bdist_wheel`` (setuptools >= 70.1, or the ``wheel`` package): skipped without it.
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


def _can_build_wheels():
    if find_spec("setuptools") is None:
        return False
    import setuptools

    version = tuple(int(x) for x in setuptools.__version__.split(".")[:2])
    return version >= (70, 1) or find_spec("wheel") is not None


def build_wheel(tmp_path):
    src = tmp_path / "src"
    for name in SOURCES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, src / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            src.mkdir(exist_ok=True)
            shutil.copy(ROOT / name, src / name)
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", str(src), "--no-deps", "--no-build-isolation",
                        "--no-index", "-w", str(tmp_path / "dist")], capture_output=True, text=True, timeout=600)
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


@pytest.mark.slow
@pytest.mark.skipif(not _can_build_wheels(), reason="setuptools here cannot build wheels (needs >= 70.1 or `wheel`)")
def test_wheel_installs_and_runs_a_scene(tmp_path):
    wheel = build_wheel(tmp_path)
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"pdem", "pdem_analysis", f"pdem-{__version__}.dist-info"}, tops
    assert "pdem_analysis/__main__.py" in names and f"pdem-{__version__}.dist-info/LICENSE" in names
    meta = zipfile.ZipFile(wheel).read(f"pdem-{__version__}.dist-info/METADATA").decode()
    for dep in ("numba", "h5py", "rich", "matplotlib", "mpi4py", "meshio", "ruff"):
        assert f"Requires-Dist: {dep}" in meta, dep
    packages = {p.parent.relative_to(ROOT).as_posix() for p in (ROOT / "pdem").rglob("__init__.py")}
    assert packages <= {n.rsplit("/", 1)[0] for n in names}, "a pdem sub-package is missing from the wheel"

    venv = fresh_venv(tmp_path, wheel)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1", MPLBACKEND="Agg", NUMBA_CACHE_DIR=str(tmp_path / "cache"))
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
