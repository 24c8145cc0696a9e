"""Packings: Newton's third law and angular momentum balance (c), stiff auto-Δt stability (f),
thread invariance of the parallel kernels (g)."""
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pdem.checks import diagnostics
from factories import box_scene

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def sphere_sphere_share(sim):
    """Per-body force and torque from sphere–sphere contacts only: the accumulators minus the wall parts."""
    p = sim.particles
    n = p.n_local
    f = p.force[:n].copy()
    t = p.torque[:n].copy()
    sw = sim.kind("sphere_wall").contacts
    for q in range(sw.n):
        if sw.state[q] == 1:
            f[sw.i[q]] -= sw.force[q]
            t[sw.i[q]] -= sw.torque[q]
    return f, t


def test_newton_third_law_and_angular_momentum():
    """(c) Settled random packing (150 spheres, walls, gravity, damping): over sphere–sphere contacts
    Σ F_i = 0 and Σ (x_i × F_i + T_i) = 0 to round-off (x_i: positions at which the forces were computed)."""
    sim = box_scene(150, seed=3).build()
    sim.run(7999)
    p = sim.particles
    n = p.n_local
    x = p.pos[:n].copy()
    sim.run(1)
    rows = sim.kind("sphere_sphere").contacts.real_rows()
    per_body = np.bincount(
        np.concatenate([sim.kind("sphere_sphere").contacts.i[rows], sim.kind("sphere_sphere").contacts.j[rows]]),
        minlength=n,
    )
    assert per_body.max() >= 4 and len(rows) > 100, "the packing must be dense"
    f, t = sphere_sphere_share(sim)
    scale_f = np.abs(f).sum()
    assert scale_f > 0
    assert np.abs(f.sum(axis=0)).max() <= 1e-12 * scale_f
    moment = np.cross(x, f) + t
    scale_m = np.abs(np.cross(x, f)).sum() + np.abs(t).sum()
    assert np.abs(moment.sum(axis=0)).max() <= 1e-10 * scale_m
    # and per contact, from the pair rows: f on i, −f on j, torques (r − pen/2)(n × f)
    i, j = sim.kind("sphere_sphere").contacts.i[rows], sim.kind("sphere_sphere").contacts.j[rows]
    fp = sim.kind("sphere_sphere").row_force(rows)
    t1, t2 = sim.kind("sphere_sphere").row_torques(rows)
    m_pair = np.cross(x[i], fp) - np.cross(x[j], fp) + t1 + t2
    assert np.abs(m_pair).max() <= 1e-10 * np.abs(np.cross(x[i], fp)).max()


def test_stiff_auto_dt_stable():
    """(f) E = 5.55e11 Pa spheres (216) with random ≤ 1 m/s velocities and gravity in a box of steel walls
    (10 E), automatic Δt: thousands of steps without InstabilityError, overlaps stay tiny."""
    sc = box_scene(
        216,
        seed=5,
        r_min=0.00999,
        r_max=0.01,
        young=5.55e11,
        wall_young=5.55e12,
        damping=0.3,
        vel_scale=1.0,
        spacing=1.002,
    )
    sim = sc.build()
    dt0 = sim.dt
    r_min = sim.particles.radius[: sim.particles.n_local].min()
    rho = 2600.0
    assert dt0 <= r_min * np.sqrt(rho / 5.55e11)  # at most the P-wave estimate
    worst = 0.0
    contacts = 0
    dts = []
    for _ in range(60):
        sim.run(50)
        worst = max(worst, diagnostics.max_overlap_ratio(sim))
        contacts = max(
            contacts,
            len(sim.kind("sphere_sphere").contacts.real_rows()) + len(sim.kind("sphere_wall").contacts.real_rows()),
        )
        dts.append(sim.dt)
    assert sim.step == 3000
    assert contacts >= 10
    assert max(dts) > dt0  # the contact-stiffness estimate took over from the P-wave one
    assert worst < 0.01, worst
    e = sim.energy()
    assert np.isfinite(e["total"])
    assert e["kinetic"] + e["rotational"] <= 0.5 * 1.0 ** 2 * 3 * sim.particles.mass[:216].sum()


THREAD_SCRIPT = textwrap.dedent("""
    import sys
    import numba
    numba.set_num_threads(int(sys.argv[1]))
    sys.path.insert(0, sys.argv[3])
    from factories import box_scene
    from pdem import kernels
    sim = box_scene(5400, seed=7, r_min=0.0058, r_max=0.006, young=1e7, damping=0.3, vel_scale=0.5, dt=2e-6,
                    spacing=1.01).build()
    sim.run(150)
    p = sim.particles
    assert sim.kind("sphere_sphere").contacts.n >= kernels.PARALLEL_MIN, sim.kind("sphere_sphere").contacts.n
    assert numba.get_num_threads() == int(sys.argv[1])
    n_real = len(sim.kind("sphere_sphere").contacts.real_rows())
    assert n_real > 100, n_real
    order = p.gid[: p.n_local].argsort()
    with open(sys.argv[2], "wb") as fh:
        for a in (p.pos, p.vel, p.angvel, p.force, p.torque):
            fh.write(a[: p.n_local][order].tobytes())
""")


@pytest.mark.slow  # a 5400-sphere bed in subprocesses with 1 and 2 threads
def test_thread_invariance(tmp_path):
    """(g) 5400 spheres (above PARALLEL_MIN, so the parallel kernels run with 2 threads): 1 and 2 threads
    give bit-identical positions, velocities, spins, forces and torques."""
    script = tmp_path / "run.py"
    script.write_text(THREAD_SCRIPT)
    out = {}
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("NUMBA_NUM_THREADS", None)
    for threads in (1, 2):
        dest = tmp_path / f"state{threads}.bin"
        r = subprocess.run([sys.executable, str(script), str(threads), str(dest), str(HERE.parent)], env=env,
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-3000:]
        out[threads] = dest.read_bytes()
    assert len(out[1]) == 5 * 5400 * 3 * 8
    assert out[1] == out[2]
