"""``appeal stimuli audit``: low-level image measures of a stimulus set."""

from __future__ import annotations

from pathlib import Path

import click

from appeal_cli.groups import CONTEXT, stimuli
from appeal_cli.options import out_options


@stimuli.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal stimuli audit stimuli/exp2/manifest.csv --out stimuli/exp2/audit
  appeal stimuli audit stimuli/exp2 --out audit/exp2            # a grid's folder: its manifest.csv
  appeal stimuli audit photos/ --out audit/photos               # a folder of face photographs""")
@click.argument("source", metavar="MANIFEST_OR_FOLDER", type=click.Path(path_type=Path))
@out_options()
def audit(source: Path, out: Path, force: bool, resume: bool) -> None:
    """Measure every image of a stimulus set: luminance, colour, contrast, spectrum, edges, face geometry.

    \b
    MANIFEST_OR_FOLDER is a rendered grid's manifest.csv (or its folder; an animated grid's
    clips are measured at their apex frame) or a folder of face photographs.
    Face mask: a grid image's face oval (from grid.json's framing) minus the background
    colour; a photograph's convex hull of its 68 dlib landmarks (no face: an error).

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
                               when no face is found in a rendered image)
    \b
    Writes DIR/audit.csv (one row per image: the manifest's columns, then the measures)
    and DIR/audit.png (each main measure's mean per level of every factor).
    """
    from appeal.outputs import output_run
    from stimulus_engine.audit.workflow import audit_factors, plot_audit, read_audit_inputs, run_audit

    job = read_audit_inputs(source)
    with output_run(out, force=force, resume=resume, inputs=[job.source]) as run:
        table = run_audit(job)
        csv = run.out / "audit.csv"
        table.to_csv(csv, index=False)
        fig = plot_audit(table, run.out / "audit.png", audit_factors(table))
        run.extra["images"] = len(table)
        n_warn = int((table["warning"] != "").sum())
        click.echo(f"{len(table)} images audited: {csv}; figure {fig}"
                   + (f"; {n_warn} without eye positions (see the warning column)" if n_warn else ""))
