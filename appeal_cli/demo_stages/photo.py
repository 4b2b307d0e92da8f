"""Demo stage 114: a character from one photograph — an embedded London photograph fitted with the
ICT model, worn as its material, at every level of the designed continuum (issue 49)."""

from __future__ import annotations

from pathlib import Path

from appeal.demo import DemoStage, missing_data
from appeal.report import ReportSection

#: The registry's datasets the stage reads (the rig and its identity components, the design).
NEEDS = ("ict-facekit", "ict-facekit-more", "gdquest-sophia")


def _grid_text(photo: Path, smile: Path, sophia: Path, landmarks: Path) -> str:
    return f"""kind: grid
name: demo_photo
characters:
  - {{name: f002, photo: '{photo.as_posix()}'}}
shapes: [0.0, 0.25, 0.5, 0.75, 1.0]
design: {{name: sophia, file: '{sophia.as_posix()}', landmarks: '{landmarks.as_posix()}', identity: 1.0,
          identity_model: data:ict-facekit-more}}
materials:
  - {{name: original}}
  - {{name: paint, style: painted, amount: 1.0}}
expressions: [neutral, happiness]
photographs:
  - character: f002
    files: {{neutral: '{photo.as_posix()}', happiness: '{smile.as_posix()}'}}
lighting: [gi_soft]
shading: [pbr]
render: {{width: 768, height: 576, shadows: false}}
"""


def _run(out: Path, seed: int) -> ReportSection:
    import numpy as np
    from PIL import Image

    from appeal.assets import protocols_dir
    from appeal.datasets import resolve_reference
    from appeal.studyfile import load_study_file
    from stimulus_engine.data import DATA_DIR
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile
    from stimulus_engine.stylisation.photo_match import render_vs_photo

    title = "A character from one photograph"
    absent = missing_data(title, NEEDS, "a character from a photograph fits the ICT face model and morphs to "
                          "GDQuest's Sophia", "photo")
    if absent is not None:  # third-party data, not embedded: the page says how to get it
        return absent
    photo, smile = DATA_DIR / "faces2d" / "002_03.jpg", DATA_DIR / "faces2d" / "002_08.jpg"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "demo_photo.yaml"
    path.write_text(_grid_text(photo, smile, Path(resolve_reference("data:gdquest-sophia")) / "sophia.glb",
                               protocols_dir() / "grids" / "designs" / "sophia_landmarks.yaml"), encoding="utf-8")
    grid = load_study_file(path, GridFile)
    manifest, sheets = run_grid(grid, out, n_jobs=2)
    real = manifest[(manifest["shape_label"] == "realistic") & (manifest["material"] == "original")]
    rgb = lambda p: np.asarray(Image.open(p).convert("RGB"))  # noqa: E731
    m = render_vs_photo(rgb(out / real[real["expression"] == "neutral"].iloc[0]["file"]), rgb(photo))
    n = int((manifest["status"] == "rendered").sum())
    text = (
        "One frontal photograph of the embedded London set (person 002, CC BY 4.0) becomes a character: the ICT "
        "model's 100 identity components and its expression shapes are fitted with a camera to the photograph's "
        "68 points, the photograph is laid into the rig's UV layout (its light divided out, the unseen side from "
        "the mirrored one), and its hair, neck and clothes stay the photograph's, on a plane behind the head. "
        f"{n} images: five shape levels toward her own cartoon of GDQuest's Sophia, the original and the painted "
        "material, neutral and the rig's happiness, and her two photographs framed like the renders. "
        f"The realistic neutral render against her photograph (aligned on dlib's points, then by a sub-pixel shift): "
        f"SSIM of luminance inside the face {m.ssim:.2f}, "
        f"dlib's descriptor distance {m.descriptor_distance:.2f} (same person below 0.6). The manifest carries her "
        f"age, gender and ethnicity from the London set ({manifest['gender'].iloc[0]}, {manifest['age'].iloc[0]:.0f}). "
        "Any photograph works the same way: `appeal stimuli photo-character PHOTO --out DIR` "
        "(docs/stimuli.md, 'Characters from one photograph').")
    figures = [p for p in sheets if p.name.startswith("contact_sheet")]
    return ReportSection(title=title, text=text, figures=figures, tables=[out / "manifest.csv"])


STAGE = DemoStage(name="photo", title="A character from one photograph", order=114, run=_run)
