"""A scene as a person sees it in a 3D view (``probeplace view``, report.html; issue 36): triangles with
one display colour each. NumPy only, so the viewers need no JAX of their own."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PreviewMesh:
    """Triangles to draw: ``vertices`` (n_vert, 3) float32 in scene units, ``faces`` (n_tri, 3) int32,
    ``face_rgb`` (n_tri, 3) uint8 sRGB (the material's albedo; emitters drawn at full brightness in their
    emission's hue, so a light reads as a light)."""

    vertices: np.ndarray
    faces: np.ndarray
    face_rgb: np.ndarray


def srgb8(linear: np.ndarray) -> np.ndarray:
    """Linear [0, 1] → 8-bit sRGB (IEC 61966-2-1), the colour a display shows for an albedo (clipped to
    [0, 1] first; also ``render.tonemap``'s last step)."""
    a = np.clip(np.asarray(linear, np.float64), 0.0, 1.0)
    s = np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)
    return np.round(s * 255.0).astype(np.uint8)


def preview_mesh(scene) -> PreviewMesh:
    """The scene's triangles with a display colour per face: its material's base colour in sRGB, and for
    emissive materials the emission normalised to its brightest channel."""
    mats = scene.materials
    albedo = np.asarray(mats.base_color, np.float64)
    emission = np.asarray(mats.emission, np.float64)
    peak = emission.max(axis=1, keepdims=True)
    colour = np.where(peak > 0, emission / np.maximum(peak, 1e-30), albedo)
    return PreviewMesh(
        vertices=np.asarray(scene.vertices, np.float32),
        faces=np.asarray(scene.faces, np.int32),
        face_rgb=srgb8(colour)[np.asarray(scene.tri_material)],
    )
