"""experiments/trace_accuracy.py rebakes a cached grid it cannot read (cut, corrupt or of an older layout),
and lets any other error through: a bug in the reader is not a stale cache."""

from __future__ import annotations

import pytest

from ._util import benchmark_module, experiment_script


@pytest.fixture
def cached_grid(tmp_path, monkeypatch):
    import probeplace.probes

    ta = experiment_script("trace_accuracy")
    monkeypatch.setattr(ta, "OUT", tmp_path)
    baked = []
    monkeypatch.setattr(
        benchmark_module("tracer"), "bake_grid", lambda *a: baked.append(a) or ("probes", 1.5)
    )
    monkeypatch.setattr(probeplace.probes, "save_probes", lambda path, lf: None)

    class Scene:
        name = "box"

    (tmp_path / "box_2x2x2_r8.npz").write_bytes(b"not an npz")
    return ta, Scene(), baked


def test_an_unreadable_cache_is_rebaked(cached_grid, capsys):
    ta, scene, baked = cached_grid
    assert ta.grid_probes(scene, None, (2, 2, 2), 8) == ("probes", 1.5)
    assert len(baked) == 1
    assert "cache box_2x2x2_r8.npz unreadable" in capsys.readouterr().out


def test_a_bug_in_the_reader_is_not_taken_for_a_stale_cache(cached_grid, monkeypatch):
    import probeplace.probes

    ta, scene, baked = cached_grid

    def broken(path):
        raise TypeError("a bug")

    monkeypatch.setattr(probeplace.probes, "load_probes", broken)
    with pytest.raises(TypeError, match="a bug"):
        ta.grid_probes(scene, None, (2, 2, 2), 8)
    assert baked == []
