"""PLY loading: geometry through trimesh, one part, one diffuse material.

PLY has no materials. The part (named after the file stem) gets roughness 1, metallic 0 and a base
colour that is :data:`~probeplace.scene._raw.DEFAULT_GREY`, or, if the file has per-vertex or per-face
colours, their average. PLY colours are 8-bit display values, taken as sRGB-encoded: they are decoded
to linear (IEC 61966-2-1) before averaging, and the average is over triangle area (per-face colours) or
over vertices used by faces (per-vertex colours).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from .._raw import DEFAULT_GREY, PartCollector, RawScene, trimesh_errors
from ._ply_check import check_ply


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """Decode sRGB values in [0, 1] to linear light (IEC 61966-2-1 piecewise curve)."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _mean_colour(mesh: trimesh.Trimesh) -> np.ndarray:
    visual = mesh.visual
    kind = getattr(visual, "kind", None)
    if kind == "face":
        lin = srgb_to_linear(np.asarray(visual.face_colors, np.float64)[:, :3] / 255.0)
        w = np.asarray(mesh.area_faces, np.float64)
        return (lin * w[:, None]).sum(0) / max(w.sum(), 1e-300)
    if kind == "vertex":
        used = np.unique(np.asarray(mesh.faces).reshape(-1))
        lin = srgb_to_linear(np.asarray(visual.vertex_colors, np.float64)[used, :3] / 255.0)
        return lin.mean(0)
    return np.asarray(DEFAULT_GREY, np.float64)


def load_ply(path: Path) -> RawScene:
    """Read a ``.ply`` mesh (ASCII or binary) as one grey (or vertex-colour-averaged) part.

    Raises:
        SceneError: a malformed header, a body shorter than the header declares or a garbled row
            (``file:line`` where there is one: :func:`check_ply`), anything else trimesh cannot parse,
            or no triangles (a point cloud).
    """
    check_ply(path)
    with trimesh_errors(path, "PLY"):
        tscene = trimesh.load(path, force="scene", process=False)
    parts = PartCollector()
    colours = []
    for frame in sorted(tscene.graph.nodes_geometry, key=str):
        transform, geom_name = tscene.graph[frame]
        geom = tscene.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        with trimesh_errors(path, "PLY"):
            colours.append(_mean_colour(geom))
        v = trimesh.transform_points(np.asarray(geom.vertices, np.float64), transform)
        parts.add(path.stem, v, np.asarray(geom.faces), len(colours) - 1)
    vertices, faces, tri_mat, tri_part = parts.arrays(str(path))
    n = len(colours)
    return RawScene(
        vertices=vertices,
        faces=faces,
        tri_material=tri_mat,
        tri_part=tri_part,
        part_names=parts.part_names,
        material_names=[path.stem if n == 1 else f"{path.stem}_{i}" for i in range(n)],
        base_color=np.stack(colours),
        roughness=np.ones(n),
        metallic=np.zeros(n),
        emission=np.zeros((n, 3)),
    )
