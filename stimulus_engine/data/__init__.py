"""Data shipped with the stimulus engine: landmark orderings, FACS recipes, and one small real
face scan (``james/``, BSD-3, see its README) and eight photographs of four people (``faces2d/``,
CC BY 4.0, see its README) so the demo shows real faces without downloads."""

from pathlib import Path

#: This folder: every asset the engine ships lies under it.
DATA_DIR = Path(__file__).resolve().parent

#: The embedded textured scan (menpo3d's "james", reduced texture; licence and credit beside it).
EMBEDDED_SCAN = DATA_DIR / "james" / "james.obj.gz"

#: Neutral (``NNN_03.jpg``) and smiling (``NNN_08.jpg``) photographs of four London-set people,
#: reduced (CC BY 4.0, DeBruine & Jones 2017; licence and credit in the folder's README).
EMBEDDED_FACES = DATA_DIR / "faces2d"
