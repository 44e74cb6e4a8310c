"""Small scenes with closed-form distances for the SDF tests, and their grids (built once per process)."""

from __future__ import annotations

import functools

import numpy as np
import trimesh

from probeplace.geometry import build_sdf
from probeplace.scene import build_scene, cornell_box, make_materials

# A box 1.2 x 0.8 x 0.6 centred here (off the origin and off the lattice on purpose).
BOX_CENTRE = np.array([0.1, 0.2, 0.3])
BOX_HALF = np.array([0.6, 0.4, 0.3])


def mesh_scene(name: str, mesh: trimesh.Trimesh):
    mats = make_materials(["grey"], np.full((1, 3), 0.5))
    return build_scene(name, mesh.vertices, mesh.faces, np.zeros(len(mesh.faces), int), mats)


@functools.cache
def sphere_scene():
    """Unit icosphere (radius 1, centred at the origin), 1280 outward-facing triangles."""
    return mesh_scene("unit_sphere", trimesh.creation.icosphere(subdivisions=3, radius=1.0))


@functools.cache
def sphere_sdf():
    return build_sdf(sphere_scene(), voxel_size=0.05, cache_dir=False)


def sphere_sagitta() -> float:
    """Largest gap between the unit sphere and its inscribed icosphere: 1 − min face-plane distance."""
    tri = np.asarray(sphere_scene().triangles, np.float64)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return float(1.0 - np.min(np.abs(np.einsum("ij,ij->i", n, tri[:, 0]))))


@functools.cache
def box_scene():
    box = trimesh.creation.box(extents=2 * BOX_HALF)
    box.apply_translation(BOX_CENTRE)
    return mesh_scene("box", box)


@functools.cache
def box_sdf():
    return build_sdf(box_scene(), voxel_size=0.05, cache_dir=False)


def box_distance(p: np.ndarray) -> np.ndarray:
    """Exact signed distance to the box (negative inside)."""
    q = np.abs(p - BOX_CENTRE) - BOX_HALF
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(np.max(q, axis=-1), 0.0)
    return outside + inside


@functools.cache
def cornell_sdf():
    return build_sdf(cornell_box(), cache_dir=False)
