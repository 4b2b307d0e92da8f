"""Which points of WebMorph's 189-point FRL template (the London set's ``.tem``) are dlib's 68.

For every public London face (``data:london-frl`` and ``data:london-frl-more``), dlib's 68 points
are detected and each is paired with the template point nearest it on average (distances in
units of the eye distance). Pairs whose mean distance is at most ``--max-distance`` (default
0.035) are kept: the template's hand-placed eyes, brows, nose base and outer lips. The jaw line,
the nasal bridge and the inner lips are drawn differently in the two markups and are not paired.

Writes ``stimulus_engine/data/faces2d/frl189_ibug68.json`` (iBUG index -> template index),
which :mod:`stimulus_engine.characters.photo_character` reads::

    .venv/bin/python scripts/frl189_to_ibug68.py
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def main() -> None:
    from PIL import Image

    from appeal.datasets import resolve_reference
    from stimulus_engine.data import DATA_DIR
    from stimulus_engine.faces2d.template import read_template
    from stimulus_engine.morphpca.keypoints import detect_landmarks

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-distance", type=float, default=0.035)
    ap.add_argument("--out", type=Path, default=DATA_DIR / "faces2d" / "frl189_ibug68.json")
    a = ap.parse_args()
    files = []
    for ds in ("london-frl", "london-frl-more"):
        files += sorted(Path(resolve_reference(f"data:{ds}")).glob("neutral_front/*.jpg"))
    dist = []
    for f in files:
        tem = f.with_suffix(".tem")
        if not tem.exists():
            continue
        img = np.asarray(Image.open(f).convert("RGB"))
        p = detect_landmarks(img, str(f))
        t = read_template(tem).points
        iod = np.linalg.norm(p[36:42].mean(axis=0) - p[42:48].mean(axis=0))
        dist.append(np.linalg.norm(p[:, None] - t[None], axis=2) / iod)
    d = np.mean(dist, axis=0)
    best = d.argmin(axis=1)
    pairs = {int(i): int(best[i]) for i in range(68) if d[i, best[i]] <= a.max_distance and not 60 <= i <= 67}
    out = {"faces": len(dist), "max_distance_iod": a.max_distance,
           "mean_distance_iod": {str(i): round(float(d[i, j]), 4) for i, j in pairs.items()},
           "ibug_to_frl189": {str(i): j for i, j in pairs.items()}}
    a.out.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"{len(pairs)} of 68 points paired over {len(dist)} faces -> {a.out}")


if __name__ == "__main__":
    main()
