"""The ``covariates:`` block of study files: low-level image measures of the stimuli as covariates.

Shared by the rating study (``analysis.ratings_schema``) and the ERP config
(``analysis.erp_schema``, its single-trial mixed models). Example::

    covariates:
      audit: ../../stimuli/exp2/audit/audit.csv   # appeal stimuli audit MANIFEST --out DIR
      measures: [face_L_mean, face_rms_contrast]
      by: stimulus                               # the data's column with each trial's image
"""

from __future__ import annotations

from pydantic import Field, field_validator, model_validator

from appeal.studyfile import InputFile, StudyModel

__all__ = ["CovariatesSpec"]


class CovariatesSpec(StudyModel):
    """Measures of ``appeal stimuli audit``'s ``audit.csv`` joined to the trials by stimulus and used as
    covariates (centred at their grand mean): fixed main effects of the mixed models, an
    ANCOVA-style adjustment of the trials before the rm-ANOVA's cell means. The stimuli of a cell
    must differ for a covariate to be estimable (docs/statistics.md)."""

    audit: InputFile = Field(description="The audit table (DIR/audit.csv of `appeal stimuli audit MANIFEST --out DIR`); "
                                         "a relative path resolves against the study file's folder.")
    measures: list[str] = Field(min_length=1, description="Audit columns to use, e.g. [face_L_mean, face_rms_contrast] "
                                                          "(checked against the audit's header when the file is read).")
    by: str = Field("stimulus", min_length=1, description="The data's column holding each trial's image as the "
                                                          "manifest's `file` (the runner's `stimulus`).")

    @field_validator("measures")
    @classmethod
    def _unique(cls, v: list[str]) -> list[str]:
        dup = sorted({m for m in v if v.count(m) > 1})
        if dup:
            raise ValueError(f"measures named twice: {', '.join(dup)}")
        return v

    @model_validator(mode="after")
    def _in_audit(self) -> CovariatesSpec:
        if not self.audit.is_file():  # not checked (validate without paths): the analysis checks it
            return self
        import pandas as pd

        from analysis.stats.covariates import AUDIT_MEASURES

        try:
            columns = [str(c) for c in pd.read_csv(self.audit, nrows=0).columns]
        except Exception as exc:  # noqa: BLE001 - a parser error becomes one line
            raise ValueError(f"{self.audit}: cannot read the audit table ({str(exc).splitlines()[0]})") from None
        if "file" not in columns:
            raise ValueError(f"{self.audit}: no 'file' column (expected the audit.csv of `appeal stimuli audit`)")
        missing = [m for m in self.measures if m not in columns]
        if missing:
            known = [c for c in AUDIT_MEASURES if c in columns] or columns
            raise ValueError(f"{', '.join(missing)} not in {self.audit} (available measures: {', '.join(known)})")
        return self
