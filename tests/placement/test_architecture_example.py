"""The "adding a method" example of docs/architecture.md, run as it is written there: one module registers
a method, and ``place`` and the registry find it (the example is not registered by default)."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from probeplace._core import ConfigError, scene_box
from probeplace.placement import method_names, method_options, place
from probeplace.placement._registry import _METHODS, PlacementMethod, register_method

DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def _example_source() -> str:
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)
    (src,) = [b for b in blocks if "placement/_centre.py" in b]
    return src


def test_the_documented_example_method_registers_and_places(cornell):
    name = "probeplace.placement._centre"
    assert "centre" not in method_names()  # not registered by default
    spec = importlib.util.spec_from_loader(name, loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "probeplace.placement"
    sys.modules[name] = module
    try:
        exec(compile(_example_source(), str(DOC), "exec"), module.__dict__)
        assert "centre" in method_names() and method_options("centre") == {"lift": 0.0}
        res = place(cornell, method="centre", options={"lift": 0.1})
        lo, hi = scene_box(cornell)
        want = 0.5 * (lo + hi) + [0.0, 0.1 * (hi - lo)[1], 0.0]
        assert res.n_probes == 1 and res.metadata["method"] == "centre"
        np.testing.assert_allclose(np.asarray(res.probes.pos_world)[0], want, atol=1e-5)  # free: unmoved
        assert 0.0 < res.coverage <= 1.0
        with pytest.raises(ConfigError, match="unknown centre options"):
            place(cornell, method="centre", options={"height": 1.0})
        with pytest.raises(ValueError, match="already registered"):
            register_method(PlacementMethod("centre", module.place_centre))
    finally:
        _METHODS.pop("centre", None)
        sys.modules.pop(name, None)
