"""The built-in scenes, made in code (no file needed): the registry every name resolves through
(``_registry``, plain Python) and the scenes themselves: ``cornell_box`` (``_cornell``), ``temple``
(``_temple``), ``rooms`` (``_rooms``) and ``courtyard`` (``_courtyard``), built from the mesh primitives of
``scene._primitives``.

This ``__init__`` is the group's face for the rest of ``scene``. The registry loads eagerly; each scene on
first use (PEP 562 ``__getattr__``): it imports JAX, and listing the built-ins must not."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._core._lazy import lazy_exports
from ._registry import BUILTIN_SCENES as BUILTIN_SCENES
from ._registry import builtin_scene_module as builtin_scene_module

# name -> the private module defining it (each imports JAX)
_LAZY = {
    "cornell_box": "_cornell",
    "courtyard": "_courtyard",
    **dict.fromkeys(
        ("ROOMS_DARK_ROOM_BOUNDS", "ROOMS_LIT_ROOM_BOUNDS", "ROOMS_WALL_THICKNESS", "rooms"), "_rooms"
    ),
    **dict.fromkeys(("TEMPLE_UNDER_STAIRS_BOX", "temple"), "_temple"),
}

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._cornell import cornell_box as cornell_box
    from ._courtyard import courtyard as courtyard
    from ._rooms import ROOMS_DARK_ROOM_BOUNDS as ROOMS_DARK_ROOM_BOUNDS
    from ._rooms import ROOMS_LIT_ROOM_BOUNDS as ROOMS_LIT_ROOM_BOUNDS
    from ._rooms import ROOMS_WALL_THICKNESS as ROOMS_WALL_THICKNESS
    from ._rooms import rooms as rooms
    from ._temple import TEMPLE_UNDER_STAIRS_BOX as TEMPLE_UNDER_STAIRS_BOX
    from ._temple import temple as temple


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), [*_LAZY])
