"""Campaign tests: a tiny plain base scene (50 spheres falling into a box, a few hundred steps),
campaign files written from text, and ``pdem campaign`` run in-process or as a subprocess with
the venv's python (the one running the tests)."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

TINY = """
[simulation]
dt = "auto"
damping = 0.3
gravity = [0.0, 0.0, -9.81]

[run]
steps = 400
progress_every = 100
output_every = 20
checkpoint_keep = 2
kind = "deposition"

[materials.ballast]
density = 2600.0
young = 1.0e7
poisson = 0.3
friction_angle = 0.5

[deposition]
box_lo = [0.0, 0.0, 0.0]
box_hi = [0.2, 0.1, 0.3]
count = 50
radius = 0.01
radius_spread = 0.3
seed = 3
material = "ballast"
walls_material = "ballast"
"""


def write_tiny(tmp_path, text=TINY):
    """The tiny base scene as tmp_path/tiny.toml."""
    p = tmp_path / "tiny.toml"
    p.write_text(text)
    return p


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
