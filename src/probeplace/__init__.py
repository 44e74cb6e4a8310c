"""probeplace: light-probe placement, light-field probe baking and evaluation in JAX.

Names load on first use (PEP 562 ``__getattr__``), so ``import probeplace`` and the NumPy-only
``probeplace.export`` never import JAX; ``probeplace.ProbeSet`` or ``lp.scene`` bring it in.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"
__all__ = ["Camera", "Hit", "Materials", "ProbeSet", "Scene", "Sun"]  # all from _core
_STAGES = ("scene", "geometry", "render", "placement", "probes", "evaluate", "experiment", "export", "view")

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._core import Camera as Camera
    from ._core import Hit as Hit
    from ._core import Materials as Materials
    from ._core import ProbeSet as ProbeSet
    from ._core import Scene as Scene
    from ._core import Sun as Sun


def __getattr__(name: str):
    if name in __all__:
        value = getattr(importlib.import_module("._core", __name__), name)
    elif name in _STAGES:
        value = importlib.import_module(f".{name}", __name__)
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # later lookups skip __getattr__
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__, *_STAGES})
