"""Measuring a mimicry (Nagle et al. §5.1): a person's frames mimicking a source sequence, projected
into the source person's expression space and compared with the source's own loadings.

``appeal stimuli morphpca mimicry`` calls :func:`measure_mimicry`; the measures themselves are
:mod:`stimulus_engine.morphpca.mimicry`. Either sequence may be frame images or a video file
(:func:`~.frame_source.read_frames`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["mimicry_frames", "measure_mimicry", "plot_loadings"]


def mimicry_frames(source_frames: Sequence[str | Path], mimic_frames: Sequence[str | Path], ma, mb):
    """The source frames at model A's size and the mimic frames at model B's (:class:`~.frame_source.Frames`,
    from image files, folders or videos), one mimic frame per source frame (one-line error otherwise)."""
    from stimulus_engine.morphpca.frame_source import read_frames

    sf = read_frames(source_frames, ma.size, "--source")
    mf = read_frames(mimic_frames, mb.size, "--mimic")
    if len(sf) != len(mf):
        raise AppealInputError(f"--mimic: expected one mimic frame per source frame ({len(sf)}), got {len(mf)}")
    if len(sf) < 2:
        raise AppealInputError(f"--source: expected a sequence of at least 2 frames (got {len(sf)})")
    return sf, mf


def plot_loadings(source: np.ndarray, mimic: np.ndarray, variances: np.ndarray, path: Path, n: int = 4) -> Path:
    """The first ``n`` components' loadings over the frames (in standard deviations): source solid,
    mimic dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = min(n, source.shape[1])
    sd = np.sqrt(np.maximum(np.asarray(variances, float)[:k], 1e-30))
    fig, axes = plt.subplots(k, 1, figsize=(6.4, 1.5 * k + 0.6), sharex=True, squeeze=False)
    for j, ax in enumerate(axes[:, 0]):
        ax.plot(source[:, j] / sd[j], "-", color="#2a4d80", label="source")
        ax.plot(mimic[:, j] / sd[j], "--", color="#c06010", label="mimic (projected)")
        ax.set_ylabel(f"PC{j + 1} (SD)")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("frame")
    fig.suptitle("loadings in the source's expression space", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return path


def measure_mimicry(ma, mb, sf, mf, out: Path, *, align: bool = True,
                    bins: int | None = None) -> dict:
    """Compare a mimicry with its source in the source's expression space.

    Parameters
    ----------
    ma, mb : MorphModel
        Morph-PCA models (``appeal stimuli morphpca build``) of the source person (A) and of the
        person mimicking (B).
    sf, mf : Frames
        The source sequence at A's size and its mimicry at B's, one mimic frame per source frame
        (:func:`mimicry_frames`).
    out : Path
        An existing output folder: ``loadings_source.csv``, ``loadings_mimic.csv`` (the mimic
        projected into A), ``frames.csv`` (per-frame distances and correlation),
        ``components.csv`` (per component: correlation over time, entropies, mutual
        information), ``loadings.png``, ``sheet.png`` (source / mimic / mimic on A's face).
    align : bool
        Faceframe alignment between the models (Nagle §3).
    bins : int, optional
        Histogram bins of the information measures.

    Returns
    -------
    dict
        Summary: frames, components, mean distances, correlations and normalised MI, seconds.
    """
    import pandas as pd

    from stimulus_engine.morphpca.mimicry import (
        component_correlations,
        information_measures,
        mimicry_measures,
        save_contact_sheet,
    )
    from stimulus_engine.morphpca.project import project_expression

    t0 = time.perf_counter()
    src, mim = sf.images, mf.images
    la = ma.project(ma.encode(src))
    proj = project_expression(mim, mb, ma, align=align)
    lm = proj.loadings
    cols = [f"pc{j + 1}" for j in range(la.shape[1])]
    pd.DataFrame(la, columns=cols).assign(frame=sf.names).to_csv(out / "loadings_source.csv", index=False)
    pd.DataFrame(lm, columns=cols).assign(frame=mf.names).to_csv(out / "loadings_mimic.csv", index=False)
    frames = mimicry_measures(la, lm, ma.variances)
    frames.to_csv(out / "frames.csv", index=False)
    comps = component_correlations(la, lm).merge(information_measures(la, lm, bins), on="component")
    comps.to_csv(out / "components.csv", index=False)
    plot_loadings(la, lm, ma.variances, out / "loadings.png")
    pick = np.unique(np.linspace(0, len(sf) - 1, min(8, len(sf))).round().astype(int))
    save_contact_sheet(out / "sheet.png", [src[pick], mim[pick], proj.images[pick]],
                       ["source A", "mimic B", "B on A"], [Path(sf.names[i]).stem for i in pick])
    summary = {"frames": len(sf), "components": int(la.shape[1]),
               "mean_euclidean": float(frames["euclidean"].mean()),
               "mean_normalised_distance": float(frames["normalised"].mean()),
               "mean_frame_correlation": float(frames["correlation"].mean()),
               "mean_component_correlation": float(comps["correlation"].mean()),
               "mean_normalised_mi": float(comps["normalised_mi"].mean()),
               "seconds": time.perf_counter() - t0}
    (out / "mimicry.json").write_text(json.dumps(summary, indent=1))
    return summary
