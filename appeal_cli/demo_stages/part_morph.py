"""Demo stage 115: a part-based morph (thesis §3.4) — a cartoon's eyes on the real face."""

from __future__ import annotations

from pathlib import Path

from appeal.demo import DemoStage
from appeal.report import ReportSection


def _run(out: Path, seed: int) -> ReportSection:
    import numpy as np

    from appeal.studyfile import validate_data
    from stimulus_engine.correspondence.alignment import umeyama
    from stimulus_engine.correspondence.auto_landmarks import detect_mesh_landmarks
    from stimulus_engine.correspondence.pipeline import deformed_mesh
    from stimulus_engine.data import EMBEDDED_SCAN
    from stimulus_engine.grid.characters import load_character
    from stimulus_engine.grid.schema import CharacterSpec
    from stimulus_engine.geometry.mesh_io import load_mesh, save_mesh
    from stimulus_engine.stylisation.morph import part_morph
    from stimulus_engine.stylisation.morph_regions import part_morph_sheet
    from stimulus_engine.stylisation.shape import stylise

    # the embedded scan, and the same scan at cartoon shape (the stylisation operator through a
    # procedural rig): two meshes in correspondence by construction
    real = load_mesh(EMBEDDED_SCAN)
    spec = validate_data({"name": "james", "procedural": {"seed": seed, "texture_size": 256, "resolution": 48},
                          "mesh": {"file": str(EMBEDDED_SCAN), "region": "front", "topology": "scan", "eyes": "scan",
                                   "mouth": "scan"}}, CharacterSpec, source=Path("demo_part_morph.yaml"))
    ch = load_character(spec, out / ".cache", "demo_part_morph.yaml")
    n = len(real.vertices)
    back = umeyama(ch.scan.neutral[:n], np.asarray(real.vertices))  # the rig's frame -> the scan's own
    cartoon = deformed_mesh(real, back.apply(ch.scan.pose(stylise(ch.rig, 1.0))[:n]))
    save_mesh(cartoon, out / "cartoon.obj")
    ibug = detect_mesh_landmarks(real, name="james").points
    morphs = {m: part_morph([real, cartoon], {"eyes": 1}, ibug, m) for m in ("slerp", "linear")}
    save_mesh(morphs["slerp"], out / "cartoon_eyes.obj")
    sheet = out / "part_morph_sheet.png"
    part_morph_sheet([real, cartoon, morphs["linear"]], morphs["slerp"], ibug,
                     ["real (embedded scan)", "cartoon (shape level 1)", "its eyes: linear Laplacians",
                      "its eyes: slerp (thesis)"], sheet, width=300)
    text = ("A part-based morph (thesis §3.4): the cartoon's eyes on the real face. The embedded scan and its "
            "cartoon-shaped version share one mesh; the eye regions (around the automatically found iBUG eye "
            "landmarks, with a smooth falloff) take the cartoon's cotangent Laplacians, interpolated by slerp "
            "(Alexa 2003), and a Poisson solve recovers the shape while the rest of the face stays as it is; the "
            "texture is blended in the gradient domain (Pérez 2003). The third panel interpolates the Laplacians "
            "linearly for comparison. CLI: `appeal stimuli morph real.obj cartoon.obj --regions eyes=1 --sheet "
            "sheet.png --out eyes.obj`.")
    return ReportSection(title="Part-based morph", text=text, figures=[sheet])


STAGE = DemoStage(name="part_morph", title="Part-based morph (cartoon eyes on a real face)", order=115, run=_run)
