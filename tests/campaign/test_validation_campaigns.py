"""The campaign files of the validation table (jobs/campaigns/validation_*.toml, docs/validation.md)
expand, run at least 5 seeds per group, and hold every group a row of jobs/validation/rows.toml
asks of them; every row names a job or campaign file that exists. Nothing is run."""
import json
import tomllib

import pytest

from campaign_helpers import ROOT
from pdem.campaign.spec import load_campaign

ROWS = tomllib.loads((ROOT / "jobs" / "validation" / "rows.toml").read_text())["row"]
FILES = sorted((ROOT / "jobs" / "campaigns").glob("validation_*.toml"))


def test_every_row_names_a_file_that_exists():
    assert len(ROWS) >= 20
    for row in ROWS:
        path = row["campaign"].split()[0]
        if path.startswith("jobs/"):
            assert (ROOT / path).is_file(), f"{row['id']}: {path}"


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_validation_campaign_expands_with_five_seeds_per_group(tmp_path, path):
    camp = load_campaign(path, out=str(tmp_path / path.stem))
    seed_key = camp.seed_key
    groups = {}
    for m in camp.members:
        key = json.dumps({k: v for k, v in m.params.items() if k != seed_key}, sort_keys=True)
        groups.setdefault(key, set()).add(m.params[seed_key])
    assert groups and all(len(seeds) >= 5 for seeds in groups.values())
    cases = {json.loads(k).get("case") for k in groups}
    rel = f"jobs/campaigns/{path.name}"
    for row in ROWS:
        spec = row["pdem"]
        if row["campaign"] != rel or spec["extractor"] != "campaign":
            continue
        for sel in spec.get("groups", [spec.get("select", {})]):
            if "case" in sel:
                assert sel["case"] in cases, f"{row['id']}: case {sel['case']} not in {path.name}"
