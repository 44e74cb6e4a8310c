"""export stage (DESIGN.md): probe sets to engine formats, NumPy only (no JAX import here).

Formats (``probeplace export <probes> --format <name> --out <path>``; docs/export.md):
``json``, ``gltf``, ``unity``, ``godot``, ``threev8``, ``ddgi``, ``usd``. Importers: json, gltf, threev8,
usd (lossless round trips).
"""

from .._core.files._io import read_exr as read_exr
from .._core.files._probe_files import PROBE_SET_FORMAT as PROBE_SET_FORMAT
from ._data import ExportError as ExportError
from ._data import ExportProbes as ExportProbes
from ._data import LightFieldMaps as LightFieldMaps
from ._data import read_light_field_npz as read_light_field_npz
from ._ddgi import write_ddgi as write_ddgi
from ._engines import GODOT_FROM_GLTF as GODOT_FROM_GLTF
from ._engines import UNITY_FROM_GLTF as UNITY_FROM_GLTF
from ._engines import write_godot as write_godot
from ._engines import write_unity as write_unity
from ._gltf import read_gltf as read_gltf
from ._gltf import write_gltf as write_gltf
from ._json import read_json as read_json
from ._json import schema as schema
from ._json import write_json as write_json
from ._octa import oct_decode as oct_decode  # NumPy octahedral helpers (``probeplace view``)
from ._octa import texel_solid_angles as texel_solid_angles
from ._registry import FORMATS as FORMATS
from ._registry import READABLE_SUFFIXES as READABLE_SUFFIXES
from ._registry import export_probes as export_probes
from ._registry import import_probes as import_probes
from ._registry import read_probes as read_probes
from ._sh import SH_CONVENTION as SH_CONVENTION
from ._sh import project_radiance as project_radiance
from ._sh import sh_irradiance as sh_irradiance
from ._threev8 import LODProbeGrid as LODProbeGrid
from ._threev8 import build_lod_grid as build_lod_grid
from ._threev8 import read_lod_grid as read_lod_grid
from ._threev8 import read_threev8 as read_threev8
from ._threev8 import write_threev8 as write_threev8
from ._usd import read_usd as read_usd
from ._usd import write_usd as write_usd
