"""A placed set whose light-field tracer cannot fit is refused after placement and before the bake (a
lod-grid at its automatic budget, 2,164 probes on the Cornell box, baked for minutes before its 38.5 GiB
tracer was refused)."""

from __future__ import annotations

import pytest
from omegaconf import OmegaConf

from probeplace._core import ResourceError
from probeplace.experiment import run, to_config
from probeplace.probes import tracer_bytes

from ._util import compose


def test_tracer_over_the_limit_is_refused_before_the_bake(tmp_path, monkeypatch):
    import probeplace.probes

    def boom(*a, **k):
        raise AssertionError("the bake started before the tracer's memory was checked")

    monkeypatch.setattr(probeplace.probes, "bake_probes", boom)
    limit = 2**29  # 8 probes' 2048² maps (~0.3 GB) fit; their tracer (2 × ~0.44 GB) does not
    assert 8 * 2050**2 * 9 < limit < 2 * tracer_bytes(8, 2048, 2)
    monkeypatch.setenv("PROBEPLACE_MAX_BYTES", str(limit))
    overrides = [
        "scene.name=cornell_box",
        "placer.method=grid",
        "placer.budget=8",
        "bake.radiance_res=8",
        "bake.geometry_res=2048",
        "progress=false",
        "name=tracer_memory",
        f"results_dir={tmp_path}",
    ]
    cfg = to_config(OmegaConf.to_container(compose(overrides), resolve=True))
    with pytest.raises(
        ResourceError,
        match=r"tracer of 8 placed probes \(all counted usable\), 8 map rows, at geometry_res=2048",
    ):
        run(cfg)
