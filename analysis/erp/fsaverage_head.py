"""A realistic template head from the fsaverage surfaces MNE ships (offline): a three-layer BEM in
MNI305 space, for source summaries comparable with the thesis's SPM analysis (§7.3).

The MNE wheel ships fsaverage's inner skull (an ico-5 surface) and its head surface (with the
neck and face), not the outer skull. The three BEM surfaces are built on the inner skull's
mesh: each vertex's ray from the inner skull's centroid to the head surface gives the local
skull + scalp thickness, clamped to 6-16 mm (the ray leaves through the neck below the skull)
and smoothed over the surface; the scalp lies that far out, the outer skull 45 % of the way.
The surfaces stay nested and fold-free, and over the electrodes the scalp is fsaverage's own.
Conductivities 0.3 / 0.006 / 0.3 S/m (MNE's defaults), surfaces at ico-3 (1280 triangles each:
the solution is 30 MB and takes seconds; ico-4 would be 470 MB). The solution is cached in the
user cache; MNE's ``fsaverage-trans.fif`` places the standard montages.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

__all__ = ["CONDUCTIVITY", "ICO", "fsaverage_bem", "fsaverage_surfaces", "fsaverage_trans_path"]

#: Brain, skull, scalp conductivities (S/m).
CONDUCTIVITY = (0.3, 0.006, 0.3)
#: Subdivision of the BEM surfaces.
ICO = 3
#: Skull + scalp thickness bounds (m) and the skull's share of it.
_GAP = (0.006, 0.016)
_SKULL_SHARE = 0.45


def _data_dir() -> Path:
    import mne

    return Path(os.path.dirname(mne.__file__)) / "data" / "fsaverage"


def fsaverage_trans_path() -> Path:
    """MNE's head <-> MRI transform of fsaverage (for the standard montages)."""
    return _data_dir() / "fsaverage-trans.fif"


def fsaverage_surfaces() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``inner_skull``, ``outer_skull``, ``outer_skin``: (vertices in metres, MRI = MNI305
    frame; triangles), all on the inner skull's ico-5 mesh (see the module docstring)."""
    import mne
    import scipy.sparse as sp
    import trimesh

    d = _data_dir()
    inner = mne.read_bem_surfaces(str(d / "fsaverage-inner_skull-bem.fif"), verbose="error")[0]
    head = mne.read_bem_surfaces(str(d / "fsaverage-head.fif"), verbose="error")[0]
    rr, tris = np.asarray(inner["rr"], float), np.asarray(inner["tris"], np.int64)
    c = rr.mean(axis=0)
    dirs = rr - c
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hm = trimesh.Trimesh(head["rr"], head["tris"], process=False)
    locs, idx, _ = hm.ray.intersects_location(np.repeat(c[None], len(dirs), axis=0), dirs, multiple_hits=False)
    gap = np.full(len(rr), _GAP[1])
    gap[idx] = np.linalg.norm(locs - rr[idx], axis=1)
    gap = np.clip(gap, *_GAP)
    n = len(rr)
    e = np.r_[tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]
    adj = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n)).tocsr()
    adj.data[:] = 1.0
    deg = np.asarray(adj.sum(axis=1)).ravel()
    for _ in range(30):
        gap = 0.5 * gap + 0.5 * (adj @ gap) / deg
    return {"inner_skull": (rr, tris), "outer_skull": (rr + _SKULL_SHARE * gap[:, None] * dirs, tris),
            "outer_skin": (rr + gap[:, None] * dirs, tris)}


def _cache_dir() -> Path:
    from appeal.datasets import user_cache_dir

    return user_cache_dir().parent / "fsaverage-bem"


def fsaverage_bem(cache: Path | None = None) -> Path:
    """The three-layer fsaverage BEM solution file, made once and cached (``-bem-sol.fif``)."""
    import mne

    from appeal.logs import logger

    key = hashlib.sha256(repr((mne.__version__, CONDUCTIVITY, _GAP, _SKULL_SHARE, ICO)).encode()).hexdigest()[:12]
    cache = Path(cache) if cache is not None else _cache_dir()
    out = cache / f"fsaverage-3layer-ico{ICO}-{key}-bem-sol.fif"
    if out.is_file():
        return out
    subjects = cache / f"subjects-{key}"
    bem_dir = subjects / "fsaverage" / "bem"
    bem_dir.mkdir(parents=True, exist_ok=True)
    for name, (rr, tris) in fsaverage_surfaces().items():
        mne.write_surface(str(bem_dir / f"{name}.surf"), rr * 1e3, tris, overwrite=True)  # FreeSurfer: mm
    logger.info("fsaverage BEM: solving the three-layer model once, cached in %s", cache)
    model = mne.make_bem_model("fsaverage", ico=ICO, conductivity=CONDUCTIVITY, subjects_dir=str(subjects), verbose="error")
    sol = mne.make_bem_solution(model, verbose="error")
    tmp = out.with_name(out.name.replace("-bem-sol.fif", ".part-bem-sol.fif"))
    mne.write_bem_solution(str(tmp), sol, overwrite=True, verbose="error")
    os.replace(tmp, out)
    return out
