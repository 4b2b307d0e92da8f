"""Packages that load their modules on first use (Scientific Python SPEC 1, via ``lazy_loader``).

``import stimulus_engine`` then costs milliseconds, and ``stimulus_engine.load_ict_rig`` imports
``stimulus_engine.characters.ict`` the first time it is used, so a command's ``--help`` does not
wait for the renderer, MNE or OpenCV. :func:`attach` is ``lazy_loader.attach`` plus one case it
leaves open: a public name that is also its own module's name (``render.contact_sheet``, the
function in ``render/contact_sheet.py``). Importing that module binds the *module* to the package's
name, shadowing a lazy attribute; here such a name is a property of the package, so it stays the
function however the module was imported (as eager ``from .m import m`` imports behaved).
"""

from __future__ import annotations

import importlib
import sys
import types
from collections.abc import Callable, Mapping, Sequence

import lazy_loader

__all__ = ["attach"]


def attach(name: str, submodules: Sequence[str] = (), submod_attrs: Mapping[str, Sequence[str]] | None = None
           ) -> tuple[Callable[[str], object], Callable[[], list[str]], list[str]]:
    """``__getattr__, __dir__, __all__`` for package ``name`` (as ``lazy_loader.attach``).

    Parameters
    ----------
    name : str
        The package's ``__name__``.
    submodules : sequence of str
        Its modules and sub-packages, each loaded when first used as an attribute.
    submod_attrs : mapping of str to sequence of str
        Module (relative, may be dotted) to the public names it defines.
    """
    attrs = {k: list(v) for k, v in (submod_attrs or {}).items()}
    getattr_, dir_, all_ = lazy_loader.attach(name, submodules=list(submodules), submod_attrs=attrs)
    clashes = {a: m for m, names in attrs.items() for a in names if a == m}
    if clashes:
        package = sys.modules[name]
        namespace: dict[str, object] = {}
        for attr, module in clashes.items():
            def get(self, _a=attr, _m=module):  # the name, not the module of the same name
                if f"_{_a}_override" in self.__dict__:  # set by hand (a test's monkeypatch)
                    return self.__dict__[f"_{_a}_override"]
                return getattr(importlib.import_module(f"{name}.{_m}"), _a)

            def put(self, value, _a=attr):  # the import system binding the module: the name keeps its meaning
                if not isinstance(value, types.ModuleType):
                    self.__dict__[f"_{_a}_override"] = value

            namespace[attr] = property(get, put)
        package.__class__ = type(f"LazyPackage[{name}]", (types.ModuleType,), namespace)
    return getattr_, dir_, all_
