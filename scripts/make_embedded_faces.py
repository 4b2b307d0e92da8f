"""Rebuild ``stimulus_engine/data/faces2d/``: four London-set identities for the demo's morph-PCA stage.

A neutral and a smiling photograph of each of four people (DeBruine & Jones 2017, Face Research
Lab London Set, CC BY 4.0), reduced from 1350 x 1350 to 480 x 480 (JPEG quality 90): enough
for the 240 x 200 registered models of the demo (a tighter crop left too little around the
face for the eye registration: its borders were smeared in). The licence text is copied beside them and the README names the source and the changes,
as the licence asks.

Usage::

    python scripts/make_embedded_faces.py ../shared/data/faces2d/london-frl
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import cv2
import pandas as pd

#: (face_id, why): a woman and a man of different ethnicities, each with a clear smile
PEOPLE = ("002", "025", "012", "008")
CROP = (0, 0, 1350)  # x0, y0, side of the square kept of the 1350 x 1350 originals (all of it)
SIZE = 480

README = """# London-set faces (reduced) — the embedded real photographs

Neutral (`NNN_03.jpg`) and smiling (`NNN_08.jpg`) photographs of four people from the
**Face Research Lab London Set**: DeBruine, L., & Jones, B. (2017). *Face Research Lab London
Set* (Version 5). figshare. https://doi.org/10.6084/m9.figshare.5047666.v5 — licensed under
Creative Commons Attribution 4.0 International (CC BY 4.0), full text in `LICENSE.md` beside
this file. All individuals gave signed consent for their images to be used in lab-based and
web-based studies in their original or altered forms and to illustrate research.

Changes made here: reduced from the 1350 x 1350 originals ({side} x {side} pixels kept from
x = {x0}, y = {y0}) to {size} x {size} pixels (JPEG quality 90). `people.csv` lists
their self-reported age, gender and ethnicity from the set's `london_info.csv`.

Used by `appeal demo` (stage *avatar*): per-person expression spaces from each neutral/smiling
pair, a smile projected from one person onto another, and an identity-blended avatar — on real
faces without `../shared`. Rebuilt by `scripts/make_embedded_faces.py`.
"""


def main(src: Path, out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    x0, y0, side = CROP
    for pid in PEOPLE:
        for folder, suffix in (("neutral_front", "03"), ("smiling_front", "08")):
            img = cv2.imread(str(src / folder / f"{pid}_{suffix}.jpg"))
            crop = cv2.resize(img[y0 : y0 + side, x0 : x0 + side], (SIZE, SIZE), interpolation=cv2.INTER_AREA)
            cv2.imwrite(str(out / f"{pid}_{suffix}.jpg"), crop, [cv2.IMWRITE_JPEG_QUALITY, 90])
    info = pd.read_csv(src / "london_info.csv", dtype={"face_id": str})
    info[info["face_id"].isin(PEOPLE)].to_csv(out / "people.csv", index=False)
    shutil.copy(src / "LICENSE.md", out / "LICENSE.md")
    (out / "README.md").write_text(README.format(side=side, x0=x0, y0=y0, size=SIZE))


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(__file__).resolve().parent.parent / "stimulus_engine" / "data" / "faces2d")
