"""The participant-information dialog: answers parsed from what the dialog returns (unanswered =
n/a, never the first option; required fields; whole numbers), and the real Qt dialog's fields
(YAML order, nothing pre-selected, the explicit 'prefer not to say' choice)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from appeal.assets import protocols_dir
from experiments.demographics import parse_answers
from experiments.protocol_schema import DemographicItem
from experiments.session import load_protocol

ITEMS = [DemographicItem(name="age", type="int", required=True),
         DemographicItem(name="gender", type="choice", choices=["female", "male", "diverse"],
                         prefer_not_to_say="prefer not to say"),
         DemographicItem(name="games", label="How often do you play video games?", type="choice",
                         choices=["never", "daily"]),
         DemographicItem(name="note", type="text")]


def test_skipped_fields_are_not_answered():
    answers, problems = parse_answers(ITEMS, {"age": "23", "gender": "", "games": "", "note": "  "})
    assert problems == []
    assert answers == {"age": 23, "gender": None, "games": None, "note": None}


def test_prefer_not_to_say_is_an_answer():
    answers, problems = parse_answers(ITEMS, {"age": "31", "gender": "prefer not to say", "games": "daily"})
    assert problems == [] and answers["gender"] == "prefer not to say" and answers["games"] == "daily"


def test_required_and_whole_numbers():
    answers, problems = parse_answers(ITEMS, {"age": "", "gender": "female"})
    assert problems == ["age: please answer (required)"] and answers["age"] is None
    _, problems = parse_answers(ITEMS, {"age": "twenty", "gender": "robot"})
    assert problems == ["age: expected a whole number, got 'twenty'",
                        "gender: expected one of female, male, diverse, prefer not to say, got 'robot'"]


def test_shipped_protocols_offer_an_explicit_refusal_for_gender():
    for name in ["exp1a_shape_material", "exp1b_shading_lighting", "exp1c_texture", "exp2_stylisation",
                 "exp3_expressions", "erp_stylisation"]:
        items = {i.name: i for i in load_protocol(protocols_dir() / f"{name}.yaml").demographics}
        assert items["gender"].options[-1] == "prefer not to say", name
        assert "not given" not in items["gender"].options


DIALOG = """
import json, sys
from experiments.demographics import _dialog
from experiments.session import load_protocol
items = load_protocol(sys.argv[1]).demographics
dlg = _dialog("t", items, {}, [])
fields = []
for name, box in zip(dlg.inputFieldNames, dlg.inputFields):
    if hasattr(box, "currentText"):
        fields.append([name, box.currentText(), [box.itemText(i) for i in range(box.count())]])
    else:
        fields.append([name, box.text(), None])
print(json.dumps(fields))
"""


@pytest.mark.gui
def test_dialog_fields_in_yaml_order_nothing_preselected():
    """The real Qt dialog (offscreen platform): fields in the protocol's order, empty, choices
    led by an empty entry (DlgFromDict sorted the fields and pre-selected the first option)."""
    proto = protocols_dir() / "exp2_stylisation.yaml"
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    res = subprocess.run([sys.executable, "-c", DIALOG, str(proto)], capture_output=True, text=True, env=env,
                         timeout=120, check=False)
    assert res.returncode == 0, res.stderr[-2000:]
    fields = json.loads(res.stdout.strip().splitlines()[-1])
    items = load_protocol(proto).demographics
    assert [f[0] for f in fields] == [i.label or i.name for i in items]
    assert all(f[1] == "" for f in fields)
    gender = fields[1]
    assert gender[2] == ["", "female", "male", "diverse", "prefer not to say"]
