"""WebMorph / Psychomorph ``.tem`` templates: points and line definitions, read and written.

A template file is the number of points, one ``x<TAB>y`` line per point, then the template's line
definitions (which points form the outline of an eye, the lips ...), kept verbatim. Writing a
template read from a file without moving its points gives back the same bytes: coordinates are
written as Python's shortest float text (``565.0``), the rest as it was.

The FRL London set uses WebMorph's 189-point FRL template (``FRL_189``: points 0 and 1 the pupils;
its left-right mirror pairs: :mod:`stimulus_engine.faces2d.symmetry`); images without a template get dlib's
68 points (:func:`stimulus_engine.morphpca.keypoints.detect_landmarks`, ``DLIB_68``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from appeal.errors import AppealInputError

__all__ = ["Template", "read_template", "write_template", "template_text"]


@dataclass(frozen=True, eq=False)
class Template:
    """A template's points ``(n, 2)`` (x, y in pixels) and the text after them (line definitions,
    empty for a template made from detected points)."""

    points: np.ndarray
    tail: str = ""

    def moved(self, points: np.ndarray) -> Template:
        """The same template with other points (same count)."""
        points = np.asarray(points, np.float64)
        if points.shape != self.points.shape:
            raise ValueError(f"expected {self.points.shape[0]} points, got {points.shape}")
        return Template(points, self.tail)


def read_template(path: str | Path) -> Template:
    """Read a ``.tem`` file (one-line errors naming the file for a missing or malformed one)."""
    path = Path(path)
    if not path.is_file():
        raise AppealInputError(f"{path}: template file not found (expected a .tem file beside the image)")
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.split("\n")
    try:
        n = int(lines[0].strip())
        pts = np.array([[float(v) for v in lines[1 + i].split()[:2]] for i in range(n)], np.float64)
    except (ValueError, IndexError):
        raise AppealInputError(f"{path}: not a .tem template (expected a point count, then one 'x y' line per point)") from None
    if n < 1 or pts.shape != (n, 2):
        raise AppealInputError(f"{path}: expected {n} 'x y' lines after the point count")
    return Template(pts, "\n".join(lines[1 + n:]))


def _number(v: float) -> str:
    return repr(float(v))


def template_text(template: Template) -> str:
    """The ``.tem`` text of ``template`` (see the module docstring)."""
    head = [str(len(template.points))] + [f"{_number(x)}\t{_number(y)}" for x, y in template.points]
    return "\n".join(head + [template.tail]) if template.tail else "\n".join(head) + "\n"


def write_template(path: str | Path, template: Template) -> Path:
    """Write ``template`` to ``path`` (atomically)."""
    from appeal.atomic import atomic_write_text

    return atomic_write_text(Path(path), template_text(template))
