"""Core pytree types and safe math shared by every stage.

The error classes load eagerly (plain Python); the rest loads on first use (PEP 562 ``__getattr__``):
most of it imports JAX, and importing ``probeplace._core._errors``, ``._sh`` or ``._io`` from the
NumPy-only ``export`` stage must not pull JAX in through this package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._errors import ConfigError as ConfigError
from ._errors import ProbeplaceError as ProbeplaceError
from ._errors import ResourceError as ResourceError
from ._errors import SceneError as SceneError
from ._lazy import lazy_exports
from ._samples import AUTO as AUTO  # plain Python, like the errors
from ._samples import PILOT_Z as PILOT_Z
from ._samples import check_count as check_count
from ._samples import check_target as check_target
from ._samples import is_auto as is_auto
from ._samples import json_number as json_number
from ._samples import mean_and_se as mean_and_se
from ._samples import smallest_count as smallest_count

# name -> the private module defining it (all but _io, _memory and _plotting import JAX)
_LAZY = {
    **dict.fromkeys(
        (
            "atomic_path",
            "read_exr",
            "write_atomic",
            "write_bytes_atomic",
            "write_exr",
            "write_json_atomic",
            "write_text_atomic",
        ),
        "_io",
    ),
    **dict.fromkeys(
        ("dot3", "luminance", "next_pow2", "norm3", "safe_norm", "safe_normalize", "safe_sqrt"), "_math"
    ),
    **dict.fromkeys(
        (
            "add_border",
            "border_index",
            "jittered_texel_directions",
            "oct_decode",
            "oct_encode",
            "oct_wrap",
            "sample_bilinear",
            "sample_nearest",
            "strip_border",
            "texel_directions",
            "texel_of_direction",
            "texel_solid_angles",
            "texel_uv",
        ),
        "_octahedral",
    ),
    **dict.fromkeys(("take_queued", "write_finished"), "_lanes"),
    **dict.fromkeys(("MAX_BYTES_ENV", "check_memory", "memory_limit_bytes"), "_memory"),
    **dict.fromkeys(("pack_normal", "unpack_normal"), "_packed"),
    "load_pyplot": "_plotting",
    **dict.fromkeys(("host_rng", "stream"), "_random"),
    **dict.fromkeys(("PROBE_SET_FORMAT", "load_probe_set", "save_probe_set"), "_probe_io"),
    **dict.fromkeys(
        (
            "BAKE_SETTINGS_VERSION",
            "BakeSettings",
            "Camera",
            "Hit",
            "LightFieldProbes",
            "Materials",
            "ProbeSet",
            "Scene",
            "Sun",
            "scene_box",
        ),
        "_types",
    ),
}
__all__ = [
    "AUTO",
    "PILOT_Z",
    "ConfigError",
    "ProbeplaceError",
    "ResourceError",
    "SceneError",
    "check_count",
    "check_target",
    "is_auto",
    "json_number",
    "mean_and_se",
    "smallest_count",
    *_LAZY,
]

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._io import atomic_path as atomic_path
    from ._io import read_exr as read_exr
    from ._io import write_atomic as write_atomic
    from ._io import write_bytes_atomic as write_bytes_atomic
    from ._io import write_exr as write_exr
    from ._io import write_json_atomic as write_json_atomic
    from ._io import write_text_atomic as write_text_atomic
    from ._lanes import take_queued as take_queued
    from ._lanes import write_finished as write_finished
    from ._math import dot3 as dot3
    from ._math import luminance as luminance
    from ._math import next_pow2 as next_pow2
    from ._math import norm3 as norm3
    from ._math import safe_norm as safe_norm
    from ._math import safe_normalize as safe_normalize
    from ._math import safe_sqrt as safe_sqrt
    from ._memory import MAX_BYTES_ENV as MAX_BYTES_ENV
    from ._memory import check_memory as check_memory
    from ._memory import memory_limit_bytes as memory_limit_bytes
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
    from ._packed import pack_normal as pack_normal
    from ._packed import unpack_normal as unpack_normal
    from ._plotting import load_pyplot as load_pyplot
    from ._probe_io import PROBE_SET_FORMAT as PROBE_SET_FORMAT
    from ._probe_io import load_probe_set as load_probe_set
    from ._probe_io import save_probe_set as save_probe_set
    from ._random import host_rng as host_rng
    from ._random import stream as stream
    from ._types import BAKE_SETTINGS_VERSION as BAKE_SETTINGS_VERSION
    from ._types import BakeSettings as BakeSettings
    from ._types import Camera as Camera
    from ._types import Hit as Hit
    from ._types import LightFieldProbes as LightFieldProbes
    from ._types import Materials as Materials
    from ._types import ProbeSet as ProbeSet
    from ._types import Scene as Scene
    from ._types import Sun as Sun
    from ._types import scene_box as scene_box

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), __all__)
