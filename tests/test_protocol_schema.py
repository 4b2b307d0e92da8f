"""Protocol files: the shipped ones validate; malformed ones give one-line errors naming file and field."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from appeal.assets import protocols_dir
from appeal_cli import main
from appeal.errors import AppealInputError
from appeal.studyfile import load_study_file
from experiments.protocol_schema import Protocol

SHIPPED = sorted(protocols_dir().glob("*.yaml"))

BASE = {
    "kind": "protocol", "name": "t", "task": "t",
    "stimuli": {"manifest": "stim/manifest.csv", "factors": ["character", "stylisation", "emotion"]},
    "timing": {"stimulus_s": 0.6, "fixation_s": [0.4, 0.5]},
    "order": {"repetitions": 2, "no_immediate_repeat": True},
    "responses": [{"type": "likert", "name": "appeal", "low": "unappealing", "high": "appealing"}],
    "triggers": {"backend": "file", "codes": [{"code": 11, "character": "c1", "stylisation": 0, "emotion": "angry"}]},
}


def test_shipped_protocols_exist():
    names = {p.stem for p in SHIPPED}
    assert {"exp1a_shape_material", "exp1b_shading_lighting", "exp1c_texture", "exp2_stylisation",
            "exp3_expressions", "erp_stylisation"} <= names


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_shipped_protocol_validates(path):
    proto = load_study_file(path, Protocol)
    assert proto.kind == "protocol"


def test_shipped_scale_texts_are_the_thesis_ones():
    p = load_study_file(protocols_dir() / "exp1a_shape_material.yaml", Protocol)
    scales = {r.name: r for r in p.responses}
    assert list(scales) == ["realism", "appeal", "reassurance", "familiarity"]
    assert scales["appeal"].low == "Extremely unappealing" and scales["appeal"].points == 7
    assert scales["reassurance"].low == "Extremely eerie" and scales["reassurance"].high == "Extremely re-assuring"
    assert scales["realism"].description.startswith("Indicate if you find the character's appearance to be highly stylized")
    assert p.timing.stimulus_s == 3.0
    e2 = load_study_file(protocols_dir() / "exp2_stylisation.yaml", Protocol)
    assert e2.timing.stimulus_s == 4.0 and [r.name for r in e2.responses] == ["realism", "appeal"]
    assert e2.anchors.select.match == ["shape", "material"] and e2.end_of_session is not None
    e1c = load_study_file(protocols_dir() / "exp1c_texture.yaml", Protocol)
    assert e1c.order.repetitions == 3 and e1c.order.shuffle == "per_repetition"
    assert "attractiveness" in e1c.response_names


def test_erp_protocol_trigger_list_is_readable_as_plain_yaml():
    """The ERP analysis reads triggers.codes straight from the YAML: a list of {code, factor: level}."""
    data = yaml.safe_load((protocols_dir() / "erp_stylisation.yaml").read_text())
    codes = data["triggers"]["codes"]
    assert isinstance(codes, list) and len(codes) == 36
    assert codes[0] == {"code": 11, "character": "james", "stylisation": 0, "emotion": "angry"}
    assert len({c["code"] for c in codes}) == 36 and all(1 <= c["code"] <= 255 for c in codes)
    conds = {(c["character"], c["stylisation"], c["emotion"]) for c in codes}
    assert len(conds) == 36


def _set(d, dotted, value):
    parts = dotted.split(".")
    for p in parts[:-1]:
        d = d[int(p)] if p.isdigit() else d[p]
    last = parts[-1]
    if value is _DELETE:
        del d[int(last) if last.isdigit() else last]
    elif isinstance(d, list) and int(last) == len(d):
        d.append(value)
    else:
        d[int(last) if last.isdigit() else last] = value


_DELETE = object()

# (change, value, expected field path in the message, expected words in the message)
MALFORMED = [
    ("kind", "protokol", "kind", "expected 'protocol'"),
    ("name", _DELETE, "name", "required field is missing"),
    ("task", "my-task", "task", "string should match pattern"),
    ("stimuli.factors", [], "stimuli.factors", "at least 1"),
    ("stimuli.folder", "imgs", "stimuli", "exactly one of 'manifest'"),
    ("stimuli.manifest", _DELETE, "stimuli", "exactly one of 'manifest'"),
    ("stimuli.factors", ["emotion", "emotion"], "stimuli", "factors must be unique"),
    ("stimuli.select", {"match": ["emotion"]}, "stimuli.select.match", "at least two factors"),
    ("timing.stimulus_s", 0, "timing.stimulus_s", "must be > 0"),
    ("timing.stimulus_s", "long", "timing.stimulus_s", "number"),
    ("timing.fixation_s", [0.5, 0.4], "timing.fixation_s", "min <= max"),
    ("timing.response_deadline_s", -1, "timing.response_deadline_s", ">"),
    ("order.repetitions", 0, "order.repetitions", "must be >= 1"),
    ("order.order", "shuffled", "order.order", "'random', 'blocked' or 'fixed'"),
    ("order.order", "blocked", "order", "needs block_by"),
    ("order.max_run", {"colour": 2}, "(top level)", "order.max_run: unknown factor 'colour'"),
    ("order.max_run", {"emotion": 0}, "order.max_run.emotion", "must be >= 1"),
    ("order.no_immediat_repeat", True, "order.no_immediat_repeat", "did you mean 'no_immediate_repeat'"),
    ("responses.0.type", "slider", "responses[0]", "'likert', 'classification'"),
    ("responses.0.points", 1, "responses[0].likert.points", "must be >= 2"),
    ("responses.0.low", _DELETE, "responses[0].likert.low", "required field is missing"),
    ("responses.1", {"type": "likert", "name": "appeal", "low": "a", "high": "b"}, "(top level)", "names must be unique"),
    ("responses.1", {"type": "classification", "name": "expr", "choices": [{"label": "a", "value": "x"}]},
     "responses[1].classification.choices", "at least 2"),
    ("responses.1", {"type": "classification", "name": "expr", "skip_intensity_for": ["z"],
                     "choices": [{"label": "a", "value": "x"}, {"label": "b", "value": "y"}]},
     "responses[1].classification", "skip_intensity_for names no choice value"),
    ("triggers.backend", "usb", "triggers.backend", "'parallel', 'serial', 'lsl' or 'file'"),
    ("triggers.backend", "serial", "triggers", "needs 'address'"),
    ("triggers.codes.0.code", 300, "triggers.codes", "code must be an integer 1-255"),
    ("triggers.codes", [{"code": 11, "emotion": "angry"}, {"code": 11, "emotion": "happy"}], "triggers.codes",
     "code 11 is used twice"),
    ("triggers.codes", [{"code": 11, "emotion": "angry"}, {"code": 12, "emotion": "angry"}], "triggers.codes",
     "already has a code"),
    ("triggers.codes", [{"emotion": "angry"}], "triggers.codes", "expected a 'code' key"),
    ("triggers.codes", [{"code": 3, "mood": "angry"}], "(top level)", "triggers.codes[0]: unknown factor 'mood'"),
    ("triggers.pulse_ms", 0, "triggers.pulse_ms", "must be > 0"),
    ("screen", {"background": 2}, "screen.background", "must be <= 1"),
    ("breaks", {"every": 0}, "breaks.every", "must be >= 1"),
    ("anchors", {"respond": False}, "anchors", "expected 'select'"),
    ("demographics", [{"name": "gender", "type": "choice"}], "demographics[0]", "at least two choices"),
    ("demographics", [{"name": "age", "type": "int", "prefer_not_to_say": "no"}], "demographics[0]",
     "need type 'choice'"),
    ("demographics", [{"name": "g", "type": "choice", "choices": ["a", "b"], "prefer_not_to_say": "a"}],
     "demographics[0]", "already one of the choices"),
    ("demographics", [{"name": "g", "type": "choice", "choices": ["a", " "]}], "demographics[0]",
     "choices must not be empty"),
    ("demographics", [{"name": "g", "type": "choice", "choices": ["a", "b"], "requird": True}], "demographics[0].requird",
     "did you mean 'required'"),
]


@pytest.mark.parametrize("change,value,field,words", MALFORMED, ids=[f"{i:02d}-{m[0]}" for i, m in enumerate(MALFORMED)])
def test_malformed_protocol_one_line_error(tmp_path, change, value, field, words):
    data = copy.deepcopy(BASE)
    _set(data, change, value)
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(data))
    with pytest.raises(AppealInputError) as exc:
        load_study_file(f, Protocol)
    lines = exc.value.lines
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"{f}: {field}: "), lines[0]
    assert words.lower() in lines[0].lower(), lines[0]


def test_at_least_twenty_kinds_of_malformed_protocol():
    assert len({m[0] for m in MALFORMED}) >= 20 and len(MALFORMED) >= 30


def test_base_protocol_is_valid(tmp_path):
    f = tmp_path / "ok.yaml"
    f.write_text(yaml.safe_dump(BASE))
    assert load_study_file(f, Protocol).name == "t"


def test_appeal_validate_cli(tmp_path, capsys):
    data = copy.deepcopy(BASE)
    data["order"]["repetitions"] = -3
    f = tmp_path / "bad.yaml"
    f.write_text(yaml.safe_dump(data))
    assert main(["validate", "--schema-only", str(SHIPPED[0]), str(f)]) == 2
    cap = capsys.readouterr()
    assert f"{SHIPPED[0]}: ok (protocol)" in cap.out
    assert cap.err.strip() == f"{f}: order.repetitions: must be >= 1 (got -3)"
    assert "Traceback" not in cap.err


def test_yaml_syntax_error_names_line(tmp_path):
    f = tmp_path / "broken.yaml"
    f.write_text("kind: protocol\nname: [unclosed\n")
    with pytest.raises(AppealInputError) as exc:
        load_study_file(f, Protocol)
    assert exc.value.lines[0].startswith(f"{f}:")
    assert "invalid YAML" in exc.value.lines[0]
