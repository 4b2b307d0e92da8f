"""Audit a stimulus set: the low-level measures of every image, one tidy row per image.

:func:`read_audit_inputs` checks a grid's ``manifest.csv`` (or a grid's output folder, or a
plain folder of images) before anything is written; :func:`run_audit` measures every image
(:mod:`stimulus_engine.audit.measures`) inside its face mask (:mod:`stimulus_engine.audit.masks`)
and the whole image; :func:`audit_manifest` does both; :func:`plot_audit` draws each main
measure's mean per level of every factor.

An animated grid's rows point to ``.mp4`` clips: their apex frame (``frames/frame_XXXXX.png``
at the row's ``apex_frame``) is audited. Rows with ``shape == photograph``, every image of a
plain folder and every image of a manifest without a grid's ``grid.json`` are photographs: their
face mask is the convex hull of the 68 dlib landmarks. An image in which dlib finds no face (the
houses, objects or scrambled faces of a control category, noise images) gets the whole-image
measures and NaN face measures (mask ``none``), and one warning line lists them all; a manifest
column such as ``category`` (face | house) is a factor like the grid's own, so faces and their
controls are tested against each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from appeal.errors import AppealInputError
from stimulus_engine.audit import masks as M
from stimulus_engine.audit import measures as X

__all__ = ["IMAGE_SUFFIXES", "FACTOR_COLUMNS", "MAIN_MEASURES", "WHOLE_IMAGE_MEASURES", "NO_FACE_WARNING", "AuditItem",
           "AuditJob", "read_audit_inputs", "read_rgb",
           "measure_image", "run_audit", "audit_manifest", "paired_factors", "declared_factors", "audit_factors",
           "plot_audit"]

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
#: A grid manifest's factor columns (those present are kept and plotted).
FACTOR_COLUMNS = ("category", "character", "shape", "stylisation", "material", "expression", "emotion", "lighting",
                  "shading")
#: The measures drawn by :func:`plot_audit`, with their axis labels.
MAIN_MEASURES = {"face_L_mean": "face L*", "face_rms_contrast": "face RMS contrast (sd L*/100)",
                 "spectrum_slope": "spectrum slope", "energy_high": "energy share >= 32 c/img",
                 "face_edge_density": "face edge density", "face_area": "face area (share)", "iod_px": "IOD (px)",
                 "eye_left_y": "left eye y (px from top)"}
#: Drawn as well when some images have no face: what faces and their controls are matched on.
WHOLE_IMAGE_MEASURES = {"image_L_mean": "image L*", "image_rms_contrast": "image RMS contrast"}
#: The ``warning`` of an image without a face.
NO_FACE_WARNING = "no face found by dlib: face measures NaN"


@dataclass(frozen=True, eq=False)
class AuditItem:
    """One image to audit: its manifest ``file``, the PNG/JPEG read, its manifest row, its mask kind
    and (a photograph's, found while checking the inputs) its 68 dlib landmarks."""

    file: str
    image: Path
    row: dict[str, Any] = field(default_factory=dict)
    #: "rendered" (face oval minus background), "landmarks" (convex hull) or "none" (no face found)
    mask: str = "landmarks"
    landmarks: np.ndarray | None = None


def _found(item: AuditItem) -> AuditItem:
    """``item`` with its landmarks, or with mask ``none`` when dlib finds no face in it (an unreadable
    image stays an input error)."""
    landmarks = M.landmarks_or_none(read_rgb(item.image), str(item.image))
    return AuditItem(item.file, item.image, item.row, item.mask if landmarks is not None else "none", landmarks)


def _with_landmarks(items: list[AuditItem]) -> list[AuditItem]:
    """Find every photograph's landmarks now (an unreadable image is an input error before any output);
    one warning line names the images without a face."""
    from appeal.progress import progress

    found = [_found(it) if it.mask == "landmarks" else it
             for it in progress(items, total=len(items), desc="landmarks", unit="image")]
    M.warn_faceless([it.file for it in found if it.mask == "none"], len(found),
                    "whole-image measures only, face measures NaN")
    return found


@dataclass(frozen=True)
class AuditJob:
    """The checked inputs of an audit: the images and, for a grid, its ``render`` settings."""

    source: Path
    items: list[AuditItem]
    render: dict[str, Any] | None = None
    factors: list[str] = field(default_factory=list)


def _is_photo(row: dict[str, Any]) -> bool:
    return any(str(row.get(c, "")).strip().lower() == "photograph" for c in ("shape", "shape_label"))


def _apex_png(folder: Path, row: dict[str, Any], manifest: Path) -> Path:
    if "apex_frame" not in row or pd.isna(row["apex_frame"]):
        raise AppealInputError(f"{manifest}: row {row['file']} is a clip but the manifest has no apex_frame column")
    frames = row.get("frames")
    frames = Path(str(frames)) if isinstance(frames, str) and frames else Path(str(row["file"])).with_suffix("")
    return folder / frames / f"frame_{int(row['apex_frame']):05d}.png"


def _read_render(manifest: Path) -> dict[str, Any] | None:
    return M.grid_render_settings(manifest.parent)


def _manifest_job(manifest: Path) -> AuditJob:
    try:
        table = pd.read_csv(manifest)
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise AppealInputError(f"{manifest}: not a readable CSV ({exc})".splitlines()[0]) from None
    if "file" not in table.columns:
        raise AppealInputError(f"{manifest}: no 'file' column (expected a grid's manifest.csv)")
    if table.empty:
        raise AppealInputError(f"{manifest}: no rows")
    render = _read_render(manifest)
    folder = manifest.parent
    items = []
    for row in table.to_dict("records"):
        rel = str(row["file"])
        image = _apex_png(folder, row, manifest) if rel.lower().endswith(".mp4") else folder / rel
        kind = "rendered" if render is not None and not _is_photo(row) else "landmarks"
        items.append(AuditItem(rel, image, row, kind))
    missing = [it.image for it in items if not it.image.is_file()]
    if missing:
        raise AppealInputError(f"{manifest}: {len(missing)} of {len(items)} images missing, first {missing[0]}")
    return AuditJob(manifest, _with_landmarks(items), render, [c for c in FACTOR_COLUMNS if c in table.columns])


def read_audit_inputs(source: Path) -> AuditJob:
    """Check what to audit: a manifest CSV, a folder holding ``manifest.csv``, or a folder of images.

    Raises
    ------
    AppealInputError
        One line: the path does not exist, is neither a CSV nor a folder, a manifest lacks its
        ``file`` column or some of its images, a folder holds no images, an image is not
        readable (photographs' landmarks are found here, once; those without a face are listed
        in one warning line and get mask ``none``).
    """
    source = Path(source)
    if not source.exists():
        raise AppealInputError(f"{source}: not found (expected a grid's manifest.csv or a folder of images)")
    if source.is_dir():
        if (source / "manifest.csv").is_file():
            return _manifest_job(source / "manifest.csv")
        images = sorted(p for p in source.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
        if not images:
            raise AppealInputError(f"{source}: no images ({', '.join(IMAGE_SUFFIXES)}) and no manifest.csv")
        return AuditJob(source, _with_landmarks([AuditItem(p.name, p, {"file": p.name}, "landmarks") for p in images]))
    if source.suffix.lower() != ".csv":
        raise AppealInputError(f"{source}: expected a manifest .csv or a folder of images")
    return _manifest_job(source)


def read_rgb(path: Path) -> np.ndarray:
    """An image file as RGB uint8 (one-line error naming an unreadable file)."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"))
    except (OSError, UnidentifiedImageError) as exc:
        raise AppealInputError(f"{path}: not a readable image ({exc})".splitlines()[0]) from None


def _prefixed(prefix: str, values: dict[str, float]) -> dict[str, float]:
    return {f"{prefix}_{k}": v for k, v in values.items()}


def measure_image(rgb: np.ndarray, face: np.ndarray | None, landmarks: np.ndarray | None) -> dict[str, float]:
    """Every measure of one image: colour, contrast and edges inside ``face`` and the whole image,
    the spectrum of the whole image, the face area and (with ``landmarks``, else NaN) the eyes.
    ``face=None`` (no face in the image): every ``face_`` measure and the face area are NaN.

    Columns: ``face_/image_`` + ``L_mean, a_mean, b_mean, rms_contrast, edge_density``;
    ``spectrum_slope``; ``energy_low, energy_mid, energy_high``; ``face_area``;
    ``eye_left_x, eye_left_y, eye_right_x, eye_right_y, iod_px`` (see :mod:`~stimulus_engine.audit.measures`).
    """
    lab = X.lab_image(rgb)
    lum = lab[..., 0] / 100.0
    whole = M.whole_image_mask(rgb.shape)
    out: dict[str, float] = {}
    nowhere = np.zeros(rgb.shape[:2], bool)  # an empty mask: NaN colour and edge measures
    for prefix, mask in (("face", nowhere if face is None else face), ("image", whole)):
        out.update(_prefixed(prefix, X.colour_stats(lab, mask)))
        out[f"{prefix}_edge_density"] = X.edge_density(lum, mask)
    out["spectrum_slope"] = X.spectrum_slope(lab[..., 0])
    out.update(_prefixed("energy", X.band_energy(lab[..., 0])))
    out["face_area"] = float("nan") if face is None else X.face_area(face)
    if landmarks is not None:
        out.update(X.eye_positions(landmarks))
    else:
        out.update({k: float("nan") for k in ("eye_left_x", "eye_left_y", "eye_right_x", "eye_right_y", "iod_px")})
    return out


def _audit_item(item: AuditItem, render: dict[str, Any] | None) -> dict[str, Any]:
    rgb = read_rgb(item.image)
    warning = ""
    face: np.ndarray | None
    if item.mask == "none":
        face, landmarks, warning = None, None, NO_FACE_WARNING
    elif item.mask == "rendered" and render is not None:
        face = M.rendered_face_mask(rgb, render["width"], render["height"], render["eye_row"],
                                    render["face_fraction"], tuple(render["background"]))
        landmarks = M.landmarks_or_none(rgb, str(item.image))
        warning = "" if landmarks is not None else "no face found by dlib: eye positions NaN"
    else:
        landmarks = item.landmarks if item.landmarks is not None else M.find_landmarks(rgb, str(item.image))
        face = M.landmark_face_mask(rgb.shape, landmarks)
    return {**item.row, "file": item.file, "image_file": str(item.image), "mask": item.mask,
            "width_px": rgb.shape[1], "height_px": rgb.shape[0], **measure_image(rgb, face, landmarks),
            "warning": warning}


def run_audit(job: AuditJob) -> pd.DataFrame:
    """One row per image of ``job``: its manifest columns, ``image_file`` (what was read),
    ``mask`` (rendered | landmarks | none), its size, the measures of :func:`measure_image` and ``warning``."""
    from appeal.progress import progress

    rows = [_audit_item(it, job.render) for it in progress(job.items, total=len(job.items), desc="audit",
                                                             unit="image")]
    table = pd.DataFrame(rows)
    table.attrs["factors"] = list(job.factors)
    return table


def audit_manifest(manifest_csv: Path) -> pd.DataFrame:
    """:func:`run_audit` of :func:`read_audit_inputs` (a manifest CSV, a grid's folder or a folder of images)."""
    return run_audit(read_audit_inputs(Path(manifest_csv)))


def paired_factors(table: pd.DataFrame, factors: list[str]) -> dict[str, str]:
    """Factors whose levels pair one to one with an earlier factor's (the same split of the images,
    e.g. the ERP grid's combined shape + material levels, or ``stylisation`` beside ``shape``):
    ``{paired factor: the earlier factor it repeats}``."""
    kept: list[str] = []
    out: dict[str, str] = {}
    for f in factors:
        sub = table[[f]].astype(str)
        for g in kept:
            pair = pd.DataFrame({"f": sub[f], "g": table[g].astype(str)})
            if (pair.groupby("g")["f"].nunique() == 1).all() and (pair.groupby("f")["g"].nunique() == 1).all():
                out[f] = g
                break
        else:
            kept.append(f)
    return out


def declared_factors(table: pd.DataFrame) -> list[str]:
    """The grid's factor columns with two levels or more (``table.attrs['factors']``, else
    :data:`FACTOR_COLUMNS` present)."""
    declared = table.attrs.get("factors") or [c for c in FACTOR_COLUMNS if c in table.columns]
    return [f for f in declared if f in table.columns and table[f].nunique(dropna=True) >= 2]


def audit_factors(table: pd.DataFrame) -> list[str]:
    """The factors to plot and test: :func:`declared_factors` less those that only repeat an
    earlier one (:func:`paired_factors`); none gives ``['file']`` (one level per image)."""
    factors = declared_factors(table)
    paired = paired_factors(table, factors)
    return [f for f in factors if f not in paired] or ["file"]


def plot_audit(table: pd.DataFrame, path: Path, factors: list[str] | None = None) -> Path:
    """Small multiples: a row per main measure (:data:`MAIN_MEASURES`), a column per factor; each
    panel shows every image (grey dots) and the mean per level (black line); without factors
    (``['file']``) one column with a point per image. Writes ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from appeal.levels import sort_levels

    factors = factors or audit_factors(table)
    labels = {**MAIN_MEASURES, **(WHOLE_IMAGE_MEASURES if "mask" in table and (table["mask"] == "none").any() else {})}
    measures = [m for m in labels if m in table.columns and table[m].notna().any()]
    per_image = factors == ["file"]  # no factors: one point per image, no line between them
    width = min(16.0, max(6.0, 0.22 * len(table) + 1.5)) if per_image else 2.6 * len(factors) + 0.8
    fig, axes = plt.subplots(len(measures), len(factors), figsize=(width, 1.55 * len(measures) + 0.8),
                             squeeze=False, sharey="row")
    for j, factor in enumerate(factors):
        levels = sort_levels(table[factor].dropna().unique())
        pos = {lv: k for k, lv in enumerate(levels)}
        x = table[factor].map(pos)
        for i, measure in enumerate(measures):
            ax = axes[i, j]
            ax.plot(x, table[measure], "o", color="0.7", ms=3, zorder=1)
            means = table.groupby(factor)[measure].mean()
            ax.plot(range(len(levels)), [means.get(lv, np.nan) for lv in levels], "o" if per_image else "-o",
                    color="k", ms=4, lw=1.2, zorder=2)
            ticks = range(0, len(levels), max(1, len(levels) // 40))  # at most about 40 labels
            ax.set_xticks(list(ticks))
            ax.set_xticklabels([str(levels[k]) for k in ticks] if i == len(measures) - 1 else [], rotation=30 if not
                               per_image else 90, ha="right" if not per_image else "center", fontsize=7)
            ax.set_xlim(-0.5, len(levels) - 0.5)
            ax.tick_params(axis="y", labelsize=7)
            ax.grid(axis="y", color="0.9", lw=0.6)
            if j == 0:
                ax.set_ylabel(labels[measure], fontsize=7.5)
            if i == 0:
                ax.set_title(factor, fontsize=9)
    what = "each image" if per_image else "mean per level (black), each image (grey)"
    fig.suptitle(f"Stimulus audit of {len(table)} images:\n{what}", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    path = Path(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
