"""Registry of built-in scenes (no file needed), keyed by the name configs and result folders use."""

from __future__ import annotations

from collections.abc import Callable

from .._core import Scene
from ._cornell import cornell_box
from ._courtyard import courtyard
from ._rooms import rooms
from ._temple import temple

#: name -> zero-argument factory returning the Scene (deterministic: same scene on every call).
BUILTIN_SCENES: dict[str, Callable[[], Scene]] = {
    "cornell_box": cornell_box,
    "temple": temple,
    "rooms": rooms,
    "courtyard": courtyard,
}
