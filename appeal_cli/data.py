"""``appeal data``: the third-party datasets the shipped study files name (``data:NAME``)."""

from __future__ import annotations

import click

from appeal_cli.groups import CONTEXT, cli
from appeal.errors import AppealInputError


@cli.group(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal data list                                  # what there is, its licence, and where it is
  appeal data fetch ict-facekit menpo3d-james       # download with checksums
  appeal data fetch --for protocols/grids/exp2_stylisation.yaml
  appeal data path ict-facekit                      # the folder, for scripts
  appeal data verify                                # re-check every fetched file""")
def data() -> None:
    """Get the third-party data (face meshes, photographs, EEG examples) the study files use.

    \b
    Shipped study files name a dataset, not a path: `ict: data:ict-facekit`,
    `file: data:menpo3d-james/james.obj`. `appeal data fetch NAME` downloads it into
    $APPEAL_DATA (if set) or the user cache (~/.cache/appeal-lab/data), checks every file's
    sha256 and prints its licence and credit. A `shared/data` folder beside the checkout is
    used too. Mirrors: --url or $APPEAL_DATA_URL (a server laid out like the data tree).
    """


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


@data.command("list", context_settings=CONTEXT, epilog="""\b
Examples:
  appeal data list
  appeal data list | grep "not fetched"     # what is still missing""")
def list_() -> None:
    """List the registered datasets: size, licence, and where each is on this machine."""
    from appeal.datasets import DATASET_GROUPS, dataset, dataset_names, find_dataset

    for name in dataset_names():
        ds = dataset(name)
        where = find_dataset(name)
        click.echo(f"{name:20s} {_size(ds.size):>9s}  {ds.licence:13s} {where if where else 'not fetched'}")
        click.echo(f"{'':20s} {ds.description}")
    for name, members in DATASET_GROUPS.items():
        click.echo(f"{name:20s} {'group':>9s}  of {', '.join(members)}")


def _members(names: tuple[str, ...]) -> list[str]:
    """Dataset names with groups (e.g. london-frl-all) replaced by their members, each once."""
    from appeal.datasets import group_members

    return list(dict.fromkeys(m for name in names for m in group_members(name)))


def _names_for(files: tuple[str, ...]) -> list[str]:
    """Datasets named by ``data:`` references anywhere in the given study files."""
    import re
    from pathlib import Path

    from appeal.datasets import DATA_PREFIX, group_members

    names = []
    for f in files:
        try:
            text = Path(f).read_text(encoding="utf-8")
        except OSError as exc:
            raise AppealInputError(f"{f}: cannot read ({exc.strerror})") from None
        refs = [m.group(1) for m in re.finditer(re.escape(DATA_PREFIX) + r"([A-Za-z0-9_.-]+)", text)]
        if re.search(r"(^|[\s{,-])photo\s*:", text, re.M):  # photo characters: the model they default to
            from stimulus_engine.grid.schema import PHOTO_DEFAULTS

            refs += [v[len(DATA_PREFIX):] for v in PHOTO_DEFAULTS.values()]
        for name in refs:
            names += group_members(name)
    return list(dict.fromkeys(names))


@data.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal data fetch ict-facekit
  appeal data fetch --all
  appeal data fetch --for protocols/grids/exp2_stylisation.yaml
  appeal data fetch --all --url https://data.example.org/appeal            # a lab mirror""")
@click.argument("names", nargs=-1)
@click.option("--all", "all_", is_flag=True, help="Every registered dataset.")
@click.option("--for", "for_files", multiple=True, metavar="STUDY.yaml",
              help="The datasets a study file names (data:NAME); repeatable.")
@click.option("--url", default=None, help="A mirror of the data tree (BASE/FOLDER/FILE) instead of the upstream URLs.")
def fetch(names: tuple[str, ...], all_: bool, for_files: tuple[str, ...], url: str | None) -> None:
    """Download datasets, check their sha256, and print their licence and credit.

    Files already present with the right content are kept; a missing or corrupted one is
    downloaded again (an interrupted download resumes). Nothing is left under a file's real
    name before its checksum has been verified.
    """
    from appeal.data_fetch import fetch_dataset
    from appeal.datasets import dataset_names

    chosen = list(dataset_names()) if all_ else list(dict.fromkeys([*_members(names), *_names_for(for_files)]))
    if not chosen:
        raise AppealInputError("appeal data fetch: name a dataset (appeal data list), --all, or --for STUDY.yaml")
    for name in chosen:
        r = fetch_dataset(name, base_url=url)
        if r.downloaded:
            click.echo(f"{name}: {len(r.downloaded)} files fetched, {len(r.present)} already there -> {r.folder}")
            click.echo(f"  licence: {r.dataset.licence}; credit: {r.dataset.credit}")
        else:
            click.echo(f"{name}: up to date ({len(r.present)} files) in {r.folder}")


@data.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal data path ict-facekit
  appeal data path london-frl-all                   # a group: one folder per line
  appeal stimuli photo-sheet stimuli/exp2/manifest.csv --photo "$(appeal data path london-frl)/neutral_front/001_03.jpg" --out sheet.png""")
@click.argument("name")
def path(name: str) -> None:
    """Print the folder of dataset NAME, one per member for a group (exit 2 if it is not on this machine)."""
    from appeal.datasets import resolve_references

    for folder in resolve_references(f"data:{name}"):
        click.echo(str(folder))


@data.command(context_settings=CONTEXT, epilog="""\b
Examples:
  appeal data verify
  appeal data verify ict-facekit london-frl""")
@click.argument("names", nargs=-1)
def verify(names: tuple[str, ...]) -> None:
    """Re-check the sha256 of every fetched file (all fetched datasets, or NAMES).

    Prints one line per dataset; a missing or corrupted file is named, with the command that
    fetches it again, and the exit status is 2.
    """
    from appeal.data_fetch import verify_dataset
    from appeal.datasets import dataset, dataset_names, fetch_root

    problems = []
    for name in _members(names) or dataset_names():
        states = verify_dataset(name)
        bad = [(f, s) for f, s in states if s != "ok"]
        if not names and len(bad) == len(states):
            continue  # never fetched
        if bad:
            problems += [f"{fetch_root() / dataset(name).folder / f}: {s} (fetch it again: appeal data fetch {name})"
                         for f, s in bad]
        else:
            click.echo(f"{name}: ok ({len(states)} files)")
    if problems:
        raise AppealInputError(problems)
