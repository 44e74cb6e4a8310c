"""Geometry: exact ray casting (Embree, JAX BVH, brute force), the SDF grid, surface samples."""

from ._raycast import AbstractJaxRayCaster as AbstractJaxRayCaster
from ._raycast import AbstractRayCaster as AbstractRayCaster
from ._raycast import BruteForceCaster as BruteForceCaster
from ._raycast import complete_hit as complete_hit
from ._raycast import intersect_triangles as intersect_triangles

# --- SDF and samples ---
from ._samples import SurfaceSamples as SurfaceSamples
from ._samples import default_sample_spacing as default_sample_spacing
from ._samples import sample_surface as sample_surface
from ._sdf import SDFGrid as SDFGrid
from ._sdf import lookup_sdf as lookup_sdf
from ._sdf import sdf_value as sdf_value
from ._sdf import sdf_value_and_grad as sdf_value_and_grad
from ._sdf_build import build_sdf as build_sdf
from ._sdf_build import default_voxel_size as default_voxel_size
from ._sphere_trace import sphere_trace as sphere_trace
from ._sphere_trace import trace_sdf_rays as trace_sdf_rays
from ._visibility import soft_visibility as soft_visibility

# --- exact ray casting backends ---
# isort: split
from ._casters import BRUTE_FORCE_MAX_TRIANGLES as BRUTE_FORCE_MAX_TRIANGLES
from ._casters import USES as USES
from ._casters import BVHCaster as BVHCaster
from ._casters import make_caster as make_caster
from ._embree import EmbreeCaster as EmbreeCaster
from ._embree import EmbreeUnavailableError as EmbreeUnavailableError
from ._embree_packets import embree_packets_available as embree_packets_available
