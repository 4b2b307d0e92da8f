"""The house drawn from its imports: no arrow runs back up between folders, no import circle.

Folders: the core ``appeal`` (errors, study files, outputs, levels, triggers ...), three rooms
(``stimulus_engine``, ``experiments``, ``analysis``) and the roof ``appeal_cli`` (the command
line). The core imports no room and not the roof; a room imports the core only, never another
room or the roof. Between modules there is no circle at all.

Inside the stimulus engine the same holds between its sub-packages (:data:`ENGINE_LAYERS`:
``geometry`` at the bottom, ``grid`` at the top); its top level keeps a few modules only.

Every ``import`` statement counts, at module level and inside functions (a lazy import is still
an arrow: it runs when the function does); imports under ``if TYPE_CHECKING:`` do not (they
never run), except for one check: no two modules name each other even there (a type both need
lives in a module of its own). ``from pkg import name`` is an arrow to ``pkg.name`` when that is
a module, else to ``pkg`` (its ``__init__``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CORE, ROOF = "appeal", "appeal_cli"
ROOMS = ("stimulus_engine", "experiments", "analysis")
PACKAGES = (CORE, ROOF, *ROOMS)

#: The stimulus engine's sub-packages, lowest first, and what each may import besides itself.
#: Its top-level modules (``stimulus_engine``, ``stimulus_engine._moved``) may import any of them;
#: no sub-package imports the top level.
ENGINE_LAYERS: dict[str, set[str]] = {
    "data": set(),
    "geometry": {"data"},
    "render": {"data", "geometry"},
    "morphpca": {"data", "geometry"},
    "correspondence": {"data", "geometry", "render", "morphpca"},
    "parts": {"data", "geometry"},
    # a character from a photograph reads its landmarks (morphpca's dlib points, faces2d's .tem)
    "characters": {"data", "geometry", "render", "morphpca", "faces2d", "correspondence", "parts"},
    "stylisation": {"data", "geometry", "render", "morphpca", "faces2d", "correspondence", "parts", "characters"},
    "grid": {"data", "geometry", "render", "morphpca", "faces2d", "correspondence", "parts", "characters",
             "stylisation"},
    "audit": {"data", "geometry", "render", "morphpca"},
    "faces2d": {"data", "geometry", "render", "morphpca"},
}
#: At most this many modules at the stimulus engine's top level, its ``__init__`` included.
ENGINE_TOP_LEVEL_MAX = 8


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for f in (ROOT / pkg).rglob("*.py"):
            parts = f.relative_to(ROOT).with_suffix("").parts
            out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return skip


def _imports(name: str, path: Path, modules: dict[str, Path], type_checking: bool = False) -> set[str]:
    """The project modules ``name`` imports (with ``type_checking``, those under TYPE_CHECKING too)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = set() if type_checking else _type_checking_nodes(tree)
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = name.split(".") if is_pkg else name.split(".")[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in modules:
                t = t.rpartition(".")[0]  # `import a.b.c` of a package path: its deepest module
            if t and t != name:
                out.add(t)
    return out


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _folder(module: str) -> str:
    return module.split(".")[0]


def test_the_graph_sees_the_house(graph):
    assert len(graph) > 140 and all(_folder(m) in PACKAGES for m in graph)
    assert "appeal.levels" in graph["experiments.trials"] and "appeal.triggers" in graph["analysis.erp.config"]


def test_no_arrow_runs_back_up(graph):
    allowed = {CORE: {CORE}, ROOF: set(PACKAGES), **{room: {room, CORE} for room in ROOMS}}
    wrong = sorted(f"{m} -> {t}" for m, ts in graph.items() for t in ts if _folder(t) not in allowed[_folder(m)])
    assert wrong == []


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components of more than one module (each sorted)."""
    index, low, on_stack, stack, circles = {}, {}, set(), [], []

    def visit(v: str) -> None:  # recursive; the graph is shallow enough
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return circles


def test_no_import_circle(graph):
    """Every strongly connected component of the import graph is a single module."""
    assert _circles(graph) == []


def test_no_circle_even_for_annotations():
    """Counting imports under TYPE_CHECKING too, still no circle: shared types live in their own module."""
    modules = _modules()
    full = {name: _imports(name, path, modules, type_checking=True) for name, path in modules.items()}
    assert _circles(full) == []


def _engine_part(module: str) -> str | None:
    """The stimulus-engine sub-package of a module (None for the engine's top-level modules)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in ENGINE_LAYERS) else None


def _upward_engine_imports(graph: dict[str, set[str]]) -> list[str]:
    wrong = []
    for m, ts in graph.items():
        if _folder(m) != "stimulus_engine":
            continue
        part = _engine_part(m)
        for t in ts:
            if _folder(t) != "stimulus_engine" or part is None:
                continue
            target = _engine_part(t)
            if target is None or (target != part and target not in ENGINE_LAYERS[part]):
                wrong.append(f"{m} -> {t}")
    return sorted(wrong)


def test_engine_layers_run_one_way(graph):
    """No sub-package of the stimulus engine imports one above it, nor the engine's top level."""
    assert _upward_engine_imports(graph) == []


def test_engine_layout_is_the_documented_one(graph):
    """Every engine module lies in a listed sub-package or is one of a few top-level modules."""
    engine = [m for m in graph if _folder(m) == "stimulus_engine"]
    top = sorted(m for m in engine if _engine_part(m) is None)
    assert len(top) <= ENGINE_TOP_LEVEL_MAX, top
    packages = {m.split(".")[1] for m in engine if m.count(".") >= 1 and (ROOT / m.replace(".", "/")).is_dir()}
    assert packages == set(ENGINE_LAYERS)
    documented = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert all(f"`stimulus_engine/{p}/`" in documented for p in ENGINE_LAYERS)


def test_the_checks_see_planted_faults(tmp_path):
    """The reader counts lazy and relative imports but not TYPE_CHECKING ones; a planted circle is found."""
    modules = {m: tmp_path for m in ("appeal", "appeal.errors", "analysis.erp", "analysis.erp.io", "analysis.erp.report",
                                      "stimulus_engine.grid", "experiments.trials")}
    src = tmp_path / "report.py"
    src.write_text("from typing import TYPE_CHECKING\n"
                   "from appeal.errors import AppealInputError\n"
                   "from .io import read_recording\n"
                   "if TYPE_CHECKING:\n    from experiments.trials import Trial\n"
                   "def f():\n    import stimulus_engine.grid.plan\n")
    assert _imports("analysis.erp.report", src, modules) == {"appeal.errors", "analysis.erp.io", "stimulus_engine.grid"}
    assert _imports("analysis.erp.report", src, modules, type_checking=True) == {
        "appeal.errors", "analysis.erp.io", "stimulus_engine.grid", "experiments.trials"}
    assert _circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _circles({"a": {"b"}, "b": set()}) == []
    planted = {"stimulus_engine.geometry.mesh_io": {"stimulus_engine.characters.rig"},
               "stimulus_engine.characters.rig": {"stimulus_engine.geometry.mesh_ops", "stimulus_engine"},
               "stimulus_engine.grid.plan": {"stimulus_engine.characters", "stimulus_engine.stylisation.shape"},
               "stimulus_engine": {"stimulus_engine.grid"}}
    assert _upward_engine_imports(planted) == ["stimulus_engine.characters.rig -> stimulus_engine",
                                               "stimulus_engine.geometry.mesh_io -> stimulus_engine.characters.rig"]
