"""The blast sensitivity campaign (jobs/campaigns/blast_sensitivity.toml) and its analysis
(``python -m analysis blast-sensitivity``, `analysis.blast_sensitivity`).

- The campaign file, expanded without running: every case runs at least 5 seeds with the paper's three
  plates, changes one input of the base (the validation campaign's scene) and only keys the blast scene
  has; the ``cn_absolute`` case's damping ratios give c_n = 0.2 N s/m for every pair of grain masses
  and for a grain on a boundary, computed here from the diameters, density and k_n.
- A reduced copy run for real (slow): the CI-size layer (tests/scenes/blast_ci.toml) with the paper's
  three plates, cases ``base`` and ``rolling_off`` x seeds 1 and 2, stages cut short. On its records:
  I_s / I_in with and without the static weight equals the trapezoid of sigma_0 (minus its value at
  t = 0) over the record divided by F0 tau / 2 / area, computed here with numpy from the HDF5 series and
  the scene's F0, tau and box; the analysis's per-case means and Student-t intervals, distances from
  the paper's values, verdicts and conclusion equal an independent computation (numpy, scipy.stats.t);
  its solid fraction agrees with the one from the prepared layer's radii.
"""
import json
import math
import subprocess
import sys
import tomllib

import h5py
import numpy as np
import pytest
from scipy import stats

from campaign_helpers import ROOT, pdem_campaign
from pdem.campaign.spec import load_campaign
from pdem.campaign.tomlw import dumps

CAMPAIGN = ROOT / "jobs" / "campaigns" / "blast_sensitivity.toml"
CI_BASE = ROOT / "tests" / "scenes" / "blast_ci.toml"
PAPER_IS = {10780.0: 7.97e-3, 2700.0: 7.96e-3, 244.0: 8.88e-3}  # [MPa s], paper section 4
PAPER_IN = 5e-3  # [MPa s]
# the factor each case varies: the last parts of the keys it may set
FACTORS = {"rolling_off": {"rolling_stiffness", "rolling_coefficient"}, "ktheta_low": {"rolling_stiffness"},
           "ktheta_high": {"rolling_stiffness"}, "beta_low": {"rolling_coefficient"},
           "beta_high": {"rolling_coefficient"}, "cn_absolute": {"damping_ratio"},
           "pour_stiff": {"prep_stiffness_factor"}, "layer_0.25": {"box"}, "layer_0.20": {"box"}}


def test_every_case_runs_five_seeds_of_the_three_plates_and_varies_one_input(tmp_path):
    camp = load_campaign(CAMPAIGN, out=str(tmp_path / "c"))
    base = tomllib.loads((CAMPAIGN.parent / "validation_blast.toml").read_text())["campaign"]["base"]
    assert camp.base == (CAMPAIGN.parent / base).resolve()
    seeds = {}
    for m in camp.members:
        seeds.setdefault(m.params["case"], set()).add(m.params[camp.seed_key])
        assert m.doc["blast"]["plates"] == list(PAPER_IS)
        changed = {k.split(".")[-1] for k in m.overrides if k != camp.seed_key}
        if m.params["case"] == "base":
            assert changed == set()
        else:
            assert changed and changed <= FACTORS[m.params["case"]], (m.name, changed)
    assert set(seeds) == {"base"} | set(FACTORS)
    assert all(len(s) >= 5 for s in seeds.values())
    assert len({json.dumps(sorted(s)) for s in seeds.values()}) == 1  # the same packings in every case


def test_cn_absolute_gives_the_absolute_dashpot():
    """c_n = zeta 2 sqrt(m* k_n), zeta of a pair the mean of its materials' (pdem.contact.viscous):
    0.2 N s/m within 10 % for the smallest and largest grains, against each other and a boundary."""
    camp = load_campaign(CAMPAIGN)
    doc = next(m.doc for m in camp.members if m.params["case"] == "cn_absolute")
    mat, blast = doc["materials"], doc["blast"]
    kn = mat["grain"]["kn"]
    masses = [mat["grain"]["density"] * math.pi / 6 * d ** 3 for d in (blast["diameter_min"], blast["diameter_max"])]
    zg = mat["grain"]["damping_ratio"]
    for m1 in masses:
        for m2 in masses:
            assert 2 * zg * math.sqrt(m1 * m2 / (m1 + m2) * kn) == pytest.approx(0.2, rel=0.1)
        for boundary in ("plate", "wall", "side"):
            zeta = 0.5 * (zg + mat[boundary]["damping_ratio"])
            assert 2 * zeta * math.sqrt(m1 * kn) == pytest.approx(0.2, rel=0.1)


# ---------------------------------------------------------------------------- the reduced campaign, run
SMALL_SET = {"blast.plates": list(PAPER_IS), "blast.settle_max_time": 0.1, "blast.plate_settle_max_time": 0.03,
             "blast.duration": 1.0e-3, "run.checkpoint_every_s": 0.0, "run.progress_every": 0}
SMALL_CASES = ("base", "rolling_off")


def small_campaign(tmp_path):
    """The campaign file on the CI-size base: two of its cases, seeds 1 and 2, short stages."""
    raw = tomllib.loads(CAMPAIGN.read_text())
    raw["campaign"].update(base=str(CI_BASE), out=str(tmp_path / "sens"), name="blast_sensitivity_small", ranks=1)
    raw["case"] = [c for c in raw["case"] if c["name"] in SMALL_CASES]
    raw["seeds"] = {"key": "blast.seed", "values": [1, 2]}
    raw["set"] = {**raw.get("set", {}), **SMALL_SET}
    raw["local"] = {"cores": 1}
    p = tmp_path / "blast_sensitivity_small.toml"
    p.write_text(dumps(raw))
    return p


def hand_ratios(plate_dir, scene):
    """(with, without the static weight) I_s / I_in of one plate record, computed here."""
    with h5py.File(plate_dir / "results.h5", "r") as f:
        t, sigma = f["series/time"][()], f["series/ceiling_stress"][()]
    b = scene["blast"]
    i_in = b["F0"] * b["tau"] / 2 / (b["box"][0] * b["box"][1])
    return np.trapezoid(sigma, t) / i_in, np.trapezoid(sigma - sigma[0], t) / i_in


def t_interval(x):
    x = np.asarray(x)
    half = stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x))
    return x.mean(), x.mean() - half, x.mean() + half


@pytest.mark.slow
def test_reduced_campaign_against_hand_computation(tmp_path):
    """Slow (4 CI-size members, ~15 s of CPU each, then the analysis)."""
    camp_file = small_campaign(tmp_path)
    r = pdem_campaign("run", camp_file, timeout=1500)
    assert r.returncode == 0, r.stdout + r.stderr
    out = tmp_path / "sens"
    rep = subprocess.run([sys.executable, "-m", "analysis", "blast-sensitivity", str(out)], capture_output=True,
                         text=True, cwd=ROOT, timeout=600)
    assert rep.returncode == 0, rep.stdout + rep.stderr
    res = json.loads((out / "analysis" / "blast_sensitivity.json").read_text())
    text = (out / "analysis" / "blast_sensitivity.txt").read_text()
    assert (out / "analysis" / "blast_sensitivity.png").stat().st_size > 10000

    from analysis.blast import analyse_blast
    from pdem.format.groups import read_blast

    hand = {}  # case -> plate -> ([with per seed], [without per seed])
    layer = {}
    for case in SMALL_CASES:
        for seed in (1, 2):
            member = out / f"{case}_seed-{seed}"
            scene = tomllib.loads((member / "scene.toml").read_text())
            for mass in PAPER_IS:
                w, wo = hand_ratios(member / f"plate_{mass:g}", scene)
                a = analyse_blast(*read_blast(member / f"plate_{mass:g}"))  # the blast analysis itself
                assert a.amplification == pytest.approx(w, rel=1e-9)
                assert a.amplification_dynamic == pytest.approx(wo, rel=1e-9)
                entry = hand.setdefault(case, {}).setdefault(mass, ([], []))
                entry[0].append(w)
                entry[1].append(wo)
            # the solid fraction from the prepared layer's radii (its checkpoint), against the analysis's
            # estimate from the sphere count and the mean sphere volume
            with h5py.File(next((member / "prepared_layer").glob("ckpt_*.h5")), "r") as f:
                radius = f["tables/particles/radius"][()]
            lx, ly, h = scene["blast"]["box"]
            layer.setdefault(case, []).append(np.sum(4 / 3 * np.pi * radius ** 3) / (lx * ly * h))

    assert [c["case"] for c in res["cases"]] == list(SMALL_CASES)
    tol = res["tolerance"]
    reach, pattern, best = [], [], []
    for c in res["cases"]:
        assert c["n"] == 2 and c["seeds"] == [1, 2]
        assert c["layer"]["solid_fraction"]["mean"] == pytest.approx(np.mean(layer[c["case"]]), rel=0.03)
        for k, (variant, label) in enumerate((("amplification", "with the static weight"),
                                              ("amplification_dynamic", "without the static weight"))):
            v = c["variants"][variant]
            dists, means = [], {}
            for mass, paper_is in PAPER_IS.items():
                e = v["plates"][f"{mass:g}"]
                mean, lo, hi = t_interval(hand[c["case"]][mass][k])
                assert (e["mean"], e["ci_low"], e["ci_high"]) == pytest.approx((mean, lo, hi), rel=1e-9)
                paper = paper_is / PAPER_IN
                assert e["paper"] == pytest.approx(paper, rel=1e-12)
                d = max(lo - paper, paper - hi, 0.0) / paper
                assert e["distance"] == pytest.approx(d, rel=1e-9, abs=1e-12)
                dists.append(d)
                means[mass] = mean
            assert v["distance"] == pytest.approx(max(dists), rel=1e-9, abs=1e-12)
            assert v["reaches_paper"] == (max(dists) <= tol)
            diff = (means[10780.0] - means[2700.0]) / (0.5 * (means[10780.0] + means[2700.0]))
            assert v["heavy_minus_middle"] == pytest.approx(diff, rel=1e-9, abs=1e-12)
            assert v["heavy_equals_middle"] == (abs(diff) <= tol)
            name = f"{c['case']} ({label})"
            (reach if max(dists) <= tol else best).append((max(dists), name))
            if abs(diff) <= tol:
                pattern.append(name)
    line = res["conclusion"]
    assert f"conclusion: {line}" in text
    if reach:
        assert line.startswith("reaching the paper's three values") and all(n in line for _, n in reach)
    else:
        assert line.startswith("no case reaches") and f"closest {min(best)[1]}" in line
    assert line.endswith(", ".join(pattern) if pattern else "no case")
