"""The light-field tracer (McGuire et al. 2017 §4; Wang et al. 2019 §4.2; docs/tracer.md): the tracer and
its per-ray engine (``_trace``), the single-probe march (``_march``, ``_surfels``), the probe
indices (``_index``), the wavefront engine (``_wavefront``), the engine switch (``_engine``), the status
codes (``_status``), which ray origins a probe sees (``_seen``) and the simple NumPy reference of the
single-probe trace that both engines are held to, sharing no step code with them (``_simple``).

This ``__init__`` is the group's face for the rest of ``probes``."""

from ._engine import trace_light_field as trace_light_field
from ._index import GridIndex as GridIndex
from ._index import VoxelIndex as VoxelIndex
from ._index import grid_index as grid_index
from ._index import voxel_index as voxel_index
from ._seen import origins_seen as origins_seen
from ._simple import trace_probe_simple as trace_probe_simple
from ._status import TraceStatus as TraceStatus
from ._trace import LightFieldTracer as LightFieldTracer
from ._trace import TraceConfig as TraceConfig
from ._trace import TraceResult as TraceResult
from ._trace import bound_table as bound_table
from ._trace import check_tracer_memory as check_tracer_memory
from ._trace import make_tracer as make_tracer
from ._trace import trace_probe as trace_probe
from ._trace import trace_ray as trace_ray
from ._trace import tracer_bytes as tracer_bytes
from ._trace import tracer_rows as tracer_rows
from ._wavefront import WavefrontStats as WavefrontStats
from ._wavefront import trace_wavefront as trace_wavefront
