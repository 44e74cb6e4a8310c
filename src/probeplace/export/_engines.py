"""Engine scene files: a Unity ``LightProbeGroup`` prefab and a Godot 4 ``LightmapGI`` scene.

Both engines bake their own SH from these positions, so only positions are written, and only the
active probes. Positions stay in scene units (they line up with the scene's own file as the engine
imports it); ``to_metres=True`` puts the scene's ``units_m`` on the root transform's scale instead.

Coordinate conventions (tested with an asymmetric probe set, tests/export/test_conventions.py):

* **Unity** is left-handed with +Y up. Its glTF importers (glTFast, UnityGLTF) and its FBX importer
  bring a right-handed +Y-up asset in by negating X, so a probe at (x, y, z) goes to (−x, y, z): it
  then sits at the same spot of the imported scene mesh.
* **Godot 4** is right-handed with +Y up, like glTF and probeplace, and its glTF importer keeps
  coordinates: (x, y, z) → (x, y, z).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .._core.files._io import write_text_atomic
from ._data import ExportError, ExportProbes
from ._io_util import fmt_f32

# Right-handed +Y up (glTF) → engine frame, as a matrix acting on column vectors.
UNITY_FROM_GLTF = np.diag([-1.0, 1.0, 1.0])
GODOT_FROM_GLTF = np.eye(3)

# Unity serialisation class IDs (https://docs.unity3d.com/Manual/ClassIDReference.html).
_GAMEOBJECT, _TRANSFORM, _LIGHT_PROBE_GROUP = 1, 4, 220
_GO_ID, _TR_ID, _LPG_ID = 1000000000, 4000000000, 22000000000


def _safe_name(name: str) -> str:
    out = "".join(c if c.isalnum() or c in "_-" else "_" for c in name)
    return out or "ProbeplaceProbes"


def unity_positions(probes: ExportProbes) -> np.ndarray:
    """Active probe positions in Unity's frame (float32), as written to the prefab."""
    act = probes.active_only()
    return (act.positions.astype(np.float64) @ UNITY_FROM_GLTF.T).astype(np.float32)


def write_unity(
    probes: ExportProbes, out: str | os.PathLike, *, name: str = "ProbeplaceProbes", to_metres: bool = False
) -> list[Path]:
    """Write a Unity prefab (``.prefab``, YAML) holding one GameObject with a ``LightProbeGroup``.

    Import: copy the file into the project's ``Assets/`` folder (Unity makes the ``.meta``), drag the
    prefab into the scene next to the imported scene model, then Window ▸ Rendering ▸ Lighting ▸
    Generate Lighting. The probe positions are in the group's local space (``m_SourcePositions``).
    """
    if Path(out).suffix != ".prefab":
        raise ExportError(f"a Unity export must end in .prefab, got {out}")
    pos = unity_positions(probes)
    scale = fmt_f32(probes.units_m) if to_metres else "1"
    header = "\n".join(
        [
            "%YAML 1.1",
            "%TAG !u! tag:unity3d.com,2011:",
            f"--- !u!{_GAMEOBJECT} &{_GO_ID}",
            "GameObject:",
            "  m_ObjectHideFlags: 0",
            "  m_CorrespondingSourceObject: {fileID: 0}",
            "  m_PrefabInstance: {fileID: 0}",
            "  m_PrefabAsset: {fileID: 0}",
            "  serializedVersion: 6",
            "  m_Component:",
            f"  - component: {{fileID: {_TR_ID}}}",
            f"  - component: {{fileID: {_LPG_ID}}}",
            "  m_Layer: 0",
            f"  m_Name: {_safe_name(name)}",
            "  m_TagString: Untagged",
            "  m_Icon: {fileID: 0}",
            "  m_NavMeshLayer: 0",
            "  m_StaticEditorFlags: 0",
            "  m_IsActive: 1",
            f"--- !u!{_TRANSFORM} &{_TR_ID}",
            "Transform:",
            "  m_ObjectHideFlags: 0",
            "  m_CorrespondingSourceObject: {fileID: 0}",
            "  m_PrefabInstance: {fileID: 0}",
            "  m_PrefabAsset: {fileID: 0}",
            f"  m_GameObject: {{fileID: {_GO_ID}}}",
            "  serializedVersion: 2",
            "  m_LocalRotation: {x: 0, y: 0, z: 0, w: 1}",
            "  m_LocalPosition: {x: 0, y: 0, z: 0}",
            f"  m_LocalScale: {{x: {scale}, y: {scale}, z: {scale}}}",
            "  m_ConstrainProportionsScale: 0",
            "  m_Children: []",
            "  m_Father: {fileID: 0}",
            "  m_LocalEulerAnglesHint: {x: 0, y: 0, z: 0}",
            f"--- !u!{_LIGHT_PROBE_GROUP} &{_LPG_ID}",
            "LightProbeGroup:",
            "  m_ObjectHideFlags: 0",
            "  m_CorrespondingSourceObject: {fileID: 0}",
            "  m_PrefabInstance: {fileID: 0}",
            "  m_PrefabAsset: {fileID: 0}",
            f"  m_GameObject: {{fileID: {_GO_ID}}}",
            "  m_Enabled: 1",
        ]
    )
    if len(pos):
        lines = ["  m_SourcePositions:"]
        lines += [f"  - {{x: {fmt_f32(x)}, y: {fmt_f32(y)}, z: {fmt_f32(z)}}}" for x, y, z in pos]
    else:
        lines = ["  m_SourcePositions: []"]
    lines.append("  m_Dering: 1")
    return [write_text_atomic(out, header + "\n" + "\n".join(lines) + "\n")]


def godot_positions(probes: ExportProbes) -> np.ndarray:
    """Active probe positions in Godot's frame (float32), as written to the scene."""
    act = probes.active_only()
    return (act.positions.astype(np.float64) @ GODOT_FROM_GLTF.T).astype(np.float32)


def write_godot(
    probes: ExportProbes, out: str | os.PathLike, *, name: str = "ProbeplaceProbes", to_metres: bool = False
) -> list[Path]:
    """Write a Godot 4 text scene (``.tscn``): a ``LightmapGI`` root with one ``LightmapProbe`` per probe.

    Import: copy the file into the project, instance it (Ctrl+Shift+A or drag) as a sibling of the
    scene's geometry (a LightmapGI bakes the meshes and probes under its *parent*), then select the
    LightmapGI node and click "Bake Lightmaps" in the 3D editor toolbar.
    """
    if Path(out).suffix != ".tscn":
        raise ExportError(f"a Godot export must end in .tscn, got {out}")
    pos = godot_positions(probes)
    lines = ["[gd_scene format=3]", "", f'[node name="{_safe_name(name)}" type="LightmapGI"]']
    parent = "."
    if to_metres and probes.units_m != 1.0:
        s = fmt_f32(probes.units_m)
        lines += [
            "",
            '[node name="Probes" type="Node3D" parent="."]',
            f"transform = Transform3D({s}, 0, 0, 0, {s}, 0, 0, 0, {s}, 0, 0, 0)",
        ]
        parent = "Probes"
    for i, (x, y, z) in enumerate(pos):
        lines += [
            "",
            f'[node name="probe_{i:04d}" type="LightmapProbe" parent="{parent}"]',
            f"transform = Transform3D(1, 0, 0, 0, 1, 0, 0, 0, 1, {fmt_f32(x)}, {fmt_f32(y)}, {fmt_f32(z)})",
        ]
    return [write_text_atomic(out, "\n".join(lines) + "\n")]
