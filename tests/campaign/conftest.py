"""Fixtures of the campaign tests (helpers in campaign_helpers.py)."""
import pytest

from factories import TINY_DEPOSITION


@pytest.fixture
def tiny(tmp_path):
    """Path of the tiny base scene (tmp_path/tiny.toml)."""
    path = tmp_path / "tiny.toml"
    path.write_text(TINY_DEPOSITION)
    return path
