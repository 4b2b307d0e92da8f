"""R reference numbers for the statistics tests, read from what the R scripts printed.

Each ``tests/r_reference/NAME.R`` prints Python literals (``R_X = {...}``) and its output is
committed beside it as ``NAME.out`` (``Rscript tests/r_reference/NAME.R > tests/r_reference/NAME.out``,
run from the repository root). Tests load those files instead of carrying pasted copies, so
a reference number in a test is always one R printed. R's ``NA`` is printed ``NAN`` (read as
``nan``) and ``Inf`` as ``Inf``.
"""

from __future__ import annotations

import ast
import math
from functools import cache
from pathlib import Path

REFERENCE_DIR = Path(__file__).parent / "r_reference"
_NAMES = {"NAN": math.nan, "Inf": math.inf}


@cache
def r_reference(name: str) -> dict[str, object]:
    """The literals ``tests/r_reference/<name>.out`` assigns, by their names."""
    tree = ast.parse((REFERENCE_DIR / f"{name}.out").read_text(encoding="utf-8"))
    values = {}
    for node in tree.body:
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)):
            raise ValueError(f"{name}.out: line {node.lineno}: expected NAME = literal")
        code = compile(ast.Expression(node.value), f"{name}.out", "eval")
        values[node.targets[0].id] = eval(code, {"__builtins__": {}}, dict(_NAMES))  # noqa: S307 - literals only
    return values
