"""Shared fixtures: where the third-party data lives, and an isolated output folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from appeal.assets import shared_data_dir


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` (or ``$APPEAL_DATA``); tests that need it fail loudly without it."""
    path = shared_data_dir()
    if path is None:
        pytest.fail("third-party test data not found: put shared/data beside the checkout or set APPEAL_DATA")
    return path
