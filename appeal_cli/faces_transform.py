"""``appeal faces transform | caricature | symmetrise``: prototype transforms, caricatures and symmetric faces."""

from __future__ import annotations

from pathlib import Path

import click

from appeal.errors import AppealInputError

from appeal_cli.groups import CONTEXT, faces
from appeal_cli.faces_ops import image_files, templates_help
from appeal_cli.options import out_options

def _numbers(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
        if not values:
            raise ValueError
    except ValueError:
        raise AppealInputError(f"{what}: cannot read '{text}' (expected numbers separated by commas, "
                               "e.g. -0.5,0.5)") from None
    return values


def _prototype(source: Path, like, what: str):
    """A prototype as (image, points, files): an image with its template, or the composite of a folder."""
    from stimulus_engine.faces2d.align import load_faces, read_face, same_size
    from stimulus_engine.faces2d.composite import average_faces

    detect = like.source != "tem"
    if source.is_dir():
        files = image_files([source])
        faces_ = load_faces(files, detect=detect)
        same_size(faces_, f"a composite for {what}")
        image, points = average_faces([f.image for f in faces_], [f.points for f in faces_])
        first = faces_[0]
    else:
        first = read_face(source, detect=detect)
        files, image, points = [source], first.image, first.points
    if len(points) != len(like.points):
        raise AppealInputError(f"{first.path}: template has {len(points)} points but {like.path.name}'s has "
                               f"{len(like.points)} ({what} must use the faces' template type)")
    return image, points, files


def _tag(prefix: str, v: float) -> str:
    return f"{prefix}{v:+.2f}"


@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces transform face.jpg --from female.png --to male.png --out masc           # 50% masculinised
  appeal faces transform faces/ --from female.png --to male.png --strength -0.5,0.5 --out sex
  appeal faces transform face.jpg --from young/ --to old/ --shape 1 --colour 0 --texture 0 --out age_shape""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--from", "proto_a", required=True, type=click.Path(path_type=Path), metavar="PROTOTYPE",
              help="Prototype A: an image with its template (e.g. a composite), or a folder (its composite is made).")
@click.option("--to", "proto_b", required=True, type=click.Path(path_type=Path), metavar="PROTOTYPE",
              help="Prototype B, the same way.")
@click.option("--shape", type=float, default=1.0, show_default=True, help="Shape weight (template += w (B - A)).")
@click.option("--colour", type=float, default=1.0, show_default=True,
              help="Colour weight (low-frequency colour difference B - A).")
@click.option("--texture", type=float, default=1.0, show_default=True,
              help="Texture weight (fine-detail amplitude ratio B / A, raised to w).")
@click.option("--strength", default="0.5", show_default=True, metavar="LIST",
              help="Comma-separated strengths; each output moves by strength x each weight (negative: towards A).")
@click.option("--region", type=click.Choice(["face", "image"]), default="face", show_default=True,
              help="Where colour and texture change: the face only (soft edge), or the whole image.")
@out_options()
def transform(images: tuple[Path, ...], proto_a: Path, proto_b: Path, shape: float, colour: float, texture: float,
              strength: str, region: str, out: Path, force: bool, resume: bool) -> None:
    """Move faces along the difference between two prototypes (e.g. female -> male composites).

    Shape: the template moves by w (B - A), the prototypes first aligned on the face's pupils.
    Colour: both prototypes are warped to the new shape and the difference of their
    heavily blurred colours is added. Texture: each Laplacian band of the face is scaled by
    the ratio of B's to A's local detail, to the power w (Tiddeman et al. 2001).
    Prototypes may be of any size; a folder's images must share one size.
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs
    from stimulus_engine.faces2d.transform import transform as move

    levels = _numbers(strength, "--strength")
    files = image_files(images)
    faces_ = load_faces(files)
    a_img, a_pts, a_files = _prototype(proto_a, faces_[0], "prototype --from")
    b_img, b_pts, b_files = _prototype(proto_b, faces_[0], "prototype --to")
    with output_run(out, force=force, resume=resume, inputs=[*files, *a_files, *b_files]) as run:
        outs = []
        for f in faces_:
            for s in levels:
                img, pts = move(f.image, f.points, a_img, a_pts, b_img, b_pts, shape=s * shape,
                                colour=s * colour, texture=s * texture, region=region)
                outs.append(FaceOutput(f"{f.path.stem}_{_tag('t', s)}.png", img, f.template.moved(pts),
                                       [f.path, proto_a, proto_b],
                                       {"strength": s, "shape": s * shape, "colour": s * colour,
                                        "texture": s * texture}))
        write_outputs(run.out, outs, "transform",
                      {"from": str(proto_a), "to": str(proto_b), "shape": shape, "colour": colour,
                       "texture": texture, "strength": levels, "region": region, "template": faces_[0].source},
                      title=f"{proto_a.name} -> {proto_b.name}", ncols=min(len(levels), 8))
        run.extra["images"] = len(outs)
        click.echo(f"transformed {len(faces_)} faces x {len(levels)} strengths ({proto_a.name} -> {proto_b.name}) "
                   f"-> {run.out}")


@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces caricature face.jpg --average composite.png --out cari                  # +50% shape
  appeal faces caricature faces/ --average composite.png --k -0.5,0.5 --colour --out cari
  appeal faces caricature face.jpg --average photos/ --k 0.3 --out cari                # composite made here""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--average", "average_src", required=True, type=click.Path(path_type=Path), metavar="AVERAGE",
              help="The average: an image with its template (e.g. a composite), or a folder (its composite is made).")
@click.option("--k", "ks", default="0.5", show_default=True, metavar="LIST",
              help="Comma-separated exaggerations: points -> avg + (1 + k)(points - avg); negative = anti-caricature.")
@click.option("--colour", is_flag=True, help="Exaggerate the low-frequency colour difference by k too.")
@click.option("--texture", is_flag=True, help="Exaggerate the fine-detail amplitude ratio by k too.")
@click.option("--region", type=click.Choice(["face", "image"]), default="face", show_default=True,
              help="Where colour and texture change: the face only (soft edge), or the whole image.")
@out_options()
def caricature(images: tuple[Path, ...], average_src: Path, ks: str, colour: bool, texture: bool, region: str,
               out: Path, force: bool, resume: bool) -> None:
    """Caricatures (k > 0) and anti-caricatures (k < 0) of faces relative to an average.

    The average's template is aligned on each face's pupils; every point's difference from it
    is scaled by 1 + k (k = 0.5: 50% more distinctive; k = -0.5: halfway to the average's
    shape; -1: the average's shape). Pupils stay in place.
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.caricature import caricature as exaggerate
    from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs

    levels = _numbers(ks, "--k")
    files = image_files(images)
    faces_ = load_faces(files)
    avg_img, avg_pts, avg_files = _prototype(average_src, faces_[0], "the average")
    with output_run(out, force=force, resume=resume, inputs=[*files, *avg_files]) as run:
        outs = []
        for f in faces_:
            for k in levels:
                img, pts = exaggerate(f.image, f.points, avg_img, avg_pts, k, colour=k if colour else 0.0,
                                      texture=k if texture else 0.0, region=region)
                outs.append(FaceOutput(f"{f.path.stem}_{_tag('k', k)}.png", img, f.template.moved(pts),
                                       [f.path, average_src], {"k": k}))
        write_outputs(run.out, outs, "caricature",
                      {"average": str(average_src), "k": levels, "colour": colour, "texture": texture,
                       "region": region, "template": faces_[0].source},
                      title=f"caricature vs {average_src.name}", ncols=min(len(levels), 8))
        run.extra["images"] = len(outs)
        click.echo(f"{len(outs)} caricatures of {len(faces_)} faces (k = {', '.join(f'{k:g}' for k in levels)}) "
                   f"-> {run.out}")


@faces.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces symmetrise face.jpg --out sym                                      # shape and colour
  appeal faces symmetrise faces/ --mode shape --mode both --out sym""")
@click.argument("images", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--mode", "modes", type=click.Choice(["both", "shape", "colour"]), multiple=True,
              default=("both",), show_default=True,
              help="shape: symmetric template, own colours; colour: own shape, colours averaged with the mirror "
                   "side; both. Repeat for several outputs per face.")
@out_options()
def symmetrise(images: tuple[Path, ...], modes: tuple[str, ...], out: Path, force: bool, resume: bool) -> None:
    """Make faces symmetric in shape, colour, or both.

    The template is averaged with its mirror image (left-right partners swapped, reflected
    about the face's own best-fitting axis, so a tilted face stays tilted); colours are
    averaged with the reflected image, both warped onto the output shape. Left-right
    partners are built in for the 189-point FRL template and dlib's 68 points. Manifest
    columns asymmetry_before / asymmetry_after: largest template-to-mirror distance (px).
    """
    from appeal.outputs import output_run
    from stimulus_engine.faces2d.align import load_faces
    from stimulus_engine.faces2d.outputs import FaceOutput, write_outputs
    from stimulus_engine.faces2d.symmetry import asymmetry, mirror_map
    from stimulus_engine.faces2d.symmetry import symmetrise as make_symmetric

    files = image_files(images)
    faces_ = load_faces(files)
    try:
        mirror = mirror_map(len(faces_[0].points))
    except ValueError as e:
        raise AppealInputError(f"{faces_[0].tem_path or faces_[0].path}: {e}") from None
    modes = tuple(dict.fromkeys(modes))
    with output_run(out, force=force, resume=resume, inputs=files) as run:
        outs = []
        for f in faces_:
            before = asymmetry(f.points, mirror)
            for mode in modes:
                img, pts = make_symmetric(f.image, f.points, mirror, mode=mode)  # type: ignore[arg-type]
                outs.append(FaceOutput(f"{f.path.stem}_sym-{mode}.png", img, f.template.moved(pts), [f.path],
                                       {"mode": mode, "asymmetry_before": round(before, 3),
                                        "asymmetry_after": round(asymmetry(pts, mirror), 3)}))
        write_outputs(run.out, outs, "symmetrise", {"modes": list(modes), "template": faces_[0].source},
                      title="symmetrise", ncols=min(len(modes), 6) if len(faces_) > 1 else None)
        run.extra["images"] = len(outs)
        click.echo(f"symmetrised {len(faces_)} faces ({', '.join(modes)}) -> {run.out}")


for _cmd in (transform, caricature, symmetrise):
    _cmd.help = (_cmd.help or "").rstrip() + "\n\n" + templates_help("Faces and prototypes")
