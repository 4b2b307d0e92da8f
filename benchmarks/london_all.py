"""Morph-PCA on the whole public London set (issue 33), run by ``benchmarks/morphpca.py --london-all``.

A face space of up to all 87 identities of ``data:london-frl-all`` (neutral photos with their
189-point .tem templates; with ``smiling`` their smiling photos too, every photo then with dlib's
68 points, since the smiling photos have no templates), registered on the eyes to 240x200,
every component kept, every fifth identity held out (both its photos). Printed:

* train: training faces reconstructed from their loadings;
* held-out: the held-out identities encoded (landmark-guided warps) and reconstructed from
  loadings fitted as images (:func:`stimulus_engine.morphpca.fit.image_fit_loadings`, what
  ``appeal stimuli morphpca build --holdout`` reports) and from the paper's orthogonal projection;
* the bounds of the face space (``morphpca._span_bounds``: shape and texture projected each on
  its own — two loading vectors, more than one point of the model can do — and each part exact);
* competitors: the same pipeline with the landmark spline alone (Psychomorph-style warps), and
  the landmark-only average (the spline-only model's mean face) warped into each held-out face's
  own landmark shape.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

SIZE = "240x200"


def _files(n_identities: int | None, smiling: bool) -> tuple[list[Path], int, int]:
    """Training files then held-out files (every fifth identity), the number held out, identities."""
    from stimulus_engine.morphpca.io import list_images

    neutral = list_images(["data:london-frl-all/neutral_front"])[:n_identities]
    people = [[f] for f in neutral]
    if smiling:
        smiles = {f.name[:3]: f for f in list_images(["data:london-frl-all/smiling_front"])}
        people = [[f, smiles[f.name[:3]]] for f in neutral if f.name[:3] in smiles]
    train = [f for i, p in enumerate(people) if (i + 1) % 5 for f in p]
    held = [f for p in people[4::5] for f in p]
    return train + held, len(held), len(people)


def _landmark_average(model, images: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """The model's mean face warped (thin-plate spline) into each image's landmark shape."""
    from stimulus_engine.morphpca.flow import grid, warp_image
    from stimulus_engine.morphpca.landmark_warp import tps_displacement

    mean = model.mean_image()
    g = grid(*model.size)
    return np.stack([warp_image(mean, g + tps_displacement(pts, model.landmarks, model.size)) for pts in landmarks])


def london_all(n_identities: int | None = None, smiling: bool = False) -> dict[str, float]:
    """Run the benchmark and print its lines (see the module docstring); returns the numbers."""
    from morphpca import _span_bounds, model_of

    from stimulus_engine.morphpca import psnr
    from stimulus_engine.morphpca.workflow import build_morph_model, read_morph_inputs

    t0 = time.perf_counter()
    files, n_held, n_people = _files(n_identities, smiling)
    inputs = read_morph_inputs(files, keypoints="detect" if smiling else "tem", register=True, size=SIZE,
                               holdout=n_held)
    n = inputs.n_train
    print(f"whole London set: {n_people} identities ({'neutral + smiling, dlib 68 points' if smiling else 'neutral, .tem'}"
          f"), {n} training faces, {n_held} held out (every fifth identity), {SIZE}, every component; "
          f"read in {inputs.seconds:.1f} s")
    out: dict[str, float] = {}
    for warp, label in (("guided", "landmark-guided (default)"), ("landmarks", "landmark spline only (competitor)")):
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            model, m = build_morph_model(inputs, Path(tmp), warp=warp)
            dt = time.perf_counter() - t
        print(f"  {label:36s} train {m['train_psnr_db']:5.2f} dB  held-out {m['holdout_psnr_db']:5.2f} dB fitted as "
              f"images ({m['holdout_psnr_projection_db']:5.2f} dB orthogonal projection)  SSIM {m['train_ssim']:.3f} / "
              f"{m['holdout_ssim']:.3f}  {dt:.1f} s")
        out |= {f"{warp}_{k}": m[k] for k in ("train_psnr_db", "holdout_psnr_db", "holdout_psnr_projection_db")}
        if warp == "landmarks":
            held, pts = inputs.images[n:], inputs.landmarks[n:]
            avg = _landmark_average(model, np.stack(held), pts)
            out["landmark_average_db"] = float(np.mean([psnr(a, b) for a, b in zip(held, avg)]))
            print(f"  {'landmark-only average in each face':36s} held-out {out['landmark_average_db']:5.2f} dB "
                  "(the spline-only mean face warped to the held-out face's landmarks)")
    bounds = _span_bounds(model_of(inputs), inputs)
    out |= {f"bound_{k}": v for k, v in bounds.items()}
    gap = bounds["split"] - out["guided_holdout_psnr_db"]
    print(f"  targets: train {out['guided_train_psnr_db']:.2f} >= 32 dB; held-out {out['guided_holdout_psnr_db']:.2f} "
          f">= 21 dB or within 0.5 dB of the bound {bounds['split']:.2f} dB (gap {gap:.2f} dB); "
          f"wall time {time.perf_counter() - t0:.0f} s")
    return out
