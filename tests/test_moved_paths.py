"""The flat layout's module paths still import for one release, with a warning naming the new path."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

from stimulus_engine._moved import MOVED

ROOT = Path(__file__).resolve().parent.parent

#: What the modules that were split exported before (their ``__all__`` in the flat layout).
SPLIT_BEFORE = {
    "stimulus_engine.materials": ["FLAT_NORMAL", "MAP_KINDS", "MATERIAL_LEVELS", "MATERIAL_STYLES", "SHADINGS",
                                  "albedo_hash", "bake_surface_points", "check_map", "maps_hash", "rig_albedo",
                                  "rig_detail_maps", "stylise_albedo", "stylise_map", "stylise_material"],
    "stimulus_engine.ict": ["ICT_GEOMETRY_RANGES", "ict_regions", "load_ict_rig"],
    "stimulus_engine.texture_transfer": ["rasterize_uv", "dilate", "transfer_texture"],
}

_PROBE = r"""
import importlib, json, sys, warnings
old, split = json.loads(sys.argv[1]), json.loads(sys.argv[2])
import stimulus_engine
out = {}
for name, targets in old.items():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mod = importlib.import_module(name)
    new = importlib.import_module(targets[0])
    out[name] = {"warnings": [(w.category.__name__, str(w.message), w.filename) for w in caught],
                 "same": mod is new,
                 "missing": [n for n in split.get(name, []) if not hasattr(mod, n)]}
from stimulus_engine.materials import rig_albedo, stylise_albedo
out["from-import"] = [rig_albedo.__module__, stylise_albedo.__module__]
from stimulus_engine import hair
out["from-package"] = hair.__name__
print(json.dumps(out))
"""


def test_old_paths_import_with_a_warning(tmp_path):
    script = tmp_path / "probe.py"
    script.write_text(_PROBE)
    res = subprocess.run([sys.executable, str(script), json.dumps(MOVED), json.dumps(SPLIT_BEFORE)],
                         capture_output=True, text=True, cwd=ROOT, check=True)
    out = json.loads(res.stdout)
    for old, targets in MOVED.items():
        got = out[old]
        assert [w[0] for w in got["warnings"]] == ["DeprecationWarning"], (old, got)
        category, message, filename = got["warnings"][0]
        assert message.startswith(f"{old} is now {targets[0]}") and filename == str(script), (old, got)
        assert got["same"] == (len(targets) == 1) and got["missing"] == [], (old, got)
    assert out["from-import"] == ["stimulus_engine.characters.skin_maps", "stimulus_engine.stylisation.materials"]
    assert out["from-package"] == "stimulus_engine.parts.hair"


def test_old_paths_are_gone_from_disk_and_new_ones_exist():
    for old, targets in MOVED.items():
        assert not (ROOT / (old.replace(".", "/") + ".py")).exists(), old
        assert all((ROOT / (t.replace(".", "/") + ".py")).is_file() for t in targets), targets


def test_nothing_in_the_repository_imports_an_old_path():
    """The deprecated paths are for users' scripts only: every caller here uses the new ones."""
    wrong = []
    for folder in ("stimulus_engine", "appeal", "appeal_cli", "experiments", "analysis", "tests", "benchmarks", "scripts"):
        for f in (ROOT / folder).rglob("*.py"):
            for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
                names = []
                if isinstance(node, ast.Import):
                    names = [a.name for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
                    names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
                wrong += [f"{f.relative_to(ROOT)}:{node.lineno}: {n}" for n in names if n in MOVED]
    assert wrong == []
