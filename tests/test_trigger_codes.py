"""One trigger-code table for the runner and the analysis (appeal.triggers, appeal.levels):
every shipped protocol's codes mean the same condition to both, and both refuse the same tables."""

from __future__ import annotations

import pytest
import yaml

from analysis.erp.config import event_map, load_erp_config, read_protocol_codes
from appeal.assets import protocols_dir
from appeal.errors import StudyFileError
from appeal.levels import level_key, level_value, order_levels, sort_levels
from appeal.studyfile import load_study_file
from appeal.triggers import trigger_table
from experiments import build_trials, load_protocol, load_stimuli
from experiments.drawn_faces import draw_face_grid
from experiments.protocol_schema import Protocol

SHIPPED_WITH_TRIGGERS = sorted(p for p in protocols_dir().glob("*.yaml")
                               if (yaml.safe_load(p.read_text(encoding="utf-8")) or {}).get("triggers"))


def test_some_shipped_protocol_has_triggers():
    assert [p.name for p in SHIPPED_WITH_TRIGGERS] == ["erp_stylisation.yaml"]


def _written_variously(tmp_path):
    """The shipped ERP protocol with levels the old analysis read otherwise than the runner:
    booleans (``'True'`` there, ``'true'`` here), numeric text (``'2.0'`` there, ``'2'`` here),
    and a declared level order that is not the natural one (the analysis ignored it)."""
    doc = yaml.safe_load((protocols_dir() / "erp_stylisation.yaml").read_text(encoding="utf-8"))
    for entry in doc["triggers"]["codes"]:
        entry["character"] = entry["character"] == "james"
        entry["stylisation"] = f"{entry['stylisation']}.0"
    doc["stimuli"]["levels"] = {"stylisation": [5, 4, 3, 2, 1, 0], "emotion": ["neutral", "happy", "angry"]}
    path = tmp_path / "written_variously.yaml"
    path.write_text(yaml.safe_dump(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize("make", [*(lambda _, p=p: p for p in SHIPPED_WITH_TRIGGERS), _written_variously],
                         ids=[*(p.name for p in SHIPPED_WITH_TRIGGERS), "written_variously"])
def test_runner_and_analysis_read_the_same_codes(make, tmp_path):
    """Each trial's trigger, read back by the analysis, names that trial's condition, and both
    sides order each factor's levels alike."""
    path = make(tmp_path)
    analysis = read_protocol_codes(path)
    protocol = load_protocol(path)
    factors = protocol.stimuli.factors
    levels = {f: sort_levels({level_key(c[f]) for c in analysis.values()}) for f in factors}
    manifest = draw_face_grid(tmp_path / "stimuli", levels, size=(40, 30))
    stimuli = load_stimuli(protocol.stimuli, override=manifest, protocol_file=path)
    trials = [t for t in build_trials(protocol, stimuli, seed=3, refresh_hz=60.0, source=str(path)) if t.trigger]
    assert len({t.trigger for t in trials}) == len(analysis)  # every code is sent
    for t in trials:
        assert {f: str(v) for f, v in analysis[t.trigger].items()} == {f: t.factors[f] for f in factors}
    config = tmp_path / "erp.yaml"
    config.write_text(f"kind: erp\nrecordings: x.bdf\nevents: {{protocol: {path}}}\n", encoding="utf-8")
    events = event_map(load_erp_config(config), config)
    assert {f: [str(v) for v in events.levels[f]] for f in factors} == {f: stimuli.levels(f) for f in factors}


@pytest.mark.parametrize(("codes", "message"), [
    ([{"code": 0, "emotion": "angry"}], "codes[0]: code must be an integer 1-255 (got 0)"),
    ([{"code": 256, "emotion": "angry"}], "codes[0]: code must be an integer 1-255 (got 256)"),
    ([{"code": True, "emotion": "angry"}], "codes[0]: code must be an integer 1-255 (got True)"),
    ([{"code": 1, "emotion": "angry"}, {"code": 2, "emotion": "angry"}],
     "codes[1]: condition {'emotion': 'angry'} already has a code (codes[0])"),
    ([{"code": 1, "level": 0}, {"code": 2, "level": 0.0}], "codes[1]: condition {'level': '0'} already has a code"),
    ([{"code": 1, "emotion": "angry"}, {"code": 1, "emotion": "happy"}], "codes[1]: code 1 is used twice (also codes[0])"),
    ([{"code": 1}], "codes[0]: code 1 names no factor level"),
    ([{"emotion": "angry"}], "codes[0]: expected a 'code' key (got ['emotion'])"),
])
def test_runner_and_analysis_refuse_the_same_tables(tmp_path, codes, message):
    """The analysis used to accept codes outside 1-255 and two codes for one condition."""
    with pytest.raises(ValueError, match=None) as direct:
        trigger_table(codes)
    assert message in str(direct.value)
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump({"triggers": {"codes": codes}}))
    with pytest.raises(StudyFileError) as analysis:
        read_protocol_codes(path)
    assert f"p.yaml: triggers.{message}" in str(analysis.value)
    protocol = yaml.safe_load((protocols_dir() / "erp_stylisation.yaml").read_text(encoding="utf-8"))
    protocol["triggers"]["codes"] = codes
    path.write_text(yaml.safe_dump(protocol))
    with pytest.raises(StudyFileError) as runner:
        load_study_file(path, Protocol)
    assert message in str(runner.value)


def test_boolean_levels_are_true_false_on_both_sides(tmp_path):
    """The analysis made True into 'True' where the runner's level_key makes 'true'."""
    path = tmp_path / "p.yaml"
    path.write_text("triggers:\n  codes:\n    - {code: 1, masked: true}\n    - {code: 2, masked: false}\n")
    assert read_protocol_codes(path) == {1: {"masked": "true"}, 2: {"masked": "false"}}
    assert level_key(True) == "true"


@pytest.mark.parametrize("value", [0, 0.0, "0", " 0 ", 1.5, "1.50", "angry", True, False, 12, "c10"])
def test_typed_and_string_forms_agree(value):
    assert str(level_value(value)) == level_key(value)


def test_levels_sort_naturally_the_same_way_everywhere():
    assert sort_levels(["c10", "c2", "b", 10, 2.5, "a"]) == [2.5, 10, "c2", "c10", "a", "b"]


def test_declared_order_first_then_natural():
    assert order_levels(["c10", "0.5", "c2", "a", "c2"], declared=[0.5, "a", "z"]) == ["0.5", "a", "c2", "c10"]


def test_analysis_refuses_a_malformed_level_order(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("stimuli: {levels: {emotion: angry}}\ntriggers: {codes: [{code: 1, emotion: angry}]}\n")
    config = tmp_path / "erp.yaml"
    config.write_text("kind: erp\nrecordings: x.bdf\nevents: {protocol: p.yaml}\n", encoding="utf-8")
    with pytest.raises(StudyFileError, match=r"p.yaml: stimuli.levels: expected a mapping of factor to a list"):
        event_map(load_erp_config(config), config)
