"""``appeal faces align | average | continuum | mask``: WebMorph-style operations on landmarked photographs."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import click

from appeal.errors import AppealInputError

from appeal_cli.groups import CONTEXT, faces
from appeal_cli.options import out_options

F = Callable[..., Any]

def templates_help(same: str = "All images of one call") -> str:
    """The help text every ``appeal faces`` command ends with: templates in, files out."""
    return f"""\b
Templates: each image's .tem beside it (WebMorph/Psychomorph, e.g. the 189-point FRL
template; pupils = points 0 and 1); an image without one gets dlib's 68 detected
landmarks. {same} must use the same template type.

\b
Writes DIR/<name>.png + <name>.tem per output, DIR/manifest.csv (file, tem, operation,
inputs, parameters, ...: one row per output; 'appeal stimuli audit DIR' reads it) and
DIR/contact_sheet.png."""


def _manifest_files(manifest: Path) -> list[Path]:
    import pandas as pd

    try:
        table = pd.read_csv(manifest)
    except (ValueError, pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise AppealInputError(f"{manifest}: not a readable CSV ({exc})".splitlines()[0]) from None
    if "file" not in table.columns or table.empty:
        raise AppealInputError(f"{manifest}: no 'file' column or no rows (expected an 'appeal faces' manifest)")
    return [manifest.parent / str(f) for f in table["file"]]


def image_files(sources: Sequence[Path]) -> list[Path]:
    """The image files the arguments name: files, folders (an earlier call's folder: its manifest's
    files), ``data:`` references (groups such as ``data:london-frl-all/neutral_front`` included)
    and glob patterns."""
    from appeal.datasets import expand_inputs
    from stimulus_engine.morphpca.io import IMAGE_SUFFIXES

    files: list[Path] = []
    for s in expand_inputs(sources):
        if s.is_dir() and (s / "manifest.csv").is_file():  # an earlier call's outputs: its manifest's files
            files.extend(_manifest_files(s / "manifest.csv"))
        elif s.is_dir():
            found = sorted(p for p in s.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
            if not found:
                raise AppealInputError(f"{s}: no images in this folder (expected .jpg or .png files)")
            files.extend(found)
        elif not s.is_file():
            raise AppealInputError(f"{s}: image file not found")
        else:
            files.append(s)
    return files


def _parse_size(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w < 8 or h < 8:
            raise ValueError
    except ValueError:
        raise AppealInputError(f"--size: cannot read '{text}' (expected WIDTHxHEIGHT in pixels, e.g. 600x800)") from None
    return w, h


def _parse_eyes(text: str | None, size: tuple[int, int]):
    import numpy as np

    if text is None:
        return None
    try:
        v = [float(x) for x in text.split(",")]
        if len(v) != 4:
            raise ValueError
    except ValueError:
        raise AppealInputError(f"--eyes: cannot read '{text}' (expected LX,LY,RX,RY as fractions of the output "
                               "width and height, e.g. 0.4,0.45,0.6,0.45)") from None
    if v[0] >= v[2]:
        raise AppealInputError(f"--eyes: the image-left pupil ({v[0]}) must be left of the other ({v[2]})")
    return np.array([[v[0] * size[0], v[1] * size[1]], [v[2] * size[0], v[3] * size[1]]])


def align_options(f: F) -> F:
    f = click.option("--fill", default="white", show_default=True, metavar="COLOUR",
                     help="Background of areas the moved image does not cover: white, black, grey, #RRGGBB, "
                          "R,G,B, or edge (repeat the image's edge pixels: no frame lines in composites).")(f)
    f = click.option("--eyes", default=None, metavar="LX,LY,RX,RY",
                     help="Pupil positions as fractions of the output width/height (default: the images' mean "
                          "pupil positions, scaled to --size).")(f)
    f = click.option("--size", default=None, metavar="WxH",
                     help="Output size in pixels, e.g. 600x800 (default: the first image's size).")(f)
    return f


def _aligned(faces_: list, size_text: str | None, eyes_text: str | None, fill_text: str):
    """Faces aligned as the options say: (images, points, parameters)."""
    from stimulus_engine.faces2d.align import align_face, default_eyes
    from stimulus_engine.faces2d.outputs import parse_colour

    fill = None if fill_text.strip().lower() == "edge" else parse_colour(fill_text)
    size = _parse_size(size_text)
    out_size = size or faces_[0].size
    eyes = _parse_eyes(eyes_text, out_size)
    if eyes is None:
        eyes = default_eyes(faces_, size)
    moved = [align_face(f.image, f.points, eyes, out_size, fill) for f in faces_]
    params = {"size": list(out_size), "eyes_px": [round(float(v), 3) for v in eyes.ravel()], "fill": fill_text}
    return [m[0] for m in moved], [m[1] for m in moved], params


def _prepared(faces_: list, align: bool, size: str | None, eyes: str | None, fill: str, what: str):
    from stimulus_engine.faces2d.align import same_size

    if align or size or eyes:
        return _aligned(faces_, size, eyes, fill)
    same_size(faces_, what)
    return [f.image for f in faces_], [f.points for f in faces_], {}


@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces align data/london/*.jpg --out aligned                 # mean pupil positions, input size
  appeal faces align photos/ --size 600x800 --eyes 0.4,0.45,0.6,0.45 --fill grey --out aligned""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@align_options
@out_options()
def align(images: tuple[Path, ...], size: str | None, eyes: str | None, fill: str, out: Path, force: bool,
          resume: bool) -> None:
    """Rotate, scale and move each image so its pupils land on the same positions.

    IMAGES are image files or folders of them (a folder an earlier 'appeal faces' call
    wrote: the files of its manifest.csv). The similarity transform puts both pupils
    exactly on the targets; templates move with the images.
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs

    files = image_files(images)
    faces_ = load_faces(files)
    with output_run(out, force=force, resume=resume, inputs=files) as run:
        imgs, pts, params = _aligned(faces_, size, eyes, fill)
        outs = [FaceOutput(f"{f.path.stem}.png", im, f.template.moved(p), [f.path])
                for f, im, p in zip(faces_, imgs, pts)]
        write_outputs(run.out, outs, "align", {**params, "template": faces_[0].source}, title="align")
        run.extra["images"] = len(outs)
        click.echo(f"aligned {len(outs)} images to {params['size'][0]}x{params['size'][1]} -> {run.out}")



@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces average aligned/*.png --out composite                  # images aligned already
  appeal faces average photos/ --align --size 600x800 --out composite --name female
  appeal faces average photos/ --align --colour-space linear --out composite""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--align", "do_align", is_flag=True, help="Align the images first (as 'appeal faces align'; implied "
                                                          "by --size or --eyes).")
@align_options
@click.option("--colour-space", type=click.Choice(["srgb", "linear"]), default="srgb", show_default=True,
              help="Average colours as sRGB values (as WebMorph/Psychomorph) or as linear light.")
@click.option("--texture/--no-texture", default=True, show_default=True,
              help="Restore the inputs' mean local contrast (skin and hair detail) in the composite, as "
                   "WebMorph's texture option (Tiddeman et al. 2001).")
@click.option("--name", default="composite", show_default=True, help="Output file name (without suffix).")
@out_options()
def average(images: tuple[Path, ...], do_align: bool, size: str | None, eyes: str | None, fill: str,
            colour_space: str, texture: bool, name: str, out: Path, force: bool, resume: bool) -> None:
    """Average faces into a composite: mean shape, mean colour, sharp features.

    The composite's template is the mean of the templates; each image is warped onto it
    (thin-plate spline) before the colours are averaged, so features stay single and sharp.
    Without --align the images must all have one size. Prints the ghosting index (0 =
    features as crisp as the inputs', ~0.5 doubled) beside a plain pixel average's.
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.composite import average_faces, composite_ghosting, pixel_average
    from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs

    files = image_files(images)
    faces_ = load_faces(files)
    imgs, pts, params = _prepared(faces_, do_align, size, eyes, fill, "averaging")
    with output_run(out, force=force, resume=resume, inputs=files) as run:
        comp, mean = average_faces(imgs, pts, colour_space=colour_space, texture=texture)
        ghost = composite_ghosting(comp, mean, imgs, pts)
        plain = composite_ghosting(pixel_average(imgs), mean, imgs, pts)
        o = FaceOutput(f"{name}.png", comp, faces_[0].template.moved(mean), files,
                       {"n_faces": len(files), "ghosting": round(ghost, 4), "ghosting_pixel_average": round(plain, 4)})
        write_outputs(run.out, [o], "average", {**params, "colour_space": colour_space, "texture": texture,
                                                "template": faces_[0].source}, title=f"average of {len(files)}")
        run.extra.update(faces=len(files), ghosting=ghost, ghosting_pixel_average=plain)
        click.echo(f"composite of {len(files)} faces -> {run.out / o.name} (ghosting {ghost:.3f}; "
                   f"plain pixel average {plain:.3f})")



@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces continuum composite_f.png composite_m.png --steps 7 --out f2m
  appeal faces continuum a.jpg b.jpg --steps 11 --align --size 600x800 --out a2b""")
@click.argument("face_a", type=click.Path(path_type=Path))
@click.argument("face_b", type=click.Path(path_type=Path))
@click.option("--steps", type=click.IntRange(min=2), default=5, show_default=True,
              help="Images from A to B, both ends included.")
@click.option("--align", "do_align", is_flag=True, help="Align both images first (implied by --size or --eyes).")
@align_options
@click.option("--colour-space", type=click.Choice(["srgb", "linear"]), default="srgb", show_default=True,
              help="Cross-dissolve in sRGB values (as WebMorph) or in linear light.")
@out_options()
def continuum(face_a: Path, face_b: Path, steps: int, do_align: bool, size: str | None, eyes: str | None, fill: str,
              colour_space: str, out: Path, force: bool, resume: bool) -> None:
    """Morph FACE_A into FACE_B in --steps images (shape and colour together).

    Step i has weight t = i/(steps-1) of B: the template is (1-t) A + t B, both images are
    warped onto it and cross-dissolved (1-t, t). Without --align both images must have
    one size.
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.continuum import continuum as make_continuum
    from stimulus_engine.faces2d.continuum import continuum_weights
    from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs

    files = image_files([face_a, face_b])
    faces_ = load_faces(files)
    imgs, pts, params = _prepared(faces_, do_align, size, eyes, fill, "a continuum")
    with output_run(out, force=force, resume=resume, inputs=files) as run:
        frames = make_continuum(imgs[0], pts[0], imgs[1], pts[1], steps, colour_space=colour_space)
        stem = f"{files[0].stem}-{files[1].stem}"
        outs = [FaceOutput(f"{stem}_{i:02d}.png", im, faces_[0].template.moved(p), files,
                           {"step": i, "weight": round(float(t), 6)})
                for i, ((im, p), t) in enumerate(zip(frames, continuum_weights(steps)))]
        write_outputs(run.out, outs, "continuum", {**params, "steps": steps, "colour_space": colour_space,
                                                   "template": faces_[0].source},
                      title=f"{files[0].name} -> {files[1].name}", ncols=min(steps, 8))
        run.extra["images"] = len(outs)
        click.echo(f"continuum of {steps} images {files[0].name} -> {files[1].name} -> {run.out}")



@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces mask aligned/ --out masked                              # soft oval on white
  appeal faces mask composite.png --kind hull --feather 20 --fill transparent --out masked""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--kind", type=click.Choice(["oval", "hull"]), default="oval", show_default=True,
              help="oval: the ellipse inscribed in the face points' bounding box; hull: their convex hull.")
@click.option("--feather", type=click.FloatRange(min=0), default=10.0, show_default=True, metavar="PX",
              help="Width of the soft edge in pixels (0: hard).")
@click.option("--fill", default="white", show_default=True, metavar="COLOUR",
              help="Background: white, black, grey, #RRGGBB, R,G,B, or 'transparent' (RGBA PNG, mask as alpha).")
@out_options()
def mask(images: tuple[Path, ...], kind: str, feather: float, fill: str, out: Path, force: bool,
         resume: bool) -> None:
    """Mask each face: keep the face (oval or landmark hull, soft edge), replace the rest.

    Face points: the face outline and hairline of a 189-point FRL template (no ears, hair
    or neck); all 68 dlib points otherwise. Templates are copied unchanged.
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.mask import apply_mask, face_mask
    from stimulus_engine.faces2d.outputs import FaceOutput, parse_colour, write_outputs

    colour = None if fill.strip().lower() == "transparent" else parse_colour(fill)
    files = image_files(images)
    faces_ = load_faces(files)
    with output_run(out, force=force, resume=resume, inputs=files) as run:
        outs = []
        for f in faces_:
            m = face_mask(f.image.shape[:2], f.points, kind, feather)
            outs.append(FaceOutput(f"{f.path.stem}.png", apply_mask(f.image, m, colour), f.template, [f.path]))
        write_outputs(run.out, outs, "mask", {"kind": kind, "feather": feather, "fill": fill,
                                              "template": faces_[0].source}, title=f"mask ({kind})")
        run.extra["images"] = len(outs)
        click.echo(f"masked {len(outs)} images ({kind}, feather {feather:g} px) -> {run.out}")


for _cmd in (align, average, continuum, mask):
    _cmd.help = (_cmd.help or "").rstrip() + "\n\n" + templates_help()
