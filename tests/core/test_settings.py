"""Settings checked from their declaration (``_core.runtime.setting`` / ``check_settings``): each rule
against a hand-written predicate on a toy config, and the one message form the runner and the CLI re-key."""

from __future__ import annotations

import dataclasses
import math

import pytest

from probeplace._core import ConfigError
from probeplace._core.runtime import check_settings, setting


@dataclasses.dataclass(frozen=True, kw_only=True)
class Toy:
    frac: float = setting(0.5, lo=0.0, hi=1.0, hi_open=True)
    count: int = setting(1, lo=1)
    gap: float | None = setting(None, lo=0.0, lo_open=True)
    mode: str = setting("a", choices=("a", "b"))
    free: float = 3.0  # not declared: not checked

    def __post_init__(self):
        check_settings(self)


def _ok(kw: dict) -> bool:
    """The rules written out by hand."""
    v = {"frac": 0.5, "count": 1, "gap": None, "mode": "a"} | kw
    f, c, g = v["frac"], v["count"], v["gap"]
    num = lambda x: isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
    return (
        num(f)
        and 0.0 <= f < 1.0
        and isinstance(c, int)
        and not isinstance(c, bool)
        and c >= 1
        and (g is None or (num(g) and g > 0))
        and v["mode"] in ("a", "b")
    )


VALUES = {
    "frac": [0.0, 0.999, 1.0, -0.1, math.nan, math.inf, True, 1],
    "count": [1, 7, 0, -3, 1.0, True],
    "gap": [None, 1e-9, 0.0, -1.0, 2],
    "mode": ["a", "b", "c", None],
}


@pytest.mark.parametrize(("name", "value"), [(k, v) for k, vs in VALUES.items() for v in vs])
def test_a_value_passes_exactly_when_the_hand_written_rule_says_so(name, value):
    try:
        Toy(**{name: value})
        passed = True
    except ConfigError as e:
        passed = False
        assert str(e).startswith(f"Toy.{name} must be "), e  # the form the runner and the CLI re-key
    assert passed == _ok({name: value}), (name, value)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"frac": 1.0}, "Toy.frac must be in [0, 1), got 1.0"),
        ({"count": 0}, "Toy.count must be ≥ 1, got 0"),
        ({"count": 1.5}, "Toy.count must be an int, got 1.5"),
        ({"gap": 0.0}, "Toy.gap must be positive or None, got 0.0"),
        ({"gap": "x"}, "Toy.gap must be a finite number or None, got 'x'"),
        ({"mode": "c"}, "Toy.mode must be one of ('a', 'b'), got 'c'"),
    ],
)
def test_the_messages(kw, message):
    with pytest.raises(ConfigError) as e:
        Toy(**kw)
    assert str(e.value) == message
