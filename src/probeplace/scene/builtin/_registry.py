"""Registry of built-in scenes (no file needed), keyed by the name configs and result folders use.

Plain Python: the table names each factory by ``module:function`` and imports it on first lookup, so
listing the built-ins (``probeplace scenes``) loads no scene builder and no JAX.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..._core import Scene

#: name -> ``"module:function"`` of its zero-argument factory (the one list of built-in scenes).
BUILTIN_SCENE_FACTORIES: dict[str, str] = {
    "cornell_box": "probeplace.scene.builtin._cornell:cornell_box",
    "temple": "probeplace.scene.builtin._temple:temple",
    "rooms": "probeplace.scene.builtin._rooms:rooms",
    "courtyard": "probeplace.scene.builtin._courtyard:courtyard",
}


class _Factories(Mapping[str, "Callable[[], Scene]"]):
    """A read-only name -> factory mapping that imports a factory's module when it is looked up."""

    def __init__(self, table: Mapping[str, str]):
        self._table = table

    def __getitem__(self, name: str) -> Callable[[], Scene]:
        module, function = self._table[name].split(":")
        return getattr(importlib.import_module(module), function)

    def __iter__(self) -> Iterator[str]:
        return iter(self._table)

    def __len__(self) -> int:
        return len(self._table)

    def __repr__(self) -> str:
        return f"BUILTIN_SCENES({list(self._table)})"


#: name -> zero-argument factory returning the Scene (deterministic: same scene on every call).
BUILTIN_SCENES: Mapping[str, Callable[[], Scene]] = _Factories(BUILTIN_SCENE_FACTORIES)


def builtin_scene_module(name: str) -> str:
    """The module defining built-in scene ``name``'s factory, without importing it."""
    return BUILTIN_SCENE_FACTORIES[name].split(":")[0]
