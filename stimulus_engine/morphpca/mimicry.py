"""Mimicry measures (Nagle et al. §5.1) and side-by-side contact sheets.

A source sequence and its mimicry are both expressed in the source's expression space (the
mimic projected there); the loading sequences are compared frame by frame (Euclidean and
variance-normalised distances, correlation across components) and component by component
(correlation over time, and the information measures the paper names: each sequence's Shannon
entropy and their mutual information, from a joint histogram of the two loadings; the
normalised mutual information I / √(H_source · H_mimic) is 1 for a perfect (or any one-to-one)
mimicry and 0 for an unrelated one).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from appeal.errors import AppealInputError

__all__ = ["mimicry_measures", "component_correlations", "information_measures", "contact_sheet", "save_contact_sheet"]


def _check_pair(source: np.ndarray, mimic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.atleast_2d(np.asarray(source, float)), np.atleast_2d(np.asarray(mimic, float))
    if a.shape != b.shape:
        raise AppealInputError(f"loadings: source {a.shape} and mimic {b.shape} sequences differ in shape "
                               "(expected the same frames × components)")
    return a, b


def _corr(x: np.ndarray, y: np.ndarray) -> float:
    x, y = x - x.mean(), y - y.mean()
    den = np.sqrt((x * x).sum() * (y * y).sum())
    return float((x * y).sum() / den) if den > 0 else float("nan")


def mimicry_measures(source: np.ndarray, mimic: np.ndarray, variances: np.ndarray | None = None) -> pd.DataFrame:
    """Per-frame distance and correlation between two loading sequences ``(frames, k)``.

    Returns
    -------
    DataFrame
        One row per frame: ``frame``, ``euclidean`` (‖a − b‖), ``normalised`` (the distance in
        standard deviations of each component, when ``variances`` are given, else NaN) and
        ``correlation`` (Pearson r of a and b across components).
    """
    a, b = _check_pair(source, mimic)
    diff = a - b
    if variances is not None:
        v = np.asarray(variances, float)[: a.shape[1]]
        normalised = np.sqrt((diff**2 / np.maximum(v, 1e-30)).sum(axis=1))
    else:
        normalised = np.full(len(a), np.nan)
    return pd.DataFrame({"frame": np.arange(len(a)), "euclidean": np.linalg.norm(diff, axis=1),
                         "normalised": normalised, "correlation": [_corr(x, y) for x, y in zip(a, b)]})


def component_correlations(source: np.ndarray, mimic: np.ndarray) -> pd.DataFrame:
    """Correlation over time of each component's loadings (``component``, ``correlation``)."""
    a, b = _check_pair(source, mimic)
    return pd.DataFrame({"component": np.arange(a.shape[1]),
                         "correlation": [_corr(a[:, j], b[:, j]) for j in range(a.shape[1])]})


def _entropy_bits(counts: np.ndarray) -> float:
    p = counts[counts > 0] / counts.sum()
    return max(0.0, float(-(p * np.log2(p)).sum()))


def information_measures(source: np.ndarray, mimic: np.ndarray, bins: int | None = None) -> pd.DataFrame:
    """Shannon entropies and mutual information of each component's loadings over time.

    Each component's two sequences are binned together (``bins`` equal-width bins over their
    joint range; default ⌈√frames⌉, at least 2); the measures come from the joint histogram.

    Returns
    -------
    DataFrame
        One row per component: ``component``, ``entropy_source``, ``entropy_mimic``,
        ``mutual_information`` (bits) and ``normalised_mi`` (I / √(H_s H_m); NaN where an
        entropy is 0).
    """
    a, b = _check_pair(source, mimic)
    n = a.shape[0]
    if n < 2:
        raise AppealInputError(f"loadings: information measures need at least 2 frames (got {n})")
    k = int(bins) if bins else max(2, int(np.ceil(np.sqrt(n))))
    rows = []
    for j in range(a.shape[1]):
        lo, hi = min(a[:, j].min(), b[:, j].min()), max(a[:, j].max(), b[:, j].max())
        edges = np.linspace(lo, hi if hi > lo else lo + 1.0, k + 1)
        joint = np.histogram2d(a[:, j], b[:, j], bins=[edges, edges])[0]
        hs, hm, hj = _entropy_bits(joint.sum(axis=1)), _entropy_bits(joint.sum(axis=0)), _entropy_bits(joint.ravel())
        mi = max(hs + hm - hj, 0.0)
        rows.append({"component": j, "entropy_source": hs, "entropy_mimic": hm, "mutual_information": mi,
                     "normalised_mi": mi / np.sqrt(hs * hm) if hs > 0 and hm > 0 else float("nan")})
    return pd.DataFrame(rows)


def contact_sheet(rows: Sequence[Sequence[np.ndarray]], row_labels: Sequence[str] = (),
                  col_labels: Sequence[str] = (), gap: int = 4) -> np.ndarray:
    """A uint8 grid of images (rows × columns, each resized to the first's size) with optional text labels."""
    first = np.asarray(rows[0][0])
    h, w = first.shape[:2]
    ncol = max(len(r) for r in rows)
    left = 90 if row_labels else 0
    top = 18 if col_labels else 0
    sheet = np.full((top + len(rows) * (h + gap), left + ncol * (w + gap), 3), 255, np.uint8)
    for i, row in enumerate(rows):
        for j, img in enumerate(row):
            im = np.asarray(img)
            if im.dtype != np.uint8:
                im = np.clip(im * 255.0 + 0.5, 0, 255).astype(np.uint8)
            if im.shape[:2] != (h, w):
                im = cv2.resize(im, (w, h), interpolation=cv2.INTER_AREA)
            y0, x0 = top + i * (h + gap), left + j * (w + gap)
            sheet[y0 : y0 + h, x0 : x0 + w] = im
        if i < len(row_labels):
            cv2.putText(sheet, str(row_labels[i])[:12], (3, top + i * (h + gap) + h // 2), cv2.FONT_HERSHEY_SIMPLEX,
                        0.4, (0, 0, 0), 1, cv2.LINE_AA)
    for j, lab in enumerate(col_labels):
        cv2.putText(sheet, str(lab)[:30], (left + j * (w + gap) + 2, 13), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1,
                    cv2.LINE_AA)
    return sheet


def save_contact_sheet(path: str | Path, rows: Sequence[Sequence[np.ndarray]], row_labels: Sequence[str] = (),
                       col_labels: Sequence[str] = ()) -> Path:
    """Write :func:`contact_sheet` as PNG."""
    from stimulus_engine.morphpca.io import save_image

    return save_image(path, contact_sheet(rows, row_labels, col_labels))
