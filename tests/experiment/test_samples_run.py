"""Issue 33, "Samples from a noise target", through the runner: ``bake.spp=auto`` runs a pilot, bakes at
the chosen count (the count the baked probes record) and reports the choice in ``metrics.json``."""

from __future__ import annotations

import json

from probeplace.experiment import run, to_config

from ._util import compose
from .test_presets import TINY


def test_an_auto_bake_reports_its_choice(tmp_path):
    over = [*TINY, "bake.spp=auto", "bake.noise_target=0.2", "bake.max_spp=8", "eval=none"]
    cfg = to_config(compose([*over, f"results_dir={tmp_path}"]))
    assert cfg.bake.spp == "auto"
    res = run(cfg)
    m = json.loads((res.out_dir / "metrics.json").read_text())
    s = m["bake_samples"]
    assert s["chosen_by"] == "target" and (s["noise_target"], s["max_spp"]) == (0.2, 8)
    assert 1 <= s["spp"] <= 8 and s["pilot_spp"] == cfg.bake.pilot_spp
    assert s["spp"] == m["bake_settings"]["spp"]  # what the probes were baked with
    assert isinstance(s["target_met"], bool) and s["seconds"] > 0
    # a fixed count is reported as such, without a pilot
    cfg = to_config(compose([*TINY, "eval=none", f"results_dir={tmp_path}", "name=fixed"]))
    m = run(cfg).metrics
    assert m["bake_samples"]["chosen_by"] == "fixed" and m["bake_samples"]["spp"] == cfg.bake.spp == 1
    assert m["bake_samples"]["pilot_spp"] is None
