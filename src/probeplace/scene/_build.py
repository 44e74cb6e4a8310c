"""Validate raw triangle data and assemble a :class:`~probeplace._core.Scene`.

Every loader and built-in scene goes through :func:`build_scene`, so input checks live in one place.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from .._core import Camera, Materials, Scene, SceneError, Sun

log = logging.getLogger(__name__)

# A triangle whose area is below this fraction of (bbox diagonal)² is degenerate: float32 cannot
# give it a stable normal, and it contributes nothing to rendering.
_DEGENERATE_REL_AREA = 1e-14
#: Largest |coordinate| and smallest extent a scene may have (float32-safe squared distances; issue 9).
MAX_COORDINATE = 1e18
MIN_EXTENT = 1e-15
# Corner normals are averaged only over faces within this angle (hard edges stay hard).
CREASE_ANGLE_DEG = 30.0
# What this process has already warned about a scene file: (path, mtime, size, message).
_warned: set[tuple] = set()


def _warn_once(source: str, msg: str, *args) -> None:
    """``log.warning(msg, *args)`` the first time for a scene file (by path, modification time and
    size) in this process, ``log.debug`` after: the runner loads one file for its early checks and again
    for every run, and the report for every view. In-memory sources always warn."""
    try:
        st = os.stat(source)
    except (OSError, ValueError):
        log.warning(msg, *args)
        return
    key = (os.path.realpath(source), st.st_mtime_ns, st.st_size, msg % args)
    if key in _warned:
        log.debug(msg, *args)
        return
    _warned.add(key)
    log.warning(msg, *args)


def make_materials(
    names: Sequence[str],
    base_color: np.ndarray,
    roughness: np.ndarray | None = None,
    metallic: np.ndarray | None = None,
    emission: np.ndarray | None = None,
) -> Materials:
    """Material table from numpy arrays, with glTF defaults (roughness 1, metallic 0, no emission)."""
    n = len(names)
    base_color = np.asarray(base_color, np.float32).reshape(n, 3)
    roughness = np.ones(n, np.float32) if roughness is None else np.asarray(roughness, np.float32).reshape(n)
    metallic = np.zeros(n, np.float32) if metallic is None else np.asarray(metallic, np.float32).reshape(n)
    emission = np.zeros((n, 3), np.float32) if emission is None else np.asarray(emission, np.float32)
    for label, arr in (("base_color", base_color), ("roughness", roughness), ("metallic", metallic)):
        if not np.all(np.isfinite(arr)):
            raise SceneError(f"material {label} has non-finite values")
    if np.any(emission < 0) or not np.all(np.isfinite(emission)):
        raise SceneError("material emission must be finite and non-negative")
    return Materials(
        base_color=jnp.asarray(np.clip(base_color, 0.0, 1.0)),
        roughness=jnp.asarray(np.clip(roughness, 0.0, 1.0)),
        metallic=jnp.asarray(np.clip(metallic, 0.0, 1.0)),
        emission=jnp.asarray(emission.reshape(n, 3)),
        names=tuple(str(s) for s in names),
    )


def materials_from_table(table: dict[str, tuple], columns: Sequence[str]) -> Materials:
    """:func:`make_materials` from ``{name: (value per column)}``, the built-in scenes' tables;
    ``columns`` names each tuple position (``base_color``, ``roughness``, ``metallic``, ``emission``)."""
    names = list(table)
    return make_materials(names, **{c: np.array([table[n][i] for n in names]) for i, c in enumerate(columns)})


def make_camera(position, look_at, fov_y_deg: float, name: str, up=(0.0, 1.0, 0.0)) -> Camera:
    f32 = lambda x: jnp.asarray(np.asarray(x, np.float32))
    return Camera(
        position=f32(position), look_at=f32(look_at), up=f32(up), fov_y_deg=f32(fov_y_deg), name=name
    )


def make_sun(direction, radiance, angular_radius: float = 0.00465) -> Sun:
    d = np.asarray(direction, np.float64)
    n = np.linalg.norm(d)
    if not np.isfinite(n) or n == 0:
        raise SceneError(f"sun direction must be a non-zero finite vector, got {direction}")
    return Sun(
        direction=jnp.asarray((d / n).astype(np.float32)),
        radiance=jnp.asarray(np.asarray(radiance, np.float32)),
        angular_radius=jnp.asarray(np.float32(angular_radius)),
    )


def crease_normals(
    vertices: np.ndarray, faces: np.ndarray, crease_deg: float = CREASE_ANGLE_DEG
) -> np.ndarray:
    """Per-corner shading normals: area-weighted face normals averaged over the faces that share the
    vertex *and* lie within ``crease_deg`` of the corner's own face (so a box keeps flat faces while a
    tessellated column is smooth). Returns (n_tri, 3, 3) unit vectors.
    """
    v = vertices.astype(np.float64)
    tri = v[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # |cross| = 2·area: area weighting
    fn = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-300)
    n_tri = len(faces)
    corners_v = faces.reshape(-1)  # (3·n_tri,) vertex of each corner
    corners_f = np.repeat(np.arange(n_tri), 3)
    # Pairs (corner c, face g) for every face g sharing c's vertex: sort corners by vertex, then
    # expand each vertex's group. Vertex valence is small, so this stays linear in practice.
    order = np.argsort(corners_v, kind="stable")
    sv = corners_v[order]
    starts = np.flatnonzero(np.r_[True, sv[1:] != sv[:-1]])
    counts = np.diff(np.r_[starts, len(sv)])
    group_of = np.repeat(np.arange(len(starts)), counts)
    # For corner at sorted position i, partners are sorted positions starts[g] .. starts[g]+counts[g]-1.
    rep = counts[group_of]
    ci = np.repeat(np.arange(len(sv)), rep)
    offs = np.arange(rep.sum()) - np.repeat(np.cumsum(rep) - rep, rep)
    pj = starts[group_of[ci]] + offs
    fi = corners_f[order[ci]]
    fj = corners_f[order[pj]]
    cos_lim = np.cos(np.deg2rad(crease_deg))
    keep = np.einsum("ij,ij->i", fn[fi], fn[fj]) >= cos_lim
    acc = np.zeros((len(sv), 3))
    np.add.at(acc, ci[keep], cross[fj[keep]])
    out = np.zeros((3 * n_tri, 3))
    out[order] = acc
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
    return out.reshape(n_tri, 3, 3).astype(np.float32)


def _check_geometry(vertices: np.ndarray, faces: np.ndarray, source: str) -> None:
    """Refuse malformed or float32-unsafe vertices and faces (shapes, NaN/inf, index range, scale)."""
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise SceneError(f"{source}: vertices must have shape (n, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] == 0:
        raise SceneError(f"{source}: the scene has no triangles (faces shape {faces.shape})")
    bad = ~np.all(np.isfinite(vertices), axis=1)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise SceneError(
            f"{source}: {int(bad.sum())} vertices are NaN or infinite "
            f"(first: index {first}, {vertices[first]})"
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(f"{source}: face indices out of range [0, {len(vertices)})")
    # float32 range (issue 9): squared distances must stay finite and normal in float32 (max ≈ 3.4e38,
    # smallest normal ≈ 1.2e-38), so coordinates stay below 1e18 and the extent above 1e-15.
    v_abs = float(np.abs(vertices).max())
    if v_abs > MAX_COORDINATE:
        raise SceneError(
            f"{source}: vertex coordinates reach {v_abs:.3g}, beyond ±{MAX_COORDINATE:g}: squared "
            "distances would overflow float32; rescale the scene"
        )
    extent = float(np.max(vertices.max(0) - vertices.min(0)))
    if extent < MIN_EXTENT:
        raise SceneError(
            f"{source}: the scene's extent {extent:.3g} is below {MIN_EXTENT:g}: squared distances "
            "would underflow float32; rescale the scene"
        )


def _checked_labels(tri_material, tri_part, part_names, n_faces: int, n_materials: int, source: str):
    """Range-checked int64 material and part ids per triangle: (tri_material, tri_part, part_names)."""
    tri_material = np.asarray(tri_material, np.int64).reshape(-1)
    if tri_material.shape[0] != n_faces:
        raise SceneError(f"{source}: tri_material has {tri_material.shape[0]} rows for {n_faces} triangles")
    if tri_material.min() < 0 or tri_material.max() >= n_materials:
        raise SceneError(f"{source}: material index out of range [0, {n_materials})")
    tri_part = np.zeros(n_faces, np.int64) if tri_part is None else np.asarray(tri_part, np.int64)
    part_names = tuple(str(p) for p in part_names)
    if tri_part.min() < 0 or tri_part.max() >= len(part_names):
        raise SceneError(f"{source}: part index out of range [0, {len(part_names)})")
    return tri_material, tri_part, part_names


def _drop_degenerate(v64: np.ndarray, faces, tri_material, tri_part, source: str):
    """Drop zero-area triangles (no stable float32 normal, nothing to render); refuse all-degenerate input."""
    tri = v64[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    diag = float(np.linalg.norm(v64.max(0) - v64.min(0)))
    degenerate = area2 <= 2 * _DEGENERATE_REL_AREA * max(diag, 1e-30) ** 2
    if degenerate.all():
        raise SceneError(f"{source}: all {len(faces)} triangles are degenerate (zero area)")
    if degenerate.any():
        _warn_once(
            source,
            "%s: dropped %d degenerate (zero-area) triangles of %d",
            source,
            int(degenerate.sum()),
            len(faces),
        )
        keep = ~degenerate
        faces, tri_material, tri_part = faces[keep], tri_material[keep], tri_part[keep]
    return faces, tri_material, tri_part


def _drop_duplicates(v64: np.ndarray, faces, tri_material, tri_part, source: str):
    """Keep the first of triangles with the same corners and winding (they z-fight and double-count area)."""
    # Duplicate triangles (same corners, same winding; issue 9) z-fight and double-count area: keep the
    # first. Opposite windings are kept: two one-sided faces back to back are a legitimate thin sheet.
    _, v_id = np.unique(v64, axis=0, return_inverse=True)
    corners = v_id.reshape(-1)[faces]
    lead = np.argmin(corners, axis=1)
    canon = np.take_along_axis(corners, (lead[:, None] + np.arange(3)[None]) % 3, axis=1)
    _, first = np.unique(canon, axis=0, return_index=True)
    if len(first) < len(faces):
        _warn_once(
            source, "%s: dropped %d duplicate triangles of %d", source, len(faces) - len(first), len(faces)
        )
        keep = np.sort(first)
        faces, tri_material, tri_part = faces[keep], tri_material[keep], tri_part[keep]
    return faces, tri_material, tri_part


def build_scene(
    name: str,
    vertices: np.ndarray,
    faces: np.ndarray,
    tri_material: np.ndarray,
    materials: Materials,
    *,
    tri_part: np.ndarray | None = None,
    part_names: Sequence[str] = ("mesh",),
    views: Sequence[Camera] = (),
    sun: Sun | None = None,
    sky_radiance=(0.0, 0.0, 0.0),
    unit_m: float = 1.0,
    source: str = "<memory>",
) -> Scene:
    """Check raw triangle data, drop degenerate and duplicate triangles (logged with a count) and build a
    Scene.

    Raises:
        SceneError: empty mesh, NaN/inf vertices, coordinates outside float32's safe range, out-of-range
            indices or material ids.
    """
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    _check_geometry(vertices, faces, source)
    tri_material, tri_part, part_names = _checked_labels(
        tri_material, tri_part, part_names, faces.shape[0], len(materials.names), source
    )

    v64 = vertices.astype(np.float64)
    faces, tri_material, tri_part = _drop_degenerate(v64, faces, tri_material, tri_part, source)
    faces, tri_material, tri_part = _drop_duplicates(v64, faces, tri_material, tri_part, source)

    # Drop vertices no face uses, so bounds describe the geometry.
    used, inverse = np.unique(faces.reshape(-1), return_inverse=True)
    vertices = vertices[used]
    faces = inverse.reshape(-1, 3)

    emissive_mat = np.asarray(materials.emission).max(axis=1) > 0
    emissive_tris = np.flatnonzero(emissive_mat[tri_material])
    return Scene(
        vertices=jnp.asarray(vertices.astype(np.float32)),
        faces=jnp.asarray(faces.astype(np.int32)),
        corner_normals=jnp.asarray(crease_normals(vertices, faces)),
        tri_material=jnp.asarray(tri_material.astype(np.int32)),
        tri_part=jnp.asarray(tri_part.astype(np.int32)),
        materials=materials,
        emissive_tris=jnp.asarray(emissive_tris.astype(np.int32)),
        sun=sun,
        sky_radiance=jnp.asarray(np.asarray(sky_radiance, np.float32)),
        views=tuple(views),
        name=name,
        part_names=part_names,
        unit_m=float(unit_m),
    )
