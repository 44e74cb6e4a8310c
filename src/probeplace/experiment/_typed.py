"""Typed dataclasses from plain mappings: what OmegaConf's structured configs did for the runner, in pure
Python, so that the library needs neither Hydra nor OmegaConf (they stay in ``experiments/run.py``).

Any ``Mapping`` works, an OmegaConf ``DictConfig`` included (it is one; reading it resolves its
interpolations). Unknown keys and values of the wrong type raise :class:`ConfigError` naming the full key.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any

from .._core import ConfigError


def from_mapping(cls: type, data: Mapping, key: str = "") -> Any:
    """An instance of the dataclass ``cls`` from ``data``; fields not in ``data`` keep their defaults.

    Args:
        cls: the dataclass.
        data: its values; nested dataclass fields take nested mappings.
        key: the dotted key of ``data`` in the whole config (error messages), ``""`` at the top.

    Raises:
        ConfigError: an unknown key or a value that does not convert to the field's type; the message
            starts with the full key (``placer.buget: ...``).
    """
    if not isinstance(data, Mapping):
        _fail(key.rstrip(".") or "config", "must be a mapping", data)
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    values = {}
    for k, v in data.items():
        if k not in names:
            where = key.rstrip(".") or "the config"
            _fail(f"{key}{k}", f"not a key of {where}; known: {names}", v)
        values[k] = convert(hints[k], v, f"{key}{k}")
    return cls(**values)


def convert(tp: Any, v: Any, key: str) -> Any:
    """``v`` as type ``tp`` (bool, int, float, str, ``X | None``, a union of those scalars such as
    ``int | str``, ``list[X]``, ``dict[str, X]``, ``Any`` or a dataclass); containers become plain lists
    and dicts."""
    if tp is Any:
        return plain(v)
    if dataclasses.is_dataclass(tp):
        return v if isinstance(v, tp) else from_mapping(tp, v, f"{key}.")
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if v is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        if len(inner) == 1:
            return convert(inner[0], v, key)
        return _scalar_union(inner, v, key)
    if origin is list:
        if isinstance(v, str) or not isinstance(v, Sequence):
            _fail(key, "must be a list", v)
        return [convert(args[0], x, f"{key}[{i}]") for i, x in enumerate(v)]
    if origin is dict:
        if not isinstance(v, Mapping):
            _fail(key, "must be a mapping", v)
        return {str(k): convert(args[1], x, f"{key}.{k}") for k, x in v.items()}
    return _scalar(tp, v, key)


def _scalar(tp: type, v: Any, key: str) -> Any:
    """A bool, int, float or str; numeric text converts (as a Hydra override's would), bools never pass
    for numbers."""
    if tp is bool:
        if isinstance(v, bool):
            return v
        if isinstance(v, str) and v.lower() in ("true", "false"):
            return v.lower() == "true"
        _fail(key, "must be a boolean", v)
    if tp in (int, float):
        if isinstance(v, bool) or (tp is int and isinstance(v, float)):
            _fail(key, f"must be {'an integer' if tp is int else 'a number'}", v)
        try:
            return tp(v)
        except (TypeError, ValueError):
            _fail(key, f"must be {'an integer' if tp is int else 'a number'}", v)
    if tp is str:
        if isinstance(v, str):
            return v
        if isinstance(v, int | float) and not isinstance(v, bool):
            return str(v)
        _fail(key, "must be a string", v)
    raise TypeError(f"{key}: unsupported schema type {tp!r}")  # a schema bug, not a user error


def _scalar_union(types_: list, v: Any, key: str) -> Any:
    """``v`` as the first of the scalar types ``types_`` it converts to, ``str`` only for text (a count
    field ``int | str`` takes ``16``, ``"16"`` and ``"auto"``, not ``2.5``); the library checks which text
    it accepts."""
    for tp in types_:
        if tp is str and not isinstance(v, str):
            continue
        try:
            return _scalar(tp, v, key)
        except ConfigError:
            continue
    names = {bool: "a boolean", int: "an integer", float: "a number", str: "a string"}
    _fail(key, "must be " + " or ".join(names.get(t, str(t)) for t in types_), v)


def plain(v: Any) -> Any:
    """``v`` with every mapping turned into a dict and every non-string sequence into a list."""
    if isinstance(v, Mapping):
        return {str(k): plain(x) for k, x in v.items()}
    if isinstance(v, Sequence) and not isinstance(v, str):
        return [plain(x) for x in v]
    return v


def _fail(key: str, what: str, got: Any) -> typing.NoReturn:
    raise ConfigError(f"{key}: {what}, got {plain(got)!r}")
