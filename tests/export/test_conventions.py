"""Coordinate conventions per engine, checked on the asymmetric fixture.

Oracle: each engine file is parsed independently of the exporter (regex / YAML / glTF JSON / USD) and
the positions must equal M·p with M the documented engine matrix: Unity (left-handed, +Y up) negates X
like glTFast/UnityGLTF/FBX import; glTF, Godot and USD (right-handed, +Y up) keep coordinates. The
handedness shows in the sign of the triple product of the +X, +Y, +Z probe offsets: it must flip for
Unity only, and "up" (probe 2 above probe 0) must stay +Y everywhere.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import yaml

from probeplace.export import GODOT_FROM_GLTF, UNITY_FROM_GLTF, export_probes

from ._fixture import asymmetric_probes


def _triple(p: np.ndarray) -> float:
    o = p[0]
    return float(np.dot(np.cross(p[1] - o, p[2] - o), p[3] - o))


def _unity_positions(path) -> np.ndarray:
    # Unity writes its %TAG directive once for all documents; standard YAML scopes it to the first one,
    # so spell the tags out before parsing (https://docs.unity3d.com/Manual/FormatDescription.html).
    text = path.read_text()
    assert text.startswith("%YAML 1.1\n%TAG !u! tag:unity3d.com,2011:\n")
    text = re.sub(r"^--- !u!(\d+) &(\d+)", r"--- !unity:\1 &\2", text.split("\n", 2)[2], flags=re.M)
    loader = type("UnityLoader", (yaml.SafeLoader,), {})
    loader.add_multi_constructor("!unity:", lambda ld, suffix, node: ld.construct_mapping(node, deep=True))
    docs = list(yaml.load_all(text, Loader=loader))
    (group,) = [d["LightProbeGroup"] for d in docs if "LightProbeGroup" in d]
    assert group["m_Enabled"] == 1
    return np.array([[q["x"], q["y"], q["z"]] for q in group["m_SourcePositions"]], np.float32)


def _godot_positions(path) -> np.ndarray:
    text = path.read_text()
    assert text.startswith("[gd_scene format=3]")
    assert '[node name="ProbeplaceProbes" type="LightmapGI"]' in text
    rows = re.findall(r'type="LightmapProbe" parent="\."\]\ntransform = Transform3D\(([^)]*)\)', text)
    return np.array([[float(v) for v in r.split(",")[9:]] for r in rows], np.float32)


def _gltf_positions(path) -> np.ndarray:
    doc = json.loads(path.read_text())
    nodes = [n for n in doc["nodes"][1:] if n["extras"]["probeplace"]["active"]]
    return np.array([n["translation"] for n in nodes], np.float32)


def _usd_positions(path) -> np.ndarray:
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    pts = np.asarray(UsdGeom.Points(stage.GetPrimAtPath("/ProbeSet/Probes")).GetPointsAttr().Get())
    active = np.asarray(
        stage.GetPrimAtPath("/ProbeSet/Probes").GetAttribute("primvars:probeplace:active").Get()
    )
    return pts[active].astype(np.float32)


CASES = {
    "unity": ("p.prefab", _unity_positions, UNITY_FROM_GLTF, -1),
    "godot": ("p.tscn", _godot_positions, GODOT_FROM_GLTF, +1),
    "gltf": ("p.gltf", _gltf_positions, np.eye(3), +1),
    "usd": ("p.usda", _usd_positions, np.eye(3), +1),
}


@pytest.mark.parametrize("fmt", sorted(CASES))
def test_engine_frame(tmp_path, fmt):
    name, parse, matrix, handed = CASES[fmt]
    src = asymmetric_probes()
    export_probes(src, fmt, tmp_path / name)
    got = parse(tmp_path / name)
    act = src.active_only().positions
    np.testing.assert_array_equal(got, (act.astype(np.float64) @ matrix.T).astype(np.float32))
    assert np.sign(_triple(got)) == handed * np.sign(_triple(act))
    assert got[2, 1] > got[0, 1]  # probe 2 is above probe 0: up stays +Y


def test_unity_and_godot_scale_to_metres(tmp_path):
    src = asymmetric_probes()
    export_probes(src, "unity", tmp_path / "m.prefab", to_metres=True)
    assert "m_LocalScale: {x: 0.5, y: 0.5, z: 0.5}" in (tmp_path / "m.prefab").read_text()
    export_probes(src, "godot", tmp_path / "m.tscn", to_metres=True)
    text = (tmp_path / "m.tscn").read_text()
    assert "Transform3D(0.5, 0, 0, 0, 0.5, 0, 0, 0, 0.5, 0, 0, 0)" in text
    assert text.count('type="LightmapProbe" parent="Probes"') == src.active.sum()
