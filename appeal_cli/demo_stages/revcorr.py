"""Demo stage 340: reverse correlation of facial expressions — simulated participants' answers to
random AU trials at a realistic and a stylised level, their AU models recovered by
``appeal analyze revcorr`` (the answers are drawn directly from template observers; the shipped
``revcorr:`` protocol runs them in the runner on a rendered pool: docs/revcorr.md)."""

from __future__ import annotations

from pathlib import Path

from appeal.demo import DemoStage
from appeal.report import ReportSection

#: Simulated participants and trials per participant and level (Jack et al. used 2,400).
N_PARTICIPANTS, TRIALS = 3, 1200


def _run(out: Path, seed: int) -> ReportSection:
    from analysis.revcorr.study import analyze_revcorr
    from analysis.revcorr.trials import read_revcorr_trials, simulated_table
    from appeal.cells import write_table
    from appeal.revcorr.observers import PROTOTYPES, TemplateObserver

    # by construction: at the stylised level these participants read a dropped jaw (AU26) as part of
    # happiness and no longer as part of surprise (a made-up effect the analysis should find)
    stylised = dict(PROTOTYPES, happy=("AU6", "AU12", "AU26"), surprise=("AU1", "AU2", "AU5"))
    ids = [f"{k + 1:02d}" for k in range(N_PARTICIPANTS)]
    plan = {"realistic": {p: TemplateObserver(seed=seed + k) for k, p in enumerate(ids)},
            "stylised": {p: TemplateObserver(templates=stylised, seed=seed + 100 + k) for k, p in enumerate(ids)}}
    table = simulated_table(plan["realistic"], TRIALS, seed=seed, levels=plan).rename(columns={"level": "shape"})
    for pid, sub in table.groupby("participant_id"):
        folder = out / "data" / f"sub-{pid}" / "ses-1" / "beh"
        folder.mkdir(parents=True, exist_ok=True)
        write_table(sub.drop(columns="participant_id"), folder / f"sub-{pid}_ses-1_task-revcorr_beh.tsv", sep="\t",
                    na_rep="n/a")
    data = read_revcorr_trials(str(out / "data" / "sub-*" / "ses-*" / "beh" / "*_task-revcorr_beh.tsv"),
                               levels=["shape"])
    res = analyze_revcorr(data, out / "analysis", n_permutations=500, seed=seed)
    changes = res.level_agreement
    happy = changes[(changes["emotion"] == "happy") & (changes["only_b"].fillna("").str.contains("AU26"))]
    share = res.consensus.set_index(["shape", "emotion", "au"])["share"]
    text = ("Reverse correlation (Jack et al. 2012; docs/revcorr.md): each trial moves 1-6 random action units of "
            f"the rig with random time courses; {N_PARTICIPANTS} **simulated** participants with known templates "
            f"(the EMFACS prototypes) named the emotion of {TRIALS} trials at each of two levels. By construction "
            "their stylised-level happiness includes the dropped jaw (AU26) and their surprise does not. "
            "`appeal analyze revcorr` recovered each participant's AU model per level (mutual information, "
            "permutation test corrected across AUs): AU26 is in the stylised happiness model and not the realistic "
            f"one for {len(happy)} of {N_PARTICIPANTS} participants; share of participants with AU12 in happiness: "
            f"realistic {share.get(('realistic', 'happy', 'AU12'), float('nan')):.2f}, stylised "
            f"{share.get(('stylised', 'happy', 'AU12'), float('nan')):.2f}. The answers are simulated, drawn here without "
            "clips; `protocols/revcorr_stylisation.yaml` runs the same observers in the runner on a rendered pool. "
            "Full report: [analysis/index.html](analysis/index.html).")
    figures = sorted((out / "analysis").glob("consensus_*.png")) + sorted((out / "analysis" / "figures").glob("*.png"))[:1]
    return ReportSection(title="Reverse correlation: AU models of the expressions (simulated participants)", text=text,
                         figures=figures, tables=[out / "analysis" / "consensus.csv",
                                                  out / "analysis" / "level_agreement.csv"],
                         links=[out / "analysis" / "index.html"])


STAGE = DemoStage(name="revcorr", title="Reverse correlation: AU models of the expressions", order=340, run=_run)
