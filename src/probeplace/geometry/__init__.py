"""Geometry: exact ray casting (Embree, JAX BVH, brute force), the SDF grid, surface samples."""

from ._raycast import AbstractRayCaster as AbstractRayCaster
from ._raycast import BruteForceCaster as BruteForceCaster
from ._raycast import complete_hit as complete_hit
from ._raycast import intersect_triangles as intersect_triangles
