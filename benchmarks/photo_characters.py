"""Characters from one photograph against the photographs (issue 49), over the public London set.

Every person of ``data:london-frl`` and ``data:london-frl-more`` with a neutral and a smiling frontal photograph becomes a
character from the neutral one (``photo:`` in a grid: the ICT model fitted, the photograph as
material); one grid renders each at the realistic level, neutral and with the rig's happiness
(``gi_soft``, ``pbr``: the shipped Exp. 2 settings). Printed, per person and pooled:

* **neutral vs its own photograph** (:func:`stimulus_engine.stylisation.photo_match.render_vs_photo`:
  aligned on dlib's 68 points, then by intensity: a sub-pixel shift and the luminance's mean and
  spread): SSIM of luminance inside the face (target >= 0.90; also printed with the landmark
  alignment alone) and dlib's descriptor distance (target <= 0.30);
* **happiness vs the person's real smile**: descriptor distance (<= 0.5), and the mouth's 20
  points' displacement from neutral in an eye-aligned frame, its correlation with the real
  smile's (>= 0.7) and its size relative to it (within 30 %);
* **fit + texture** seconds per photograph (<= 10 s), timed for ``--timed`` photographs after the
  model is loaded, beside dlib's landmark detection alone (the competitor every fit starts from).

Run::

    .venv/bin/python benchmarks/photo_characters.py            # all 87 people (about 15 min)
    .venv/bin/python benchmarks/photo_characters.py --people 10
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


def _people(n: int | None, ids: list[str] | None = None) -> list[tuple[str, Path, Path]]:
    from appeal.datasets import resolve_reference

    roots = [Path(resolve_reference(f"data:{d}")) for d in ("london-frl", "london-frl-more")]
    smiles = {f.name[:3]: f for r in roots for f in sorted((r / "smiling_front").glob("*.jpg"))}
    neutral = sorted((f for r in roots for f in (r / "neutral_front").glob("*.jpg")), key=lambda f: f.name)
    out = [(f.name[:3], f, smiles[f.name[:3]]) for f in neutral if f.name[:3] in smiles]
    if ids:
        out = [p for p in out if p[0] in {f"{int(i):03d}" for i in ids}]
    return out[:n]


def fixed_smile_reach(motions: list[np.ndarray]) -> dict[str, float]:
    """How far any one smile, the same for everybody, could agree with people's real smiles: the spread
    of their sizes, the share within 30 % of the best single size, and the share whose own motion
    correlates >= 0.7 with the mean real motion (the rig's happiness is one recipe at one intensity)."""
    m = np.stack([np.ravel(x) for x in motions])
    size = np.linalg.norm(m, axis=1)
    grid = np.linspace(size.min(), size.max(), 400)
    share = [float(np.mean(np.abs(c / size - 1) <= 0.3)) for c in grid]
    mean = m.mean(axis=0)
    return {"cv": float(size.std() / size.mean()), "smallest": float(size.min()), "largest": float(size.max()),
            "best_size": float(grid[int(np.argmax(share))]), "best_size_share": max(share),
            "mean_smile_share": float(np.mean([np.corrcoef(x, mean)[0, 1] >= 0.7 for x in m]))}


def _grid_text(people: list[tuple[str, Path, Path]], neutral_shape: str) -> str:
    chars = "\n".join(f"  - {{name: p{pid}, photo: '{neutral}', neutral: {neutral_shape}}}" for pid, neutral, _ in people)
    return (f"kind: grid\nname: photo_benchmark\ncharacters:\n{chars}\nshapes: [0.0]\n"
            "materials: [original]\nexpressions: [neutral, happiness]\nlighting: [gi_soft]\nshading: [pbr]\nrender: {shadows: false}\n")


def main() -> None:
    import pandas as pd
    from PIL import Image

    from appeal.studyfile import load_study_file
    from stimulus_engine.characters.photo_character import photo_character
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.schema import GridFile
    from stimulus_engine.morphpca.keypoints import detect_landmarks
    from stimulus_engine.stylisation.identity import face_descriptor, identity_distance
    from stimulus_engine.stylisation.photo_match import (
        motion_agreement,
        mouth_motion,
        render_vs_photo,
    )

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--people", type=int, default=None, help="the first N people (default all)")
    ap.add_argument("--ids", nargs="+", default=None, help="only these people (London numbers, e.g. 17 82)")
    ap.add_argument("--neutral", choices=["photograph", "identity"], default="photograph",
                    help="the characters' neutral (default photograph: the realistic neutral render is the photograph)")
    ap.add_argument("--timed", type=int, default=10, help="photographs timed for fit + texture")
    ap.add_argument("--out", type=Path, default=None, help="keep the grid and the table here")
    a = ap.parse_args()
    people = _people(a.people, a.ids)
    rgb = lambda p: np.asarray(Image.open(p).convert("RGB"))

    from appeal.datasets import resolve_reference

    ict, more = resolve_reference("data:ict-facekit"), resolve_reference("data:ict-facekit-more")
    photo_character(people[0][1], ict, more, neutral=a.neutral)  # the model loaded once
    fit_s, detect_s = [], []
    for _, neutral, _ in people[:a.timed]:
        t = time.perf_counter()
        photo_character(neutral, ict, more, neutral=a.neutral)
        fit_s.append(time.perf_counter() - t)
        img = rgb(neutral)
        t = time.perf_counter()
        detect_landmarks(img)
        detect_s.append(time.perf_counter() - t)

    with tempfile.TemporaryDirectory() as tmp:
        folder = a.out or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "grid.yaml").write_text(_grid_text(people, a.neutral), encoding="utf-8")
        grid = load_study_file(folder / "grid.yaml", GridFile)
        t = time.perf_counter()
        manifest, _ = run_grid(grid, folder / "out")
        grid_s = time.perf_counter() - t
        rows, real_smiles = [], []
        for pid, neutral, smile in people:
            sub = manifest[manifest["character"] == f"p{pid}"].set_index("expression")
            rn = rgb(folder / "out" / sub.loc["neutral", "file"])
            rh = rgb(folder / "out" / sub.loc["happiness", "file"])
            pn, ps = rgb(neutral), rgb(smile)
            try:
                m = render_vs_photo(rn, pn)
                lm = [detect_landmarks(x) for x in (rn, rh, pn, ps)]
                real_smiles.append(mouth_motion(lm[2], lm[3]))
                corr, size = motion_agreement(mouth_motion(lm[0], lm[1]), real_smiles[-1])
                smile_d = identity_distance(face_descriptor(rh), face_descriptor(ps))
            except Exception as exc:  # noqa: BLE001 - a face dlib misses is a failed person, reported
                print(f"p{pid}: not measured ({str(exc).splitlines()[0]})")
                m, corr, size, smile_d = None, np.nan, np.nan, np.nan
            rows.append({"person": pid, "ssim": np.nan if m is None else m.ssim,
                         "ssim_landmarks": np.nan if m is None else m.ssim_landmarks,
                         "shift_px": np.nan if m is None else m.shift_px,
                         "descriptor": np.nan if m is None else m.descriptor_distance,
                         "smile_descriptor": smile_d, "mouth_corr": corr, "mouth_size": size})
        df = pd.DataFrame(rows)
        if a.out:
            df.to_csv(a.out / "photo_characters.csv", index=False)
    df["neutral_ok"] = (df["ssim"] >= 0.90) & (df["descriptor"] <= 0.30)
    df["smile_ok"] = (df["smile_descriptor"] <= 0.5) & (df["mouth_corr"] >= 0.7) & ((df["mouth_size"] - 1).abs() <= 0.3)
    with pd.option_context("display.width", 160, "display.max_rows", 200):
        print(df.round(3).to_string(index=False))
    print(f"\n{len(df)} people; grid of {len(manifest)} images rendered in {grid_s:.0f} s")
    print(f"neutral vs own photo: SSIM median {df['ssim'].median():.3f} (>= 0.90 in {(df['ssim'] >= 0.9).mean():.0%}), "
          f"descriptor median {df['descriptor'].median():.3f} (<= 0.30 in {(df['descriptor'] <= 0.3).mean():.0%}); "
          f"both: {df['neutral_ok'].mean():.0%}")
    print(f"  (SSIM aligned on the landmarks alone: median {df['ssim_landmarks'].median():.3f}, >= 0.90 in "
          f"{(df['ssim_landmarks'] >= 0.9).mean():.0%}; the intensity refinement's shift median "
          f"{df['shift_px'].median():.2f} px, largest {df['shift_px'].max():.2f} px)")
    print(f"happiness vs real smile: descriptor median {df['smile_descriptor'].median():.3f} "
          f"(<= 0.5 in {(df['smile_descriptor'] <= 0.5).mean():.0%}), mouth correlation median "
          f"{df['mouth_corr'].median():.2f} (>= 0.7 in {(df['mouth_corr'] >= 0.7).mean():.0%}), size median "
          f"{df['mouth_size'].median():.2f} (within 30 % in {((df['mouth_size'] - 1).abs() <= 0.3).mean():.0%}); "
          f"all three: {df['smile_ok'].mean():.0%}")
    reach = fixed_smile_reach(real_smiles)
    print(f"  what one fixed smile could reach at best: the real smiles' sizes vary {reach['cv']:.2f} (CV; "
          f"{reach['smallest']:.2f}-{reach['largest']:.2f} eye distances), so the best single size is within 30 % of "
          f"{reach['best_size_share']:.0%} of people; the mean real smile correlates >= 0.7 with "
          f"{reach['mean_smile_share']:.0%} of people's own")
    print(f"fit + texture: median {np.median(fit_s):.2f} s per photograph over {len(fit_s)} "
          f"(dlib's 68 points alone: {np.median(detect_s):.2f} s; ratio {np.median(fit_s) / np.median(detect_s):.1f}x)")


if __name__ == "__main__":
    main()
