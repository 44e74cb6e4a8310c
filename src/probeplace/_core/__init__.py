"""Core pytree types and safe math shared by every stage."""

from ._errors import ConfigError as ConfigError
from ._errors import ProbeplaceError as ProbeplaceError
from ._errors import ResourceError as ResourceError
from ._errors import SceneError as SceneError
from ._math import luminance as luminance
from ._math import safe_norm as safe_norm
from ._math import safe_normalize as safe_normalize
from ._math import safe_sqrt as safe_sqrt

# --- octahedral mapping ---
from ._octahedral import add_border as add_border
from ._octahedral import border_index as border_index
from ._octahedral import jittered_texel_directions as jittered_texel_directions
from ._octahedral import oct_decode as oct_decode
from ._octahedral import oct_encode as oct_encode
from ._octahedral import oct_wrap as oct_wrap
from ._octahedral import sample_bilinear as sample_bilinear
from ._octahedral import sample_nearest as sample_nearest
from ._octahedral import strip_border as strip_border
from ._octahedral import texel_directions as texel_directions
from ._octahedral import texel_of_direction as texel_of_direction
from ._octahedral import texel_solid_angles as texel_solid_angles
from ._octahedral import texel_uv as texel_uv

# --- ProbeSet files ---
from ._probe_io import PROBE_SET_FORMAT as PROBE_SET_FORMAT
from ._probe_io import load_probe_set as load_probe_set
from ._probe_io import save_probe_set as save_probe_set
from ._probe_io import write_json_atomic as write_json_atomic
from ._types import BAKE_SETTINGS_VERSION as BAKE_SETTINGS_VERSION
from ._types import BakeSettings as BakeSettings
from ._types import Camera as Camera
from ._types import Hit as Hit
from ._types import LightFieldProbes as LightFieldProbes
from ._types import Materials as Materials
from ._types import ProbeSet as ProbeSet
from ._types import Scene as Scene
from ._types import Sun as Sun
