"""Every shared library the live-session paths load is installed (``scripts/system-deps.sh``).

``ldd`` on the Qt binaries the demographics dialog loads (PyQt6's modules, the xcb platform
plugin and its GL/input plugins), on psychtoolbox's extensions (keyboard, clock, audio), and a
load of every library pyglet opens by name for the PsychoPy window. A missing Debian package
(e.g. libxcb-icccm4 for ``libqxcb.so``) made every real session abort with SIGABRT at the dialog.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ldd and the xcb plugin are Linux's")

#: Plugin folders of Qt6 the dialog loads on X11 (platform themes are optional: Qt skips them).
QT_PLUGINS = ["platforms/libqxcb.so", "xcbglintegrations/*.so", "platforminputcontexts/*.so", "imageformats/*.so",
              "iconengines/*.so"]
#: Libraries pyglet 1.5 opens by name on Linux for a window, its GL context and text.
PYGLET_LIBS = ["GL", "GLU", "X11", "Xext", "Xi", "Xinerama", "Xxf86vm", "fontconfig", "freetype"]


def _package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    assert spec is not None and spec.submodule_search_locations, f"{name} is not installed"
    return Path(next(iter(spec.submodule_search_locations)))


def _binaries() -> list[Path]:
    qt = _package_dir("PyQt6")
    files = [qt / f"{m}.abi3.so" for m in ("QtCore", "QtGui", "QtWidgets")]
    for pattern in QT_PLUGINS:
        files += sorted((qt / "Qt6" / "plugins").glob(pattern))
    files += sorted(_package_dir("psychtoolbox").glob("*.so"))
    return files


def missing_libraries(path: Path) -> list[str]:
    """The libraries ``ldd`` reports as 'not found' for one binary."""
    res = subprocess.run(["ldd", str(path)], capture_output=True, text=True, check=False)
    return [line.split("=>")[0].strip() for line in res.stdout.splitlines() if "not found" in line]


def test_gui_binaries_find_all_their_libraries():
    if shutil.which("ldd") is None:
        pytest.fail("ldd not found (Debian: libc-bin)")
    binaries = _binaries()
    names = {p.name for p in binaries}
    assert {"libqxcb.so", "QtWidgets.abi3.so", "PsychHID.abi3.so", "GetSecs.abi3.so"} <= names
    problems = {str(p): m for p in binaries if (m := missing_libraries(p))}
    assert not problems, "missing shared libraries (add their Debian packages to scripts/system-deps.sh): " + \
        "; ".join(f"{Path(p).name}: {', '.join(m)}" for p, m in problems.items())


def test_pyglet_window_libraries_load():
    missing = []
    for name in PYGLET_LIBS:
        soname = ctypes.util.find_library(name)
        try:
            ctypes.CDLL(soname or f"lib{name}.so")
        except OSError:
            missing.append(name)
    assert not missing, f"pyglet cannot load lib{', lib'.join(missing)} (add them to scripts/system-deps.sh)"

