"""Crytek Sponza (262k triangles): the JAX BVH agrees with Embree (slow: ~10 s build + compile)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from probeplace.geometry import BVHCaster, EmbreeCaster
from probeplace.scene import build_scene, make_materials
from tests.geometry.raycast_reference import assert_same_hits, random_rays
from tests.helpers import shared_scene_path

pytestmark = pytest.mark.slow


def test_sponza_bvh_agrees_with_embree():
    mesh = trimesh.load(shared_scene_path("crytek_sponza.glb"), force="mesh")
    mats = make_materials(["grey"], np.full((1, 3), 0.5))
    scene = build_scene("sponza", mesh.vertices, mesh.faces, np.zeros(len(mesh.faces), int), mats)
    o, d = random_rays(scene, 20000, seed=7)
    ref = EmbreeCaster(scene, threads=1).closest_hit(o, d)
    hit = BVHCaster(scene).closest_hit(o, d)
    # Sponza's overlapping coplanar wall quads make ~1 % of rays a verified tie (0.9906 same id on 1M rays
    # in docs/raycast.md; the share follows Embree's traversal order, so it is not judged): every ray must
    # agree on hit/miss and distance, and hit the same triangle or a verified tie
    assert_same_hits(scene, o, d, hit, ref, label="sponza")
