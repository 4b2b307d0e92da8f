"""How photographic a rendered grid's realistic level is, beside London photographs (issue 51's checks).

For every realistic-level image of one or more rendered grids (``appeal stimuli grid`` output
folders) it measures:

* ``score``: dlib's HOG face-detector score of the image at its own size, upsampled once (issue
  51's measure; the landmarks come from
  :func:`stimulus_engine.morphpca.keypoints.detect_landmarks_scored`, which detects on the image
  shrunk to 480 px);
* ``iris_right``, ``iris_left`` and ``gaze_ok`` (neutral images): where each iris sits between its
  eye's corners (:func:`stimulus_engine.audit.iris.iris_positions`) and whether both sit where
  photographed irises do, alike (:func:`stimulus_engine.audit.iris.gaze_check`);
* ``cheek_detail``: fine skin detail in the cheeks
  (:func:`stimulus_engine.stylisation.image_distance.cheek_detail`).

The same measures of the London neutral photographs, each scaled so that its eyes lie as far apart
as the renders' (cheek detail depends on the face's size in pixels), are printed as the reference.

Usage::

    .venv/bin/python benchmarks/realistic_level.py OUT_ERP OUT_EXP2 [--photos 'data:london-frl-all/neutral_front/*.jpg']
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd


def measure(image: np.ndarray, neutral: bool = True) -> dict[str, float]:
    """The detector score, iris positions, gaze check and cheek detail of one RGB image."""
    from stimulus_engine.audit.iris import gaze_check, iris_positions
    from stimulus_engine.morphpca.keypoints import detect_landmarks_scored
    from stimulus_engine.stylisation.image_distance import cheek_detail

    import dlib

    lm, _ = detect_landmarks_scored(image)
    _, scores, _ = dlib.get_frontal_face_detector().run(np.ascontiguousarray(image[..., :3]), 1, 0.0)
    row = {"score": float(max(scores)) if len(scores) else float("nan"), "cheek_detail": cheek_detail(image, lm),
           "iod_px": float(np.linalg.norm(lm[36:42].mean(axis=0) - lm[42:48].mean(axis=0)))}
    if neutral:
        iris = iris_positions(image, lm)
        row.update({"iris_right": iris["right"], "iris_left": iris["left"], "gaze_ok": gaze_check(iris)})
    return row


def rendered(folders: list[Path]) -> pd.DataFrame:
    """One row per realistic-level image of the grids rendered into ``folders``."""
    from PIL import Image

    rows = []
    for folder in folders:
        manifest = pd.read_csv(folder / "manifest.csv")
        for r in manifest[manifest["shape_label"] == "realistic"].itertuples():
            image = np.asarray(Image.open(folder / r.file).convert("RGB"))
            rows.append({"grid": folder.name, "file": Path(r.file).name, "character": r.character,
                         "expression": r.expression, **measure(image, r.expression == "neutral")})
    return pd.DataFrame(rows)


def photographs(pattern: str, iod_px: float) -> pd.DataFrame:
    """The photographs matching ``pattern`` (``data:`` references allowed), each scaled so its
    eyes lie ``iod_px`` apart, measured."""
    import cv2
    from PIL import Image

    from appeal.datasets import expand_inputs
    from stimulus_engine.morphpca.keypoints import detect_landmarks

    rows = []
    for path in expand_inputs([pattern]):
        image = np.asarray(Image.open(path).convert("RGB"))
        lm = detect_landmarks(image, str(path))
        s = iod_px / float(np.linalg.norm(lm[36:42].mean(axis=0) - lm[42:48].mean(axis=0)))
        image = cv2.resize(image, None, fx=s, fy=s, interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_CUBIC)
        rows.append({"file": path.name, **measure(image)})
    return pd.DataFrame(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("grids", nargs="+", type=Path, help="rendered grid folders (with manifest.csv)")
    ap.add_argument("--photos", default="data:london-frl-all/neutral_front/*.jpg", help="photographs to compare with")
    args = ap.parse_args()
    pd.set_option("display.width", 200)
    renders = rendered(args.grids)
    photos = photographs(args.photos, float(renders["iod_px"].median()))
    print(renders.round(3).to_string(index=False))
    q = photos[["score", "cheek_detail"]].quantile([0.1, 0.5, 0.9]).round(4)
    iris = np.concatenate([photos["iris_right"], photos["iris_left"]])
    print(f"\nphotographs ({len(photos)}, eyes {renders['iod_px'].median():.0f} px apart): score and cheek detail "
          f"10/50/90 %:\n{q.to_string()}\niris positions 2.5-97.5 %: {np.nanpercentile(iris, [2.5, 97.5]).round(3)}; "
          f"eyes apart (97.5 %): {np.nanpercentile(np.abs(photos['iris_right'] - photos['iris_left']), 97.5):.3f}; "
          f"gaze check passed by {photos['gaze_ok'].mean():.0%}")
    for grid, g in renders.groupby("grid"):
        neutral = g[g["expression"] == "neutral"]
        print(f"{grid}: detector median {g['score'].median():.2f} (photographs {photos['score'].median():.2f}); "
              f"gaze check passed by {int(neutral['gaze_ok'].sum())} of {len(neutral)} neutral images; cheek detail "
              + ", ".join(f"{c} {x:.4f}" for c, x in g.groupby("character")["cheek_detail"].median().items()))


if __name__ == "__main__":
    main()
