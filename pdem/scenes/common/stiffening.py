"""Full stiffness by way of a soft preparation: the ``stiffen`` stage shared by the scenes that
prepare a bed at a reduced stiffness and load it at the materials' (the box test,
`pdem.scenes.box_test`; the track section, `pdem.scenes.track`).

At the thesis's stiffness (E_k = 2.8e11 Pa) Δt is ~1e-6 s and preparing a bed (seconds of
pouring, vibrating, settling) would take millions of steps. With ``prep_stiffness_factor`` f < 1
(law "linear": k_n, k_s ∝ young, Yade's Ip2_FrictMat_FrictMat_FrictPhys) the scene prepares with
every material's young times f (Δt times 1/√f) and inserts `stiffen_stage` before its loading:

- every ``check_every`` steps the scale s = f^(1 − t'/T) (t' since the stage started,
  T = ``stiffen_time`` [s]; 1 from t' = T on): new contacts are made at s·young, the existing
  contacts' k_n, k_s are multiplied by s/s_before (`pdem.simulation.Simulation.set_stiffness_scale`:
  their tangential force stays) and Δt is re-estimated at once;
- then it settles as a settle stage does (unbalanced-force ratio < ``settle_ratio`` and, if the
  scene asks, its rigid bodies at rest), the stage ending at the latest ``stiffen_time`` +
  ``stiffen_settle_max_time`` [s] (default ``settle_max_time``) after it started; the
  energy-growth check is off (stiffening at a fixed overlap raises the elastic energy).

Afterwards every contact's k_n, k_s are what Ip2 gives at the full stiffness within rounding.
Keys (in the scene's table, next to the preparation's): `STIFFEN_DEFAULTS`, checked by
`check_stiffening`. The run keeps the scale reached in ``state["stiffness_scale"]`` (in the
checkpoints: a restart inside the stage is exact).
"""
from ...driver import observables
from ...driver.stages import Stage
from ...errors import InputError
from ...build.validate import number
from .preparation import always

# keys and defaults (SI); stiffen_settle_max_time None: settle_max_time
STIFFEN_DEFAULTS = {
    "prep_stiffness_factor": 1.0,      # prepare with every material's young times this [-]; 1: no stiffen stage
    "stiffen_time": 0.2,               # the stiffness grows geometrically to the materials' over this time [s]
    "stiffen_settle_max_time": None,   # settling after it at most this long [s] (default settle_max_time)
}


def check_stiffening(name, c, doc):
    """Validate the keys of `STIFFEN_DEFAULTS` in the table ``name`` (``c`` with defaults filled
    in) in place; one-line InputError naming ``name.key``."""
    c["prep_stiffness_factor"] = number(f"{name}.prep_stiffness_factor", c["prep_stiffness_factor"], 0.0, 1.0,
                                        lo_open=True, allow="in (0, 1]")
    if c["prep_stiffness_factor"] != 1.0 and doc.get("simulation", {}).get("law", "linear") != "linear":
        raise InputError(f"{name}.prep_stiffness_factor = {c['prep_stiffness_factor']!r}: the stiffening stage "
                         "needs simulation.law = 'linear' (its stiffness is proportional to young); use 1.0")
    c["stiffen_time"] = number(f"{name}.stiffen_time", c["stiffen_time"], 0.0, lo_open=True)
    if c["stiffen_settle_max_time"] is not None:
        c["stiffen_settle_max_time"] = number(f"{name}.stiffen_settle_max_time", c["stiffen_settle_max_time"], 0.0,
                                              lo_open=True, allow="a time > 0 [s]")
    return c


def soft(c):
    """True if the scene prepares at a reduced stiffness (and so has a stiffen stage)."""
    return c["prep_stiffness_factor"] != 1.0


def stiffen_stage(run, scene, after=None, at_rest=always):
    """The ``stiffen`` stage of a `pdem.scenes.common.preparation.PreparedRun` ``run`` whose
    ``run.c`` holds the keys and ``run.state["stiffness_scale"]`` the scale reached (start: f):
    ``scene`` (tables → Scene) builds it at the preparation's stiffness; ``after(sim)`` is done
    at its end after the stage-end line (e.g. the first row of the load record); ``at_rest(sim)``
    the scene's rigid bodies at rest."""
    c = run.c

    def prepare(sim, sc, mid_stage):  # the scale reached so far (the carried contacts hold it already)
        sim.set_stiffness_scale(run.state["stiffness_scale"] / c["prep_stiffness_factor"])
        sim.moving_boundaries = True  # stiffening raises the elastic energy: no energy-growth check

    def program(sim, sc):
        """Every ``check_every`` steps the scale s = f^(1 − t'/T), existing contacts rescaled by
        s/s_before and Δt re-estimated; then settle."""
        state, cfg = run.state, run.run_cfg
        t0, f, duration, every = state["stage_t0"], c["prep_stiffness_factor"], c["stiffen_time"], c["check_every"]
        settle = c["settle_max_time"] if c.get("stiffen_settle_max_time") is None else c["stiffen_settle_max_time"]
        t_end = t0 + duration + settle

        def on_step(sim):
            if sim.step % every == 0 and state["stiffness_scale"] < 1.0:
                s = 1.0 if sim.time - t0 >= duration else f ** (1.0 - (sim.time - t0) / duration)
                sim.set_stiffness_scale(s / f, s / state["stiffness_scale"])
                state["stiffness_scale"] = s
                sim.update_dt(force=True)
            if cfg["output_every"] and sim.step % cfg["output_every"] == 0:
                run.prep.append(run.prep_sample(sim))
            run.snapshot(sim)

        def settled(sim):
            return sim.time >= t_end or (state["stiffness_scale"] == 1.0
                                         and observables.unbalanced_force(sim) < c["settle_ratio"] and at_rest(sim))

        return on_step, settled, every, t_end

    def close(sim):
        run.stage_done(sim, "stiffen")
        if after is not None:
            after(sim)
        ratio = observables.unbalanced_force(sim)
        if run.state["stiffness_scale"] != 1.0 or ratio >= c["settle_ratio"] or not at_rest(sim):
            run.loop.log(f"warning: stage stiffen reached stiffen_time + settle time with stiffness scale "
                         f"{run.state['stiffness_scale']:g}, unbalanced force ratio {ratio:.3g}"
                         + ("" if at_rest(sim) else ", the rigid bodies not at rest") + "; going on")
        run.prep.append(run.prep_sample(sim))

    note = f"stiffness x {c['prep_stiffness_factor']:g} -> x 1 over {c['stiffen_time']:g} s; settle"
    return Stage("stiffen", scene, program, open=lambda tables: (tables, note), prepare=prepare, close=close,
                 record=run.stage_record)
