"""How a simulation meets its ranks from outside pdem: the README's Python API under the venv's
``mpiexec`` (``scene.build()`` and ``scene.build(MPI.COMM_WORLD)`` both decompose over every rank),
and a launcher that announces more tasks than MPI sees (refused with one line, exit status 2)."""
import os
import subprocess
import sys

import pytest

from factories import TINY_DEPOSITION
from pdem.parallel.comm import LaunchError, get_comm
from pdem_cli import MPIEXEC, needs_mpiexec

# the README's API on a lattice of 4 x 4 x 6 spheres (two ranks each own part), run for 20 steps
SCRIPT = """
import sys
import numpy as np
import pdem

scene = pdem.Scene(dt=2e-6, damping=0.1, gravity=(0, 0, -9.81))
ballast = scene.material(density=2600, young=1e7, poisson=0.3, friction_angle=0.5)
grid = np.stack(np.meshgrid(*(np.arange(n) * 0.025 for n in (4, 4, 6)), indexing="ij"), -1).reshape(-1, 3)
scene.add_spheres(grid, np.full(len(grid), 0.01), [ballast] * len(grid))
if sys.argv[1] == "world":
    from mpi4py import MPI
    sim = scene.build(MPI.COMM_WORLD)
else:
    sim = scene.build()
sim.run(20)
n = sim.particles.n_local
row = f"{sim.comm.rank} {sim.comm.size} {n} {sim.comm.allreduce_sum_int(n)}"
open(f"{sys.argv[2]}/rank_{sim.comm.rank}.txt", "w").write(row)  # a file each: ranks' stdout may interleave
"""


def child_env(**extra):
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1", **extra)
    for var in ("PMI_SIZE", "PMI_RANK", "OMPI_COMM_WORLD_SIZE", "MV2_COMM_WORLD_SIZE", "SLURM_STEP_NUM_TASKS"):
        if var not in extra:
            env.pop(var, None)
    return env


@needs_mpiexec
@pytest.mark.parametrize("how", ["default", "world"])
def test_readme_api_under_mpiexec_builds_one_decomposed_simulation(tmp_path, how):
    script = tmp_path / "script.py"
    script.write_text(SCRIPT)
    r = subprocess.run([str(MPIEXEC), "-n", "2", sys.executable, str(script), how, str(tmp_path)], capture_output=True,
                       text=True, timeout=600, env=child_env())
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    rows = sorted(tuple(int(x) for x in p.read_text().split()) for p in tmp_path.glob("rank_*.txt"))
    assert [(rank, size) for rank, size, _, _ in rows] == [(0, 2), (1, 2)], rows
    assert {total for *_, total in rows} == {96}, rows
    assert all(0 < owned < 96 for _, _, owned, _ in rows) and sum(owned for _, _, owned, _ in rows) == 96, rows


@pytest.mark.parametrize("var", ["SLURM_STEP_NUM_TASKS", "OMPI_COMM_WORLD_SIZE"])
def test_more_tasks_announced_than_mpi_sees_is_refused(tmp_path, var):
    (tmp_path / "tiny.toml").write_text(TINY_DEPOSITION)
    r = subprocess.run([sys.executable, "-m", "pdem", "run", str(tmp_path / "tiny.toml"), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=600, env=child_env(**{var: "2"}))
    assert r.returncode == 2, r.stdout + r.stderr
    lines = [x for x in r.stderr.splitlines() if x.startswith("pdem")]  # (mpi4py may warn about Open MPI's variable)
    assert len(lines) == 1 and lines[0].startswith(f"pdem: {var}=2: the launcher started 2 tasks"), r.stderr
    assert "mpiexec -n 2" in lines[0] and "Traceback" not in r.stderr and not (tmp_path / "o").exists()


def test_announced_ranks_without_mpi4py_are_refused(monkeypatch):
    monkeypatch.setenv("SLURM_STEP_NUM_TASKS", "4")
    for var in ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE", "MV2_COMM_WORLD_SIZE"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.delitem(sys.modules, "mpi4py.MPI", raising=False)
    monkeypatch.setitem(sys.modules, "mpi4py", None)  # import mpi4py fails
    with pytest.raises(LaunchError, match=r"^SLURM_STEP_NUM_TASKS=4: .* mpi4py is not installed.*pdem\[mpi\]\)$"):
        get_comm()
