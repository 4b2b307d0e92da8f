"""Study-file loading: one-line errors naming file, dotted path and what was expected."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import Field

from appeal.errors import StudyFileError
from appeal.studyfile import InputDir, InputFile, StudyModel, load_study_file, validate_data


class Timing(StudyModel):
    duration_s: float = Field(gt=0)
    fixation_s: tuple[float, float] = (0.4, 0.5)


class Scale(StudyModel):
    name: str
    points: int = Field(default=7, ge=2, le=11)


class Demo(StudyModel):
    kind: Literal["demo"]
    title: str
    trials: Timing
    scales: list[Scale] = []
    order: Literal["random", "blocked"] = "random"
    stimuli: InputDir | None = None
    manifest: InputFile | None = None


def _write(tmp_path: Path, text: str, name: str = "study.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _errors(tmp_path: Path, text: str) -> list[str]:
    path = _write(tmp_path, text)
    with pytest.raises(StudyFileError) as info:
        load_study_file(path, Demo)
    for line in info.value.lines:
        assert line.startswith(f"{path}:"), line
        assert "\n" not in line
    return info.value.lines


GOOD = "kind: demo\ntitle: t\ntrials: {duration_s: 3}\n"


def test_good_file_loads_and_resolves_relative_paths(tmp_path):
    (tmp_path / "faces").mkdir()
    (tmp_path / "m.csv").write_text("file\n")
    m = load_study_file(_write(tmp_path, GOOD + "stimuli: faces\nmanifest: m.csv\n"), Demo)
    assert m.stimuli == (tmp_path / "faces").resolve()
    assert m.manifest == (tmp_path / "m.csv").resolve()
    assert m.trials.duration_s == 3


@pytest.mark.parametrize(
    "text, expected",
    [
        ("kind: demo\ntitle: t\ntrials: {duration_s: -3}\n", "trials.duration_s: must be > 0 (got -3)"),
        ("kind: demo\ntitle: t\ntrials: {duration_s: 0}\n", "trials.duration_s: must be > 0 (got 0)"),
        ("kind: demo\ntitle: t\ntrials: {duration_s: abc}\n", "trials.duration_s: expected number"),
        ("kind: demo\ntitle: t\n", "trials: required field is missing"),
        ("kind: demo\ntrials: {duration_s: 1}\n", "title: required field is missing"),
        (GOOD + "titel: x\n", "titel: unknown key 'titel' (did you mean 'title'?)"),
        ("kind: demo\ntitle: t\ntrials: {duration_s: 1, duraton_s: 2}\n", "trials.duraton_s: unknown key 'duraton_s' (did you mean 'duration_s'?)"),
        (GOOD + "scales: [{name: appeal, points: 1}]\n", "scales[0].points: must be >= 2 (got 1)"),
        (GOOD + "scales: [{name: a}, {name: b, points: 12}]\n", "scales[1].points: must be <= 11 (got 12)"),
        (GOOD + "scales: [{nam: a}]\n", "scales[0].nam: unknown key 'nam' (did you mean 'name'?)"),
        (GOOD + "order: shuffled\n", "order: expected 'random' or 'blocked' (got 'shuffled')"),
        (GOOD + "stimuli: no_such_folder\n", "stimuli: folder not found"),
        (GOOD + "manifest: missing.csv\n", "manifest: file not found"),
        (GOOD + "scales: appeal\n", "scales: expected list"),
        ("kind: other\ntitle: t\ntrials: {duration_s: 1}\n", "kind: expected 'demo' (got 'other')"),
        ("kind: demo\ntitle: t\ntrials: {duration_s: 1, fixation_s: [0.4]}\n", "trials.fixation_s"),
        (GOOD + "zzzzzz: 1\n", "zzzzzz: unknown key 'zzzzzz' (expected one of:"),
    ],
)
def test_malformed_files_give_one_line_per_problem(tmp_path, text, expected):
    lines = _errors(tmp_path, text)
    assert any(expected in line for line in lines), lines


def test_several_problems_are_all_reported(tmp_path):
    lines = _errors(tmp_path, "kind: demo\ntrials: {duration_s: -1}\nextra: 1\n")
    assert len(lines) == 3


@pytest.mark.parametrize(
    "text, expected",
    [
        ("", "(top level): expected a mapping of keys to values, got an empty file"),
        ("- a\n- b\n", "(top level): expected a mapping of keys to values, got list"),
        ("kind: demo\ntitle: [unclosed\n", "invalid YAML"),
        ("kind: demo\n\ttitle: t\n", "invalid YAML"),
    ],
)
def test_not_a_study_document(tmp_path, text, expected):
    assert any(expected in line for line in _errors(tmp_path, text))


def test_yaml_error_names_line_and_column(tmp_path):
    (line,) = _errors(tmp_path, "kind: demo\ntitle: [unclosed\n")
    assert re.match(rf"{re.escape(str(tmp_path))}/study.yaml:\d+:\d+: invalid YAML: ", line)


def test_missing_file_and_folder(tmp_path):
    with pytest.raises(StudyFileError, match="nope.yaml: file not found"):
        load_study_file(tmp_path / "nope.yaml", Demo)
    with pytest.raises(StudyFileError, match="is a folder"):
        load_study_file(tmp_path, Demo)


def test_not_utf8(tmp_path):
    p = tmp_path / "bin.yaml"
    p.write_bytes(b"kind: demo\ntitle: \xff\xfe\n")
    with pytest.raises(StudyFileError, match="not UTF-8"):
        load_study_file(p, Demo)


def test_check_paths_false_skips_existence(tmp_path):
    m = load_study_file(_write(tmp_path, GOOD + "stimuli: later\n"), Demo, check_paths=False)
    assert m.stimuli == (tmp_path / "later").resolve()


# A fuzz test: whatever document comes in, the loader either returns a model or raises a
# StudyFileError whose lines all have the FILE: path: message form -- nothing else escapes.
_scalars = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.text(max_size=8))
_keys = st.sampled_from(["kind", "title", "trials", "scales", "order", "duration_s", "name", "points", "x", "fixation_s"])
_docs = st.recursive(_scalars, lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(_keys, inner, max_size=5)), max_leaves=12)


@settings(max_examples=300, deadline=None)
@given(doc=st.dictionaries(_keys, _docs, max_size=6))
def test_fuzz_only_one_line_errors(doc):
    try:
        validate_data(doc, Demo, source="fuzz.yaml", check_paths=False)
    except StudyFileError as exc:
        assert exc.lines
        for line in exc.lines:
            assert re.match(r"^fuzz\.yaml: [^:]+: .+$", line) or line.startswith("fuzz.yaml: (top level)"), line
            assert "\n" not in line


@settings(max_examples=100, deadline=None)
@given(text=st.text(max_size=60))
def test_fuzz_arbitrary_text(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("fz") / "f.yaml"
    p.write_text(text)
    try:
        load_study_file(p, Demo, check_paths=False)
    except StudyFileError as exc:
        assert all(line.startswith(str(p)) for line in exc.lines)
    yaml.safe_dump({"ok": True})
