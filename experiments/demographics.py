"""The participant-information dialog: the protocol's questions in the YAML's order, nothing
pre-filled, unanswered fields recorded as ``n/a``.

A choice field starts on an empty entry, so a participant who skips it is recorded as not
answered (never as the first option). A protocol may offer an explicit refusal with
``prefer_not_to_say: "prefer not to say"`` (recorded as written). Fields marked ``required:
true`` must be answered (a refusal counts as an answer): OK shows the dialog again, answers
kept, with the missing fields named. Integer fields must hold a whole number.

:func:`parse_answers` is the pure part (tested without a screen); :func:`ask_demographics`
shows the dialog with PsychoPy's Qt ``gui.Dlg``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from appeal.errors import AppealInputError
from experiments.protocol_schema import DemographicItem

__all__ = ["field_label", "parse_answers", "ask_demographics"]

#: The entry a choice field starts on (no answer).
UNANSWERED = ""


def field_label(item: DemographicItem) -> str:
    """The label shown beside a field (``*`` marks a required one)."""
    return (item.label or item.name) + (" *" if item.required else "")


def parse_answers(items: Sequence[DemographicItem], raw: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """Turn the dialog's raw values into answers, and list what must be corrected.

    Parameters
    ----------
    items : sequence of DemographicItem
        The protocol's questions.
    raw : mapping
        ``item.name`` -> the text or choice the dialog returned (missing = not answered).

    Returns
    -------
    answers : dict
        ``item.name`` -> ``int`` (int fields), the text/choice, or None (not answered).
    problems : list of str
        One line per field to correct (required but empty, not a whole number, unknown choice).
    """
    answers: dict[str, Any] = {}
    problems: list[str] = []
    for item in items:
        value = raw.get(item.name)
        text = "" if value is None else str(value).strip()
        label = item.label or item.name
        if not text:
            answers[item.name] = None
            if item.required:
                problems.append(f"{label}: please answer (required)")
            continue
        if item.type == "int":
            try:
                answers[item.name] = int(text)
            except ValueError:
                answers[item.name] = None
                problems.append(f"{label}: expected a whole number, got {text!r}")
        elif item.type == "choice" and text not in item.options:
            answers[item.name] = None
            problems.append(f"{label}: expected one of {', '.join(item.options)}, got {text!r}")
        else:
            answers[item.name] = text
    return answers, problems


def _dialog(title: str, items: Sequence[DemographicItem], values: Mapping[str, Any], problems: Sequence[str]) -> Any:
    from psychopy import gui

    dlg = gui.Dlg(title=title)
    if not any(i.required for i in items):
        dlg.requiredMsg.hide()
    for line in problems:
        dlg.addText(line, color="red")
    for item in items:
        value = values.get(item.name)
        if item.type == "choice":
            options = [UNANSWERED, *item.options]
            dlg.addField(item.name, initial=options.index(value) if value in options else 0, choices=options,
                         label=field_label(item))
        else:
            dlg.addField(item.name, initial="" if value is None else str(value), label=field_label(item))
    return dlg


def ask_demographics(items: Sequence[DemographicItem], title: str) -> dict[str, Any]:
    """Show the dialog until its answers are valid; Cancel raises :class:`AppealInputError`.

    Parameters
    ----------
    items : sequence of DemographicItem
        The protocol's questions, shown in this order.
    title : str
        Window title (the protocol's title).

    Returns
    -------
    dict
        ``item.name`` -> answer (None where not answered).
    """
    values: dict[str, Any] = {}
    problems: list[str] = []
    while True:
        dlg = _dialog(title, items, values, problems)
        data = dlg.show()
        if not dlg.OK or data is None:
            raise AppealInputError("participant dialog cancelled: no data recorded")
        values = {i.name: data.get(i.name) for i in items}
        answers, problems = parse_answers(items, values)
        if not problems:
            return answers
        values = {k: (v if v not in (None, "") else None) for k, v in values.items()}
