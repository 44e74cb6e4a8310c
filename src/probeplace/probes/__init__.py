"""probes stage: light-field probe baking (McGuire et al. 2017), pre-filtering, shading, save/load; the
light-field tracer in ``tracer/`` (its ``__init__`` the group's face)."""

from .._core import BakeSettings as BakeSettings
from ._bake import DEFAULT_EVAL_MAX_DEPTH as DEFAULT_EVAL_MAX_DEPTH
from ._bake import INSIDE_TESTS as INSIDE_TESTS
from ._bake import BakeConfig as BakeConfig
from ._bake import PathTracedRadiance as PathTracedRadiance
from ._bake import RadianceFn as RadianceFn
from ._bake import bake_depth_for as bake_depth_for
from ._bake import bake_probes as bake_probes
from ._bake import check_bake_settings as check_bake_settings
from ._bake import check_probe_scene as check_probe_scene
from ._bake import check_probes_in_scene as check_probes_in_scene
from ._bake import default_radiance_res as default_radiance_res
from ._bake import map_resolutions as map_resolutions
from ._bake import pad_probes as pad_probes
from ._bake import padded_capacity as padded_capacity
from ._bake import path_traced_radiance as path_traced_radiance
from ._bake import probe_bytes as probe_bytes
from ._bake_samples import BakeSamples as BakeSamples
from ._bake_samples import choose_bake_spp as choose_bake_spp
from ._filter import distance_moments as distance_moments
from ._filter import irradiance_map as irradiance_map
from ._inside import face_normals as face_normals
from ._inside import host_closest_hit as host_closest_hit
from ._inside import points_in_solid as points_in_solid
from ._inside import probes_inside as probes_inside
from ._io import load_probes as load_probes
from ._io import save_probes as save_probes
from ._plot import save_contact_sheet as save_contact_sheet

# --- tracing and shading ---
from .tracer import GridIndex as GridIndex
from .tracer import LightFieldTracer as LightFieldTracer
from .tracer import TraceConfig as TraceConfig
from .tracer import TraceResult as TraceResult
from .tracer import TraceStatus as TraceStatus
from .tracer import VoxelIndex as VoxelIndex
from .tracer import WavefrontStats as WavefrontStats
from .tracer import bound_table as bound_table
from .tracer import check_tracer_memory as check_tracer_memory
from .tracer import grid_index as grid_index
from .tracer import make_tracer as make_tracer
from .tracer import origins_seen as origins_seen
from .tracer import trace_light_field as trace_light_field
from .tracer import trace_probe as trace_probe
from .tracer import trace_ray as trace_ray
from .tracer import trace_wavefront as trace_wavefront
from .tracer import tracer_bytes as tracer_bytes
from .tracer import tracer_rows as tracer_rows
from .tracer import voxel_index as voxel_index

# --- shading (EVAL helper, issue 4) ---
# isort: split
from ._shade import SHADINGS as SHADINGS
from ._shade import default_index as default_index
from ._shade import diffuse_irradiance as diffuse_irradiance
from ._shade import glossy_radiance as glossy_radiance
from ._shade import irradiance_weights as irradiance_weights
from ._shade import sh_coefficients as sh_coefficients
from ._shade import sh_irradiance as sh_irradiance
from ._shade import shade_irradiance as shade_irradiance

# --- glossy reads (issue 16: filtered by direction, perfect trace) ---
# isort: split
from ._glossy import DEFAULT_GLOSSY_FILTER as DEFAULT_GLOSSY_FILTER
from ._glossy import GLOSSY_FILTERS as GLOSSY_FILTERS
from ._glossy import GlossyResult as GlossyResult
from ._glossy import PerfectTraceResult as PerfectTraceResult
from ._glossy import glossy_maps as glossy_maps
from ._glossy import glossy_trace as glossy_trace
from ._glossy import perfect_trace_radiance as perfect_trace_radiance
from ._glossy import radiance_mips as radiance_mips
