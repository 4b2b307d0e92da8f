"""``appeal stimuli grid`` and ``appeal stimuli neoteny``: rendered stimulus grids and their measures."""

from __future__ import annotations

from pathlib import Path

import click

from appeal.cells import write_table
from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options, parallel_options, refuse_existing_file
from appeal.errors import AppealInputError


def _audit_grid(out: Path, manifest):
    """The rendered grid's audit in ``out/audit`` (skipped, with a line saying why, when images failed)."""
    from appeal_cli.audit_outputs import write_audit
    from stimulus_engine.audit.workflow import read_audit_inputs

    if not manifest["status"].isin(["rendered", "up to date"]).all():
        click.echo("audit: skipped (some images failed to render; run appeal stimuli audit DIR once they exist)")
        return None
    result = write_audit(read_audit_inputs(out / "manifest.csv"), out / "audit")
    click.echo(f"audit: {result.summary()}")
    return result


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli grid protocols/grids/exp1a_shape_material.yaml --out stimuli/exp1a
  appeal stimuli grid protocols/grids/exp2_stylisation.yaml --out stimuli/exp2 --n-jobs 2
  appeal stimuli grid protocols/grids/exp2_stylisation.yaml --out stimuli/exp2 --resume   # only what changed
  appeal stimuli grid my_animated_grid.yaml --out stimuli/clips   # animation: {...}: clips, DIR/clips/*.mp4
  appeal validate protocols/grids/*.yaml                                                    # check without rendering""")
@click.argument("grid_file", metavar="GRID.yaml", type=click.Path(path_type=Path))
@click.option("--audit/--no-audit", default=True, show_default=True,
              help="Also measure every image's luminance, contrast, spectrum, edges and face geometry and "
                   "test them against the design (DIR/audit/, as appeal stimuli audit DIR does).")
@out_options()
@parallel_options
def grid(grid_file: Path, audit: bool, out: Path, force: bool, resume: bool, n_jobs: int | None,
         scheduler: str | None) -> None:
    """Render a stimulus grid: characters x shapes x materials x expressions x lighting x shading.

    \b
    GRID.yaml (kind: grid) names the characters (the ICT face model or a procedural head),
    stylisation levels (0 realistic .. 1 cartoon, by the artist-free shape operator), materials
    (original, blur25, blur50, bilateral, flat, painted, an albedo from another character,
    or {levels: N} evenly spaced),
    expressions (FACS recipes: neutral, anger, happiness, sadness, surprise, ...), lighting
    presets (direct_hard, direct_soft, gi_soft, flat) and shading (pbr, phong, skin, toon: cel-shaded).

    \b
    Writes DIR/images/*.png (1024 x 768 by default, 50% grey background, every face framed
    with the same size and eye position), DIR/manifest.csv (one row per image: file, factors,
    input hashes, camera, seconds), DIR/landmarks.csv, contact sheets and the continuum report
    (DIR/continuum.csv and .png: per character, the image step between neighbouring shape and
    material levels and each level's identity distance to the realistic one, dlib's face
    descriptor, same person within 0.6) and, with neutral plus other expressions at several shape
    levels, how far each expression moves the face at each level in face lengths
    (DIR/expression_measures.csv: mouth opening and width, mouth corner and brow raise, eye
    opening, total; DIR/expression_agreement.csv: their spread across levels against the
    realistic one; DIR/expression_measures.png). materials: {levels: 5} asks for five levels of one
    painted family spaced by measured image steps; the run prints the levels it measured as the
    grid file's materials.measured (and shapes.measured) that pin them, as the shipped grids do.
    With animation: {fps, lead, onset, hold, easing, expression} in GRID.yaml every cell is a clip
    from neutral to its apex instead: DIR/clips/<cell>/frame_00000.png ... (lossless) and
    DIR/clips/<cell>.mp4 (H.264, every frame a key frame), one manifest row per clip (frames,
    n_frames, fps, onset_frame, apex_frame, weight_curve, frames_sha256, mp4_sha256), contact
    sheets of the apex frames and a filmstrip per character.
    With --resume, images (and clips) whose inputs are unchanged are kept. All input problems are
    reported before rendering. Unless --no-audit, the rendered set is audited into DIR/audit/
    (appeal stimuli audit: low-level measures per image, their means per level of every factor,
    which differ beyond the default thresholds, DIR/audit/report.html). DIR/index.html shows the
    contact sheets and measures with what the audit found to differ between levels.
    """
    import json

    from appeal.outputs import output_run
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid import run_grid
    from stimulus_engine.grid.continuum import pins
    from stimulus_engine.grid.schema import GridFile

    spec = load_study_file(grid_file, GridFile)
    with output_run(out, force=force, resume=resume, seed=spec.seeds(), inputs=[grid_file]) as run:
        manifest, sheets = run_grid(spec, run.out, n_jobs=n_jobs, scheduler=scheduler, source=str(grid_file))
        n_ok = int(manifest["status"].isin(["rendered", "up to date"]).sum())
        run.extra["images"] = len(manifest)
        what = "clips" if spec.animation is not None else "images"
        click.echo(f"{n_ok} of {len(manifest)} {what} in {run.out / what}; manifest {run.out / 'manifest.csv'}")
        result = _audit_grid(run.out, manifest) if audit else None
        for s in sheets:
            if s.name == "continuum.png":
                click.echo(f"continuum: {s} (table {s.with_suffix('.csv')})")
            elif s.name == "expression_measures.png":
                click.echo(f"expression per level: {s} (tables expression_measures.csv, expression_agreement.csv)")
            else:
                click.echo(f"{'filmstrip' if s.name.startswith('filmstrip') else 'contact sheet'}: {s}")
        from appeal_cli.audit_outputs import write_grid_page

        page = write_grid_page(run.out, sheets, result, f"Stimulus grid: {grid_file.name}")
        click.echo(f"page: {page} (contact sheets{', what differs between levels' if result else ''})")
        measured = pins(spec, manifest.attrs["grid"])
        for factor, pin in measured.items():  # a study's levels belong in its protocol
            click.echo(f"{factor} measured; to keep these levels, write in {grid_file}:  {factor}: {json.dumps(pin)}")
        if n_ok < len(manifest):
            bad = manifest[~manifest["status"].isin(["rendered", "up to date"])]
            raise click.ClickException(f"{len(bad)} image(s) failed, first: {bad.iloc[0]['file']}: {bad.iloc[0]['status']}")


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli neoteny stimuli/exp2/manifest.csv
  appeal stimuli neoteny stimuli/erp/manifest.csv --out stimuli/erp/neoteny""")
@click.argument("manifest", metavar="MANIFEST", type=click.Path(path_type=Path))
@out_options(required=False)
def neoteny(manifest: Path, out: Path | None, force: bool, resume: bool) -> None:
    """Neoteny measures (thesis Fig. 7.10) of every stimulus of a rendered grid.

    \b
    Reads MANIFEST (a grid's manifest.csv) and the landmarks.csv beside it; writes a tidy
    table neoteny.csv (character, shape, stylisation, expression, measure, value: eye width and
    height, nose length and width, mouth width, forehead height, vertical eye position, each
    relative to face width or length) and a plot across stylisation levels (PNG + SVG) into
    --out (default: MANIFEST's folder / neoteny).
    """
    import pandas as pd

    from appeal.outputs import output_run
    from stimulus_engine.stylisation.neoteny import neoteny_table, plot_neoteny

    manifest = Path(manifest)
    if not manifest.is_file():
        raise AppealInputError(f"{manifest}: manifest not found (expected DIR/manifest.csv of a rendered grid)")
    lm_path = manifest.parent / "landmarks.csv"
    if not lm_path.is_file():
        raise AppealInputError(f"{lm_path}: landmarks table not found (expected beside the manifest; "
                               "re-render the grid with 'appeal stimuli grid')")
    try:
        lms = pd.read_csv(lm_path)
        table = neoteny_table(lms)
    except (ValueError, pd.errors.ParserError) as exc:
        raise AppealInputError(f"{lm_path}: {exc}".splitlines()[0]) from None
    out = out or manifest.parent / "neoteny"
    with output_run(out, force=force, resume=resume, inputs=[manifest, lm_path]) as run:

        write_table(table, run.out / "neoteny.csv")
        figs = plot_neoteny(table, run.out / "neoteny.png")
        click.echo(f"{len(table)} rows -> {run.out / 'neoteny.csv'}; plot {figs[0]}")


@stimuli.command("photo-sheet", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli photo-sheet stimuli/exp2/manifest.csv --photo "$(appeal data path london-frl)/neutral_front/001_03.jpg" --out exp2_vs_photo.png
  appeal stimuli photo-sheet stimuli/erp/manifest.csv --photo a.jpg --photo b.jpg --out erp_vs_photo.png""")
@click.argument("manifest", metavar="MANIFEST", type=click.Path(path_type=Path))
@click.option("--photo", "photos", multiple=True, required=True, type=click.Path(path_type=Path),
              help="A frontal photograph of a real person (repeatable; used in turn for the characters).")
@click.option("--out", "out", required=True, type=click.Path(path_type=Path), metavar="PNG", help="Sheet to write.")
@click.option("--force", is_flag=True, help="Overwrite PNG if it exists.")
def photo_sheet(manifest: Path, photos: tuple[Path, ...], out: Path, force: bool) -> None:
    """Each character's most realistic rendered image beside a real photograph, framed alike.

    \b
    The photograph is moved, scaled and turned so that its eye centres land on those of the
    rendering (dlib finds both), at the rendering's size, on its background: judge the
    realistic level of a grid side by side with a photograph (the studies need it to read as
    one). Reads MANIFEST (a rendered grid's manifest.csv) and its images.
    """
    from stimulus_engine.grid.photo_sheet import realism_sheet
    from stimulus_engine.render import save_png

    refuse_existing_file(out, force)
    sheet = realism_sheet(manifest, list(photos))
    save_png(sheet, out)
    click.echo(f"photo sheet: {out}")


@stimuli.command("engine-sheet", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli engine-sheet protocols/grids/exp1b_shading_lighting.yaml \\
      --photo "$(appeal data path london-frl)/neutral_front/001_03.jpg" --out engines
  appeal stimuli engine-sheet protocols/grids/exp2_stylisation.yaml --character lps --photo p.jpg --out lps
  appeal stimuli engine-sheet my_grid.yaml --photo me.jpg --engine pyrender --out preview""")
@click.argument("grid_file", metavar="GRID.yaml", type=click.Path(path_type=Path))
@click.option("--photo", "photo", required=True, type=click.Path(path_type=Path),
              help="A frontal photograph of a real person, aligned on the eyes in the last column.")
@click.option("--engine", "engines", multiple=True, type=click.Choice(["pyrender", "cycles"]),
              help="Engines to compare (repeatable; default: pyrender and cycles).")
@click.option("--character", default=None, metavar="NAME", help="The grid's character to show (default: the first).")
@out_options()
@parallel_options
def engine_sheet(grid_file: Path, photo: Path, engines: tuple[str, ...], character: str | None, out: Path, force: bool,
                 resume: bool, n_jobs: int | None, scheduler: str | None) -> None:  # noqa: ARG001 - renders locally
    """A character of GRID.yaml (the first, or --character) under each render engine, beside a photograph.

    \b
    Renders the character's realistic level (first material) neutral and happy under
    direct_hard, direct_soft and gi_soft with pyrender's pbr shading (as before), its skin
    shading, and Cycles — the same scene, only render.engine and shading differ — into
    DIR/ENGINE-SHADING/, and writes DIR/engine_sheet.png: one row per expression and lighting,
    one column per renderer, the photograph (eyes aligned) last.
    """
    from appeal.outputs import output_run
    from appeal.studyfile import load_study_file
    from stimulus_engine.grid.engine_sheet import engine_sheet as make_sheet
    from stimulus_engine.grid.schema import GridFile
    from stimulus_engine.render import save_png
    from stimulus_engine.render.cycles import check_cycles

    spec = load_study_file(grid_file, GridFile)
    engines = engines or ("pyrender", "cycles")
    if "cycles" in engines:
        check_cycles("--engine")
    if not photo.is_file():
        raise AppealInputError(f"--photo: {photo}: image not found (expected a frontal photograph)")
    with output_run(out, force=force, resume=resume, inputs=[grid_file, photo]) as run:
        sheet = make_sheet(spec, run.out, photo, engines=engines, character=character, n_jobs=n_jobs)
        save_png(sheet, run.out / "engine_sheet.png")
        click.echo(f"engine sheet: {run.out / 'engine_sheet.png'}")
