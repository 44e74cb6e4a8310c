"""benchmarks/tracer.py reports the same keys whether Sponza loads or not: null figures where it does not,
so a reader of the JSON finds every Sponza key either measured or null (the run itself is stubbed out)."""

from __future__ import annotations

import pytest

from ._util import benchmark_module


class AnyFigure(dict):
    """A stand-in measurement: every figure asked of it reads 1.0."""

    def __missing__(self, key):
        return 1.0


@pytest.fixture
def tracer_bench(monkeypatch):
    import probeplace.scene

    tb = benchmark_module("tracer")
    sponza_absent = {"value": False}

    def load_scene(name):
        if name == "crytek_sponza" and sponza_absent["value"]:
            raise tb.SceneError(f"unknown scene {name!r}")
        return name

    monkeypatch.setattr(probeplace.scene, "load_scene", load_scene)
    monkeypatch.setattr(tb, "bench_scene", lambda *a, **k: (AnyFigure(), None))
    monkeypatch.setattr(tb, "frame_shading", lambda *a, **k: AnyFigure())
    monkeypatch.setattr(tb, "EmbreeCaster", lambda scene: None)
    monkeypatch.setattr(tb, "hierarchy_steps", lambda *a, **k: {"r128": AnyFigure(), "r256": AnyFigure()})
    monkeypatch.setattr(tb, "march_cost", lambda *a, **k: AnyFigure())
    monkeypatch.setattr(tb, "cornell_eval", lambda *a, **k: AnyFigure())
    monkeypatch.setattr(tb, "gpu_figures", lambda *a, **k: None)
    monkeypatch.setattr(tb, "write_result", lambda name, result: None)
    return tb, sponza_absent


def test_a_run_without_sponza_nulls_exactly_the_keys_a_run_with_it_measures(tracer_bench):
    tb, sponza_absent = tracer_bench
    with_sponza = tb.main(["--quick"])
    sponza_absent["value"] = True
    without = tb.main(["--quick"])
    assert without["sponza_note"] == "crytek_sponza not loaded: unknown scene 'crytek_sponza'"
    assert set(without) - {"sponza_note"} == set(with_sponza)
    newly_null = {k for k, v in without.items() if v is None and with_sponza.get(k) is not None}
    assert newly_null == set(tb.SPONZA_KEYS)
