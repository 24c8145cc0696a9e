"""Fixtures of the campaign tests (helpers in campaign_helpers.py)."""
import pytest

from campaign_helpers import write_tiny


@pytest.fixture
def tiny(tmp_path):
    """Path of the tiny base scene (tmp_path/tiny.toml)."""
    return write_tiny(tmp_path)
