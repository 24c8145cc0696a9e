"""Campaign tests: campaign files written from text over the tiny base scene
(`factories.TINY_DEPOSITION`, the ``tiny`` fixture), and ``pdem campaign`` run as a subprocess with
the venv's python (the one running the tests)."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def write_campaign(tmp_path, body, name="camp", base="tiny.toml", out=None, head=""):
    """A campaign file in tmp_path: [campaign] with base and out, then ``body``."""
    out = out or tmp_path / "runs" / name
    p = tmp_path / f"{name}.toml"
    p.write_text(f'[campaign]\nname = "{name}"\nbase = "{base}"\nout = "{out}"\n{head}\n{body}\n')
    return p


def pdem_campaign(*args, timeout=600, **kw):
    """``python -m pdem campaign ARGS`` as a subprocess (CompletedProcess, text output)."""
    env = kw.pop("env", None) or dict(os.environ, OMP_NUM_THREADS="1", MPLBACKEND="Agg")
    return subprocess.run([sys.executable, "-m", "pdem", "campaign", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, env=env, cwd=kw.pop("cwd", ROOT), **kw)
