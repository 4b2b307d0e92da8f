"""Demo stage 125: WebMorph-style operations on the embedded photographs (``appeal faces``).

The eight London-set photographs embedded in the package (four people, neutral and smiling; no
``.tem`` templates, so dlib's 68 points are found on each) are aligned on the pupils, averaged
into a composite of the four neutral faces and into a female and a male composite, and one
woman's face is transformed along the female → male difference in shape and
caricatured against the four-face average. Every step writes PNG + ``.tem``, a manifest and a
contact sheet, as the commands do.
"""

from __future__ import annotations

from pathlib import Path

from appeal.demo import DemoStage
from appeal.report import ReportSection

#: Output size of the aligned faces (width, height).
SIZE = (360, 420)
#: Transform strengths along the female → male difference.
STRENGTHS = (-0.5, 0.5, 1.0)


def _run(out: Path, seed: int) -> ReportSection:  # noqa: ARG001 - deterministic: no random choices
    import pandas as pd

    from stimulus_engine.data import EMBEDDED_FACES
    from stimulus_engine.faces2d import (FaceOutput, Template, align_face, average_faces, composite_ghosting,
                                         default_eyes, load_faces, pixel_average, write_outputs)
    from stimulus_engine.faces2d.caricature import caricature
    from stimulus_engine.faces2d.transform import transform

    people = pd.read_csv(EMBEDDED_FACES / "people.csv", dtype={"face_id": str})
    files = [EMBEDDED_FACES / f"{p}_03.jpg" for p in people["face_id"]]
    faces = load_faces(files)
    eyes = default_eyes(faces, SIZE)
    aligned = [align_face(f.image, f.points, eyes, SIZE) for f in faces]
    images, points = [a[0] for a in aligned], [a[1] for a in aligned]
    write_outputs(out / "aligned", [FaceOutput(p.name.replace(".jpg", ".png"), im, Template(pt), [p])
                                    for p, im, pt in zip(files, images, points)], "align", {"size": list(SIZE)})
    comp, comp_pts = average_faces(images, points, texture=True)
    ghost = composite_ghosting(comp, comp_pts, images, points)
    ghost_plain = composite_ghosting(pixel_average(images), comp_pts, images, points)
    sex = people["face_gender"].tolist()
    protos = {}
    for g in ("female", "male"):
        idx = [i for i, s in enumerate(sex) if s == g]
        protos[g] = average_faces([images[i] for i in idx], [points[i] for i in idx], texture=True)
    write_outputs(out / "composites", [
        FaceOutput("all_neutral.png", comp, Template(comp_pts), files, {"ghosting": round(ghost, 3)}),
        FaceOutput("female.png", *protos["female"][:1], Template(protos["female"][1]),
                   [f for f, s in zip(files, sex) if s == "female"]),
        FaceOutput("male.png", *protos["male"][:1], Template(protos["male"][1]),
                   [f for f, s in zip(files, sex) if s == "male"])], "average", {"texture": True})
    who = sex.index("female")
    moved = [transform(images[who], points[who], *protos["female"], *protos["male"], shape=s)
             for s in STRENGTHS]
    write_outputs(out / "transform", [FaceOutput(f"{files[who].stem}_masc{s:+.1f}.png", im, Template(pt), [files[who]],
                                                 {"strength": s}) for s, (im, pt) in zip(STRENGTHS, moved)],
                  "transform", {"from": "female composite", "to": "male composite", "strengths": list(STRENGTHS),
                                "weights": "shape"},
                  title="female to male transform, shape (-0.5, +0.5, +1.0)")
    cari = [caricature(images[who], points[who], comp, comp_pts, k) for k in (-0.5, 0.5)]
    write_outputs(out / "caricature", [FaceOutput(f"{files[who].stem}_k{k:+.1f}.png", im, Template(pt), [files[who]],
                                                  {"k": k}) for k, (im, pt) in zip((-0.5, 0.5), cari)],
                  "caricature", {"average": "all_neutral", "k": [-0.5, 0.5]})
    text = (f"The four embedded London-set people's neutral photographs (dlib's 68 points found on each, no "
            f"templates) aligned on the pupils ({SIZE[0]} × {SIZE[1]}) and averaged: the composite's features stay "
            f"single and sharp (ghosting index {ghost:.2f} against a plain pixel average's {ghost_plain:.2f}; "
            "`appeal faces average`). From a female and a male composite (two people each), the first woman's face "
            "moved along the female → male difference in shape (`appeal faces transform`, strengths −0.5, +0.5, "
            "+1; colour and texture are left out: with two people per prototype their differences are those "
            "people's skin, not their sex), and caricatured against the four-face average (k = −0.5, +0.5: "
            "`appeal faces caricature`). With two faces per prototype the transform carries those people's "
            "identities as much as their sex; the 87-identity London set (`appeal data fetch london-frl-all`) "
            "gives real prototypes.")
    sheets = [out / d / "contact_sheet.png" for d in ("composites", "transform", "caricature")]
    return ReportSection(title="2-D faces: composites, transforms, caricatures", text=text, figures=sheets,
                         tables=[out / "composites" / "manifest.csv"])


STAGE = DemoStage(name="faces2d", title="2-D faces: composites, transforms, caricatures (WebMorph-style)", order=125,
                  run=_run)
