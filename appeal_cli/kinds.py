"""Which schema validates which ``kind:`` of study file (imported lazily)."""

from __future__ import annotations

import importlib
from pathlib import Path

from pydantic import BaseModel

from appeal.errors import StudyFileError
from appeal.studyfile import load_yaml, validate_data

#: kind -> "module:Class" of its pydantic model.
KINDS: dict[str, str] = {
    "grid": "stimulus_engine.grid.schema:GridFile",
    "protocol": "experiments.protocol_schema:Protocol",
    "ratings": "analysis.ratings_schema:RatingsAnalysis",
    "psychometric": "analysis.psychometric.schema:PsychometricAnalysis",
    "erp": "analysis.erp_schema:ErpConfig",
}


#: kind -> "module:function" listing problems with the inputs a valid file needs to run (files
#: made by an earlier stage, so not part of the schema): ``function(model, path) -> [lines]``.
INPUT_CHECKS: dict[str, str] = {
    "protocol": "experiments.session:session_input_problems",
    "erp": "analysis.erp.config:recording_problems",
}


def _load(spec: str):
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


def input_problems(kind: str, model: BaseModel, path: str | Path) -> list[str]:
    """Problems with the inputs of a validated study file (none for kinds without a check)."""
    return _load(INPUT_CHECKS[kind])(model, path) if kind in INPUT_CHECKS else []


def model_for_kind(kind: str) -> type[BaseModel]:
    """The pydantic model of a study-file kind."""
    return _load(KINDS[kind])


def load_any_study_file(path: str | Path) -> tuple[str, BaseModel]:
    """Load a study file of any kind, chosen by its ``kind:`` key.

    Returns
    -------
    kind : str
        The file's kind.
    model : BaseModel
        The validated content.

    Raises
    ------
    StudyFileError
        One line per problem.
    """
    path = Path(path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        validate_data(data, BaseModel, source=path)  # raises the top-level error
    kind = data.get("kind")
    if kind is None:
        raise StudyFileError(f"{path}: kind: required field is missing (expected one of: {', '.join(KINDS)})")
    if kind not in KINDS:
        import difflib

        close = difflib.get_close_matches(str(kind), KINDS, n=1)
        hint = f"did you mean '{close[0]}'?" if close else f"expected one of: {', '.join(KINDS)}"
        raise StudyFileError(f"{path}: kind: unknown kind {kind!r} ({hint})")
    return kind, validate_data(data, model_for_kind(kind), source=path, base_dir=path.resolve().parent)
