"""The stylisation continuum of a grid: levels spaced by measurement, and its report.

**Even material steps.** ``materials: {levels: N}`` (:class:`~stimulus_engine.grid.schema.MaterialContinuum`)
asks for N levels of the ``painted`` family (:mod:`stimulus_engine.stylisation.materials`).
:func:`even_materials` renders each character's realistic neutral face wearing
:data:`CANDIDATES` amounts of the family, measures the image distance between every two of
consecutive ones (:func:`~stimulus_engine.stylisation.image_distance.ssim_distance` inside the
face's oval, at the grid's own size and lighting) and picks the N amounts whose consecutive
images differ by equal distances (:func:`even_amounts`, interpolating between the candidates). A parameter
spaced evenly is not a look spaced evenly: the thesis's blur25 -> blur50 -> bilateral -> flat
steps differ by 0.018, 0.010, 0.011 and 0.100 on james and 0.003, 0.002, 0.003 and 0.045 on
Lee Perry-Smith.

**Even by value.** A continuum with ``spacing: even`` (a dense one for psychophysics, up to 101
levels) is not measured: :func:`spaced_by_value` writes its levels out evenly by value (or
amount), and :func:`needs_measuring` tells the grid workflow whether anything is left to render
probes for (:func:`stimulus_engine.grid.prepare.measured_grid`).

**The report.** :func:`continuum_table` measures a rendered grid along its continuum, per
character: each shape level (first material, neutral) and each material level (realistic
shape) against the realistic level and the next one, by image distance and by identity
distance (:mod:`~stimulus_engine.stylisation.identity`: dlib's face descriptor; the same person
within 0.6), and the identity distance to every other character's realistic level;
:func:`plot_continuum` draws it. :func:`write_continuum` writes ``continuum.csv`` and
``continuum.png`` beside the contact sheets.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from stimulus_engine.grid.schema import GridFile, MaterialContinuum, MaterialSpec, ShapeContinuum
from appeal.cells import write_table

__all__ = ["CANDIDATES", "EVEN_STEPS", "LEVEL_MEASURES", "common_levels", "continuum_table", "even_amounts", "even_materials", "even_shapes",
           "needs_measuring", "pins", "plot_continuum", "spaced_by_value", "write_continuum"]

logger = logging.getLogger(__name__)

#: Steps within this factor of each other count as even in the report (the issue's "within 2x").
EVEN_STEPS = 2.0
#: Amounts of the family rendered to measure it out.
CANDIDATES: tuple[float, ...] = tuple(np.linspace(0.0, 1.0, 5).round(4))
#: Then the levels themselves are rendered and re-spaced by their own steps, at most this many
#: times, until the largest step is within this factor of the smallest.
REFINE, EVEN_ENOUGH = 3, 1.2
#: How a shape step's image distance grows with the step (:func:`even_amounts`): on the ERP
#: grid's james, 0 -> 0.156 measured 0.137 where 0 -> 0.125 gave 0.124 and 0.125 -> 0.25 0.093.
SHAPE_POWER = 0.5


def even_amounts(candidates: np.ndarray, steps: np.ndarray, levels: int, power: float = 2.0) -> np.ndarray:
    """``levels`` amounts from the first candidate to the last whose consecutive images differ equally.

    ``1 - SSIM`` grows with the square of a small change (SSIM is 1 and flat at identity), so
    for small changes its square root is what adds up along a family: the candidates'
    cumulative sum of ``step ** (1 / power)`` is the family's length, and the levels divide it
    into equal parts (linear between candidates); each level's step is then the same
    ``(length / (levels - 1)) ** power`` where the family runs straight. ``power`` 2 fits the
    materials' small changes; a shape's change misaligns the features and saturates (two shape
    steps together measured less than either alone plus half the other): 0.5 fits it
    (:data:`SHAPE_POWER`).

    Parameters
    ----------
    candidates : (K,) array
        Increasing amounts.
    steps : (K - 1,) array
        Distance between the images of consecutive candidates.
    levels : int
    power : float
        How the distance grows with the change (above).

    Returns
    -------
    (levels,) array
        Increasing, from ``candidates[0]`` to ``candidates[-1]``.

    Examples
    --------
    >>> t = np.linspace(0, 1, 9)
    >>> look = np.where(t < 0.75, 0.1 * t, 0.075 + 3 * (t - 0.75))  # little change until 0.75, then much
    >>> np.round(even_amounts(t, np.diff(look) ** 2, 3), 3)           # half the length: just past the knee
    array([0.   , 0.862, 1.   ])
    """
    t = np.asarray(candidates, np.float64)
    length = np.concatenate([[0.0], np.cumsum(np.maximum(np.asarray(steps, np.float64), 0.0) ** (1.0 / power))])
    if length[-1] <= 0:
        return np.linspace(t[0], t[-1], levels)
    keep = np.concatenate([[True], np.diff(length) > 0])  # np.interp needs increasing lengths
    return np.interp(np.linspace(0.0, length[-1], levels), length[keep], t[keep])


def common_levels(candidates: np.ndarray, steps: np.ndarray, levels: int, power: float = 2.0,
                  mixes: int = 21) -> np.ndarray:
    """One set of ``levels`` amounts for several characters, each of whose images steps differently
    (``steps``: (characters, K - 1)): spaced evenly along a mixture of the characters' normalised
    lengths (:func:`even_amounts`), the mixture chosen so that the worst character's largest step
    is the least multiple of its smallest (each character's steps predicted from its measured
    length between the candidates).

    Examples
    --------
    >>> t = np.linspace(0, 1, 5)
    >>> same = np.array([[1.0, 1.0, 1.0, 1.0], [4.0, 4.0, 4.0, 4.0]])  # one scaled by 4: no compromise
    >>> np.round(common_levels(t, same, 3), 3)
    array([0. , 0.5, 1. ])
    """
    t = np.asarray(candidates, np.float64)
    root = np.maximum(np.atleast_2d(np.asarray(steps, np.float64)), 0.0) ** (1.0 / power)
    length = np.concatenate([np.zeros((len(root), 1)), np.cumsum(root, axis=1)], axis=1)
    share = root / np.maximum(length[:, -1:], 1e-12)  # each character's length, normalised to 1

    def worst(at: np.ndarray) -> float:
        pred = np.diff(np.array([np.interp(at, t, row) for row in length]), axis=1) ** power
        return float(np.max(pred.max(axis=1) / np.maximum(pred.min(axis=1), 1e-12)))

    best = None
    for weights in _mixtures(len(root), mixes):
        at = even_amounts(t, (weights @ share) ** power, levels, power)
        score = worst(at)
        if best is None or score < best[0] - 1e-12:
            best = (score, at)
    return best[1]


def _mixtures(n: int, steps: int) -> list[np.ndarray]:
    """Weights of ``n`` characters to try: equal ones, and for two characters every mix in ``steps``
    steps; for more, each character's alone and half with the equal mix."""
    equal = np.full(n, 1.0 / n)
    if n == 1:
        return [equal]
    if n == 2:
        return [np.array([a, 1 - a]) for a in np.linspace(0, 1, steps)]
    return [equal] + [np.eye(n)[i] for i in range(n)] + [(np.eye(n)[i] + equal) / 2 for i in range(n)]


def _refined(stored: Path, name: str, start: np.ndarray, steps: Callable[[np.ndarray], np.ndarray],
             space: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> list:
    """Levels measured out, or read back from ``stored`` (JSON, under ``name``).

    ``steps(at)`` renders amounts ``at`` (the :data:`CANDIDATES` for all characters, or a row of
    them per character) and returns the steps between neighbours (one row per character);
    ``space(at, steps)`` places the levels from measured amounts. First ``start``, then the
    levels themselves, re-spaced by their own steps up to :data:`REFINE` times until the worst
    row's largest step is within :data:`EVEN_ENOUGH` of its smallest; every round is kept in the
    record.
    """
    if stored.exists():
        return json.loads(stored.read_text())[name]
    first = steps(start)
    record: dict = {"candidates": start.tolist(), "candidate_steps": first.round(6).tolist()}
    levels = space(start, first)
    for round_ in range(1, REFINE + 1):  # measure the levels themselves, re-space them by what they show
        measured = steps(levels)
        record[f"round{round_}"] = {name: levels.round(4).tolist(), "steps": measured.round(6).tolist()}
        worst = max(row.max() / max(row.min(), 1e-12) for row in np.atleast_2d(measured))
        if worst <= EVEN_ENOUGH or round_ == REFINE:
            break
        levels = space(levels, measured)
    record[name] = np.round(levels, 4).tolist()
    stored.parent.mkdir(parents=True, exist_ok=True)
    stored.write_text(json.dumps(record))
    return record[name]


def _probe_of(grid: GridFile, **update: object) -> GridFile:
    """A probe grid: ``grid`` neutral (or its first expression), in its first lighting and
    shading, without photographs, with ``update``'s shapes and materials."""
    expression = "neutral" if "neutral" in grid.expressions else grid.expressions[0]
    return grid.model_copy(update={"name": f"{grid.name}_probe", "expressions": [expression],
                                   "lighting": grid.lighting[:1], "shading": grid.shading[:1], "photographs": [],
                                   **update})


def _probe(grid: GridFile, amounts: np.ndarray) -> GridFile:
    """A grid of every character's realistic neutral face wearing each amount of the family
    (``amounts``: a row of them per character)."""
    names = [c.name for c in grid.characters]
    mats = [MaterialSpec(name=f"c{i}", style="painted", amount={c: float(a) for c, a in zip(names, column)})
            for i, column in enumerate(np.asarray(amounts).T)]
    return _probe_of(grid, shapes=[min(grid.shape_levels())], materials=mats, pair_materials_with_shapes=False)


def _per_character(images: list[np.ndarray], characters: int, mask: np.ndarray) -> np.ndarray:
    """The image steps between neighbouring levels, a row per character (a probe's images come
    character by character)."""
    from stimulus_engine.stylisation.image_distance import ssim_distance

    rows = np.array_split(np.arange(len(images)), characters)
    return np.array([[ssim_distance(images[a], images[b], mask) for a, b in zip(r, r[1:])] for r in rows])


def _mask(grid: GridFile) -> np.ndarray:
    from stimulus_engine.stylisation.image_distance import face_mask

    r = grid.render
    return face_mask(r.width, r.height, r.eye_row, r.face_fraction)


def even_materials(grid: GridFile, cache: Path, render: Callable[[GridFile], list[np.ndarray]]) -> GridFile:
    """``grid`` with its :class:`MaterialContinuum` measured out: explicit ``painted`` materials
    whose amounts (one per character) give equal image steps (see the module docstring); a grid
    with listed materials is returned as it is.

    Parameters
    ----------
    grid : GridFile
    cache : Path
        The grid's input cache; the measurement is kept in ``cache/continuum``.
    render : callable
        ``render(probe_grid)``: the probe grid's images, character by character and in material
        order (the grid's own preparation and renderer: :func:`stimulus_engine.grid.prepare.measured_grid`
        passes it). Every character is measured in the same probes, one per round, so that the
        workers share out the stylisation and rendering of all of them.
    """
    from stimulus_engine.grid.cache import GRID_VERSION, sha

    cont = grid.materials
    if not isinstance(cont, MaterialContinuum):
        return grid
    if cont.spacing == "even":  # spaced by amount: nothing rendered
        return grid.model_copy(update={"materials": cont.specs()})
    mask = _mask(grid)
    amounts = {c.name: cont.measured[c.name] for c in grid.characters if c.name in cont.measured}
    todo = grid.model_copy(update={"characters": [c for c in grid.characters if c.name not in amounts]})
    if todo.characters:  # measured together: one probe per round
        names = [c.name for c in todo.characters]
        start = np.tile(np.asarray(CANDIDATES), (len(names), 1))
        key = sha(GRID_VERSION, "materials", _probe(todo, start).model_dump_json(), cont.levels)
        at = _refined(Path(cache) / "continuum" / f"{key}.json", "amounts", start,
                      lambda at: _per_character(render(_probe(todo, at)), len(names), mask),
                      lambda at, measured: np.array([even_amounts(a, m, cont.levels) for a, m in zip(at, measured)]))
        amounts.update(zip(names, at))
        for c in names:
            logger.info("%s: material levels of %s measured at amounts %s", grid.name, c, amounts[c])
    specs = [MaterialSpec(name=s.name, style="painted", amount={c: amounts[c][k] for c in amounts})
             for k, s in enumerate(MaterialContinuum(levels=cont.levels).specs())]
    return grid.model_copy(update={"materials": specs if cont.order == "original_first" else specs[::-1]})


def _paired_material(grid: GridFile, position: float) -> MaterialSpec:
    """The material worn at ``position`` (0 realistic .. 1 most stylised) along the scale: with
    materials paired with shapes and measured out (``painted``), the amount interpolated between
    the levels (per character); otherwise the realistic end's material."""
    specs = grid.material_specs()
    order = sorted(range(len(specs)), key=lambda i: grid.shape_levels()[i]) if grid.pair_materials_with_shapes \
        else [0]
    ends = [specs[i] for i in order]
    if not grid.pair_materials_with_shapes or any(m.style != "painted" for m in ends):
        return ends[0]
    u = np.linspace(0.0, 1.0, len(ends))
    names = [c.name for c in grid.characters]
    return MaterialSpec(name="m", style="painted",
                        amount={c: float(np.interp(position, u, [m.amount_for(c) for m in ends])) for c in names})


def even_shapes(grid: GridFile, cache: Path, render: Callable[[GridFile], list[np.ndarray]]) -> GridFile:
    """``grid`` with its :class:`ShapeContinuum` measured out: explicit shape values, the same for
    every character, whose neighbouring levels differ by equal image steps (averaged over the
    characters: the square roots of their steps, as :func:`even_amounts`), each rendered neutral
    wearing its paired material (:func:`_paired_material`; measure the materials first,
    :func:`even_materials`). Candidates, then the levels re-spaced by their own steps, as for
    materials; cached in ``cache/continuum``."""
    from stimulus_engine.grid.cache import GRID_VERSION, sha

    cont = grid.shapes
    if not isinstance(cont, ShapeContinuum):
        return grid
    if cont.spacing == "even":  # spaced by value: nothing rendered
        return grid.model_copy(update={"shapes": cont.values()})
    values = list(cont.measured) if cont.measured is not None else None
    if values is None:
        mask = _mask(grid)
        names = [c.name for c in grid.characters]

        def probe(at: np.ndarray) -> GridFile:
            mats = [_paired_material(grid, float(a)).model_copy(update={"name": f"c{i}"}) for i, a in enumerate(at)]
            return _probe_of(grid, shapes=[float(a) for a in at], materials=mats, pair_materials_with_shapes=True)

        key = sha(GRID_VERSION, "shapes", probe(np.asarray(CANDIDATES)).model_dump_json(), cont.levels)
        values = _refined(Path(cache) / "continuum" / f"{key}.json", "values", np.asarray(CANDIDATES),
                          lambda at: _per_character(render(probe(at)), len(names), mask),
                          lambda at, measured: common_levels(at, measured, cont.levels, SHAPE_POWER))
        logger.info("%s: shape levels measured at %s", grid.name, values)
    return grid.model_copy(update={"shapes": values if cont.order == "realistic_first" else values[::-1]})


def measured(grid: GridFile, cache: Path, render: Callable[[GridFile], list[np.ndarray]]) -> GridFile:
    """``grid`` with its material and shape continua measured out (:func:`even_materials`, then
    :func:`even_shapes`, which renders the shapes in the measured materials); continua with
    ``spacing: even`` are written out by value (:func:`spaced_by_value`), nothing rendered."""
    return even_shapes(even_materials(grid, cache, render), cache, render)


def spaced_by_value(grid: GridFile) -> GridFile:
    """``grid`` with its ``spacing: even`` continua written out as listed levels (shape values, or
    ``painted`` materials at evenly spaced amounts); measured continua are left as they are.
    Nothing is rendered or read.

    Examples
    --------
    >>> from stimulus_engine.grid.schema import CharacterSpec
    >>> g = GridFile(kind="grid", name="g", characters=[CharacterSpec(name="a", procedural={})],
    ...              shapes={"levels": 41, "spacing": "even"}, materials=["original"], expressions=["neutral"])
    >>> v = spaced_by_value(g).shapes
    >>> len(v), v[:3], v[-1]
    (41, [0.0, 0.025, 0.05], 1.0)
    """
    update: dict[str, object] = {}
    if isinstance(grid.materials, MaterialContinuum) and grid.materials.spacing == "even":
        update["materials"] = grid.materials.specs()
    if isinstance(grid.shapes, ShapeContinuum) and grid.shapes.spacing == "even":
        update["shapes"] = grid.shapes.values()
    return grid.model_copy(update=update) if update else grid


def needs_measuring(grid: GridFile) -> bool:
    """Whether ``grid`` has a continuum spaced by measurement (``spacing: measured``, the
    default) still to be written out: only then are probe images rendered."""
    return any(isinstance(c, (MaterialContinuum, ShapeContinuum)) and c.spacing == "measured"
               for c in (grid.materials, grid.shapes))


def pins(spec: GridFile, grid: GridFile) -> dict[str, dict]:
    """The levels ``grid`` measured for the continua ``spec`` (its grid file) left to measure, as
    the ``measured`` fields that pin them: ``{"materials": {...}, "shapes": {...}}`` (only the
    factors with something measured).

    Examples
    --------
    >>> from stimulus_engine.grid.schema import CharacterSpec
    >>> spec = GridFile(kind="grid", name="g", characters=[CharacterSpec(name="a", procedural={})],
    ...                 shapes={"levels": 3}, materials=["original"], expressions=["neutral"])
    >>> pins(spec, spec.model_copy(update={"shapes": [0.0, 0.31, 1.0]}))
    {'shapes': {'levels': 3, 'measured': [0.0, 0.31, 1.0]}}
    """
    out: dict[str, dict] = {}
    cont = spec.materials
    if isinstance(cont, MaterialContinuum) and cont.spacing == "measured":  # an even one is spaced by amount
        todo = [c.name for c in spec.characters if c.name not in cont.measured]
        if todo:
            specs = grid.material_specs()
            measured = {**cont.measured, **{c: sorted(round(m.amount_for(c), 4) for m in specs) for c in todo}}
            out["materials"] = {**cont.model_dump(exclude_defaults=True), "measured": measured}
    shapes = spec.shapes
    if isinstance(shapes, ShapeContinuum) and shapes.spacing == "measured" and shapes.measured is None:
        out["shapes"] = {**shapes.model_dump(exclude_defaults=True),
                         "measured": sorted(round(float(v), 4) for v in grid.shape_levels())}
    return out


def _slices(grid: GridFile, manifest: pd.DataFrame) -> list[tuple[str, str, pd.DataFrame]]:
    """(character, factor, rows from the realistic end) of each continuum the report measures: the
    shape levels (the first material; with paired materials, each shape with its own: factor
    ``shape+material``) and the material levels (the realistic shape); neutral (or the first
    expression), the first lighting and shading."""
    expression = "neutral" if "neutral" in grid.expressions else grid.expressions[0]
    m = manifest[manifest["status"].isin(["rendered", "up to date"])]
    m = m[(m["expression"] == expression) & (m["lighting"] == grid.lighting[0]) & (m["shading"] == grid.shading[0])
          & (m["shape"] != "photograph")]
    mats = [s.name for s in grid.material_specs()]
    out = []
    for ch in dict.fromkeys(m["character"]):
        own = m[m["character"] == ch].copy()
        own["shape"] = own["shape"].astype(float)
        if grid.pair_materials_with_shapes:
            out.append((ch, "shape+material", own.sort_values("shape")))
            continue
        out.append((ch, "shape", own[own["material"] == mats[0]].sort_values("shape")))
        if len(mats) > 1:
            real = own[own["shape"] == own["shape"].min()]
            out.append((ch, "material", real.set_index("material").loc[[n for n in _material_order(grid)
                                                                         if n in set(real["material"])]].reset_index()))
    return out


def _material_order(grid: GridFile) -> list[str]:
    """Material names from the realistic end: ``painted`` levels (a continuum's) by amount, listed
    styles as listed."""
    specs = grid.material_specs()
    if all(s.style == "painted" for s in specs):
        specs = sorted(specs, key=lambda s: s.amount_for(grid.characters[0].name))
    return [s.name for s in specs]


#: The neoteny measures (rig landmarks, neutral) the report gives per level (thesis Fig. 7.10).
LEVEL_MEASURES: tuple[str, ...] = ("eye_area", "eye_roundness", "nose_width", "mouth_width", "forehead_height")


def _level_measures(landmarks: pd.DataFrame | None) -> dict[tuple[str, float], dict[str, float]]:
    """(character, shape) -> :data:`LEVEL_MEASURES` of its neutral (first expression) geometry."""
    from stimulus_engine.stylisation.neoteny import neoteny_measures

    if landmarks is None or landmarks.empty:
        return {}
    expression = "neutral" if "neutral" in set(landmarks["expression"]) else landmarks["expression"].iloc[0]
    out = {}
    for (ch, shape), g in landmarks[landmarks["expression"] == expression].groupby(["character", "shape"]):
        m = neoteny_measures({r.landmark: np.array([r.x, r.y, r.z], float) for r in g.itertuples()})
        out[str(ch), float(shape)] = {k: m[k] for k in LEVEL_MEASURES}
    return out


def _cheek_detail(image: np.ndarray) -> float:
    """:func:`~stimulus_engine.stylisation.image_distance.cheek_detail` of the face dlib finds (NaN without one)."""
    from appeal.errors import AppealInputError
    from stimulus_engine.stylisation.image_distance import cheek_detail
    from stimulus_engine.morphpca.keypoints import detect_landmarks

    try:
        return cheek_detail(image, detect_landmarks(image))
    except AppealInputError:
        return float("nan")


def continuum_table(out: Path, manifest: pd.DataFrame, grid: GridFile,
                    landmarks: pd.DataFrame | None = None) -> pd.DataFrame:
    """The continuum of a rendered grid, one row per (character, factor, level) (module docstring).

    Columns: character, factor (``shape``, ``material`` or ``shape+material``), position (0 at
    the realistic end), level (its shape value or material name), file, image_to_realistic,
    image_to_next (the image distance to the next level; empty at the last), identity_to_realistic
    (to the same factor's realistic level), identity_to_nearest_other (the least identity
    distance to another character's realistic level of the same factor), same_person (identity
    to realistic within :data:`~stimulus_engine.stylisation.identity.SAME_PERSON`), cheek_detail
    (:func:`~stimulus_engine.stylisation.image_distance.cheek_detail`: fine skin detail in the cheeks) and, from
    the grid's ``landmarks`` (its rig landmarks), the level's :data:`LEVEL_MEASURES`.
    """
    from PIL import Image

    from stimulus_engine.stylisation.identity import SAME_PERSON, face_descriptor, framing_box, identity_distance
    from stimulus_engine.stylisation.image_distance import ssim_distance

    r = grid.render
    mask = _mask(grid)
    box = framing_box(r.width, r.height, r.eye_row, r.face_fraction)
    images: dict[str, np.ndarray] = {}
    descriptors: dict[str, np.ndarray] = {}

    def image(f: str) -> np.ndarray:
        if f not in images:
            with Image.open(Path(out) / f) as im:
                images[f] = np.asarray(im.convert("RGB"))
        return images[f]

    def descriptor(f: str) -> np.ndarray:
        if f not in descriptors:
            descriptors[f] = face_descriptor(image(f), box)
        return descriptors[f]

    shapes = _level_measures(landmarks)
    slices = [(ch, factor, rows) for ch, factor, rows in _slices(grid, manifest) if len(rows)]  # none where all failed
    realistic = {(ch, factor): rows["file"].iloc[0] for ch, factor, rows in slices}
    table = []
    for ch, factor, rows in slices:
        files = list(rows["file"])
        levels = list(rows["material"] if factor == "material" else rows["shape"])
        others = [f for (c, fac), f in realistic.items() if fac == factor and c != ch]
        for i, f in enumerate(files):
            to_real = identity_distance(descriptor(files[0]), descriptor(f))
            table.append({
                "character": ch, "factor": factor, "position": i, "level": levels[i], "file": f,
                "image_to_realistic": ssim_distance(image(files[0]), image(f), mask),
                "image_to_next": ssim_distance(image(f), image(files[i + 1]), mask) if i + 1 < len(files) else np.nan,
                "identity_to_realistic": to_real,
                "identity_to_nearest_other": min((identity_distance(descriptor(o), descriptor(f)) for o in others),
                                                 default=np.nan),
                "same_person": bool(to_real <= SAME_PERSON), "cheek_detail": _cheek_detail(image(f)),
                **shapes.get((str(ch), float(rows["shape"].iloc[i])), {k: np.nan for k in LEVEL_MEASURES})})
    return pd.DataFrame(table)


#: The most characters :func:`plot_continuum` names in a legend.
LEGEND_MAX = 12


def plot_continuum(table: pd.DataFrame, path: Path) -> Path:
    """Image step and identity distance along each continuum, a panel per factor (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stimulus_engine.stylisation.identity import SAME_PERSON

    factors = list(dict.fromkeys(table["factor"]))
    fig, axes = plt.subplots(2, len(factors), figsize=(4.2 * len(factors), 6.4), squeeze=False,
                             constrained_layout=True)
    for j, factor in enumerate(factors):
        sub = table[table["factor"] == factor]
        for ch, g in sub.groupby("character", sort=False):
            line = axes[0, j].plot(g["position"][:-1] + 0.5, g["image_to_next"][:-1], marker="o", label=str(ch))[0]
            axes[1, j].plot(g["position"], g["identity_to_realistic"], marker="o", color=line.get_color(), label=str(ch))
            axes[1, j].plot(g["position"], g["identity_to_nearest_other"], ls="--", color=line.get_color(), alpha=0.6)
        labels = sub.drop_duplicates("position").sort_values("position")["level"].astype(str)
        for ax in axes[:, j]:
            ax.set_xticks(range(len(labels)), [str(x)[:9] for x in labels], rotation=30, fontsize=8)
        axes[0, j].set_title(f"{factor}: step between neighbouring levels")
        axes[0, j].set_ylabel("1 - SSIM (luma, face oval)")
        top = sub["image_to_next"].max()  # NaN with a single level
        axes[0, j].set_ylim(0, 1.15 * float(top) if top > 0 else 1.0)  # the points inside the frame
        axes[1, j].axhline(SAME_PERSON, color="grey", lw=0.8)
        axes[1, j].set_title(f"{factor}: identity distance (dlib)")
        axes[1, j].set_ylabel("to own realistic (solid), other's (dashed)")
        n = sub["character"].nunique()
        if n <= LEGEND_MAX:
            axes[0, j].legend(fontsize=8)
        else:  # a legend of every character would squeeze the panels to nothing
            axes[0, j].text(0.02, 0.97, f"{n} characters, a line each", transform=axes[0, j].transAxes, va="top",
                            fontsize=8)
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_continuum(out: Path, table: pd.DataFrame, grid: GridFile) -> list[Path]:
    """``continuum.csv`` and ``continuum.png`` (of :func:`continuum_table`) in ``out``, each step logged."""

    if table.empty:
        return []
    for (ch, factor), g in table.groupby(["character", "factor"], sort=False):
        steps = g["image_to_next"].dropna()
        ratio = steps.max() / max(steps.min(), 1e-12) if len(steps) else 1.0
        logger.info("%s: %s %s steps %s (largest / smallest %.2f: %s); reaches %.3f from the realistic level; "
                    "identity to realistic %s; cheek detail %s of the realistic level's", grid.name, ch, factor,
                    ", ".join(f"{x:.4f}" for x in steps), ratio, "even" if ratio <= EVEN_STEPS else "uneven",
                    float(g["image_to_realistic"].iloc[-1]), ", ".join(f"{x:.2f}" for x in g["identity_to_realistic"]),
                    ", ".join(f"{x / g['cheek_detail'].iloc[0]:.2f}" for x in g["cheek_detail"]))
    csv = write_table(table, Path(out) / "continuum.csv", float_format="%.5f")
    return [csv, plot_continuum(table, Path(out) / "continuum.png")]
