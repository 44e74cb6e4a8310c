"""Settings checked from their declaration (issue 35: a config's checks were one hand-written ``raise``
each). A dataclass field declares its range or choices with :func:`setting`; :func:`check_settings`
checks every declared field of an instance against its type hint (an int, a finite number, text, each
possibly ``None``) and its declaration, with one message form: ``TraceConfig.thickness must be in [0, 1),
got 2.0`` — the form the runner and the CLI re-key to their own names (``lightfield.thickness: must ...``).
Checks that relate fields or are not a range (a power of two) stay in the class's ``__post_init__``."""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import types
import typing
from typing import Any

from .._errors import ConfigError


def setting(
    default: Any,
    *,
    lo: int | float | None = None,
    hi: int | float | None = None,
    lo_open: bool = False,
    hi_open: bool = False,
    choices: tuple | None = None,
) -> Any:
    """A dataclass field with ``default`` whose value :func:`check_settings` holds to [``lo``, ``hi``]
    (either end open, either absent) or to ``choices``."""
    rule = {"lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open, "choices": choices}
    return dataclasses.field(default=default, metadata={"setting": rule})


def _range_text(rule: dict) -> str:
    lo, hi = rule["lo"], rule["hi"]
    if lo is not None and hi is not None:
        return f"in {'(' if rule['lo_open'] else '['}{lo:g}, {hi:g}{')' if rule['hi_open'] else ']'}"
    if lo is not None:
        return "positive" if lo == 0 and rule["lo_open"] else f"{'>' if rule['lo_open'] else '≥'} {lo:g}"
    return f"{'<' if rule['hi_open'] else '≤'} {hi:g}"


def _inside(v: int | float, rule: dict) -> bool:
    lo, hi = rule["lo"], rule["hi"]
    above = lo is None or (v > lo if rule["lo_open"] else v >= lo)
    below = hi is None or (v < hi if rule["hi_open"] else v <= hi)
    return above and below


@functools.cache
def _declared(cls: type) -> tuple[tuple[str, bool, type, dict], ...]:
    """(field, None allowed, scalar type, rule) of each field of ``cls`` declared with :func:`setting`:
    read once per class (type hints are slow to resolve; a config is built often)."""
    hints = typing.get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        rule = f.metadata.get("setting")
        if rule is None:
            continue
        tp = hints[f.name]
        args = typing.get_args(tp) if isinstance(tp, types.UnionType) else (tp,)
        out.append((f.name, type(None) in args, next(a for a in args if a is not type(None)), rule))
    return tuple(out)


def check_settings(obj: Any) -> None:
    """Check each field of dataclass ``obj`` declared with :func:`setting` (the first failure, as
    ``<Class>.<field> must be ..., got <value>``).

    Raises:
        ConfigError: a value of the wrong type, outside its range or not one of its choices.
    """
    cls = type(obj).__name__
    for name, optional, kind, rule in _declared(type(obj)):
        v = getattr(obj, name)
        if v is None and optional:
            continue
        where, none = f"{cls}.{name} must be", " or None" if optional else ""
        if kind is int and (not isinstance(v, int) or isinstance(v, bool)):
            raise ConfigError(f"{where} an int{none}, got {v!r}")
        if kind is float and (not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v)):
            raise ConfigError(f"{where} a finite number{none}, got {v!r}")
        if rule["choices"] is not None and v not in rule["choices"]:
            raise ConfigError(f"{where} one of {rule['choices']}, got {v!r}")
        if (rule["lo"] is not None or rule["hi"] is not None) and not _inside(v, rule):
            raise ConfigError(f"{where} {_range_text(rule)}{none}, got {v}")


def rekeyed(lib: type, values: dict, keys: dict[str, str]) -> Any:
    """``lib(**values)``; its ConfigError (``BakeConfig.n_sub must be ...`` or ``budget must be ...``)
    re-keyed to the name the user wrote (``keys``: field → ``bake.n_sub`` for the runner, ``--budget`` for
    ``probeplace place``): ``bake.n_sub: must be ...``, comparisons in ASCII as the runner's messages always
    had. An error about a field not in ``keys`` (or in another form) is raised as it is."""
    try:
        return lib(**values)
    except ConfigError as e:
        m = re.match(rf"(?:{lib.__name__}\.)?(\w+):? (.*)", str(e), re.S)
        if m is None or m.group(1) not in keys:
            raise
        rest = m.group(2) if m.group(2).startswith("must") else str(e)
        raise ConfigError(f"{keys[m.group(1)]}: {rest.replace('≥', '>=')}") from None
