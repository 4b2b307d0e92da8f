"""Morph-space PCA benchmarks: ours and a plain baseline in the same run (medians of repeats).

Targets (issue 6): build a model from 100 images of 240×200 in ≤ 10 s; reconstruct ≥ 200
faces/s; held-out PSNR ≥ 30 dB at 100 components; projection SSIM to the target's true
rendering higher than naive loading transfer.

Baselines — the same steps written plainly with the same libraries:

* build: OpenCV DIS with its MEDIUM preset searching down to full resolution (finest scale 0),
  mean shape by fixed-point inversion, textures by ``cv2.remap``, vectors serialised with
  ``np.concatenate``/``moveaxis``, PCA by scikit-learn ``PCA()`` (full SVD, its default here);
* reconstruct: the float64 product ``loadings @ components + mean`` (what scikit-learn's
  ``inverse_transform`` computes), then per face the warp inversion and texture sampling with
  ``scipy.ndimage.map_coordinates`` at full resolution.

Real photographs (``--photos`` runs only this): a face space of the London set (first 15 and all
30 neutral photos, .tem templates, the last 3 identities held out), reconstruction PSNR with all
components for flow-only, spline-only (Psychomorph-style) and landmark-guided warps; bounds of
what any reconstruction from the face space could reach; and the held-out score with 4 times the
training images of the same 27 people (their smiles and mirror images).

The whole public London set (``--london-all``, issue 33): a face space of up to all 87
identities (``data:london-frl-all``; neutral photos with .tem templates, or with ``--smiling``
their smiling photos too, all with dlib's 68 points), every fifth identity held out, 240x200,
every component: training and held-out PSNR (loadings fitted as images, and the paper's
orthogonal projection), the bounds of the face space, and two competitors: the landmark spline
alone (Psychomorph-style) and the landmark-only average warped into each held-out face's shape.
Targets: train >= 32 dB; held-out >= 21 dB or within 0.5 dB of the bound.

Data: synthetic faces drawn in code (stimulus_engine.morphpca.synthetic) under known
expression weights, so the target identity's true rendering of a projected expression exists.
Every timing line carries the 1-minute load average of the machine (``os.getloadavg``);
``--busy N`` runs N CPU-bound processes during the timings (another process is busy).

    .venv/bin/python benchmarks/morphpca.py [--quick] [--busy 1]
    .venv/bin/python benchmarks/morphpca.py --london-all [--identities N] [--smiling]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import statistics
import time

import cv2
import numpy as np


def _median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def _load() -> str:
    return "load avg {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def _burn() -> None:  # a busy process (--busy)
    x = 0
    while True:
        x = (x * 1103515245 + 12345) % 2147483648


# ---- baseline: the same steps written plainly -------------------------------------------------

def baseline_build(images: np.ndarray):
    """Plain OpenCV + scikit-learn build (see the module docstring)."""
    from sklearn.decomposition import PCA

    n, h, w = images.shape[:3]
    grey = [np.clip(cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) * 255 + 0.5, 0, 255).astype(np.uint8) for im in images]
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    dis.setFinestScale(0)
    flows = np.stack([dis.calc(grey[0], g, None) for g in grey])
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    base = np.dstack([x, y])
    mean = flows.mean(axis=0)
    inv = -mean
    for _ in range(12):
        inv = -cv2.remap(mean, base + inv, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    ref_pos = base + inv
    vecs = []
    for im, f in zip(images, flows):
        warp = ref_pos + cv2.remap(f, ref_pos, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        tex = cv2.remap(im, warp, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        hw5 = np.concatenate([tex * 255.0, warp], axis=-1)
        vecs.append(np.moveaxis(hw5, (0, 1, 2), (2, 1, 0)).ravel())
    return PCA().fit(np.stack(vecs))


def baseline_reconstruct(components: np.ndarray, mean: np.ndarray, loadings: np.ndarray, size: tuple[int, int],
                         iterations: int = 6) -> np.ndarray:
    """Plain NumPy/SciPy reconstruction (see the module docstring)."""
    from scipy.ndimage import map_coordinates

    h, w = size
    vecs = loadings.astype(np.float64) @ components + mean  # what PCA.inverse_transform computes
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    out = []
    for v in vecs:
        planes = v.reshape(5, w, h).transpose(0, 2, 1)  # (c, h, w)
        dx, dy = planes[3] - x, planes[4] - y
        ex, ey = -dx, -dy
        for _ in range(iterations):
            coords = [y + ey, x + ex]
            ex = -map_coordinates(dx, coords, order=1, mode="nearest")
            ey = -map_coordinates(dy, coords, order=1, mode="nearest")
        coords = [y + ey, x + ex]
        img = np.dstack([map_coordinates(planes[c] / 255.0, coords, order=1, mode="nearest") for c in range(3)])
        out.append((np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8))
    return np.stack(out)


# ---- the run -----------------------------------------------------------------------------------

def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats instead of 5; skip the quality section")
    ap.add_argument("--busy", type=int, default=0, metavar="N", help="run N CPU-bound processes during the timings")
    ap.add_argument("--photos", action="store_true", help="only the real-photograph section (London set)")
    ap.add_argument("--london-all", action="store_true", help="only the face space of the whole London set (87 people)")
    ap.add_argument("--identities", type=int, default=None, metavar="N", help="--london-all: the first N identities")
    ap.add_argument("--smiling", action="store_true", help="--london-all: their smiling photos too (dlib keypoints)")
    args = ap.parse_args()
    if args.london_all:
        from london_all import london_all

        london_all(args.identities, args.smiling)
        return
    if args.photos:
        real_photographs()
        return

    from sklearn.decomposition import PCA

    from stimulus_engine.morphpca import (Reconstructor, build_model, naive_transfer, project_expression, psnr,
                                          random_identity, render_synthetic_face, ssim, synthetic_set)
    from stimulus_engine.morphpca.morphvec import decompose
    from stimulus_engine.morphpca.pca import pca
    from stimulus_engine.morphpca.synthetic import draw_weights

    reps = 3 if args.quick else 5
    ida, idb = random_identity(11), random_identity(12)
    train, _, frames = synthetic_set(ida, 110, 0)
    test, _, _ = synthetic_set(ida, 10, 1, include_neutral=False)
    print(f"Morph-space PCA benchmark (images 240x200, synthetic faces), {os.cpu_count()} CPUs, "
          f"cv2 threads {cv2.getNumThreads()}, {reps} repeats, busy processes {args.busy}")
    burners = [mp.Process(target=_burn, daemon=True) for _ in range(args.busy)]
    for p in burners:
        p.start()
    try:
        # 1. build: 100 images
        imgs = train[:100]
        build_model(imgs[:8], faceframes=frames[:8])  # warm-up (imports, DIS buffers)
        t_ours = _median_time(lambda: build_model(imgs, faceframes=frames[:100]), reps)
        print(f"build 100 images: ours {t_ours:.2f} s (target <= 10 s)  [{_load()}]")
        t_base = _median_time(lambda: baseline_build(imgs), max(1, reps // 2))
        print(f"  baseline (plain OpenCV DIS full resolution + scikit-learn PCA) {t_base:.2f} s, "
              f"ratio {t_base / t_ours:.1f}x  [{_load()}]")
        rel = decompose(imgs).vectors()
        rel -= rel.mean(axis=0)
        t_pca = _median_time(lambda: pca(rel), reps)
        t_skl = _median_time(lambda: PCA().fit(rel), max(1, reps // 2))
        print(f"  PCA step alone: ours (Gram via ssyrk + eigh) {t_pca:.3f} s, scikit-learn PCA() {t_skl:.3f} s, "
              f"ratio {t_skl / t_pca:.1f}x  [{_load()}]")

        # 2. reconstruction speed: 200 faces of a 109-component model
        model = build_model(train, faceframes=frames)
        rec = Reconstructor(model)
        lo = np.tile(model.loadings, (2, 1))[:200]
        rec(lo)  # warm-up: work buffers
        t_batch = _median_time(lambda: rec(lo), reps)
        print(f"reconstruct ({model.n_components} components): ours batch of 200 {len(lo) / t_batch:.0f} faces/s "
              f"(target >= 200 faces/s)  [{_load()}]")
        t_single = _median_time(lambda: [rec(v) for v in lo[:50]], reps) / 50
        print(f"  ours one face per call {1 / t_single:.0f} faces/s  [{_load()}]")
        comps64, mean64 = model.components.astype(np.float64), model.mean.astype(np.float64)
        nb = 20
        t_b = _median_time(lambda: baseline_reconstruct(comps64, mean64, lo[:nb], model.size), max(1, reps // 2)) / nb
        print(f"  baseline (float64 product + scipy map_coordinates, full resolution) {1 / t_b:.1f} faces/s, "
              f"ratio {t_b / (t_batch / len(lo)):.0f}x  [{_load()}]")
        same = baseline_reconstruct(comps64, mean64, lo[:5], model.size)
        agree = [psnr(a / 255.0, b / 255.0) for a, b in zip(rec(lo[:5]).astype(np.float32), same.astype(np.float32))]
        print(f"  ours vs baseline images (5 faces, uint8): PSNR {np.mean(agree):.1f} dB (same faces; ours inverts "
              f"the warp at half resolution)")
    finally:
        for p in burners:
            p.terminate()
    if args.quick:
        return

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
    real_photographs()


def real_photographs() -> None:
    """5. A face space of real photographs (London set, .tem templates, registered to 240x200,
    the last 3 identities held out): reconstruction PSNR with every component kept, for optical
    flow alone (the old default), the landmark spline alone (Psychomorph-style warps, the
    competitor) and the landmark-guided warps (the spline refined by flow; the default)."""
    from appeal.assets import shared_data_dir
    from stimulus_engine.morphpca.workflow import build_morph_model, read_morph_inputs

    data = shared_data_dir()
    if data is None:
        print("real photographs: skipped (../shared/data not found)")
        return
    folder = data / "faces2d" / "london-frl" / "neutral_front"
    print("real photographs (London set, 240x200, all components, last 3 identities held out; "
          "targets: train >= 32 dB, held-out >= 22 dB):")
    import tempfile
    from pathlib import Path

    for n in (15, 30):
        files = sorted(folder.glob("*.jpg"))[:n]
        inputs = read_morph_inputs(files, keypoints="tem", register=True, size="240x200", holdout=3)
        for warp, label in (("flow", "optical flow only (DIS, before)"), ("landmarks", "landmark spline only (Psychomorph-style)"),
                            ("guided", "landmark-guided (spline + flow)")):
            with tempfile.TemporaryDirectory() as tmp:
                t = time.perf_counter()
                _, m = build_morph_model(inputs, Path(tmp), warp=warp)
                dt = time.perf_counter() - t
            print(f"  {len(files) - 3:2d} train  {label:42s} train {m['train_psnr_db']:5.2f} dB  held-out "
                  f"{m['holdout_psnr_db']:5.2f} dB  (SSIM {m['train_ssim']:.3f} / {m['holdout_ssim']:.3f})  {dt:.1f} s")
        _span_bounds(model_of(inputs), inputs)
    _more_faces_of_the_same_people(data / "faces2d" / "london-frl")


def _more_faces_of_the_same_people(london) -> None:
    """Does the held-out score grow with more training *images* of the same 27 identities? Their
    mirror images and their smiling photos (dlib keypoints) added, flow-only warps: the face
    space then holds 108 faces but still 27 people."""
    from stimulus_engine.morphpca import build_model, psnr
    from stimulus_engine.morphpca.workflow import read_morph_inputs

    neutral = read_morph_inputs(sorted((london / "neutral_front").glob("*.jpg")), keypoints="tem", register=True,
                                size="240x200")
    smiling = read_morph_inputs(sorted((london / "smiling_front").glob("*.jpg"))[:27], keypoints="detect",
                                register=True, size="240x200")
    train, held = list(neutral.images[:27]), neutral.images[27:]
    mirror = [np.ascontiguousarray(im[:, ::-1]) for im in train + list(smiling.images)]
    for label, faces in (("27 neutral", train), ("+ their smiles and mirror images", train + list(smiling.images) + mirror)):
        m = build_model(faces)
        rec = m.reconstruct(m.project(m.encode(held)))
        print(f"     flow only, {len(faces):3d} training faces ({label}): held-out "
              f"{np.mean([psnr(a, b) for a, b in zip(held, rec)]):5.2f} dB")


def model_of(inputs):
    """The landmark-guided model of the training part of ``inputs``."""
    from stimulus_engine.morphpca import build_model

    n = inputs.n_train
    return build_model(inputs.images[:n], landmarks=inputs.landmarks[:n], faceframes=inputs.faceframes[:n])


def _span_bounds(model, inputs) -> dict[str, float]:
    """How well *any* reconstruction from this face space could do on the held-out identities:
    their encoding with texture (or warp) kept exactly and only the other part projected, and
    both parts projected each on its own (not one loading vector: an upper bound)."""
    from stimulus_engine.morphpca import psnr
    from stimulus_engine.morphpca.pca import pca_with_loadings
    from stimulus_engine.morphpca.reconstruct import render_vectors

    n = inputs.n_train
    held = inputs.images[n:]
    enc = model.encode(held, inputs.landmarks[n:])
    rel_train = model.vectors(model.loadings) - model.mean
    nt = model.size[0] * model.size[1] * 3
    split = enc.copy()
    for part in (slice(0, nt), slice(nt, None)):
        comps = pca_with_loadings(np.ascontiguousarray(rel_train[:, part]))[0]
        split[:, part] = ((enc[:, part] - model.mean[part]) @ comps.T) @ comps + model.mean[part]
    score = lambda v: np.mean([psnr(a, b) for a, b in zip(render_vectors(v, model.size), held)])  # noqa: E731
    tex_exact, warp_exact = split.copy(), split.copy()
    tex_exact[:, :nt], warp_exact[:, nt:] = enc[:, :nt], enc[:, nt:]
    bounds = {"split": score(split), "texture_exact": score(tex_exact), "warp_exact": score(warp_exact)}
    print(f"     bounds of the {n}-face space on the held-out faces: shape and texture projected each on its own "
          f"{bounds['split']:5.2f} dB; texture exact {bounds['texture_exact']:5.2f} dB; warp exact "
          f"{bounds['warp_exact']:5.2f} dB")
    return bounds


if __name__ == "__main__":
    main()
