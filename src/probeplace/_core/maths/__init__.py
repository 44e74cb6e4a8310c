"""The numerics the stages share: NaN-safe math and power-of-two bucket sizes (``_math``), the octahedral
map and the probes' bordered texel layout (``_octahedral``), the normal maps' two snorm16 components
(``_packed``), the SH L2 basis in NumPy (``_sh``), the run's named random streams (``_random``) and the
wavefront lane scheduler of the ray loops (``_lanes``).

This ``__init__`` is the group's face for the rest of the package. Every name loads on first use (PEP 562
``__getattr__``): all but ``_sh`` and ``_colour`` (the luminance weights) import JAX, and the NumPy-only
``export`` stage reads the SH basis."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

# name -> the private module defining it (all but _sh and _colour import JAX)
_LAZY = {
    **dict.fromkeys(("take_queued", "write_finished"), "_lanes"),
    "REC709_LUMA": "_colour",
    **dict.fromkeys(
        (
            "dot3",
            "luminance",
            "next_pow2",
            "norm3",
            "padded_count",
            "safe_norm",
            "safe_normalize",
            "safe_sqrt",
        ),
        "_math",
    ),
    **dict.fromkeys(
        (
            "add_border",
            "border_index",
            "fill_border",
            "jittered_texel_directions",
            "oct_decode",
            "oct_encode",
            "oct_wrap",
            "sample_bilinear",
            "sample_nearest",
            "strip_border",
            "surfel_directions",
            "surfel_texels",
            "texel_directions",
            "texel_of_direction",
            "texel_solid_angles",
            "texel_uv",
        ),
        "_octahedral",
    ),
    **dict.fromkeys(("pack_normal", "unpack_normal"), "_packed"),
    **dict.fromkeys(("host_rng", "stream"), "_random"),
    **dict.fromkeys(("COSINE_LOBE", "SH_CONVENTION", "SH_ORDER", "sh_basis"), "_sh"),
}

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._colour import REC709_LUMA as REC709_LUMA
    from ._lanes import take_queued as take_queued
    from ._lanes import write_finished as write_finished
    from ._math import dot3 as dot3
    from ._math import luminance as luminance
    from ._math import next_pow2 as next_pow2
    from ._math import norm3 as norm3
    from ._math import padded_count as padded_count
    from ._math import safe_norm as safe_norm
    from ._math import safe_normalize as safe_normalize
    from ._math import safe_sqrt as safe_sqrt
    from ._octahedral import add_border as add_border
    from ._octahedral import border_index as border_index
    from ._octahedral import fill_border as fill_border
    from ._octahedral import jittered_texel_directions as jittered_texel_directions
    from ._octahedral import oct_decode as oct_decode
    from ._octahedral import oct_encode as oct_encode
    from ._octahedral import oct_wrap as oct_wrap
    from ._octahedral import sample_bilinear as sample_bilinear
    from ._octahedral import sample_nearest as sample_nearest
    from ._octahedral import strip_border as strip_border
    from ._octahedral import surfel_directions as surfel_directions
    from ._octahedral import surfel_texels as surfel_texels
    from ._octahedral import texel_directions as texel_directions
    from ._octahedral import texel_of_direction as texel_of_direction
    from ._octahedral import texel_solid_angles as texel_solid_angles
    from ._octahedral import texel_uv as texel_uv
    from ._packed import pack_normal as pack_normal
    from ._packed import unpack_normal as unpack_normal
    from ._random import host_rng as host_rng
    from ._random import stream as stream
    from ._sh import COSINE_LOBE as COSINE_LOBE
    from ._sh import SH_CONVENTION as SH_CONVENTION
    from ._sh import SH_ORDER as SH_ORDER
    from ._sh import sh_basis as sh_basis


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), [*_LAZY])
