"""``appeal stimuli correspond``, ``transfer-texture`` and ``morph`` (ElastiFace, thesis ch. 3)."""

from __future__ import annotations

import json
from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options, refuse_existing_file
from appeal.errors import AppealInputError


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli correspond src.obj tgt.obj --landmarks pairs.json --out corr/
  appeal stimuli correspond head.obj.gz scan.obj --landmarks '{"source": [12, 40, 99], "target": [[0,1,2], 17, {"face": 3, "bary": [0.2,0.3,0.5]}]}' --out corr/ --json metrics.json
  appeal stimuli correspond src.obj cartoon.ply --landmarks pairs.json --lambda1 10 --out corr/ --force   # extreme pair
  appeal stimuli correspond head.obj scan.obj --landmarks auto --out corr/   # landmarks found in renders

\b
Sparse solver: CHOLMOD (pip install 'appeal-lab[fast]'; make installs it) when available, else
SciPy's SuperLU; APPEAL_SPARSE_SOLVER=superlu|cholmod chooses.""")
@click.argument("source", type=click.Path(path_type=Path))
@click.argument("target", type=click.Path(path_type=Path))
@click.option("--landmarks", "landmarks", required=True, metavar="PAIRS",
              help='Pairs file (.json) or inline JSON {"source": [...], "target": [...]}; each entry a '
                   'vertex index, a point [x, y, z] snapped to the surface, or {"face": f, "bary": [a, b, c]}. '
                   '"auto": the 68 iBUG landmarks found in renders of both meshes (inner points, confident on both).')
@click.option("--boundary", "boundary", default=None, metavar="PAIRS",
              help='Optional boundary-loop anchors as JSON [[src_vertex, tgt_vertex], ...]; every other vertex '
                   'of those source loops is matched by relative arc length (thesis Fig. 3.5).')
@click.option("--lambda1", type=float, default=0.1, show_default=True, help="Fairing smoothness (10 for extreme pairs).")
@click.option("--fairing-iterations", type=int, default=5, show_default=True,
              help="Most joint-fairing solves (Voronoi areas updated; fewer once nothing moves).")
@click.option("--no-sheet", is_flag=True, help="Skip the contact-sheet PNG (rendering).")
@click.option("--json", "json_out", type=click.Path(path_type=Path), default=None, metavar="METRICS",
              help="Also write the metrics to this JSON file.")
@out_options()
def correspond(source: Path, target: Path, landmarks: str, boundary: str | None, lambda1: float,
               fairing_iterations: int, no_sheet: bool, json_out: Path | None, out: Path, force: bool,
               resume: bool) -> None:
    """Put SOURCE into dense correspondence with TARGET (joint fairing + non-rigid registration).

    \b
    The source is aligned (Umeyama similarity on the landmark pairs), both meshes are faired
    jointly into smooth, similar base meshes (eq. 3.7-3.10), the faired source is registered
    onto the faired target with a stiffness schedule (eq. 3.11-3.13), and the correspondences
    found there drive the final fit of the original source onto the original target.

    \b
    Writes DIR/deformed.obj (the source's vertices moved onto the target, source vertex order,
    faces and UVs kept), DIR/correspondence.npz (per source vertex: target triangle and
    barycentric weights), DIR/metrics.json (seconds, hausdorff_rel, mean_dist_rel,
    median_dist_rel, flipped_triangles, n_source_vertices, n_target_vertices, stage seconds)
    and DIR/contact_sheet.png (source, faired meshes, registered base, result, target).
    """
    from appeal.atomic import atomic_write_text
    from appeal.outputs import output_run
    from stimulus_engine.correspondence.workflow import read_correspondence_job, run_correspondence

    job = read_correspondence_job(source, target, landmarks, boundary=boundary, lambda1=lambda1,
                                  fairing_iterations=fairing_iterations)
    if json_out is not None and not json_out.parent.exists():
        raise AppealInputError(f"{json_out}: --json folder {json_out.parent} does not exist")
    with output_run(out, force=force, resume=resume, inputs=[source, target]) as orun:
        metrics = run_correspondence(job, orun.out, sheet=not no_sheet)
        if json_out is not None:
            atomic_write_text(json_out, json.dumps(metrics, indent=2))
        orun.extra["metrics"] = metrics
        click.echo(
            f"deformed.obj: {metrics['n_source_vertices']} vertices; hausdorff {metrics['hausdorff_rel']:.3%}, "
            f"median {metrics['median_dist_rel']:.3%} of the bbox diagonal; {metrics['flipped_triangles']} "
            f"fold-overs; {metrics['seconds']:.2f} s"
        )


@stimuli.command("transfer-texture", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli transfer-texture corr/deformed.obj james.obj --out james_in_src_layout.png
  appeal stimuli transfer-texture corr/deformed.obj tgt.obj --map tgt_specular.png --size 2048 2048 --out spec.png""")
@click.argument("deformed", metavar="SRC_DEFORMED", type=click.Path(path_type=Path))
@click.argument("target", metavar="TGT", type=click.Path(path_type=Path))
@click.option("--out", "out", required=True, type=click.Path(path_type=Path), metavar="TEX.png", help="Output image.")
@click.option("--map", "map_path", type=click.Path(path_type=Path), default=None,
              help="Target map to transfer instead of its albedo (specular, normal map, ...).")
@click.option("--size", type=(int, int), default=None, metavar="W H", help="Output size (default: the source texture's, else the target map's).")
@click.option("--force", is_flag=True, help="Overwrite TEX.png.")
def transfer_texture(deformed: Path, target: Path, out: Path, map_path: Path | None, size, force: bool) -> None:
    """Re-lay TGT's texture into the UV layout of SRC_DEFORMED (thesis §3.3).

    \b
    SRC_DEFORMED is DIR/deformed.obj from `appeal stimuli correspond` (the source's UVs on the
    target's shape). For every texel of the source layout: its 3D point, the closest target
    point, the target's UV there, a bilinear lookup; then a 1-pixel dilation of the islands.
    """
    import io

    from PIL import Image

    from appeal.atomic import atomic_write_bytes
    from stimulus_engine.geometry.mesh_io import load_mesh
    from stimulus_engine.correspondence.texture_transfer import transfer_texture as run

    refuse_existing_file(out, force)
    src = load_mesh(deformed)
    tgt = load_mesh(target)
    image = None
    if map_path is not None:
        if not map_path.exists():
            raise AppealInputError(f"{map_path}: --map image not found")
        try:
            image = Image.open(map_path)
            image.load()
        except OSError as exc:
            raise AppealInputError(f"{map_path}: cannot read image ({exc})") from None
    img = run(src, tgt, image=image, size=size)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    atomic_write_bytes(out, buf.getvalue())
    click.echo(f"{out}: {img.size[0]} x {img.size[1]}")


def _split_weights(items: tuple, first: str) -> tuple[list[Path], list[float]]:
    """MESH... and the weights: ``--weights 0.5 0.5`` leaves the trailing numbers among the
    arguments (click options take one value), ``--weights 0.5,0.5`` is one value."""
    rest = list(items)
    trailing: list[str] = []
    while rest:
        try:
            float(str(rest[-1]))
        except ValueError:
            break
        trailing.insert(0, str(rest.pop()))
    values = [x for x in str(first).replace(",", " ").split() if x] + trailing
    try:
        weights = [float(x) for x in values]
    except ValueError:
        raise AppealInputError(f"--weights: expected numbers (got {' '.join(values)})") from None
    return [Path(x) for x in rest], weights


def _part_morph(paths: list[Path], regions: str, landmarks: str, interpolation: str, sheet: Path | None,
                out: Path, force: bool) -> None:
    """``appeal stimuli morph --regions``: load, check, morph, save (and the sheet)."""
    from stimulus_engine.geometry.mesh_io import save_mesh
    from stimulus_engine.stylisation.morph import load_corresponded, part_morph
    from stimulus_engine.stylisation.morph_regions import parse_regions, part_morph_sheet, read_ibug

    if len(paths) < 2:
        raise AppealInputError(f"MESH...: expected a base mesh and at least one donor (got {len(paths)})")
    chosen = parse_regions(regions, len(paths))
    refuse_existing_file(out, force)
    loaded = load_corresponded(paths)
    ibug = read_ibug(landmarks, loaded[0], str(paths[0]))
    result = part_morph(loaded, chosen, ibug, interpolation)
    save_mesh(result, out)
    if sheet is not None:
        labels = [f"base: {paths[0].name}", *[f"{k}: {p.name}" for k, p in enumerate(paths[1:], 1)],
                  "morph: " + ", ".join(f"{r} from {k}" for r, k in chosen.items())]
        part_morph_sheet(loaded, result, ibug, labels, sheet)
    click.echo(f"{out}: " + ", ".join(f"{r} from {paths[k].name}" for r, k in chosen.items())
               + f" on {paths[0].name} ({interpolation} Laplacians, gradient-domain texture)"
               + (f"; sheet {sheet}" if sheet else ""))


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli morph corr_a/deformed.obj corr_b/deformed.obj --weights 0.5 0.5 --out half.obj
  appeal stimuli morph a.obj b.obj c.obj --weights 0.2,0.3,0.5 --out blend.obj --force
  appeal stimuli morph real.obj cartoon.obj --regions eyes=1 --out eyes.obj --sheet eyes.png
  appeal stimuli morph a.obj b.obj c.obj --regions eyes=1,mouth=2 --landmarks a.ljson --out parts.obj""")
@click.argument("meshes", nargs=-1, required=True, metavar="MESH...")
@click.option("--weights", "weights", default=None, metavar="W...",
              help="One weight per mesh, summing to 1: '--weights 0.3 0.7' or '--weights 0.3,0.7'.")
@click.option("--regions", default=None, metavar="REGION=MESH,...",
              help="Part-based morph instead: regions (eyes, brows, nose, mouth) from the given meshes "
                   "(1, 2, ...) on the first mesh, e.g. 'eyes=1,mouth=2'.")
@click.option("--landmarks", default="auto", show_default=True, metavar="auto|FILE",
              help="With --regions: the first mesh's 68 iBUG points (found in renders, or a .ljson / JSON file).")
@click.option("--interpolation", type=click.Choice(["slerp", "linear"]), default="slerp", show_default=True,
              help="With --regions: how the Laplacians blend (slerp as the thesis, or linearly).")
@click.option("--sheet", type=click.Path(path_type=Path), default=None, metavar="SHEET.png",
              help="With --regions: render the meshes and the morph side by side.")
@click.option("--out", "out", required=True, type=click.Path(path_type=Path), metavar="OUT.obj", help="Output mesh.")
@click.option("--force", is_flag=True, help="Overwrite OUT.obj (and its texture).")
def morph(meshes: tuple, weights: str | None, regions: str | None, landmarks: str, interpolation: str,
          sheet: Path | None, out: Path, force: bool) -> None:
    """Blend corresponded meshes (same connectivity and UV layout): whole faces with weights, or
    parts of faces with --regions (thesis §3.4).

    \b
    The meshes are typically DIR/deformed.obj files of `appeal stimuli correspond` runs from
    one source. With --weights, vertex positions blend linearly; when every mesh has a texture
    of one size, the textures blend too (OUT.png beside OUT.obj). With --regions, the named
    regions come from other meshes: their cotangent Laplacians are interpolated by slerp and
    the shape recovered by a Poisson solve (Alexa 2003), the rest of the first mesh kept as it
    is; textures are blended in the gradient domain (Pérez 2003), so the part takes the
    surrounding skin tone. Regions sit around the first mesh's iBUG landmarks.
    """
    from stimulus_engine.geometry.mesh_io import save_mesh
    from stimulus_engine.stylisation.morph import blend_meshes

    if (weights is None) == (regions is None):
        raise AppealInputError("morph: give either --weights (a whole-face blend) or --regions (a part-based morph)")
    if regions is not None:
        _part_morph([Path(m) for m in meshes], regions, landmarks, interpolation, sheet, out, force)
        return
    paths, w = _split_weights(meshes, weights)
    refuse_existing_file(out, force)
    save_mesh(blend_meshes(paths, w, "--weights"), out)
    click.echo(f"{out}: blend of {len(paths)} meshes, weights {', '.join(f'{x:g}' for x in w)}")
