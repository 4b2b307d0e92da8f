"""Every character of the shipped grids is complete at the realistic end: hair on every head."""

from __future__ import annotations

from pathlib import Path

import pytest

from appeal.studyfile import load_study_file
from stimulus_engine.grid.schema import GridFile

GRIDS = sorted((Path(__file__).resolve().parent.parent / "protocols" / "grids").glob("*.yaml"))


@pytest.mark.parametrize("path", GRIDS, ids=lambda p: p.stem)
def test_every_head_has_hair(path):
    """A character wears a hairstyle, or is a scan drawn with its own (sculpted) hair, or a photo
    character with the photograph's hair (its head-and-shoulders layer); only an explicit
    ``hair: none`` goes bald."""
    for c in load_study_file(path, GridFile).characters:
        own = (c.mesh is not None and c.mesh.topology == "scan") or c.photo is not None
        assert c.hair_style is not None or own or c.hair == "none", (path.name, c.name)
        assert c.hair != "none" or c.photo is not None, (path.name, c.name)  # no shipped study shows a bald head
