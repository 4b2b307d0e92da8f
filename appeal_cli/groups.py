"""The ``appeal`` command and its groups; commands attach to these from their own modules."""

from __future__ import annotations

import click

from appeal import __version__
from appeal.logs import set_log_level
from appeal.progress import set_quiet

CONTEXT = {"help_option_names": ["-h", "--help"], "max_content_width": 100}


@click.group(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal demo --out demo_out                      # the whole pipeline on built-in assets
  appeal data fetch --for protocols/grids/exp1a_shape_material.yaml   # the third-party data it names
  appeal validate protocols/*.yaml protocols/grids/*.yaml
  appeal stimuli grid protocols/grids/exp2_stylisation.yaml --out stimuli/exp2
  appeal run protocols/exp2_stylisation.yaml --participant 01 --out data
  appeal export web protocols/exp2_stylisation.yaml --out site/exp2   # the same study in a browser
  appeal analyze ratings protocols/analysis/exp2_ratings.yaml --out results/exp2

Every command has --help with examples. -v/--verbose and -q/--quiet may stand anywhere.
Exit status: 0 success, 2 bad input (one line per problem on stderr), 1 internal error.""")
@click.version_option(__version__, "--version", prog_name="appeal")
@click.option("-v", "--verbose", is_flag=True, help="Log debugging detail (and tracebacks of internal errors).")
@click.option("-q", "--quiet", is_flag=True, help="Only warnings and errors; no progress bars.")
def cli(verbose: bool, quiet: bool) -> None:
    """Appeal Lab: stylised face stimuli, PsychoPy experiments and their analysis.

    \b
    The three parts, each a group of commands:
      stimuli   build face stimuli (3D correspondence, grids, morph-space PCA models)
      faces     2-D photographs: align, composites, continua, transforms, caricatures
      run       present a protocol to a participant (PsychoPy) and record the data
      analyze   statistics on ratings and EEG (rm-ANOVA, post-hocs, ERP windows)
      data      fetch and check the third-party datasets the study files name (data:NAME)
      export    a protocol as a study that runs elsewhere (a browser: `export web`)
      import    data recorded elsewhere into the lab's BIDS layout (`import web`)
    """
    set_log_level(True if verbose else (False if quiet else None))
    set_quiet(quiet)


@cli.group(context_settings=CONTEXT)
def stimuli() -> None:
    """Make stimuli: correspondence, texture transfer, morphs, rendered grids, 2D face models."""


@cli.group(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal faces align "data:london-frl-all/neutral_front/*.jpg" --out aligned   # the 87 London faces
  appeal faces average aligned --out composite          # a composite of every aligned face
  appeal faces continuum female.png male.png --steps 7 --out f2m
  appeal faces transform face.jpg --from female.png --to male.png --shape 0.5 --out masc""")
def faces() -> None:
    """2-D face photographs, WebMorph-style: align, average, continuum, transform, caricature, symmetrise, mask."""


@cli.group(context_settings=CONTEXT)
def analyze() -> None:
    """Analyse recorded data: rating statistics, psychometric fits and ERP pipelines."""


@cli.group(name="export", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal export web protocols/exp2_stylisation.yaml --out site/exp2 --participants 60
  python -m http.server -d site/exp2 8000     # then open http://127.0.0.1:8000/?participant=01""")
def export_() -> None:
    """Export a protocol to run elsewhere: a static browser study (jsPsych) for online data collection."""


@cli.group(name="import", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal import web ~/Downloads/sub-*_task-exp2_beh.tsv --protocol protocols/exp2_stylisation.yaml --out data""")
def import_() -> None:
    """Bring data recorded elsewhere (browser sessions) into the lab's BIDS layout."""
