"""Adaptive-procedure states read back from data files are hostile input (issue 47, part 4).

A state (a data row's ``procedure_state``) is JSON anyone can edit: it is checked against a schema
before anything is built, nothing in it executes, and it can neither allocate nor compute without
bound — each hostile state is refused by a one-line :class:`AppealInputError` before any large
allocation or replay (the sizes are refused by length, not after building them). The runner's
resume, which rebuilds the procedures from the answers on disk, turns garbage rows into one line.
"""

from __future__ import annotations

import copy
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from appeal.errors import AppealInputError
from appeal.psychophysics import (ConstantStimuli, PsiProcedure, SimulatedObserver, UpDownStaircase,
                                  procedure_from_dict, procedure_from_json, run_procedure)
from appeal.psychophysics.states import MAX_HISTORY, MAX_STATE_CHARS, state_problems
from cli_errors import one_line_error
from test_psychophysics_runtime import stim, write  # noqa: F401 - the drawn continuum and protocol files

LEVELS = [round(float(x), 3) for x in np.linspace(0.05, 1, 20)]
KINDS = (PsiProcedure, UpDownStaircase, ConstantStimuli)


def _played(proc, n: int, seed: int = 1):
    """``proc`` after ``n`` answers of a simulated observer."""
    obs = SimulatedObserver(0.4, 0.3, 0.02, seed=seed)
    for _ in range(n):
        if proc.finished:
            break
        x = proc.next_level()
        proc.update(x, obs.respond(x))
    return proc


def _procedures():
    return {
        "psi": _played(PsiProcedure(LEVELS, max_trials=60), 25),
        "psi-marginal-norm": _played(PsiProcedure(LEVELS, family="norm", entropy="threshold", max_trials=40,
                                                  guess=0.0), 15, 2),
        "psi-weibull-width-rule": _played(PsiProcedure(LEVELS, family="weibull", thresholds=np.log(LEVELS),
                                                       widths=[0.5, 1.0, 2.0], max_ci_width=0.3, min_trials=5),
                                          12, 3),
        "psi-finished": _finished_psi(),
        "updown": _played(UpDownStaircase(LEVELS, down=3, up=1, step=2, start=0.5, max_trials=80), 40),
        "updown-reversals": _played(UpDownStaircase(LEVELS, max_reversals=8), 30, 5),
        "constant": _played(ConstantStimuli(LEVELS[:5], trials_per_level=4, seed=7), 9),
        "fresh-constant": ConstantStimuli(LEVELS, trials_per_level=2, seed=123456789),
    }


def _finished_psi():
    proc = PsiProcedure(LEVELS, max_trials=20)
    run_procedure(proc, SimulatedObserver(0.4, 0.3, 0.02, seed=4))
    return proc


PROCEDURES = _procedures()


def _same(a, b) -> None:
    assert type(a) is type(b)
    assert a.next_level() == b.next_level() and a.n_trials == b.n_trials and a.finished == b.finished
    ea, eb = a.estimate(), b.estimate()
    assert ea.keys() == eb.keys()
    for k in ea:
        assert ea[k] == eb[k] or (math.isnan(ea[k]) and math.isnan(eb[k])), k
    assert a.history == b.history and a.to_dict() == b.to_dict()
    if isinstance(a, UpDownStaircase):
        assert a.reversals == b.reversals


@pytest.mark.parametrize("name", sorted(PROCEDURES))
def test_every_kind_round_trips_through_json(name):
    proc = PROCEDURES[name]
    text = json.dumps(proc.to_dict(), separators=(",", ":"))  # as the runner writes the column
    _same(procedure_from_json(text), proc)
    _same(procedure_from_json(text.encode()), proc)
    _same(procedure_from_dict(json.loads(text), where="f.tsv: row 3"), proc)
    _same(type(proc).from_dict(json.loads(text)), proc)
    assert state_problems(json.loads(text)) == []


def _state(kind: str = "psi") -> dict:
    return copy.deepcopy({"psi": PROCEDURES["psi"], "updown": PROCEDURES["updown"],
                          "constant": PROCEDURES["constant"]}[kind].to_dict())


def _with(which: str, **changes) -> dict:
    s = _state(which)
    s.update(changes)
    return s


def _without(which: str, key: str) -> dict:
    s = _state(which)
    del s[key]
    return s


NESTED = "[" * 100_000 + "]" * 100_000
HOSTILE = [
    # sizes: refused by their length, nothing is allocated or replayed
    ("huge psi grid", _with("psi", thresholds=list(range(10 ** 6)), widths=[0.1 * (i + 1) for i in range(10)]),
     "thresholds: expected a list of 1 to 1001"),
    ("huge grid product", _with("psi", thresholds=[i / 1000 for i in range(1000)],
                                widths=[0.01 * (i + 1) for i in range(1000)]),
     "expected a grid of at most 1000000 cells"),
    ("huge lapse axis", _with("psi", lapses=[i / 10 ** 6 for i in range(10 ** 5)]), "lapses: expected a list of 1 to 101"),
    ("huge history", _with("updown", max_trials=None, max_reversals=5, history=[[0.5, 1]] * (2 * MAX_HISTORY)),
     f"history: expected a list of at most {MAX_HISTORY} answers"),
    ("history past max_trials", _with("psi", history=[[0.5, 1]] * 61), "history: expected a list of at most 60 answers"),
    ("replay too long for the grid", _with("psi", max_trials=None, max_ci_width=0.1,
                                           thresholds=[i / 1000 for i in range(1000)],
                                           widths=[0.01 * (i + 1) for i in range(40)], lapses=[0.0],
                                           history=[[0.5, 1]] * 50_000),
     "history: expected at most 5000 answers for a grid of 40000 points"),
    ("too many levels", _with("constant", levels=[i / 10 for i in range(5000)], history=[]),
     "levels: expected a list of 2 to 1001"),
    ("plan too long", _with("constant", trials_per_level=10 ** 9), "trials_per_level: expected an integer from 1"),
    ("plan too long for its levels", _with("constant", levels=LEVELS, trials_per_level=50_000, history=[]),
     "trials_per_level: expected at most 5000 with 20 levels"),
    ("staircase steps", _with("updown", down=10 ** 12), "down: expected an integer from 1 to 1001, got 1000000000000"),
    ("a huge integer", _with("constant", seed=10 ** 400), "seed: expected an integer from 0 to 9223372036854775807, "
                                                          "got an integer of about 401 digits"),
    # wrong numbers
    ("NaN guess", _with("psi", guess=float("nan")), "guess: expected a number in [0, 1), got nan"),
    ("inf level", _with("psi", levels=LEVELS[:-1] + [float("inf")]), "levels[19]: expected an item of a list"),
    ("huge level", _with("psi", levels=LEVELS[:-1] + [1e300]), "levels[19]:"),
    ("levels not increasing", _with("updown", levels=[0.5, 0.2, 0.9]), "levels[1]: expected a number above levels[0]"),
    ("zero width", _with("psi", widths=[0.0, 0.1]), "widths[0]: expected an item of a list of 1 to 1001 finite"),
    ("lapse of one", _with("psi", lapses=[0.0, 1.0]), "lapses[1]:"),
    ("guess plus lapse", _with("psi", guess=0.9, lapses=[0.0, 0.2]), "guess: expected a number below 1 - max(lapses)"),
    ("negative seed", _with("constant", seed=-1), "seed: expected an integer from 0"),
    ("weibull at zero", _with("psi", family="weibull", levels=[0.0] + LEVELS[1:]), "levels[0]: expected a positive"),
    ("level of an answer", _with("psi", history=[[0.333, True]]), "history[0][0]: expected one of the 20 levels"),
    ("answer neither 0 nor 1", _with("psi", history=[[0.05, 2]]), "history[0][1]: expected true, false, 1 or 0, got 2"),
    ("answer as text", _with("psi", history=[[0.05, "1"]]), "history[0][1]: expected true, false, 1 or 0, got '1'"),
    ("entry of three", _with("updown", history=[[0.05, 1, 2]]), "history[0]: expected an answer [level, correct]"),
    ("start off the levels", _with("updown", start=0.33), "start: expected one of the 20 levels or null, got 0.33"),
    # wrong types
    ("string levels", _with("psi", levels="0.1,0.2"), "levels: expected a list of 2 to 1001 finite, increasing numbers"),
    ("string level", _with("psi", levels=["0.1", "0.2"]), "levels[0]: expected an item of a list"),
    ("bool max_trials", _with("psi", max_trials=True), "max_trials: expected an integer from 1 to 100000 or null, got true"),
    ("float max_trials", _with("psi", max_trials=60.0), "max_trials: expected an integer from 1 to 100000 or null, "
                                                        "got 60.0"),
    ("nested lists", _with("psi", thresholds=[[0.1, 0.2]]), "thresholds[0]: expected an item of a list"),
    ("object as history", _with("psi", history={"a": 1}), "history: expected a list of at most 60 answers"),
    ("unknown family", _with("psi", family="__import__('os').system('id')"), "family: expected one of 'logistic', "
                                                                             "'norm', 'weibull', got "),
    ("unknown entropy", _with("psi", entropy=None), "entropy: expected one of 'joint', 'threshold', got null"),
    ("no stopping rule", _with("psi", max_trials=None, max_ci_width=None, history=[]),
     "max_trials: expected an integer when max_ci_width is null (a stopping rule), got null"),
    ("no staircase stopping rule", _with("updown", max_trials=None, max_reversals=None),
     "max_trials: expected an integer when max_reversals is null"),
    ("missing setting", _without("psi", "widths"), "widths: expected a list of 1 to 1001 finite, increasing numbers "
                                                   "in (0, 1e+12], got no such field"),
    # wrong kind, foreign fields
    ("unknown kind", _with("psi", kind="pickle"), "kind: expected one of 'psi', 'updown', 'constant', got 'pickle'"),
    ("no kind", _without("psi", "kind"), "kind: expected one of 'psi', 'updown', 'constant', got no such field"),
    ("kind as a list", _with("psi", kind=["psi"]), "kind: expected one of"),
    ("__class__ field", _with("psi", __class__="subprocess.Popen"), "procedure_state: '__class__': expected one of the "
                                                                    "fields of a 'psi' state"),
    ("__reduce__ field", _with("constant", __reduce__=["os.system", ["id"]]), "'__reduce__': expected one of the fields"),
    ("a staircase field in a psi state", _with("psi", down=2), "'down': expected one of the fields of a 'psi' state"),
    ("not an object", [1, 2, 3], "got a list of 3 items"),
    ("a JSON string", '"psi"', "procedure_state: expected a JSON object, got 'psi'"),
    # text: only procedure_from_json
    ("50 MB text", " " * (50 * 2 ** 20), f"expected at most {MAX_STATE_CHARS} characters of JSON, got 52428800"),
    ("deep nesting", NESTED, "got JSON nested too deep to read"),
    ("deep object nesting", '{"a":' * 50_000 + "1" + "}" * 50_000, "got JSON nested too deep to read"),
    ("NaN literal", json.dumps(_state("psi")).replace('"guess": 0.5', '"guess": NaN'), "expected finite numbers, got NaN"),
    ("Infinity literal", json.dumps(_state("psi")).replace('"pc": 0.5', '"pc": -Infinity'), "got -Infinity"),
    ("not JSON", "{'kind': 'psi'}", "expected JSON, got text that is not (Expecting property name enclosed in double "
                                    "quotes at line 1 column 2)"),
    ("cut JSON", json.dumps(_state("psi"))[:100], "expected JSON, got text that is not"),
    ("pickle bytes", b"\x80\x04\x95\x1d\x00\x00\x00", "expected UTF-8 text, got a byte 0x80 at 0"),
    ("integer of 5000 digits", '{"kind": "constant", "seed": ' + "9" * 5000 + "}", "expected JSON, got text that is not "
                                                                                    "(Exceeds the limit"),
    ("JSON array", "[1, 2]", "procedure_state: expected a JSON object, got a list of 2 items"),
    ("JSON null", "null", "procedure_state: expected a JSON object, got null"),
    ("empty text", "", "expected JSON, got text that is not (Expecting value at line 1 column 1)"),
]


#: What the text route refuses first when a state's JSON text is itself too long or holds NaN/Infinity.
TEXT_REFUSALS = ("characters of JSON", "expected finite numbers, got")


def _one_line(call, where: str = "sub-01_beh.tsv: row 7") -> str:
    with pytest.raises(AppealInputError) as exc:
        call()
    lines = exc.value.lines
    assert len(lines) == 1 and "\n" not in str(exc.value), lines
    assert lines[0].startswith(f"{where}: procedure_state"), lines[0]
    assert len(lines[0]) < 400  # a hostile value is shown cut, never whole
    return lines[0]


@pytest.mark.parametrize("state, needle", [h[1:] for h in HOSTILE], ids=[h[0] for h in HOSTILE])
def test_hostile_states_are_one_line_refusals(state, needle):
    where = "sub-01_beh.tsv: row 7"
    if isinstance(state, (str, bytes)):
        assert needle in _one_line(lambda: procedure_from_json(state, where=where))
        return
    assert needle in _one_line(lambda: procedure_from_dict(state, where=where))
    line = _one_line(lambda: procedure_from_json(json.dumps(state, allow_nan=True), where=where))
    assert needle in line or any(t in line for t in TEXT_REFUSALS), line


def test_a_state_that_is_not_a_mapping():
    for value in ("psi", None, 3, [["kind", "psi"]]):
        assert "procedure_state: expected an object (a procedure's state), got" in _one_line(
            lambda: procedure_from_dict(value, where="w"), "w")


@pytest.mark.parametrize("cls", KINDS)
def test_a_class_refuses_another_kinds_state(cls):
    other = next(p for p in PROCEDURES.values() if not isinstance(p, cls))
    with pytest.raises(AppealInputError, match=f"procedure_state: kind: expected '{cls.kind}', got '{other.kind}'"):
        cls.from_dict(other.to_dict())


def test_several_violations_are_one_line_each():
    bad = _with("psi", guess="half", family="gumbel", widths=[-1.0], __init__=1)
    with pytest.raises(AppealInputError) as exc:
        procedure_from_dict(bad)
    assert len(exc.value.lines) == 4 and all(line.startswith("procedure_state: ") for line in exc.value.lines)


def test_the_state_text_is_never_executed(tmp_path, monkeypatch):
    """Only json.loads reads a state: no pickle, no eval; a state naming code stays data."""
    import builtins
    import pickle

    def refuse(*_a, **_k):
        raise AssertionError("a state must never be executed")

    monkeypatch.setattr(pickle, "loads", refuse)
    monkeypatch.setattr(builtins, "eval", refuse)
    monkeypatch.setattr(builtins, "exec", refuse)
    marker = tmp_path / "ran"
    for text in (json.dumps({"kind": "psi", "__reduce__": ["os.system", [f"touch {marker}"]]}),
                 pickle.dumps(PROCEDURES["psi"]).decode("latin-1"),
                 json.dumps(_with("psi", family=f"__import__('os').system('touch {marker}')"))):
        with pytest.raises(AppealInputError):
            procedure_from_json(text)
    assert not marker.exists()
    _same(procedure_from_json(json.dumps(PROCEDURES["psi"].to_dict())), PROCEDURES["psi"])


# --------------------------------------------------------------------------- fuzz
_json = st.recursive(
    st.none() | st.booleans() | st.integers(-10 ** 6, 10 ** 6) | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=12),
    lambda children: st.lists(children, max_size=6) | st.dictionaries(st.text(max_size=12), children, max_size=6),
    max_leaves=30)
_FIELDS = sorted({k for p in PROCEDURES.values() for k in p.to_dict()} | {"__class__", "extra"})


def _small(kind: str) -> dict:
    """Small valid states (a fuzz example must stay cheap)."""
    levels = [0.1, 0.2, 0.4, 0.7, 1.0]
    if kind == "psi":
        proc = PsiProcedure(levels, thresholds=[0.1, 0.4, 0.8], widths=[0.2, 0.5], lapses=[0.0, 0.02], max_trials=8)
    elif kind == "updown":
        proc = UpDownStaircase(levels, max_trials=8)
    else:
        proc = ConstantStimuli(levels, trials_per_level=2, seed=3)
    return _played(proc, 4).to_dict()


@st.composite
def _mutated(draw) -> dict:
    state = _small(draw(st.sampled_from(["psi", "updown", "constant"])))
    for _ in range(draw(st.integers(1, 3))):
        # mostly the state's own fields (a plausible edit), sometimes another kind's or a foreign one
        own = sorted(k for k in state if k != "kind")
        key = draw(st.sampled_from(own) if draw(st.integers(0, 4)) else st.sampled_from(_FIELDS))
        how = draw(st.sampled_from(["tweak", "tweak", "set", "delete", "item", "number"]))
        value = state.get(key)
        if how == "tweak" and isinstance(value, (int, float)) and not isinstance(value, bool):
            # a nearby value: often still valid, so the procedure is built and used
            state[key] = draw(st.sampled_from([value + 1, value - 1, value * 2, value / 2, -value, 0]))
        elif how == "tweak" and isinstance(value, list) and value:
            i = draw(st.integers(0, len(value) - 1))
            state[key] = draw(st.sampled_from([value[:i], value[:i] + value[i + 1:], value + value[-1:],
                                               value[::-1]]))
        elif how == "tweak":
            continue
        elif how == "delete":
            state.pop(key, None)
        elif how == "item" and isinstance(state.get(key), list) and state[key]:
            items = state[key]
            i = draw(st.integers(0, len(items) - 1))
            if isinstance(items[i], list) and items[i] and draw(st.booleans()):
                items[i][draw(st.integers(0, len(items[i]) - 1))] = draw(_json)
            else:
                items[i] = draw(_json)
        elif how == "number":
            state[key] = draw(st.integers(-3, 10 ** 6) | st.floats(-2.0, 2.0) | st.sampled_from([0, 1, 0.5, 1e-300]))
        else:
            state[key] = draw(_json)
    return state


def _check_outcome(text) -> None:
    try:
        proc = procedure_from_json(text, where="f.tsv: row 2")
    except AppealInputError as exc:
        assert exc.lines and all("\n" not in line for line in exc.lines)
        return
    assert isinstance(proc, KINDS)
    proc.next_level()
    proc.estimate()
    assert proc.n_trials <= MAX_HISTORY and isinstance(proc.finished, bool)


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_mutated())
def test_fuzz_mutated_states(state):
    _check_outcome(json.dumps(state, allow_nan=True))


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_json)
def test_fuzz_arbitrary_json(value):
    _check_outcome(json.dumps(value, allow_nan=True))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_fuzz_damaged_text(data):
    text = json.dumps(_small(data.draw(st.sampled_from(["psi", "updown", "constant"]))))
    i = data.draw(st.integers(0, len(text) - 1))
    j = data.draw(st.integers(i, min(len(text), i + 8)))
    _check_outcome(text[:i] + data.draw(st.text(max_size=6)) + text[j:])


# --------------------------------------------------------------------------- the runner's resume
def _cut_session(stim, tmp_path):
    """A finished psi session (2 tracks of 5 trials), its file and the lines of it."""
    from experiments.session import run_session

    proto = write(stim, "hostile", psy={"procedure": {"method": "psi", "max_trials": 5}})
    out = tmp_path / "o"
    res = run_session(proto, "01", out=out, simulate="default", window=False, report=False)
    assert res.status == "complete"
    return proto, out, res.beh, res.beh.read_text(encoding="utf-8").splitlines(keepends=True)


def _resume(proto, out):
    return ["run", str(proto), "--participant", "01", "--simulate", "default", "--no-window", "--out", str(out),
            "--resume"]


def _edited(line: str, header: str, column: str, value: str) -> str:
    """``line`` of a session file with ``column``'s cell replaced by ``value``."""
    cells = line.rstrip("\n").split("\t")
    cells[header.rstrip("\n").split("\t").index(column)] = value
    return "\t".join(cells) + "\n"


@pytest.mark.parametrize("column, value, needle", [
    ("response_choice", "=HYPERLINK(\"http://x\")", "trial 3: response_choice: expected one of left, right or n/a, "
                                                   "got '=HYPERLINK"),
    ("response_choice", "\x1b[31mleft", "trial 3: response_choice: expected one of left, right or n/a"),
    ("stimulus", "../../../etc/passwd", "trial 3 ('../../../etc/passwd', "),
    ("procedure", "x" * 5000, "does not match the procedure's trial"),
    ("trial", "3\x1b[2J", "trial '3\\x1b[2J'"),
])
def test_resume_refuses_garbage_rows_in_one_line(stim, tmp_path, capsys, column, value, needle):
    proto, out, beh, lines = _cut_session(stim, tmp_path)
    row = _edited(lines[3], lines[0], column, value)
    if column == "trial":  # the trial number is only named: make the row mismatch as well
        row = _edited(row, lines[0], "stimulus", "other.png")
    beh.write_text("".join(lines[:3]) + row, encoding="utf-8")
    line = one_line_error(capsys, _resume(proto, out), str(beh.name), needle)
    assert "\x1b" not in line and len(line) < 600


def test_resume_does_not_read_the_state_column(stim, tmp_path):
    """The procedures are rebuilt from the answers alone: a hostile state in the rows is never parsed."""
    from experiments.session import run_session

    proto, out, beh, lines = _cut_session(stim, tmp_path)
    hostile = ['{"kind":"psi","thresholds":[' + ",".join(["0"] * 10 ** 5) + "]}", "[" * 10 ** 5, "NaN", "x"]
    beh.write_text(lines[0] + "".join(_edited(lines[i], lines[0], "procedure_state", hostile[i - 1])
                                      for i in range(1, 5)), encoding="utf-8")
    res = run_session(proto, "01", out=out, simulate="default", window=False, report=False, resume=True)
    assert res.status == "complete"
    assert len(beh.read_text(encoding="utf-8").splitlines()) == len(lines)  # the same 10 trials, 6 added


def test_resume_refuses_rows_past_the_sessions_end(stim, tmp_path, capsys):
    proto, out, beh, lines = _cut_session(stim, tmp_path)
    beh.write_text("".join(lines) + lines[-1] * 3, encoding="utf-8")
    one_line_error(capsys, _resume(proto, out), "13 rows, but the procedures stopped after 10 trials")
