"""USD (usd-core): one ``UsdGeomPoints`` prim with per-probe primvars, for Omniverse / Houdini / Blender.

Stage metadata: ``upAxis = "Y"`` and ``metersPerUnit = units_m`` (USD is right-handed, so positions are
copied as they are; https://openusd.org/release/api/group___usd_geom_up_axis__group.html). Layout::

    /ProbeSet                  Xform (defaultPrim), customData: probeplace format, method, config (JSON)
    /ProbeSet/Probes           Points: points (float3, scene units), widths,
                               primvars:probeplace:active (bool, vertex),
                               primvars:probeplace:inside (bool, vertex; optional),
                               primvars:probeplace:sh (float3, vertex, elementSize 9; optional)

``read_usd`` is the lossless inverse. ``pxr`` is imported lazily, so the rest of the package works
without usd-core.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .._core.files._io import atomic_path
from ._data import ExportError, ExportProbes
from ._sh import SH_CONVENTION

USD_FORMAT = "probeplace.USDProbes/1"


def _pxr():
    try:
        from pxr import Sdf, Usd, UsdGeom, Vt
    except ImportError as e:  # pragma: no cover - usd-core is a dependency
        raise ExportError(f"USD export needs usd-core (pip install usd-core): {e}") from None
    return Sdf, Usd, UsdGeom, Vt


def write_usd(probes: ExportProbes, out: str | os.PathLike, *, width: float | None = None) -> list[Path]:
    """Write a ``.usda`` / ``.usdc`` / ``.usd`` file; ``width`` is the display diameter of each point
    (default: 2 % of the set's bounding-box diagonal, or 0.1 scene units for a single probe)."""
    Sdf, Usd, UsdGeom, Vt = _pxr()
    out = Path(out)
    if out.suffix not in (".usda", ".usdc", ".usd"):
        raise ExportError(f"a USD export must end in .usda, .usdc or .usd, got {out}")
    if width is None:
        ext = np.ptp(probes.positions, axis=0) if probes.n else np.zeros(3)
        width = float(0.02 * np.linalg.norm(ext)) or 0.1
    with atomic_path(out, suffix=".tmp" + out.suffix) as tmp:
        stage = Usd.Stage.CreateNew(str(tmp))
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, probes.units_m)
        root = UsdGeom.Xform.Define(stage, "/ProbeSet")
        stage.SetDefaultPrim(root.GetPrim())
        root.GetPrim().SetCustomData(
            {
                "probeplace:format": USD_FORMAT,
                "probeplace:method": probes.method,
                "probeplace:config": json.dumps(probes.metadata, sort_keys=True, allow_nan=False),
            }
        )
        pts = UsdGeom.Points.Define(stage, "/ProbeSet/Probes")
        pts.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(probes.positions))
        pts.CreateWidthsAttr(Vt.FloatArray.FromNumpy(np.full(probes.n, width, np.float32)))
        pts.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        if probes.n:
            lo, hi = probes.positions.min(0) - width, probes.positions.max(0) + width
            pts.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(np.stack([lo, hi]).astype(np.float32)))
        api = UsdGeom.PrimvarsAPI(pts.GetPrim())
        pv = api.CreatePrimvar("probeplace:active", Sdf.ValueTypeNames.BoolArray, UsdGeom.Tokens.vertex)
        pv.Set(Vt.BoolArray([bool(a) for a in probes.active]))
        if probes.inside is not None:
            pv = api.CreatePrimvar("probeplace:inside", Sdf.ValueTypeNames.BoolArray, UsdGeom.Tokens.vertex)
            pv.Set(Vt.BoolArray([bool(a) for a in probes.inside]))
        if probes.sh is not None:
            pv = api.CreatePrimvar(
                "probeplace:sh", Sdf.ValueTypeNames.Float3Array, UsdGeom.Tokens.vertex, elementSize=9
            )
            pv.Set(Vt.Vec3fArray.FromNumpy(probes.sh.reshape(-1, 3)))
            pv.GetAttr().SetDocumentation(SH_CONVENTION)
        stage.GetRootLayer().Save()
        del stage
    return [out]


def read_usd(path: str | os.PathLike) -> ExportProbes:
    """Load probes written by :func:`write_usd` (lossless)."""
    _, Usd, UsdGeom, _ = _pxr()
    path = Path(path)
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        raise ExportError(f"{path}: USD could not open the file")
    root = stage.GetPrimAtPath("/ProbeSet")
    pts_prim = stage.GetPrimAtPath("/ProbeSet/Probes")
    data = root.GetCustomData() if root else {}
    if not root or data.get("probeplace:format") != USD_FORMAT or not pts_prim.IsA(UsdGeom.Points):
        raise ExportError(f"{path}: no probeplace /ProbeSet/Probes points prim")
    if UsdGeom.GetStageUpAxis(stage) != UsdGeom.Tokens.y:
        raise ExportError(f"{path}: only Y-up stages are supported")
    pts = UsdGeom.Points(pts_prim)
    pos = np.asarray(pts.GetPointsAttr().Get(), np.float32).reshape(-1, 3)
    api = UsdGeom.PrimvarsAPI(pts_prim)

    def primvar(name):
        pv = api.GetPrimvar(name)
        return pv.Get() if pv and pv.HasValue() else None

    active = primvar("probeplace:active")
    inside = primvar("probeplace:inside")
    sh = primvar("probeplace:sh")
    return ExportProbes(
        positions=pos,
        active=np.ones(len(pos), bool) if active is None else np.asarray(active, bool),
        method=str(data.get("probeplace:method", "manual")),
        units_m=float(UsdGeom.GetStageMetersPerUnit(stage)),
        metadata=json.loads(data.get("probeplace:config", "{}")),
        sh=None if sh is None else np.asarray(sh, np.float32).reshape(-1, 9, 3),
        inside=None if inside is None else np.asarray(inside, bool),
    )
