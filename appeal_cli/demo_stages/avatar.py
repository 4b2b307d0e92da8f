"""Demo stage 120: morph-space PCA — expression spaces, projection between identities, an avatar.

Runs on synthetic faces drawn in code (no downloads, no shared data): three identities with
known expression weights; one model per identity; expressions of identity 0 projected onto
identity 1 beside the true rendering and the naive baseline; an identity-blended avatar.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from appeal.demo import DemoStage
from appeal.report import ReportSection


def _run(out: Path, seed: int) -> ReportSection:
    from stimulus_engine.morphpca import (build_avatar, build_model, mimicry_measures, naive_transfer,
                                          project_expression, psnr, random_identity, render_synthetic_face,
                                          save_contact_sheet, save_image, save_model, ssim, synthetic_set)
    from stimulus_engine.morphpca.synthetic import draw_weights

    rng = np.random.default_rng(seed)
    ids = [random_identity(int(s)) for s in rng.integers(0, 2**31, 3)]
    models = []
    for i, idn in enumerate(ids):
        imgs, _, frames = synthetic_set(idn, 14, int(rng.integers(0, 2**31)))
        models.append(build_model(imgs, faceframes=frames, names=[f"id{i}_{j}" for j in range(len(imgs))]))
    w = draw_weights(5, int(rng.integers(0, 2**31)))
    w[:, 1] = np.maximum(w[:, 1], 0.4)
    src = np.stack([render_synthetic_face(ids[0], x)[0] for x in w])
    truth = np.stack([render_synthetic_face(ids[1], x)[0] for x in w])
    proj = project_expression(src, models[0], models[1])
    naive = naive_transfer(src, models[0], models[1])
    sheet = save_contact_sheet(out / "projection.png", [list(src), list(truth), list(proj.images), list(naive.images)],
                               ["source A", "truth B", "projected", "naive"])
    rows = [{"method": name, "ssim": np.mean([ssim(a, b) for a, b in zip(imgs, truth)]),
             "psnr_db": np.mean([psnr(a, b) for a, b in zip(imgs, truth)])}
            for name, imgs in (("projection", proj.images), ("naive loading transfer", naive.images))]
    table = out / "projection_scores.csv"
    pd.DataFrame(rows).to_csv(table, index=False)
    # mimicry: B's true renderings projected back into A's space vs A's own loadings
    back = project_expression(truth, models[1], models[0])
    mim = mimicry_measures(proj.source_loadings, back.loadings, models[0].variances)
    mim_table = out / "mimicry.csv"
    mim.to_csv(mim_table, index=False)
    av = build_avatar(models)
    save_model(av.model, out / "avatar_model.npz")
    show = [0, 3, 14, 17, 28, 31]
    blend = save_contact_sheet(out / "avatar.png", [list(av.projections[j]) + [av.frames[j]] for j in show],
                               [f"expr {j}" for j in show], ["id 0", "id 1", "id 2", "avatar"])
    save_image(out / "avatar_mean.png", av.model.mean_image())
    text = (f"Three synthetic identities (14 images each, known expression weights) → one morph-space PCA model "
            f"each. Projection of 5 expressions of identity 0 onto identity 1 (SSIM to the true rendering: "
            f"{rows[0]['ssim']:.3f}; naive loading transfer {rows[1]['ssim']:.3f}). The avatar blends the three "
            f"identities ({av.model.n_components} components from {len(av.frames)} blended frames). "
            "Optical flow: OpenCV DIS (the paper's McGM is not available).")
    return ReportSection(title="Morph-space PCA: projection and identity-blended avatar", text=text,
                         figures=[sheet, blend, out / "avatar_mean.png"], tables=[table, mim_table],
                         links=[out / "avatar_model.npz"])


STAGE = DemoStage(name="avatar", title="Morph-space PCA: projection and identity-blended avatar", order=120, run=_run)
