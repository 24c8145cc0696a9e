"""The stability map (jobs/campaigns/stability_map.toml) at reduced size, end to end: the same
cases on the same base scene, with 61 spheres instead of 3001 and a few thousand steps, expanded
and run by ``pdem campaign run`` and judged by ``python -m analysis stability``.

What must hold (SPEC.md 4, issue 11): every case either ran stably (exit 0, its mechanical energy
never rising more than 10 % of its largest kinetic+elastic energy, with contacts formed: a map of
free flight would prove nothing) or stopped with exit 4 and one line naming the step, the body and
the cause; each case does what the campaign file expects of it; and no output of any case (results,
checkpoints, logs, summaries) holds a NaN or an infinity — checked here by the report and again
by an independent scan of every HDF5 dataset.

The reduced size: uniform radii (radius_spread 0) so that the bottom layer starts within 0.1 r of
the floor and even the stiff case (time step 140 times shorter) forms contacts within its 20 000
steps; the extra sphere lower down, so that the stiff projectile reaches the bed after bouncing
off the wall. Every case of the campaign file needs an entry in SMALL_STEPS: a new case cannot be
left out of ``make test``.
"""
import json
import subprocess
import sys
import tomllib

import h5py
import numpy as np
import pytest

from campaign_helpers import ROOT, pdem_campaign
from pdem.campaign.tomlw import dumps

CAMPAIGN = ROOT / "jobs" / "campaigns" / "stability_map.toml"
SMALL_SET = {"deposition.count": 60, "deposition.box_hi": [0.3, 0.2, 0.6], "deposition.radius_spread": 0.0,
             "deposition.seed": 2, "spheres.0.pos": [[0.26375, 0.1, 0.2]], "run.output_every": 20,
             "run.progress_every": 0, "run.checkpoint_every_s": 0.0}
SMALL_STEPS = {"reference": 1500, "undamped": 1500, "frictionless": 1500, "radius_ratio_10": 5000,
               "projectile": 200, "dt_above_critical": 1500, "projectile_stiff": 6000, "stiff": 20000}
CAUSES = ("of its radius per step", "exceeds max_overlap_ratio", "mechanical energy grew", "non-finite",
          "went through wall", "left the domain", "not finite in the results")


def small_campaign(tmp_path):
    """The campaign file with the reduced size: [set] SMALL_SET, each case's steps from SMALL_STEPS
    (its own run.output_every dropped for the small one)."""
    raw = tomllib.loads(CAMPAIGN.read_text())
    names = [c["name"] for c in raw["case"]]
    assert set(names) == set(SMALL_STEPS), f"give every case of {CAMPAIGN.name} a reduced size here: {names}"
    raw["campaign"].update(base=str(CAMPAIGN.parent / raw["campaign"]["base"]), out=str(tmp_path / "map"),
                           name="stability_map_small")
    raw["set"] = {**raw.get("set", {}), **SMALL_SET}
    for c in raw["case"]:
        c.pop("run.output_every", None)
        c["run.steps"] = SMALL_STEPS[c["name"]]
    raw["local"] = {"cores": 2}
    p = tmp_path / "stability_map_small.toml"
    p.write_text(dumps(raw))
    return p


def nonfinite_datasets(path):
    """Every HDF5 dataset under ``path`` holding a NaN or an infinity (an independent scan)."""
    bad = []
    for f in sorted(path.rglob("*.h5")):
        with h5py.File(f, "r") as h:
            def visit(name, obj):
                if isinstance(obj, h5py.Dataset) and obj.dtype.kind in "fc" and not np.all(np.isfinite(obj[()])):
                    bad.append(f"{f.relative_to(path)}:{name}")
            h.visititems(visit)
    return bad


@pytest.mark.slow
def test_stability_map_small(tmp_path):
    """Slow (about a minute on two idle cores, mostly 8 interpreter starts; longer under load): it
    runs the eight members of the map as pdem would on a cluster."""
    camp = small_campaign(tmp_path)
    r = pdem_campaign("run", camp, timeout=1500)
    assert r.returncode in (0, 1), r.stdout + r.stderr  # 1: some member stopped (exit 4), as expected
    out = tmp_path / "map"
    rep = subprocess.run([sys.executable, "-m", "analysis", "stability", str(out)], capture_output=True, text=True,
                         cwd=ROOT, timeout=600)
    report = json.loads((out / "analysis" / "stability.json").read_text())
    text = (out / "analysis" / "stability.txt").read_text()
    assert rep.returncode == 0 and report["passed"], rep.stdout + rep.stderr + text
    assert text.startswith("stability map PASSED: 8 members: 6 stable, 2 stopped, 0 FAILED")
    assert "no NaN or infinity in any output" in text.splitlines()[0]
    verdicts = {m["case"]: m for m in report["members"]}
    for case, m in verdicts.items():
        assert m["verdict"] == m["expected"], (case, m["line"])
        assert m["nonfinite"] == [], (case, m["nonfinite"])
        if m["verdict"] == "stable":
            assert m["exit"] == 0 and m["line"].startswith("ran stably (energy balance: "), m["line"]
            assert m["energy"]["checked"] and m["energy"]["rise_ratio"] <= 0.10, (case, m["energy"])
            assert m["steps"] == SMALL_STEPS[case]
            with h5py.File(out / case / "results.h5") as f:
                assert f["series"]["contacts_per_particle"][()].max() > 0, f"{case}: no contact ever formed"
        else:
            assert m["exit"] == 4 and m["line"].startswith("stopped: step "), m["line"]
            assert "\n" not in m["message"] and any(c in m["line"] for c in CAUSES), m["line"]
    assert "the initial velocity is too high for the time step" in verdicts["projectile"]["line"]
    assert "body gid 0 " in verdicts["projectile"]["line"]  # the extra sphere is the first body
    assert "the time step fixed by simulation.dt is" in verdicts["dt_above_critical"]["line"]
    # the stiff runs took far more, shorter steps: their time step follows the stiffness
    with h5py.File(out / "stiff" / "results.h5") as f, h5py.File(out / "reference" / "results.h5") as g:
        assert f["series"]["dt"][()].max() < g["series"]["dt"][()].min() / 50
    assert nonfinite_datasets(out) == []
    assert (out / "analysis" / "stability.png").stat().st_size > 10000
    md = (out / "analysis" / "stability.md").read_text()
    assert md.count("\n| stability_map_small | ") == 8
