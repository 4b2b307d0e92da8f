"""Data shipped with the stimulus engine: landmark orderings, FACS recipes, and one small real
face scan (``james/``, BSD-3, see its README) so the demo shows a real face without downloads."""

from pathlib import Path

#: The embedded textured scan (menpo3d's "james", reduced texture; licence and credit beside it).
EMBEDDED_SCAN = Path(__file__).resolve().parent / "james" / "james.obj.gz"
