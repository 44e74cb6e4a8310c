"""Flags made from a stage's schema: a dataclass field's name and type become an option's flag and its
argparse ``type`` (``probeplace place``'s ``placement.PlaceRequest`` settings, ``probeplace evaluate``'s
``probes.TraceConfig`` settings)."""

from __future__ import annotations

import types
import typing
from collections.abc import Callable
from typing import Any


def flag(name: str, prefix: str = "") -> str:
    """The flag of a setting: ``n_opt_samples`` → ``--n-opt-samples`` (``prefix`` before the name)."""
    return "--" + (prefix + name).replace("_", "-")


def value_parser(tp: Any) -> Callable[[str], Any]:
    """argparse's ``type`` for a field of type ``tp`` (a scalar, or a union of scalars and ``None``):
    ``none`` is ``None`` where the type allows it; ``int | str`` (a count or ``auto``) an int when the
    text is one; otherwise the first scalar type's conversion (the field's own check refuses the rest,
    naming the flag)."""
    args = typing.get_args(tp) if isinstance(tp, types.UnionType) else (tp,)
    optional, kinds = type(None) in args, [a for a in args if a is not type(None)]

    def convert(text: str) -> Any:
        if optional and text.lower() == "none":
            return None
        if kinds == [int, str]:
            return int(text) if text.lstrip("-").isdigit() else text
        return kinds[0](text)

    convert.__name__ = " or ".join(k.__name__ for k in kinds) + (" or none" if optional else "")
    return convert
