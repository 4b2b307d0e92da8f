"""The command line starts at once (issue 52, part 1; issue 50's start-up): ``--help`` of the whole command,
of a statistics command and of the retargeting command loads neither the stimulus engine's sub-packages nor
MNE, PsychoPy, Numba, OpenCV, dlib or OpenGL (they load on first use: ``lazy_loader``, SPEC 1). No timing is
asserted; ``python -X importtime`` lists what was imported."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

#: Modules a ``--help`` must not import (the heavy ones: each costs 0.2-3 s here).
HEAVY = ("mne", "psychopy", "numba", "cv2", "dlib", "pyrender", "OpenGL", "trimesh", "skimage", "pyglet")
#: What of the project's own packages may load: their lazy ``__init__``s, and one module of defaults
#: written to be imported by the command line (no imports of its own).
ALLOWED = {"stimulus_engine", "stimulus_engine._moved", "stimulus_engine.morphpca", "stimulus_engine.morphpca.defaults",
           "analysis", "experiments"}


def _imported(*args: str) -> list[str]:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "appeal_cli", *args], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return [ln.rsplit("|", 1)[1].strip() for ln in r.stderr.splitlines() if ln.startswith("import time:") and "|" in ln]


@pytest.mark.parametrize("args", [("--help",), ("analyze", "lmm", "--help"), ("stimuli", "retarget", "--help")])
def test_help_imports_nothing_heavy(args):
    mods = _imported(*args)
    assert "appeal_cli" in mods
    heavy = sorted({m for m in mods if m.split(".")[0] in HEAVY})
    assert not heavy, f"appeal {' '.join(args)} imported {heavy[:8]}"
    own = sorted({m for m in mods if m.split(".")[0] in ("stimulus_engine", "analysis", "experiments")} - ALLOWED)
    assert not own, f"appeal {' '.join(args)} imported {own[:8]}"


@pytest.mark.parametrize("args", [("--help",), ("analyze", "revcorr", "--help"), ("validate", "--help")])
def test_help_of_the_command_line_imports_neither_numpy_nor_pydantic(args):
    """Finding the commands imports the command modules only (not their helpers), and they import
    NumPy, pandas and the study-file schemas when they run."""
    mods = set(_imported(*args))
    assert not {"numpy", "pandas", "pydantic", "appeal.studyfile", "tqdm"} & mods, sorted(mods)[:20]


def test_the_command_keeps_freed_heap_unless_the_user_set_it(monkeypatch):
    """appeal.allocator: glibc's top pad set through mallopt (what MALLOC_TOP_PAD_ does), left alone
    when the user chose one."""
    from appeal.allocator import keep_heap_pad

    monkeypatch.delenv("MALLOC_TOP_PAD_", raising=False)
    assert keep_heap_pad(64) is True  # the machines this project runs on use glibc
    monkeypatch.setenv("MALLOC_TOP_PAD_", "0")
    assert keep_heap_pad(64) is False


def test_public_names_still_load_on_first_use():
    import stimulus_engine
    from stimulus_engine import characters

    assert callable(stimulus_engine.load_ict_rig) and callable(characters.retarget_performance)
    assert "run_grid" in dir(stimulus_engine) and stimulus_engine.grid.run_grid is stimulus_engine.run_grid
    with pytest.raises(AttributeError):
        stimulus_engine.no_such_name  # noqa: B018


def test_a_name_that_is_its_modules_name_stays_the_function():
    """``render.contact_sheet`` (the function in ``render/contact_sheet.py``): importing the module binds
    the module to the package's name; the lazy package keeps the name the function (appeal.lazy)."""
    import types

    import stimulus_engine.render.contact_sheet  # noqa: F401 - the import that would shadow the name
    from stimulus_engine import morphpca, render

    assert not isinstance(render.contact_sheet, types.ModuleType) and callable(render.contact_sheet)
    assert callable(morphpca.pca) and not isinstance(morphpca.pca, types.ModuleType)
