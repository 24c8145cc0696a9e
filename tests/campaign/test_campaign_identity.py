"""Campaign and resume identity is what changes results: editing an output-only key (progress,
output, snapshot or checkpoint intervals: `pdem.build.config.OUTPUT_ONLY_KEYS`) neither locks a
campaign's members nor refuses a staged run's resume; any other edit still does."""
import tomllib

import pytest
from campaign_helpers import write_campaign

from pdem.build.config import OUTPUT_ONLY_KEYS, result_identity
from pdem.campaign.layout import write_campaign as expand_into
from pdem.campaign.spec import load_campaign
from pdem.driver.stages import same_results
from pdem.errors import InputError

BODY = "[seeds]\nkey = \"deposition.seed\"\nvalues = [1, 2]\n"


def expand(path):
    camp = load_campaign(path)
    expand_into(camp, log=lambda m: None)
    return camp


def test_identity_leaves_out_exactly_the_output_only_keys():
    doc = {"run": {"steps": 10, **{k.split(".")[1]: 7 for k in OUTPUT_ONLY_KEYS}}, "simulation": {"damping": 0.1}}
    assert result_identity(doc) == {"run": {"steps": 10}, "simulation": {"damping": 0.1}}
    assert doc["run"]["progress_every"] == 7  # the document itself is left alone
    assert result_identity({"run": {"progress_every": 5}}) == {}


def test_output_only_edits_do_not_lock_members(tmp_path, tiny):
    p = write_campaign(tmp_path, BODY)
    camp = expand(p)
    tiny.write_text(tiny.read_text().replace("progress_every = 100", "progress_every = 7")
                    .replace("output_every = 20", "output_every = 10"))
    camp = expand(p)  # no refusal: the members are the same runs
    doc = tomllib.loads((camp.out / camp.members[0].name / "scene.toml").read_text())
    assert doc["run"]["progress_every"] == 7 and doc["run"]["output_every"] == 10  # rewritten with the new ones
    p.write_text(p.read_text() + "[set]\n\"run.checkpoint_every\" = 50\n")
    expand(p)  # an output-only key in [set] neither


def test_result_edits_still_lock_members(tmp_path, tiny):
    p = write_campaign(tmp_path, BODY)
    expand(p)
    tiny.write_text(tiny.read_text().replace("damping = 0.3", "damping = 0.2"))
    with pytest.raises(InputError, match="its scene"):
        expand(p)


def test_staged_resume_identity(tiny):
    text = tiny.read_text()
    assert same_results(text, text.replace("progress_every = 100", "progress_every = 3"))
    assert same_results(text, text.replace("[run]\n", "[run]\nsnapshot_every = 40\n"))
    assert not same_results(text, text.replace("steps = 400", "steps = 401"))
    assert not same_results(text, text.replace("young = 1.0e7", "young = 2.0e7"))
    assert not same_results(None, text)
