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


@pytest.fixture(scope="session")
def james_scan(shared_data, tmp_path_factory):
    """The menpo3d james scan as a grid character drawn as itself (``topology: scan``, ``region:
    front``, every part at its default: eyeballs, cut lips, the bust), loaded once."""
    from appeal.studyfile import validate_data
    from stimulus_engine.grid.characters import load_character
    from stimulus_engine.grid.schema import GridFile

    d = shared_data / "meshes"
    spec = validate_data({
        "kind": "grid", "name": "james", "characters": [{"name": "james", "ict": str(d / "ict-facekit"), "mesh": {
            "file": str(d / "menpo3d-james" / "james.obj"), "region": "front", "topology": "scan"}}],
        "shapes": [0.0], "materials": ["original"], "expressions": ["neutral"], "lighting": ["gi_soft"],
        "shading": ["pbr"]}, GridFile, source="g.yaml")
    return load_character(spec.characters[0], tmp_path_factory.mktemp("james_scan"), "g.yaml")
