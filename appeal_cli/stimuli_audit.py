"""``appeal stimuli audit``: low-level image measures of a stimulus set."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import click

from appeal.errors import AppealInputError

from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli audit stimuli/exp2/manifest.csv --out stimuli/exp2/audit
  appeal stimuli audit stimuli/exp2 --out audit/exp2            # a grid's folder: its manifest.csv
  appeal stimuli audit photos/ --out audit/photos               # a folder of face photographs
  appeal stimuli audit photos.csv --factor expression --factor gender --item face_id --out audit/photos
                                    # photographs listed in a CSV (file, expression, gender, face_id)
  appeal stimuli audit n170.csv --out audit/n170   # file, category (face | house): faces vs controls""")
@click.argument("source", metavar="MANIFEST_OR_FOLDER", type=click.Path(path_type=Path))
@click.option("--threshold", "thresholds", metavar="MEASURE=VALUE", multiple=True,
              help="Flag MEASURE when its level means span more than VALUE (its own units); repeat for "
                   "several. Defaults: L*/a*/b* 2, RMS contrast 0.02, spectrum slope 0.1, energy shares 0.02, "
                   "edge density 0.01, face area 0.02, eye positions and IOD 3 px.")
@click.option("--factor", "factor", metavar="COLUMN", multiple=True,
              help="A manifest column to test as a factor (repeat for several); replaces the grid's "
                   "factor columns (character, shape, material, expression, lighting, shading ...).")
@click.option("--item", "item", metavar="COLUMN", multiple=True,
              help="Column naming an item (e.g. character): each factor is tested across these items, "
                   "the other factors averaged. Default: the combinations of the other factors.")
@out_options()
def audit(source: Path, thresholds: tuple[str, ...], factor: tuple[str, ...], item: tuple[str, ...], out: Path,
          force: bool, resume: bool) -> None:
    """Measure every image of a stimulus set: luminance, colour, contrast, spectrum, edges, face geometry.

    \b
    MANIFEST_OR_FOLDER is a rendered grid's manifest.csv (or its folder; an animated grid's
    clips are measured at their apex frame), a folder of images or a CSV listing them
    (file plus any factor columns, e.g. category: face | house).
    Face mask: a grid image's face oval (from grid.json's framing) minus the background
    colour; a photograph's convex hull of its 68 dlib landmarks. An image without a face
    (houses, objects, scrambled faces, noise) gets the whole-image measures and NaN face
    measures; one warning line lists them.

    \b
    Measures (face_ = inside the mask, image_ = whole image):
      L_mean, a_mean, b_mean   mean CIE L*a*b* (sRGB -> XYZ D65 -> L*a*b*)
      rms_contrast             standard deviation of L*/100
      edge_density             share of pixels that are Canny edges (sigma 1 px)
      spectrum_slope           log-log slope of the rotationally averaged amplitude
                               spectrum of L* (mean-subtracted, Hann window), fitted
                               over 4-64 cycles/image (shorter side; <= 0.8 Nyquist)
      energy_low/mid/high      spectral energy share below 8, 8-32, from 32 cycles/image
      face_area                mask pixels / image pixels
      eye_*_x/y, iod_px        dlib eye centres and their distance (NaN + warning
                               when no face is found)
    \b
    Tested against the design: for every factor of the manifest (less one that only repeats
    another, e.g. the ERP grid's material paired with shape), each measure's mean per level and
    the range of those means against its threshold (--threshold): beyond it the measure is
    flagged. A test says whether the difference holds across the items (the images'
    combinations of the other factors crossed with it, or --item): a one-way rm-ANOVA when
    every item is seen at every level, a between-items ANOVA when each is seen at one.

    \b
    Writes DIR/audit.csv (one row per image: the manifest's columns, then the measures),
    DIR/audit.png (each main measure's mean per level of every factor), DIR/design_tests.csv
    (one row per factor x measure: level means, range, threshold, flagged, F, df, p, effect
    size), DIR/level_means.csv, DIR/flags.png (range / threshold for every factor x measure)
    and DIR/report.md + report.html (what differs between levels, figures, tables).
    """
    from appeal.outputs import output_run
    from appeal_cli.audit_outputs import write_audit
    from analysis.confounds import parse_thresholds
    from stimulus_engine.audit.workflow import read_audit_inputs

    limits = parse_thresholds(thresholds)
    job = read_audit_inputs(source)
    for option, names in (("--factor", factor), ("--item", item)):
        bad = [c for c in names if c not in job.items[0].row]
        if bad:
            raise AppealInputError(f"{option}: {source} has no column '{bad[0]}' "
                                   f"(expected one of: {', '.join(map(str, job.items[0].row))})")
    if factor:
        job = dataclasses.replace(job, factors=list(factor))
    with output_run(out, force=force, resume=resume, inputs=[job.source]) as run:
        result = write_audit(job, run.out, thresholds=limits, item=list(item) or None)
        run.extra["images"] = len(result.table)
        run.extra["flagged"] = result.n_flagged
        click.echo(result.summary())
