"""Rigid transforms of whole scenes, for the stability study (DESIGN.md: "spread ... over small scene
offsets/rotations": a uniform grid's quality swings with its alignment)."""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .._core import Camera, Scene
from ._primitives import Vec3Like

#: A 3×3 matrix given as nested sequences or an array.
Mat3Like = Sequence[Sequence[float]] | np.ndarray | Array


def axis_angle_rotation(axis: Vec3Like, angle_rad: float) -> np.ndarray:
    """3×3 rotation by ``angle_rad`` about ``axis`` (right-handed), by Rodrigues' formula."""
    k = np.asarray(axis, np.float64)
    n = np.linalg.norm(k)
    if k.shape != (3,) or not np.isfinite(n) or n == 0:
        raise ValueError(f"axis must be a non-zero finite 3-vector, got {axis!r}")
    k = k / n
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle_rad) * kx + (1.0 - np.cos(angle_rad)) * (kx @ kx)


def _check_rotation(rotation: Mat3Like) -> np.ndarray:
    r = np.asarray(rotation, np.float64)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError(f"rotation must be a finite 3×3 matrix, got shape {r.shape}")
    # float32 scenes: an orthonormality error ~1e-6 is round-off, 1e-4 is a wrong matrix.
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-5) or np.linalg.det(r) <= 0:
        raise ValueError(
            "rotation must be a proper rotation (orthonormal, determinant +1); "
            f"got det {np.linalg.det(r):.6g}"
        )
    return r


def transform_scene(
    scene: Scene, rotation: Mat3Like | None = None, translation: Vec3Like | Array | None = None
) -> Scene:
    """Move a whole scene rigidly: x ↦ R x + t.

    Points (vertices, camera positions and look-at points) get R x + t; directions (shading normals,
    camera up vectors, the sun direction) get R d. Materials, lights' radiance, sky and names are
    unchanged; a proper rotation keeps every triangle's counter-clockwise winding (front side) intact.

    Args:
        scene: the scene.
        rotation: (3, 3) proper rotation matrix (default identity), world frame.
        translation: (3,) offset in scene units (default zero).

    Returns:
        The transformed Scene, same dtypes as ``scene``. Not differentiable w.r.t. anything useful
        (host-side helper); call it outside jit.

    Raises:
        ValueError: ``rotation`` is not a proper rotation or ``translation`` is not a finite 3-vector.
    """
    r = np.eye(3) if rotation is None else _check_rotation(rotation)
    t = np.zeros(3) if translation is None else np.asarray(translation, np.float64)
    if t.shape != (3,) or not np.all(np.isfinite(t)):
        raise ValueError(f"translation must be a finite 3-vector, got {translation!r}")
    dtype = scene.vertices.dtype
    rj, tj = jnp.asarray(r, dtype), jnp.asarray(t, dtype)

    def point(p):
        return p @ rj.T + jnp.broadcast_to(tj, p.shape)  # explicit: rank promotion is an error in tests

    def vector(d):
        return d @ rj.T

    def camera(c: Camera) -> Camera:
        return eqx.tree_at(
            lambda c: (c.position, c.look_at, c.up), c, (point(c.position), point(c.look_at), vector(c.up))
        )

    out = eqx.tree_at(
        lambda s: (s.vertices, s.corner_normals, s.views),
        scene,
        (point(scene.vertices), vector(scene.corner_normals), tuple(camera(c) for c in scene.views)),
    )
    if scene.sun is not None:
        out = eqx.tree_at(lambda s: s.sun.direction, out, vector(scene.sun.direction))
    return out
