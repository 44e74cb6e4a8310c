"""Issue 31, item 4: Vardis ranks probes by path-traced radiance, so a scene without light is refused up
front — by ``probeplace place --method vardis`` in one line naming the method, the scene and the sidecar
keys, and by ``place(method="vardis")`` before the SDF is built — while the geometric methods still place
in the dark (docs/baselines.md, "Vardis needs a light")."""

from __future__ import annotations

import numpy as np
import pytest

from probeplace._core import SceneError
from probeplace.cli import main
from probeplace.scene import build_scene, make_materials
from probeplace.scene._primitives import box
from tests.scene.sidecar_util import write_room_obj


def test_cli_refuses_vardis_on_a_scene_without_light(tmp_path, capsys, no_slow_work):
    scene = write_room_obj(tmp_path)  # no emitter, no sidecar: no light
    out = tmp_path / "p.json"
    code = main(["place", str(scene), "--method", "vardis", "--budget", "8", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # the refusal alone: no "no light" warning before it
    assert lines[0].startswith(f"probeplace: error: {scene}: the scene has no light"), lines[0]
    assert "which --method vardis needs" in lines[0]
    assert "sidecar room.probeplace.yaml" in lines[0] and "keys: sun, sky, emitters" in lines[0]
    assert not (tmp_path / "p.json").exists() and not (tmp_path / "p.png").exists()


def test_place_vardis_refuses_before_the_sdf(monkeypatch):
    import probeplace.placement.baselines._methods as baselines
    from probeplace.placement import place

    def boom(*a, **k):
        raise AssertionError("vardis built the SDF before refusing a scene without light")

    monkeypatch.setattr(baselines, "build_sdf", boom)
    v, f = box(np.zeros(3), np.array([4.0, 3.0, 5.0]))
    grey = make_materials(["w"], np.full((1, 3), 0.5))
    dark = build_scene("dark", v, f[:, ::-1], np.zeros(len(f), int), grey)
    want = (
        r"^vardis placement ranks probes by the light they see, and scene 'dark' has no light .*"
        r"sidecar dark\.probeplace\.yaml .*keys: sun, sky, emitters"
    )
    with pytest.raises(SceneError, match=want):
        place(dark, method="vardis", budget=4)
