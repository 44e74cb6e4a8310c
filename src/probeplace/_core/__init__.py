"""Core pytree types and safe math shared by every stage, grouped by role:

* ``_errors``, ``_samples``, ``_types``, ``_lazy``: the error classes, sample counts from a noise target,
  the pytree containers, and the PEP 562 lazy loading of this face and the stages';
* ``files/``: atomic writes and EXR images, the probe files (ProbeSet JSON, baked ``.npz``, sidecars) and
  the ProbeSet as pytrees, matplotlib for charts;
* ``maths/``: NaN-safe math, the octahedral map, packed normals, the SH basis, the named random streams
  and the wavefront lane scheduler;
* ``runtime/``: checks before slow work, the memory limit and sizes, Ctrl-C, JAX's compilation cache and
  progress bars.

Each group's ``__init__`` is its face for the rest of the package; this one is the package's. The error
classes and ``_samples`` load eagerly (plain Python); the rest loads on first use (PEP 562 ``__getattr__``),
each name alone: most of it imports JAX, and the NumPy-only ``export`` stage (which reads ``_errors``,
``files``' ``_io`` and ``_probe_files`` and ``maths``' ``_sh``) must not pull JAX in through this package.
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

# name -> the group face or private module defining it (files: _io and _probe_files are NumPy only, and
# _plotting imports matplotlib on use; runtime: plain Python; the rest imports JAX)
_LAZY = {
    **dict.fromkeys(
        (
            "PROBE_SET_FORMAT",
            "RunFiles",
            "atomic_path",
            "load_probe_set",
            "load_pyplot",
            "read_exr",
            "save_probe_set",
            "write_atomic",
            "write_bytes_atomic",
            "write_exr",
            "write_json_atomic",
            "write_text_atomic",
        ),
        "files",
    ),
    **dict.fromkeys(
        (
            "add_border",
            "border_index",
            "fill_border",
            "dot3",
            "host_rng",
            "jittered_texel_directions",
            "luminance",
            "REC709_LUMA",
            "next_pow2",
            "norm3",
            "oct_decode",
            "oct_encode",
            "oct_wrap",
            "pack_normal",
            "padded_count",
            "safe_norm",
            "safe_normalize",
            "safe_sqrt",
            "sample_bilinear",
            "sample_nearest",
            "stream",
            "strip_border",
            "surfel_directions",
            "surfel_texels",
            "take_queued",
            "texel_directions",
            "texel_of_direction",
            "texel_solid_angles",
            "texel_uv",
            "unpack_normal",
            "write_finished",
        ),
        "maths",
    ),
    **dict.fromkeys(("MAX_BYTES_ENV", "check_memory", "memory_limit_bytes"), "runtime"),
    **dict.fromkeys(
        (
            "BAKE_SETTINGS_VERSION",
            "FIRST_HIT_LOBES",
            "TEXEL_RAYS",
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
    from ._types import BAKE_SETTINGS_VERSION as BAKE_SETTINGS_VERSION
    from ._types import FIRST_HIT_LOBES as FIRST_HIT_LOBES
    from ._types import TEXEL_RAYS as TEXEL_RAYS
    from ._types import BakeSettings as BakeSettings
    from ._types import Camera as Camera
    from ._types import Hit as Hit
    from ._types import LightFieldProbes as LightFieldProbes
    from ._types import Materials as Materials
    from ._types import ProbeSet as ProbeSet
    from ._types import Scene as Scene
    from ._types import Sun as Sun
    from ._types import scene_box as scene_box
    from .files import PROBE_SET_FORMAT as PROBE_SET_FORMAT
    from .files import RunFiles as RunFiles
    from .files import atomic_path as atomic_path
    from .files import load_probe_set as load_probe_set
    from .files import load_pyplot as load_pyplot
    from .files import read_exr as read_exr
    from .files import save_probe_set as save_probe_set
    from .files import write_atomic as write_atomic
    from .files import write_bytes_atomic as write_bytes_atomic
    from .files import write_exr as write_exr
    from .files import write_json_atomic as write_json_atomic
    from .files import write_text_atomic as write_text_atomic
    from .maths import REC709_LUMA as REC709_LUMA
    from .maths import add_border as add_border
    from .maths import border_index as border_index
    from .maths import dot3 as dot3
    from .maths import fill_border as fill_border
    from .maths import host_rng as host_rng
    from .maths import jittered_texel_directions as jittered_texel_directions
    from .maths import luminance as luminance
    from .maths import next_pow2 as next_pow2
    from .maths import norm3 as norm3
    from .maths import oct_decode as oct_decode
    from .maths import oct_encode as oct_encode
    from .maths import oct_wrap as oct_wrap
    from .maths import pack_normal as pack_normal
    from .maths import padded_count as padded_count
    from .maths import safe_norm as safe_norm
    from .maths import safe_normalize as safe_normalize
    from .maths import safe_sqrt as safe_sqrt
    from .maths import sample_bilinear as sample_bilinear
    from .maths import sample_nearest as sample_nearest
    from .maths import stream as stream
    from .maths import strip_border as strip_border
    from .maths import surfel_directions as surfel_directions
    from .maths import surfel_texels as surfel_texels
    from .maths import take_queued as take_queued
    from .maths import texel_directions as texel_directions
    from .maths import texel_of_direction as texel_of_direction
    from .maths import texel_solid_angles as texel_solid_angles
    from .maths import texel_uv as texel_uv
    from .maths import unpack_normal as unpack_normal
    from .maths import write_finished as write_finished
    from .runtime import MAX_BYTES_ENV as MAX_BYTES_ENV
    from .runtime import check_memory as check_memory
    from .runtime import memory_limit_bytes as memory_limit_bytes

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), __all__)
