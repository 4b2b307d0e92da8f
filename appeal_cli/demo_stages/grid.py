"""Demo stage: a small stimulus grid of the procedural head (stylised shapes, expressions,
materials, lighting), its contact sheets and neoteny measures."""

from __future__ import annotations

from pathlib import Path

from appeal.cells import write_table
from appeal.demo import DemoStage
from appeal.report import ReportSection


def _run(out: Path, seed: int) -> ReportSection:
    from appeal.studyfile import validate_data
    from appeal_cli.audit_outputs import write_audit, write_grid_page
    from stimulus_engine.audit.workflow import read_audit_inputs
    from stimulus_engine.grid import run_grid
    from stimulus_engine.data import EMBEDDED_SCAN
    from stimulus_engine.grid.schema import AnimationSpec, CharacterSpec, GridFile, MaterialContinuum
    from stimulus_engine.stylisation.neoteny import neoteny_table, plot_neoteny

    import pandas as pd

    spec = {
        "kind": "grid",
        "name": "demo_grid",
        "characters": [
            {"name": "headA", "procedural": {"seed": seed, "texture_size": 512, "resolution": 64}},
            {"name": "headB", "procedural": {"seed": seed + 1, "texture_size": 512, "resolution": 64}},
        ],
        "shapes": [0.0, 0.5, 1.0],
        "materials": ["original", "blur50", "flat", {"name": "from_headB", "style": "original",
                                                     "from_character": "headB"}],
        "expressions": ["neutral", "happiness", "anger", "surprise"],
        "expression_transfer": "aligned",
        "lighting": ["gi_soft", "direct_hard"],
        "shading": ["pbr"],
        "render": {"width": 480, "height": 360},
    }
    grid = validate_data(spec, GridFile, source=Path("demo_grid.yaml"), base_dir=out)
    # a smaller product for the second lighting: keep the run short
    manifest, sheets = run_grid(grid.model_copy(update={"lighting": ["gi_soft"]}), out, n_jobs=2)
    lit = grid.model_copy(update={"characters": grid.characters[:1], "materials": ["original"],
                                  "expressions": ["neutral"], "lighting": ["gi_soft", "direct_hard", "direct_soft"]})
    lit_dir = out / "lighting"
    _, lit_sheets = run_grid(lit, lit_dir, n_jobs=2)
    # a real face without downloads: the embedded scan drawn as itself, posed through headA's rig
    scan = grid.model_copy(update={
        "characters": [validate_data({"name": "james", "procedural": {"seed": seed, "texture_size": 512, "resolution": 64},
                                      "mesh": {"file": str(EMBEDDED_SCAN), "region": "front", "topology": "scan"}},
                                     CharacterSpec, source=Path("demo_grid.yaml"))],
        "materials": MaterialContinuum(levels=3), "lighting": ["gi_soft"]})
    _, scan_sheets = run_grid(scan, out / "scan", n_jobs=2)
    # the scan grid audits itself, as appeal stimuli grid does: what differs between its levels
    audit = write_audit(read_audit_inputs(out / "scan" / "manifest.csv"), out / "scan" / "audit")
    write_grid_page(out / "scan", scan_sheets, audit, "Demo grid: the embedded scan")
    # a dynamic stimulus: the scan's surprise rising from neutral, one clip per shape level
    clip = scan.model_copy(update={"shapes": [0.0, 1.0], "materials": ["original"], "expressions": ["surprise"],
                                   "render": scan.render.model_copy(update={"width": 320, "height": 240}),
                                   "animation": AnimationSpec(fps=15, onset=0.8, hold=0.2)})
    clips, clip_sheets = run_grid(clip, out / "clips", n_jobs=2)
    strips = [p for p in clip_sheets if p.name.startswith("filmstrip")]
    table = neoteny_table(pd.read_csv(out / "landmarks.csv"))
    write_table(table, out / "neoteny.csv")
    figs = plot_neoteny(table, out / "neoteny.png")
    n = int((manifest["status"] == "rendered").sum())
    text = ("A real face first: the embedded 3D scan (menpo3d's 'james', BSD-3) drawn as itself — its own "
            "surface, photographic texture and hair, eyeballs behind its lids that look into the lens, teeth behind "
            "its lips — with its landmarks found automatically, posed through a procedural head's rig for shape "
            "stylisation levels 0, 0.5, 1 (artist-free operator: larger eyes, smaller nose and mouth, shorter jaw, "
            "larger cranium, smoother skin) and FACS-recipe expressions carried onto every level by the "
            "thesis's range-of-motion-aligned blendshape transfer (ch. 4: each level's own blendshapes, moving "
            "the face as far in units of its own length as the rig does; `scan/expression_measures.png` shows "
            "mouth opening, brow raise ... per level), and three material levels of one painted family spaced by "
            "measured image steps, with the continuum's report (`scan/continuum.png`: the step between "
            "neighbouring levels and each level's face-recognition distance to the realistic one) and its stimulus "
            f"audit (`scan/audit/report.html`, `scan/index.html`): {audit.n_flagged} factor × measure pairs of "
            "luminance, colour, contrast, spectrum, edges and face geometry differ between levels beyond their "
            "thresholds, each tested across the items. The same "
            f"scan's surprise as {len(clips)} clips ({int(clips['n_frames'].iloc[0])} frames at 15 fps, neutral to "
            "apex, one weight curve for both levels: lossless PNG frames and an H.264 MP4 each, "
            "`clips/clips/*.mp4`; the filmstrip shows every level's frames side by side). Then "
            f"{n} images of two procedurally generated, textured heads (no downloaded assets): the same shapes and "
            "expressions, materials original / blurred / flat / albedo of the other head. Every face is framed "
            "with the same size and eye position. Manifest: `manifest.csv`.")
    return ReportSection(title="Stimulus grid", text=text, figures=[*scan_sheets, audit.folder / "flags.png", *strips, *sheets, *lit_sheets, figs[0]],
                         tables=[out / "manifest.csv", out / "neoteny.csv", audit.folder / "design_tests.csv"],
                         links=[out / "scan" / "index.html", audit.report_html])


STAGE = DemoStage(name="grid", title="Stimulus grid (a real scan, then procedural heads)", order=100, run=_run)
