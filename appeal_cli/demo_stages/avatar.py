"""Demo stage 120: morph-space PCA on real photographs — expression spaces, a projected smile, an avatar.

Runs on the photographs embedded in the package (``stimulus_engine/data/faces2d``: a neutral and
a smiling photo of four London-set people, CC BY 4.0; no downloads, no shared data): one
expression space per person from a morph sequence between their two photos (the stand-in for
video frames), the smile of person 0 projected onto person 1 beside person 1's own smiling
photo and the naive baseline, the mimicry measures between the two, a face-space average of
the four neutral photos, and an identity-blended avatar (landmark-guided warps throughout).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from appeal.demo import DemoStage
from appeal.report import ReportSection

#: Frames of each person's neutral → smile morph sequence.
N_FRAMES = 8


def _run(out: Path, seed: int) -> ReportSection:  # noqa: ARG001 - deterministic: no random choices
    from stimulus_engine.data import EMBEDDED_FACES
    from stimulus_engine.morphpca import (build_avatar, mimicry_measures, naive_transfer, project_expression, psnr,
                                          save_contact_sheet, save_image, save_model, ssim)
    from stimulus_engine.morphpca.ghosting import ghosting_index
    from stimulus_engine.morphpca.workflow import pair_expression_model, read_morph_inputs
    from stimulus_engine.morphpca.pca import build_model

    people = pd.read_csv(EMBEDDED_FACES / "people.csv", dtype={"face_id": str})["face_id"].tolist()
    built = [pair_expression_model(EMBEDDED_FACES / f"{p}_03.jpg", EMBEDDED_FACES / f"{p}_08.jpg", n_frames=N_FRAMES)
             for p in people]
    models = [b[0] for b in built]
    (ma, frames_a, _, points_a), (mb, frames_b, photos_b, points_b) = built[0], built[1]
    proj = project_expression(frames_a, ma, mb, landmarks=points_a)
    naive = naive_transfer(frames_a, ma, mb)
    show = np.linspace(0, N_FRAMES - 1, 4).round().astype(int)
    sheet = save_contact_sheet(out / "projection.png",
                               [[frames_a[j], proj.images[j], naive.images[j], frames_b[j]] for j in show],
                               [f"frame {j}" for j in show],
                               [f"{people[0]} (source)", f"projected on {people[1]}", "naive transfer",
                                f"{people[1]}'s own morph"])
    truth = photos_b[1]
    rows = [{"method": name, "ssim_to_true_smile": ssim(img, truth), "psnr_db": psnr(img, truth)}
            for name, img in (("projection", proj.images[-1]), ("naive loading transfer", naive.images[-1]),
                              (f"{people[1]}'s neutral photo (no expression)", photos_b[0]))]
    table = out / "projection_scores.csv"
    pd.DataFrame(rows).to_csv(table, index=False)
    # mimicry: B's own frames projected back into A's space vs A's loadings
    back = project_expression(frames_b, mb, ma, landmarks=points_b)
    mim_table = out / "mimicry.csv"
    mimicry_measures(proj.source_loadings, back.loadings, ma.variances).to_csv(mim_table, index=False)
    # a face space of the four neutral photos: its average, with landmark-guided warps
    space = read_morph_inputs([EMBEDDED_FACES / f"{p}_03.jpg" for p in people], keypoints="detect", register=True,
                              size="240x200")
    fs = build_model(space.images, faceframes=space.faceframes, landmarks=space.landmarks)
    save_image(out / "face_space_mean.png", fs.mean_image())
    ghost = ghosting_index(fs.mean_image(), fs.landmarks, space.images, space.landmarks, fs.faceframe)
    av = build_avatar(models)
    save_model(av.model, out / "avatar_model.npz")
    pick = [j for j, (s, i) in enumerate(av.sources) if i in (0, N_FRAMES - 1)][:6]
    blend = save_contact_sheet(out / "avatar.png", [list(av.projections[j]) + [av.frames[j]] for j in pick],
                               [f"{people[s]} #{i}" for s, i in (av.sources[j] for j in pick)],
                               [*people, "avatar"])
    save_image(out / "avatar_mean.png", av.model.mean_image())
    text = (f"Real photographs (London set, CC BY 4.0, embedded): {len(people)} people, each an expression space "
            f"from a {N_FRAMES}-frame morph between their neutral and smiling photo. {people[0]}'s smile projected "
            f"onto {people[1]}: SSIM to {people[1]}'s own smiling photo {rows[0]['ssim_to_true_smile']:.3f} "
            f"(naive loading transfer {rows[1]['ssim_to_true_smile']:.3f}, {people[1]}'s neutral photo "
            f"{rows[2]['ssim_to_true_smile']:.3f}). Face-space average of the neutral photos with landmark-guided "
            f"warps (dlib's 68 points; ghosting index {ghost:.2f}). The avatar blends the {len(people)} identities "
            f"({av.model.n_components} components from {len(av.frames)} blended frames).")
    return ReportSection(title="Morph-space PCA on real photographs: projected smile and identity-blended avatar",
                         text=text, figures=[sheet, blend, out / "avatar_mean.png", out / "face_space_mean.png"],
                         tables=[table, mim_table], links=[out / "avatar_model.npz"])


STAGE = DemoStage(name="avatar", title="Morph-space PCA on real photographs: projected smile and avatar", order=120,
                  run=_run)
