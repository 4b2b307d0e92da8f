"""Render a stimulus grid: characters × shapes × materials × expressions × lighting × shading.

:func:`run_grid` plans every image (with a hash of everything that determines its pixels),
prepares the shared inputs once in this process (stylised shapes with expressions carried over by
deformation transfer, stylised albedos) into ``DIR/.cache``, renders the images that are not
already up to date in parallel worker processes (one OpenGL context each; Dask when a scheduler
is given), and writes:

``DIR/manifest.csv``
    One row per image: ``file`` (relative to DIR), the factors ``character``, ``shape`` (level
    0 = realistic .. 1 = cartoon), ``shape_label`` (``realistic``, ``shape0.5``, ``cartoon``:
    what file names and contact sheets say), ``stylisation`` (the thesis's level number, the
    same way round in every grid: 0 = the grid's most stylised shape level, counting up towards
    the realistic end; photographs above all, see :meth:`GridFile.stylisation_index`), ``material``, ``expression``
    (canonical), ``emotion`` (as written in the grid), ``lighting``, ``shading``; the input
    hashes ``geometry_hash``, ``albedo_hash``, ``maps_hash`` (normal and specular maps, ``none``
    without), ``input_hash``; ``camera``; ``seconds``; ``status``.
``DIR/landmarks.csv``
    3D landmarks of every (character, shape, expression) geometry (for neoteny measures).
``DIR/contact_sheet.png`` (+ ``contact_sheet_expressions.png``, ``contact_sheet_lighting.png``)
    Rows = character × shape level, columns = materials (thesis Fig. 6.11), for the first
    expression/lighting/shading; and the same rows against expressions (and lighting/shading).
    Only the cells the grid has: with ``pair_materials_with_shapes`` the first sheet has one row
    per character and one column per shape+material pair.
``DIR/continuum.csv``, ``continuum.png``
    The stylisation continuum (:mod:`~stimulus_engine.grid.continuum`).
``DIR/expression_measures.csv``, ``expression_agreement.csv``, ``expression_measures.png``
    With a neutral and another expression at more than one shape level: how far each expression
    moves the face at each level in face lengths, and how far the levels agree
    (:mod:`~stimulus_engine.grid.expression_measures`).
``DIR/performance_measures.csv``, ``performance_agreement.csv``, ``performance_measures.png``
    With ``animation: {performance: ...}`` at more than one shape level: every frame's measures
    per level and how far each level performs the realistic one's movement
    (:mod:`~stimulus_engine.grid.performance_measures`).
``DIR/clips/<stem>/frame_00000.png`` ..., ``DIR/clips/<stem>.mp4``, ``DIR/filmstrip_<character>.png``
    With ``animation:`` every cell is a clip from neutral to its apex instead of an image: its
    lossless PNG frames and an H.264 MP4, one manifest row per clip (its ``file`` the MP4, with
    ``frames``, ``n_frames``, ``fps``, ``onset_frame``, ``apex_frame``, ``weight_curve``,
    ``frames_sha256``, ``mp4_sha256``); the contact sheets show the apex frames, a filmstrip per
    character the onset over time (:mod:`~stimulus_engine.grid.animation`).

A re-run over the same folder (``--resume``) skips images (and clips) whose ``input_hash`` and
files are unchanged.

The package, one step per module (each usable on its own):

:mod:`~stimulus_engine.grid.plan`
    The images of a grid from the grid file alone (pure).
:mod:`~stimulus_engine.grid.characters`
    The rig of each character by kind (:data:`~stimulus_engine.grid.characters.CHARACTER_KINDS`:
    ICT, procedural; a mesh corresponded on top) and its albedo.
:mod:`~stimulus_engine.grid.prepare`
    Inputs prepared once each in ``DIR/.cache`` (:mod:`~stimulus_engine.grid.cache`), one
    render item and manifest row per planned image.
:mod:`~stimulus_engine.grid.worker`
    One image rendered by a render engine (:data:`~stimulus_engine.grid.worker.ENGINES`).
:mod:`~stimulus_engine.grid.animation`
    An animated grid's weight curve, its clips' frames prepared and rendered.
:mod:`~stimulus_engine.grid.sheets`
    Contact sheets.
:mod:`~stimulus_engine.grid.run`
    :func:`run_grid`, the workflow's one entry.
"""

from appeal.lazy import attach as _attach

# the modules load on first use (appeal.lazy: Scientific Python SPEC 1)
__getattr__, __dir__, _ = _attach(
    __name__,
    submodules=["animation", "cache", "characters", "continuum", "designs", "engine_sheet", "examples",
                "expression_measures", "inputs", "performance_measures", "photo_framing", "photo_sheet", "plan", "prepare", "run",
                "schema", "sheets", "worker"],
    submod_attrs={
        "cache": ["GRID_VERSION"],
        "plan": ["plan_images", "plan_photos"],
        "prepare": ["prepare_grid"],
        "run": ["run_grid"],
        "sheets": ["sheet_layout"],
        "worker": ["RenderItem", "render_item"],
    },
)

__all__ = ["GRID_VERSION", "RenderItem", "plan_images", "plan_photos", "prepare_grid", "render_item", "run_grid",
           "sheet_layout"]
