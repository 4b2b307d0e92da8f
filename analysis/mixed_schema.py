"""The ``mixed:`` block of study files: a linear mixed model's random part and its dfs.

Shared by the rating study (``analysis.ratings_schema``) and the ERP config
(``analysis.erp_schema``, single-trial models).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import AfterValidator, Field

from appeal.studyfile import StudyModel

__all__ = ["MixedOptions", "RandomPart"]


def _random_terms(value: str) -> str:
    if value == "maximal":
        return value
    from analysis.stats.formula import FormulaError, parse_formula

    try:
        f = parse_formula(f"y ~ 1 + {value}")
    except FormulaError as exc:
        raise ValueError(str(exc).replace("y ~ 1 + ", "")) from None
    if f.fixed or not f.random:
        raise ValueError(f"expected 'maximal' or lme4 random terms such as '(1 + shape | participant_id) + (1 | stimulus)', "
                         f"got '{value}'")
    return value


#: ``maximal`` or lme4 random terms, checked when the study file is read.
RandomPart = Annotated[str, AfterValidator(_random_terms)]


class MixedOptions(StudyModel):
    """A linear mixed model on trial-level data (ratings: ``model: mixed``, ``both`` or ``all``;
    ERP: ``mixed: {enabled: true}``)."""

    random: RandomPart = Field(
        "maximal", description="'maximal' (slopes for every term that varies within participants / stimuli, "
                               "simplified in a documented order until the fit converges without a singular fit) or "
                               "lme4 random terms, e.g. '(1 + shape | participant_id) + (1 | stimulus)'.")
    ddf: Literal["satterthwaite", "kenward-roger"] = "satterthwaite"


