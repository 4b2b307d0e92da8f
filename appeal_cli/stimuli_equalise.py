"""``appeal stimuli equalise``: SHINE-style luminance, histogram or spectrum equalisation of a grid or of photographs."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import click

from appeal.cells import write_table
from appeal.errors import AppealInputError
from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options


def _parse_background(value: str) -> float | None:
    """``--background``: a grey fraction 0..1, or ``keep`` (None: original pixels outside the face)."""
    if value.strip().lower() == "keep":
        return None
    try:
        b = float(value)
    except ValueError:
        raise AppealInputError(f"--background {value}: expected a grey fraction 0..1 (0.5 = 50% grey) or 'keep'") \
            from None
    if not 0.0 <= b <= 1.0:
        raise AppealInputError(f"--background {value}: expected a grey fraction 0..1 (0.5 = 50% grey) or 'keep'")
    return b


def _face_masks(folder: Path, images: list, files: list[str], region: str) -> tuple[list, str]:
    """The masks to equalise inside and how they were made: ``region == "image"``, every whole
    image; else a rendered grid's from ``folder/grid.json`` (:func:`stimulus_engine.audit.masks.rendered_face_mask`:
    the framing's face oval minus the background), else photographs' from their dlib landmarks
    (the convex hull, :func:`stimulus_engine.audit.masks.landmark_face_mask`), as
    ``appeal stimuli audit`` makes them; an image without a face (a house, an object, noise) is
    matched as a whole, and one warning line lists those."""
    import numpy as np

    from stimulus_engine.audit.masks import (grid_render_settings, landmark_face_mask, landmarks_or_none,
                                             rendered_face_mask, warn_faceless, whole_image_mask)

    if region == "image":
        return [whole_image_mask(im.shape) for im in images], "whole images"
    render = grid_render_settings(folder)
    if render is None:
        masks, faceless = [], []
        for im, f in zip(images, files):
            landmarks = landmarks_or_none(im, f)
            masks.append(whole_image_mask(im.shape) if landmarks is None else landmark_face_mask(im.shape, landmarks))
            if landmarks is None:
                faceless.append(f)
        warn_faceless(faceless, len(files), "matched as whole images")
        return masks, "landmarks" + (f", {len(faceless)} whole images" if faceless else "")
    size = (int(render["height"]), int(render["width"]))
    return [rendered_face_mask(im, render["width"], render["height"], render["eye_row"], render["face_fraction"],
                               tuple(render["background"])) if im.shape[:2] == size
            else np.zeros(im.shape[:2], bool)  # check_set names the size mismatch
            for im in images], "rendered"


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli equalise stimuli/exp2/manifest.csv --match luminance --out stimuli/exp2_lum
  appeal stimuli equalise stimuli/exp2/manifest.csv --match histogram --grey --out stimuli/exp2_hist
  appeal stimuli equalise stimuli/erp/manifest.csv --match spectrum --background keep --out stimuli/erp_spec
  appeal stimuli equalise aligned/manifest.csv --match spectrum --grey --out aligned_spec   # photographs
  appeal stimuli equalise n170.csv --match luminance --region image --out n170_lum   # faces and houses, whole""")
@click.argument("manifest", metavar="MANIFEST", type=click.Path(path_type=Path))
@click.option("--match", "method", required=True, type=click.Choice(["luminance", "histogram", "spectrum"]),
              help="luminance: masked mean and SD of L*; histogram: exact masked L* histogram; "
                   "spectrum: Fourier amplitude spectrum.")
@click.option("--grey", is_flag=True, help="Write grey images (exact 8-bit histograms); default: keep the colour.")
@click.option("--background", "background", default="0.5", show_default=True, metavar="FRACTION|keep",
              help="Grey outside the face (0.5 = 8-bit 128), or 'keep' the original pixels.")
@click.option("--region", type=click.Choice(["face", "image"]), default="face", show_default=True,
              help="face: inside each face mask (an image without a face as a whole); image: every whole image.")
@out_options()
def equalise(manifest: Path, method: str, grey: bool, background: str, region: str, out: Path, force: bool,
             resume: bool) -> None:
    """Equalise the luminance of a stimulus set's faces (SHINE: lumMatch, histMatch, specMatch).

    \b
    Reads MANIFEST (a manifest.csv with a 'file' column; images relative to its folder) and,
    for a rendered grid, the grid.json beside it (the face mask: the framing oval, less the
    background pixels); without one (photographs, e.g. appeal faces outputs) each face's mask
    is the convex hull of its dlib landmarks, and an image without a face (the houses, objects
    or scrambled faces of a control category) is matched as a whole image, listed in one
    warning line; --region image matches every image as a whole. Works on CIE L*
    only, keeping a* and b* (or grey with --grey); see stimulus_engine.audit.equalise.
    Writes the equalised images under DIR with the same relative file names, DIR/manifest.csv
    (the same columns plus 'equalised' and 'ssim', the SSIM of each image's L* to its
    original) so a protocol can point to it unchanged, and copies of landmarks.csv and grid.json
    (pixels do not move: appeal stimuli audit DIR measures the equalised set inside the same
    face masks). Nothing is written when an input is bad.
    """
    import numpy as np
    import pandas as pd

    from appeal.outputs import output_run
    from stimulus_engine.audit.equalise import equalise as run_equalise
    from stimulus_engine.render import save_png

    bg = _parse_background(background)
    manifest = Path(manifest)
    if not manifest.is_file():
        raise AppealInputError(f"{manifest}: manifest not found (expected DIR/manifest.csv of a rendered grid)")
    try:
        table = pd.read_csv(manifest)
    except (ValueError, pd.errors.ParserError) as exc:
        raise AppealInputError(f"{manifest}: {exc}".splitlines()[0]) from None
    if "file" not in table.columns:
        raise AppealInputError(f"{manifest}: no 'file' column (expected a grid manifest)")
    folder = manifest.parent
    files = [str(f) for f in table["file"]]
    for f in files:
        if Path(f).is_absolute() or ".." in Path(f).parts:
            raise AppealInputError(f"{manifest}: file {f}: expected a path relative to the manifest's folder")
        if not (folder / f).is_file():
            raise AppealInputError(f"{folder / f}: image not found (listed in {manifest})")
    from stimulus_engine.audit.workflow import read_rgb

    images = [read_rgb(folder / f) for f in files]
    masks, mask_kind = _face_masks(folder, images, files, region)
    results, ssims = run_equalise(images, masks, method, grey=grey, background=bg, names=files)

    label = f"{method} (grey)" if grey else method
    new = table.copy()
    new["equalised"] = label
    new["ssim"] = np.round(ssims, 4)
    inputs = [manifest, *([folder / "grid.json"] if mask_kind == "rendered" else []), *(folder / f for f in files)]
    with output_run(out, force=force, resume=resume, inputs=inputs) as run:
        run.extra.update({"equalised": label, "background": "keep" if bg is None else bg, "images": len(files),
                          "face_masks": mask_kind})
        tmp = Path(tempfile.mkdtemp(prefix=".equalise-", dir=run.out))
        try:
            for f, im in zip(files, results):
                save_png(im, tmp / f)
            for name in ("landmarks.csv", "grid.json"):  # the framing is unchanged: the audit finds the same masks
                if (folder / name).is_file():
                    shutil.copyfile(folder / name, tmp / name)
            for entry in sorted(tmp.iterdir()):
                dest = run.out / entry.name
                if dest.is_dir() and not dest.is_symlink():
                    shutil.rmtree(dest)
                os.replace(entry, dest)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        write_table(new, run.out / "manifest.csv")
        click.echo(f"{len(files)} images equalised ({label}) -> {run.out}; manifest {run.out / 'manifest.csv'}; "
                   f"SSIM to the originals mean {np.mean(ssims):.3f}, min {np.min(ssims):.3f}")
