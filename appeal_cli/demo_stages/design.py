"""Demo stage 112: the designed continuum — two photographed people morphed to their own cartoons of an
artist's head (the shipped Exp. 2 grid's ``design:``, issue 48), with the continuum report."""

from __future__ import annotations

from pathlib import Path

from appeal.demo import DemoStage, missing_data
from appeal.report import ReportSection

#: The registry's datasets the shipped Exp. 2 grid reads (photographs, rig, identity model, design).
NEEDS = ("london-frl", "ict-facekit", "ict-facekit-more", "gdquest-sophia")


def _run(out: Path, seed: int) -> ReportSection:
    import pandas as pd

    from appeal.assets import protocols_dir
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile, MaterialSpec

    title = "Designed stylisation: each person's own cartoon"
    absent = missing_data(title, NEEDS, "the designed continuum morphs two photographed people to their cartoons of "
                          "GDQuest's Sophia", "design")
    if absent is not None:  # third-party data, not embedded: the page says how to get it
        return absent
    grid = load_study_file(protocols_dir() / "grids" / "exp2_stylisation.yaml", GridFile)
    painted = MaterialSpec(name="paint4", style="painted", amount=1.0)
    cut = grid.model_copy(update={
        "name": "demo_design", "shapes": [0.0, 0.5, 1.0], "materials": [MaterialSpec(name="original"), painted],
        "expressions": ["neutral", "happiness", "surprise"], "photographs": []})  # the shipped grid's image size
    manifest, sheets = run_grid(cut, out, n_jobs=2)
    cont = pd.read_csv(out / "continuum.csv")
    shape = cont[cont["factor"] == "shape"].sort_values("position")
    rows = []
    for ch, g in shape.groupby("character", sort=False):
        real, toon = g.iloc[0], g.iloc[-1]
        rows.append(f"| {ch} | {toon['eye_area'] / real['eye_area']:.1f}× | {real['eye_roundness']:.2f} → "
                    f"{toon['eye_roundness']:.2f} | {toon['nose_width'] / real['nose_width']:.2f}× | "
                    f"{', '.join(f'{s:.3f}' for s in g['image_to_next'].dropna())} |")
    mat = cont[cont["factor"] == "material"].sort_values("position")
    cheek = {ch: g["cheek_detail"].iloc[-1] / g["cheek_detail"].iloc[0] for ch, g in mat.groupby("character")}
    n = int((manifest["status"] == "rendered").sum())
    text = (
        "The stylised end as a design (thesis §6.4, §3.2): GDQuest's Sophia, an artist-made chibi head "
        "(CC BY 4.0), is brought into the ICT rig's topology by ElastiFace from "
        f"{len(grid.design.landmarks)} landmarks read off her painted "
        "eyes and mouth, the rig's eyes, nose and mouth carried over whole at her features' sizes. Each person "
        "is a character from one London-set photograph (the ICT model fitted to it, the photograph as material); "
        "their own proportions (the model's 100 identity components) are carried onto the design by deformation "
        "transfer, so the man's and the woman's cartoons are two people in one design language; the levels between are morphs, and the expressions reach every level by the aligned "
        f"blendshape transfer. {n} images: the shipped Exp. 2 grid (`protocols/grids/exp2_stylisation.yaml`) cut "
        "to shape levels 0, 0.5, 1, the original and the most painted material, neutral, happiness and "
        "surprise.\n\n"
        "| character | eye area (cartoon / realistic) | eye height / width | nose width | image steps (1 − SSIM) |\n"
        "|---|---|---|---|---|\n" + "\n".join(rows) + "\n\n"
        "Cheek detail at the most painted level (skin detail left from the photograph): "
        + ", ".join(f"{ch} {v:.2f}×" for ch, v in cheek.items()) + " of the original's. "
        "`continuum.csv` holds every level's measures (docs/stimuli.md, 'A designed stylised end').")
    figures = [p for p in sheets if p.name.startswith("contact_sheet")] + [out / "continuum.png"]
    return ReportSection(title=title, text=text, figures=figures, tables=[out / "continuum.csv"])


STAGE = DemoStage(name="design", title="Designed stylisation (each person's own cartoon of Sophia)", order=112, run=_run)
