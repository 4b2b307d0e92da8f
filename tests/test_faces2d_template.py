"""WebMorph/Psychomorph templates: every shipped London template reads and writes back byte for byte."""

from __future__ import annotations

import numpy as np
import pytest

from appeal.errors import AppealInputError
from stimulus_engine.faces2d import Template, read_template, template_text, write_template


def test_every_london_template_round_trips_byte_for_byte(shared_data, tmp_path):
    files = sorted((shared_data / "faces2d").glob("london-frl*/**/*.tem"))
    assert len(files) >= 87  # 30 + 57 identities' neutral templates
    for f in files:
        t = read_template(f)
        assert t.points.shape == (189, 2)
        out = write_template(tmp_path / f.name, t)
        assert out.read_bytes() == f.read_bytes(), f


def test_moved_points_are_written_and_read_back(tmp_path):
    t = Template(np.array([[1.0, 2.0], [3.25, 4.5]]), "1\n0 1\n")
    moved = t.moved(t.points + 0.5)
    back = read_template(write_template(tmp_path / "m.tem", moved))
    assert np.array_equal(back.points, moved.points) and back.tail == moved.tail
    assert template_text(Template(np.array([[5.0, 6.0]]))) == "1\n5.0\t6.0\n"  # detected points: no line definitions
    with pytest.raises(ValueError):
        t.moved(np.zeros((3, 2)))


def test_malformed_templates_are_one_line_errors(tmp_path):
    (tmp_path / "bad.tem").write_text("3\n1 2\n3 4\n")
    with pytest.raises(AppealInputError, match="bad.tem: .*expected"):
        read_template(tmp_path / "bad.tem")
    with pytest.raises(AppealInputError, match="not found"):
        read_template(tmp_path / "missing.tem")
