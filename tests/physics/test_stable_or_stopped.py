"""Stable or stopped, never NaN (SPEC.md 4): what the stability map (docs/stability.md) found and
what holds it.

- A NaN or an infinity in a position or velocity is caught by the per-step guard at the next
  step, naming the body: `max` drops a NaN (max(0.3, nan) is 0.3), so the guard's reduction used
  to let a NaN state run on unseen until the next periodic check.
- No output ever holds a NaN: a results row with one, a checkpoint or a snapshot of a non-finite
  state stop the run instead (exit 4); a run that stops keeps the rows recorded before the stop.
- Two spheres on one centre (allowed overlaps) have no contact normal: refused with one line, not
  a ZeroDivisionError from inside the contact loop.
- A fixed Δt above the stable one is named as the cause, with the factor.
- The total mechanical energy is synchronised to the positions: for a linear contact the
  leapfrog conserves ½ m v_{n−1/2}·v_{n+1/2} + U(x_n) exactly (its shadow energy), while
  ½ m v_{n+1/2}² + U(x_n) swings by (h/2) F·v. Independent truth: that identity of the leapfrog.
"""
import math

import h5py
import numpy as np
import pytest

from pdem import InputError
from pdem.build.config import scene_from_dict
from pdem.driver.plain import run_scene_file
from pdem.driver.results import SCHEMA, FiniteSeriesWriter, finite_row
from pdem.driver.runloop import RunLoop
from pdem.build.config import RUN_DEFAULTS
from pdem.errors import InstabilityError
from pdem.contact.neighbors import max_motion
from pdem.parallel.comm import SerialComm
from pdem.build.scene import Scene

R, RHO, E = 0.01, 2600.0, 2.8e7


def deposition_doc(**sim_changes):
    return {"simulation": {"dt": "auto", "damping": 0.3, "gravity": [0.0, 0.0, -9.81], **sim_changes},
            "run": {"steps": 400, "output_every": 10, "progress_every": 0},
            "materials": {"ballast": {"density": RHO, "young": E, "poisson": 0.3, "friction_angle": 0.5}},
            "deposition": {"box_lo": [0, 0, 0], "box_hi": [0.2, 0.1, 0.2], "count": 20, "radius": R, "seed": 1,
                           "material": "ballast", "walls_material": "ballast"}}


@pytest.mark.parametrize("what", ["vel", "pos"])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_nonfinite_state_stopped_at_the_next_step(what, value):
    """check_interval 1000: only the per-step guard can see it. Before the fix a NaN velocity ran
    on to step 1000 (the reduction dropped it)."""
    sim = scene_from_dict(deposition_doc(check_interval=1000)).build()
    sim.run(5)
    p = sim.particles
    k = int(np.flatnonzero(p.gid[: p.n_local] == 7)[0])
    getattr(p, what)[k, 1] = value
    with pytest.raises(InstabilityError) as err:
        sim.run(10)
    msg = str(err.value)
    assert sim.step == 5 and msg.startswith("step 5: non-finite position or velocity of body gid 7 "), msg
    assert "nan" not in msg.lower().replace("non-finite", ""), msg


def test_max_motion_reports_a_nonfinite_body_as_infinitely_fast():
    pos = np.zeros((4, 3))
    vel = np.zeros((4, 3))
    vel[1, 0] = 1.0
    r = np.ones(4)
    assert max_motion.serial(pos, pos.copy(), vel, r, 4) == (0.0, 1.0)
    for twin in (max_motion.serial, max_motion.parallel):
        v = vel.copy()
        v[2, 2] = np.nan
        assert twin(pos, pos.copy(), v, r, 4)[1] == np.inf
        x = pos.copy()
        x[3, 0] = np.nan
        assert twin(x, pos.copy(), vel, r, 4)[1] == np.inf


def test_spheres_on_one_centre_refused_even_with_allowed_overlaps():
    sc = Scene(allow_initial_overlap=True)
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=0.5)
    sc.add_spheres([(0.0, 0.0, 0.0), (0.005, 0.0, 0.0), (0.0, 0.0, 0.0)], R, m)
    with pytest.raises(InputError) as err:
        sc.build()
    assert str(err.value) == ("spheres: bodies gid 0 and 2 have the same centre [0.0, 0.0, 0.0] m (a repeated row?): "
                              "no contact normal exists between them")


def test_fixed_dt_above_the_stable_one_named_as_the_cause():
    """dt fixed at 20 times the automatic step: the message says so, with the factor against the
    step dt = "auto" would take in that state (collective, the same on every rank)."""
    auto = scene_from_dict(deposition_doc()).build().dt
    sim = scene_from_dict(deposition_doc(dt=20 * auto)).build()
    with pytest.raises(InstabilityError) as err:
        sim.run(3000)
    msg = str(err.value)
    assert "the time step fixed by simulation.dt is " in msg and 'times the one dt = "auto" takes here' in msg, msg
    factor = float(msg.split("simulation.dt is ")[1].split(" times")[0])
    assert factor > 1.0
    # with dt = "auto" the same kind of stop does not blame the time step
    sim = scene_from_dict(deposition_doc(check_interval=1000)).build()
    sim.particles.vel[0] = (1e3, 0.0, 0.0)
    with pytest.raises(InstabilityError) as err:
        sim.run(1)
    assert "simulation.dt" not in str(err.value) and "the initial velocity is too high" in str(err.value)


def test_results_row_with_nan_stops_the_run(tmp_path):
    w = FiniteSeriesWriter(tmp_path / "r.h5", {"step": "-", "x": "m"}, schema=SCHEMA, every=10)
    w.append({"step": 1, "x": 0.5})
    with pytest.raises(InstabilityError) as err:
        w.append({"step": 2, "x": math.nan})
    assert str(err.value).startswith("step 2: x not finite in the results"), err.value
    w.close()
    with h5py.File(tmp_path / "r.h5") as f:
        assert f["series"]["x"][()].tolist() == [0.5]
    with pytest.raises(InstabilityError):
        finite_row({"step": 3, "x": 1.0, "y": -math.inf})
    assert finite_row({"step": 3, "x": 1.0}) == {"step": 3, "x": 1.0}


def test_checkpoint_of_a_nonfinite_state_refused(tmp_path):
    sim = scene_from_dict(deposition_doc()).build()
    sim.run(3)
    sim.particles.vel[4, 0] = np.nan
    loop = RunLoop(SerialComm(), tmp_path, dict(RUN_DEFAULTS), "scene.toml", "")
    try:
        with pytest.raises(InstabilityError) as err:
            loop.checkpoint(sim, "test")
    finally:
        loop.close()
    assert "non-finite position or velocity of body gid" in str(err.value)
    assert not list((tmp_path / "checkpoints").glob("*.h5")) if (tmp_path / "checkpoints").exists() else True


def test_a_stopped_run_keeps_its_rows_and_no_nan(tmp_path):
    """dt fixed at 20 times the automatic step: exit 4 (InstabilityError) after some output rows;
    the rows up to the stop are in results.h5 (the writer buffers 10 rows: they used to be lost),
    all finite; the energies of a plain run are there, with external_work = 0 (nothing moves)."""
    doc = deposition_doc()
    auto = scene_from_dict(doc).build().dt
    doc = deposition_doc(dt=20 * auto)
    scene = tmp_path / "s.toml"
    scene.write_text("")
    with pytest.raises(InstabilityError):
        run_scene_file(scene, doc, tmp_path / "out", SerialComm())
    with h5py.File(tmp_path / "out" / "results.h5") as f:
        s = {k: f["series"][k][()] for k in f["series"]}
        assert f.attrs["external_work"] == 0
    assert len(s["step"]) >= 2 and s["step"][0] == 0
    for k, v in s.items():
        assert np.all(np.isfinite(v)), k
    assert {"potential_energy", "total_energy", "max_overlap_ratio"} <= set(s)


def test_moving_wall_marks_external_work(tmp_path):
    doc = deposition_doc()
    doc["walls"] = [{"axis": "z", "position": 0.3, "material": "ballast", "sense": -1, "velocity": [0, 0, -0.01]}]
    doc["run"]["steps"] = 20
    scene = tmp_path / "s.toml"
    scene.write_text("")
    assert run_scene_file(scene, doc, tmp_path / "out", SerialComm()) == 0
    with h5py.File(tmp_path / "out" / "results.h5") as f:
        assert f.attrs["external_work"] == 1


def sphere_on_floor(z, vz, dt=1e-9):
    sc = Scene(dt=dt, damping=0.0, gravity=(0.0, 0.0, -9.81), allow_initial_overlap=True)
    m = sc.material(density=RHO, young=E, poisson=0.3, friction_angle=0.0)
    sc.add_spheres([(0.0, 0.0, z)], R, m, vel=[(0.0, 0.0, vz)])
    sc.add_wall(2, 0.0, m)
    return sc.build()


def oscillator(dt_fraction):
    """A sphere on a floor under gravity, no damping, no friction, bouncing on its contact spring
    k_n about the static overlap m g / k_n with an amplitude of half of it (never opens): x'' is
    affine in x, so the leapfrog's shadow energy is conserved exactly. Δt = dt_fraction × the
    critical 2 sqrt(m/k_n)."""
    probe = sphere_on_floor(R - 1e-7, 0.0)
    probe.run(1)
    k = probe.kind("sphere_wall").contacts.params[0, 0]
    mass = probe.particles.mass[0]
    static = mass * 9.81 / k
    sim = sphere_on_floor(R - static, 0.5 * static / math.sqrt(mass / k), dt=dt_fraction * 2.0 * math.sqrt(mass / k))
    return sim


def test_kinetic_energy_alone_is_the_energys_kinetic_and_rotational_bit_for_bit():
    from pdem.checks.diagnostics import kinetic_energy

    sim = scene_from_dict(deposition_doc()).build()
    for _ in range(300):
        sim.advance()
    e = sim.energy()
    assert e["kinetic"] > 0.0 and kinetic_energy(sim) == e["kinetic"] + e["rotational"]


def test_total_energy_is_the_leapfrogs_shadow_energy():
    """Δt at 60 % of the critical 2 sqrt(m/k): the synchronised total stays constant to rounding
    (1e-6 of the oscillation's energy: the potential energy m g z is 10^5 times larger) every
    step, while kinetic + potential + elastic of the same samples swings by a fifth of it."""
    sim = oscillator(0.6)
    totals, naive, kinetic = [], [], []
    for _ in range(200):
        sim.advance()
        e = sim.energy()
        totals.append(e["total"])
        naive.append(e["kinetic"] + e["rotational"] + e["potential"] + e["elastic"])
        kinetic.append(e["kinetic"])
    assert sim.kind("sphere_wall").contacts.state[0] == 1  # still in contact: one linear spring
    swing = max(kinetic)  # the energy of the oscillation
    assert np.ptp(totals) < 1e-6 * swing, np.ptp(totals) / swing
    assert np.ptp(naive) > 0.2 * swing, np.ptp(naive) / swing
