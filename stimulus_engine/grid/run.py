"""The grid workflow: plan and prepare -> render the images (or clips) not up to date -> manifest, sheets.

:func:`run_grid` is the one entry of ``appeal stimuli grid`` (and the demo's grid stage).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import pandas as pd

from appeal.atomic import atomic_write_text
from appeal.cells import write_table
from appeal.logs import logger
from stimulus_engine.grid.animation import apex_view, clip_checksums, render_clip, revcorr_trial_table
from stimulus_engine.grid.designs import grid_characters
from stimulus_engine.grid.continuum import continuum_table, write_continuum
from stimulus_engine.grid.expression_measures import write_expression_measures
from stimulus_engine.grid.performance_measures import performance_landmarks, write_performance_measures
from stimulus_engine.grid.prepare import measured_grid, prepare_grid
from stimulus_engine.grid.sheets import write_filmstrips, write_sheets
from stimulus_engine.grid.worker import place_photo, render_item
from stimulus_engine.grid.schema import GridFile

__all__ = ["previous_hashes", "run_grid"]


def _framing_reference(manifest: pd.DataFrame, character: str, out: Path) -> str | None:
    """The rendered image a character's photographs are framed like: its realistic level, neutral
    where there is one (None without renders)."""
    from stimulus_engine.grid.photo_sheet import realistic_images

    rendered = manifest[(manifest["character"] == character) & (manifest["shape"].astype(str) != "photograph")]
    if rendered.empty:
        return None
    return str(out / realistic_images(rendered).iloc[0]["file"])


def _performance_landmarks(manifest: pd.DataFrame) -> pd.DataFrame:
    """A performance grid's per-frame landmarks (:func:`~stimulus_engine.grid.performance_measures.performance_landmarks`;
    empty for any other grid)."""
    if "_frame_landmarks" not in manifest.columns:
        return pd.DataFrame()
    cells = manifest.dropna(subset=["_frame_landmarks"]).rename(columns={"_frame_landmarks": "landmarks_file"})
    return performance_landmarks(cells)


def previous_hashes(out: Path) -> dict[str, str]:
    """``file`` -> ``input_hash`` of the images a previous run over ``out`` rendered (none without its manifest)."""
    p = out / "manifest.csv"
    if not p.exists():
        return {}
    try:
        old = pd.read_csv(p, dtype=str)
    except (OSError, ValueError, pd.errors.ParserError):
        return {}
    if not {"file", "input_hash", "status"} <= set(old.columns):
        return {}
    old = old[old["status"].isin(["rendered", "up to date"])]
    return dict(zip(old["file"], old["input_hash"]))


def run_grid(grid: GridFile, out: Path, *, n_jobs: int | None = None, scheduler: str | None = None,
             source: str = "grid") -> tuple[pd.DataFrame, list[Path]]:
    """Render ``grid`` into ``out`` (see :mod:`stimulus_engine.grid` for the files written).

    Parameters
    ----------
    grid : GridFile
    out : Path
        Output folder (prepared by the caller, e.g. :func:`appeal.outputs.output_run`).
    n_jobs : int, optional
        Local worker processes (default: all cores; 1 = in this process).
    scheduler : str, optional
        Dask scheduler address.
    source : str
        The grid file's name, for error messages.

    Returns
    -------
    manifest : DataFrame
        Its ``attrs["grid"]`` is the grid as rendered: continua measured out into listed levels
        (:func:`stimulus_engine.grid.continuum.pins` turns them into a grid file's pins).
    sheets : list of Path
        The contact sheets written (an animated grid's of its clips' apex frames, then a
        filmstrip per character), then the continuum's figure (``continuum.png``, its table
        ``continuum.csv`` beside it), then how far each expression moves the face
        per shape level (``expression_measures.png``, with ``expression_measures.csv`` and
        ``expression_agreement.csv``; :mod:`stimulus_engine.grid.expression_measures`).
    """
    from appeal.parallel import parallel_map

    out = Path(out)
    chars = grid_characters(grid, out / ".cache", source)  # loaded once
    grid = measured_grid(grid, out, source=source, characters=chars)  # the continua's levels, for the sheets and the report too
    manifest, items, landmarks = prepare_grid(grid, out, source=source, characters=chars)
    previous = previous_hashes(out)
    status = {}
    todo = []
    for it, row in zip(items, manifest[manifest["shape"] != "photograph"].itertuples()):
        if previous.get(it.file) == row.input_hash and all((out / f).exists() for f in it.outputs()):
            status[it.file] = ("up to date", float("nan"))
        else:
            todo.append(it)
    logger.info("%s: %d images, %d up to date, %d to render", grid.name, len(manifest), len(status), len(todo))
    # rendered in runs that share an albedo (a grid lists materials inside expressions): a worker
    # keeps the texture it drew last on the GPU, and uploading (and mipmapping) a scan's 2400 x
    # 1600 albedo again for every image was a tenth of its time
    todo.sort(key=lambda t: (t.albedo_png, t.rig_npz))
    animated = grid.animation is not None  # every cell a clip (stimulus_engine.grid.animation)
    res = parallel_map(render_clip if animated else render_item, todo, n_jobs=n_jobs, scheduler=scheduler,
                       desc="rendering clips" if animated else "rendering", labels=[t.file for t in todo])
    failed = {f.index: f.error for f in res.failures}
    for i, (it, secs) in enumerate(zip(todo, res.results)):
        status[it.file] = (f"failed: {failed[i]}", float("nan")) if i in failed else ("rendered", float(secs))
    for idx in manifest.index[manifest["shape"] == "photograph"]:
        t0 = time.perf_counter()
        f = manifest.at[idx, "file"]
        place_photo(manifest.at[idx, "_photo"], out / f, grid.render.width, grid.render.height,
                     grid.render.background, _framing_reference(manifest, manifest.at[idx, "character"], out))
        status[f] = ("rendered", time.perf_counter() - t0)
    manifest["seconds"] = [round(status[f][1], 4) for f in manifest["file"]]
    manifest["status"] = [status[f][0] for f in manifest["file"]]
    performance = _performance_landmarks(manifest)
    manifest = manifest.drop(columns=[c for c in manifest.columns if c.startswith("_")])
    if animated:
        manifest = clip_checksums(out, manifest)
    shown = manifest
    if animated and grid.animation.revcorr is not None:  # a pool: its trials' parameters, its first trial shown
        pool = grid.animation.revcorr
        write_table(revcorr_trial_table(grid.animation), out / "revcorr_trials.csv")
        shown = manifest[manifest["revcorr_trial"] == pool.first].reset_index(drop=True)
    stills = apex_view(shown)  # a clip shown by its apex frame
    continuum = continuum_table(out, stills, grid, landmarks)
    if not continuum.empty:  # each measured image's identity distance to its character's realistic level
        distance = stills["file"].map(continuum.drop_duplicates("file").set_index("file")["identity_to_realistic"])
        if shown is manifest:
            manifest["identity_to_realistic"] = distance
        else:  # a pool's clips of one cell share its first trial's measure
            cells = ["character", "shape", "material"]
            per_cell = dict(zip(map(tuple, shown[cells].to_numpy()), distance))
            manifest["identity_to_realistic"] = [per_cell.get(tuple(k)) for k in manifest[cells].to_numpy()]
    write_table(manifest, out / "manifest.csv")
    write_table(landmarks, out / "landmarks.csv")
    atomic_write_text(out / "grid.json", json.dumps(grid.model_dump(mode="json"), indent=2))
    manifest.attrs["grid"] = grid
    sheets = (write_sheets(out, stills, grid) + (write_filmstrips(out, shown, grid) if animated else [])
              + write_continuum(out, continuum, grid)[1:])
    sheets += write_expression_measures(out, landmarks, grid)[2:]  # how far each expression moves the face, per level
    sheets += write_performance_measures(out, performance, grid.animation.fps if animated else None)[2:]
    if res.failures:
        logger.warning(res.summary())
    return manifest, sheets
