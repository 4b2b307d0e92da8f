"""Morph-space PCA benchmarks: ours and a baseline in the same run (medians of repeats).

Targets (issue 6): build a model from 100 images of 240×200 in ≤ 10 s; reconstruct ≥ 200
faces/s; held-out PSNR ≥ 30 dB at 100 components; projection SSIM to the target's true
rendering higher than naive loading transfer.

Data: synthetic faces drawn in code (stimulus_engine.morphpca.synthetic) under known
expression weights, so the target identity's true rendering of a projected expression exists.

    .venv/bin/python benchmarks/morphpca.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _naive_remap(texture: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Baseline: a per-pixel Python loop doing bilinear lookups (what a first implementation does)."""
    h, w = positions.shape[:2]
    out = np.empty_like(texture)
    for y in range(h):
        for x in range(w):
            px, py = positions[y, x]
            px, py = min(max(px, 0.0), w - 1.001), min(max(py, 0.0), h - 1.001)
            x0, y0 = int(px), int(py)
            fx, fy = px - x0, py - y0
            out[y, x] = ((1 - fx) * (1 - fy) * texture[y0, x0] + fx * (1 - fy) * texture[y0, x0 + 1]
                         + (1 - fx) * fy * texture[y0 + 1, x0] + fx * fy * texture[y0 + 1, x0 + 1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    args = ap.parse_args()
    from sklearn.decomposition import PCA

    from stimulus_engine.morphpca import (Reconstructor, build_model, naive_transfer, project_expression, psnr,
                                          random_identity, render_synthetic_face, ssim, synthetic_set)
    from stimulus_engine.morphpca.flow import grid
    from stimulus_engine.morphpca.morphvec import decompose, deserialise
    from stimulus_engine.morphpca.pca import pca
    from stimulus_engine.morphpca.synthetic import draw_weights

    reps = 1 if args.quick else 3
    ida, idb = random_identity(11), random_identity(12)
    train, _, frames = synthetic_set(ida, 110, 0)
    test, _, _ = synthetic_set(ida, 10, 1, include_neutral=False)
    print("Morph-space PCA benchmark (images 240x200, synthetic faces with known expressions)")

    # 1. build: 100 images
    t_build = _median_time(lambda: build_model(train[:100], faceframes=frames[:100]), reps)
    rel = decompose(train[:100]).vectors()
    rel = rel - rel.mean(axis=0)
    t_pca = _median_time(lambda: pca(rel), reps)
    t_skl = _median_time(lambda: PCA(svd_solver="full").fit(rel), reps)
    print(f"build 100 images: ours {t_build:.2f} s (target <= 10 s)")
    print(f"  PCA step: ours (Gram eigendecomposition) {t_pca:.3f} s, scikit-learn PCA(svd_solver='full') "
          f"{t_skl:.3f} s, ratio {t_skl / t_pca:.1f}x")

    # 2. reconstruction speed
    model = build_model(train, faceframes=frames)
    rec = Reconstructor(model)
    lo = np.tile(model.loadings, (2, 1))[:200]
    t_batch = _median_time(lambda: rec(lo), reps)
    t_single = _median_time(lambda: [rec(v) for v in lo[:50]], reps) / 50
    tex, warp = deserialise(model.vectors(lo[:1]), model.size)
    pos = grid(*model.size) + (warp[0] - grid(*model.size))  # forward positions as a stand-in lookup map
    t_loop = _median_time(lambda: _naive_remap(tex[0], pos), 1)
    print(f"reconstruct: ours batch of 200 {len(lo) / t_batch:.0f} faces/s, one at a time {1 / t_single:.0f} faces/s "
          f"(target >= 200 faces/s); naive per-pixel loop (one remap only) {1 / t_loop:.2f} faces/s, "
          f"ratio {t_loop / (t_batch / len(lo)):.0f}x")

    # 3. held-out reconstruction at 100 components
    m100 = build_model(train, n_components=100, faceframes=frames)
    recon = m100.reconstruct(m100.project(m100.encode(test)))
    ps = [psnr(a, b) for a, b in zip(test, recon)]
    print(f"held-out PSNR at {m100.n_components} components: mean {np.mean(ps):.1f} dB, min {np.min(ps):.1f} dB "
          f"(target >= 30 dB); SSIM {np.mean([ssim(a, b) for a, b in zip(test, recon)]):.3f}")

    # 4. projection between identities vs naive loading transfer
    ib, _, fb = synthetic_set(idb, 60, 2)
    ma = build_model(train[:60], faceframes=frames[:60])
    mb = build_model(ib, faceframes=fb)
    w = draw_weights(12, 5)
    src = np.stack([render_synthetic_face(ida, x)[0] for x in w])
    truth = np.stack([render_synthetic_face(idb, x)[0] for x in w])
    score = lambda imgs: (np.mean([ssim(a, b) for a, b in zip(imgs, truth)]),  # noqa: E731
                          np.mean([psnr(a, b) for a, b in zip(imgs, truth)]))
    rows = [("projection, warp-weighted (default, texture_weight 0.1)", project_expression(src, ma, mb).images),
            ("projection, paper's inner product (texture_weight 1)", project_expression(src, ma, mb, texture_weight=1.0).images),
            ("projection without faceframe alignment", project_expression(src, ma, mb, align=False).images),
            ("naive loading transfer (baseline)", naive_transfer(src, ma, mb).images),
            ("target's mean face (no expression)", np.stack([mb.mean_image()] * len(w)))]
    print("projection A -> B, 12 expressions, compared with B's true rendering:")
    for name, imgs in rows:
        s, p = score(imgs)
        print(f"  {name:58s} SSIM {s:.4f}  PSNR {p:.2f} dB")


if __name__ == "__main__":
    main()
