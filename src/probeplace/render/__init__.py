"""render stage: the BRDF (Lambert + GGX), the reference path tracer and its components, image I/O.

See docs/render.md for the component definitions and the Mitsuba 3 cross-check. The backend names load
eagerly (plain Python); the rest loads on first use (PEP 562 ``__getattr__``): it imports JAX, and the
command-line parsers that offer ``BACKEND_CHOICES`` must not.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._core._lazy import lazy_exports
from ._backends import BACKEND_CHOICES as BACKEND_CHOICES
from ._backends import BACKENDS as BACKENDS

# name -> the private module defining it (each imports JAX)
_LAZY = {
    **dict.fromkeys(
        (
            "ALPHA_MIN",
            "BrdfParams",
            "BrdfSample",
            "brdf_params",
            "eval_brdf",
            "ggx_d",
            "lobe_probability",
            "pdf_brdf",
            "sample_brdf",
            "sample_ggx_vndf",
            "schlick_fresnel",
            "smith_g1",
        ),
        "_brdf",
    ),
    **dict.fromkeys(("camera_basis", "camera_ray", "camera_rays"), "_camera"),
    **dict.fromkeys(("load_exr", "save_exr", "save_png", "save_render", "tonemap"), "_image_io"),
    "COMPONENTS": "_integrator",
    **dict.fromkeys(("LightSample", "LightTable", "light_table", "sample_light"), "_lights"),
    **dict.fromkeys(("best_mitsuba_variant", "mitsuba_scene_dict"), "_mitsuba"),
    **dict.fromkeys(
        (
            "RayRadiance",
            "RenderConfig",
            "RenderResult",
            "default_caster",
            "render",
            "resolve_backend",
            "trace_rays",
        ),
        "_render",
    ),
    **dict.fromkeys(
        (
            "N_UNIFORMS",
            "make_frame",
            "path_uniforms",
            "power_heuristic",
            "seed_from_key",
            "to_local",
            "to_world",
        ),
        "_sampling",
    ),
    "load_mitsuba": "_mitsuba_backend",
    "RAY_EPS": "_integrator",
    "sample_cosine_hemisphere": "_sampling",
}
__all__ = ["BACKEND_CHOICES", "BACKENDS", *_LAZY]

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._brdf import ALPHA_MIN as ALPHA_MIN
    from ._brdf import BrdfParams as BrdfParams
    from ._brdf import BrdfSample as BrdfSample
    from ._brdf import brdf_params as brdf_params
    from ._brdf import eval_brdf as eval_brdf
    from ._brdf import ggx_d as ggx_d
    from ._brdf import lobe_probability as lobe_probability
    from ._brdf import pdf_brdf as pdf_brdf
    from ._brdf import sample_brdf as sample_brdf
    from ._brdf import sample_ggx_vndf as sample_ggx_vndf
    from ._brdf import schlick_fresnel as schlick_fresnel
    from ._brdf import smith_g1 as smith_g1
    from ._camera import camera_basis as camera_basis
    from ._camera import camera_ray as camera_ray
    from ._camera import camera_rays as camera_rays
    from ._image_io import load_exr as load_exr
    from ._image_io import save_exr as save_exr
    from ._image_io import save_png as save_png
    from ._image_io import save_render as save_render
    from ._image_io import tonemap as tonemap
    from ._integrator import COMPONENTS as COMPONENTS
    from ._integrator import RAY_EPS as RAY_EPS
    from ._lights import LightSample as LightSample
    from ._lights import LightTable as LightTable
    from ._lights import light_table as light_table
    from ._lights import sample_light as sample_light
    from ._mitsuba import best_mitsuba_variant as best_mitsuba_variant
    from ._mitsuba import mitsuba_scene_dict as mitsuba_scene_dict
    from ._mitsuba_backend import load_mitsuba as load_mitsuba
    from ._render import RayRadiance as RayRadiance
    from ._render import RenderConfig as RenderConfig
    from ._render import RenderResult as RenderResult
    from ._render import default_caster as default_caster
    from ._render import render as render
    from ._render import resolve_backend as resolve_backend
    from ._render import trace_rays as trace_rays
    from ._sampling import N_UNIFORMS as N_UNIFORMS
    from ._sampling import make_frame as make_frame
    from ._sampling import path_uniforms as path_uniforms
    from ._sampling import power_heuristic as power_heuristic
    from ._sampling import sample_cosine_hemisphere as sample_cosine_hemisphere
    from ._sampling import seed_from_key as seed_from_key
    from ._sampling import to_local as to_local
    from ._sampling import to_world as to_world


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), __all__)
