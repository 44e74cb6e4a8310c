"""Apply a :class:`~probeplace.scene.config._sidecar.SceneConfig` to a built Scene: materials, emitters,
sun, sky, cameras, then units and the up axis (docs/scenes.md, "Sidecar config").

Works on a built :class:`~probeplace._core.Scene`, so the same code serves scene files and built-in
scenes; the config's points and vectors are in the file frame, so the up-axis turn comes last and carries
the file's cameras, the config's cameras and the sun with the geometry.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core import Camera, ConfigError, Scene, Sun
from .._build import make_camera, make_materials, make_sun
from .._raw import DEFAULT_GREY
from .._transform import transform_scene
from ..light import DAYLIGHT_SUN_IRRADIANCE, sun_direction, sun_from_irradiance
from ._sidecar import NO_SUN, CameraSpec, SceneConfig, SunSpec, check_up

#: File frame → scene frame (+Y up). Z-up: (x, y, z) ↦ (x, z, −y), a proper rotation (−90° about X),
#: the one Blender's glTF exporter uses, so +X stays +X and the file's +Z becomes +Y.
TO_Y_UP = {"y": np.eye(3), "z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])}


def _listing(names: Iterable[str], limit: int = 12) -> str:
    names = list(names)
    more = f", ... ({len(names) - limit} more)" if len(names) > limit else ""
    return ", ".join(repr(n) for n in names[:limit]) + more


def file_up(up_axis: str | None) -> np.ndarray:
    """The file frame's up vector."""
    return TO_Y_UP[up_axis or "y"].T @ np.array([0.0, 1.0, 0.0])


def check_layer(
    layer: SceneConfig, material_names: set[str], part_names: Sequence[str], up_axis: str | None
) -> set[str]:
    """Check one layer's names against the scene, before any work: materials' ``parts``, emitters'
    materials (those of the file, of lower layers and new ones of this layer), cameras' default up.

    Returns:
        The material names after this layer (a new material of this layer may be named by a later one).

    Raises:
        ConfigError: an unknown part, an emitter naming no material, a new material without parts, or a
            camera looking straight along the up axis without its own ``up``.
    """
    names = set(material_names)
    for name, spec in layer.materials.items():
        at = f"{layer.source}: materials.{name}"
        for part in spec.parts:
            if part not in part_names:
                raise ConfigError(f"{at}.parts: no part {part!r} in the scene; parts: {_listing(part_names)}")
        if name not in names and not spec.parts:
            raise ConfigError(
                f"{at}: not a material of the scene (materials: {_listing(sorted(names))}); "
                "a new material needs parts: [...] to say which triangles it covers"
            )
        names.add(name)
    for name in layer.emitters:
        if name not in names:
            raise ConfigError(
                f"{layer.source}: emitters.{name}: no material of that name; "
                f"materials: {_listing(sorted(names))}"
            )
    for name, cam in layer.cameras.items():
        if cam.up is None:
            check_up(
                cam.position,
                cam.look_at,
                tuple(file_up(up_axis)),
                f"{layer.source}: cameras.{name} (default up)",
            )
    return names


def _materials(scene: Scene, cfg: SceneConfig) -> Scene:
    if not cfg.materials and not cfg.emitters:
        return scene
    m = scene.materials
    names = list(m.names)
    base = np.asarray(m.base_color, np.float64).tolist()
    rough = np.asarray(m.roughness, np.float64).tolist()
    metal = np.asarray(m.metallic, np.float64).tolist()
    emit = np.asarray(m.emission, np.float64).tolist()
    tri_material = np.asarray(scene.tri_material).copy()
    tri_part = np.asarray(scene.tri_part)
    for name, spec in cfg.materials.items():
        if name not in names:  # a new material: glTF's defaults for an unspecified material
            names.append(name)
            base.append(list(DEFAULT_GREY))
            rough.append(1.0)
            metal.append(0.0)
            emit.append([0.0, 0.0, 0.0])
        i = names.index(name)
        if spec.base_color is not None:
            base[i] = list(spec.base_color)
        if spec.roughness is not None:
            rough[i] = spec.roughness
        if spec.metallic is not None:
            metal[i] = spec.metallic
        for part in spec.parts:
            tri_material[tri_part == scene.part_names.index(part)] = i
    for name, em in cfg.emitters.items():
        if name not in names:  # check_layer refuses this first; kept for direct callers
            raise ConfigError(f"{cfg.source}: emitters.{name}: no material of that name")
        emit[names.index(name)] = [em.strength * c for c in em.color]
    mats = make_materials(names, np.asarray(base), np.asarray(rough), np.asarray(metal), np.asarray(emit))
    emissive = np.flatnonzero(np.asarray(mats.emission).max(axis=1)[tri_material] > 0)
    return eqx.tree_at(
        lambda s: (s.materials, s.tri_material, s.emissive_tris),
        scene,
        (mats, jnp.asarray(tri_material.astype(np.int32)), jnp.asarray(emissive.astype(np.int32))),
    )


def make_config_sun(spec: SunSpec, up_axis: str | None) -> Sun:
    """The Sun of a spec, direction in the file frame (az/el are about the file's up axis)."""
    if spec.direction is not None:
        d = np.asarray(spec.direction, np.float64)
    else:  # sun_direction is +Y up; turn it back into the file frame (the up-axis turn redoes it)
        assert spec.azimuth_deg is not None and spec.elevation_deg is not None  # parse_sun_spec's rule
        d = TO_Y_UP[up_axis or "y"].T @ sun_direction(spec.azimuth_deg, spec.elevation_deg)
    radius = float(np.deg2rad(spec.angular_diameter_deg) / 2.0)
    if spec.radiance is not None:
        return make_sun(d, spec.radiance, radius)
    return sun_from_irradiance(d, spec.irradiance or DAYLIGHT_SUN_IRRADIANCE, radius)


def _cameras(scene: Scene, cfg: SceneConfig) -> tuple[Camera, ...]:
    views = list(scene.views) if cfg.keep_file_cameras in (None, True) else []
    for name, spec in cfg.cameras.items():
        up = spec.up if spec.up is not None else tuple(file_up(cfg.up_axis))
        check_up(spec.position, spec.look_at, up, f"{cfg.source}: cameras.{name}.up")
        cam = make_camera(spec.position, spec.look_at, spec.fov_deg, name, up=up)
        taken = [i for i, v in enumerate(views) if v.name == name]
        if taken:  # a config camera replaces the file's camera of that name, in its place
            views[taken[0]] = cam
        else:
            views.append(cam)
    return tuple(views)


def camera_origin(layers: Sequence[SceneConfig], name: str) -> tuple[str, CameraSpec] | None:
    """(source, spec) of the highest layer that sets camera ``name`` (the one the scene got), or ``None``
    for a camera no layer sets (the file's own, or a view derived from the bounds)."""
    for layer in reversed(layers):
        if name in layer.cameras:
            return layer.source, layer.cameras[name]
    return None


def apply_scene_config(scene: Scene, cfg: SceneConfig) -> Scene:
    """``scene`` with ``cfg`` applied (see the module docstring for the order).

    Args:
        scene: a built scene, in its file's frame and units.
        cfg: the merged config (:func:`~probeplace.scene.config._sidecar.merge_scene_configs`).

    Returns:
        The configured scene, +Y up; host-side (call outside jit).

    Raises:
        ConfigError: a name the scene does not have (run :func:`check_layer` per layer first for
            messages naming the layer), or a camera whose up is along its viewing direction.
    """
    scene = _materials(scene, cfg)
    changes: dict = {}
    if cfg.sun == NO_SUN:
        changes["sun"] = None
    elif isinstance(cfg.sun, SunSpec):
        changes["sun"] = make_config_sun(cfg.sun, cfg.up_axis)
    if cfg.sky is not None:
        changes["sky_radiance"] = jnp.asarray(np.asarray(cfg.sky, np.float32))
    views = _cameras(scene, cfg) if cfg.cameras or cfg.keep_file_cameras is False else scene.views
    unit_m = scene.unit_m if cfg.unit_m is None else cfg.unit_m
    if cfg.scale_to_metres:
        s = jnp.asarray(unit_m, scene.vertices.dtype)

        def scaled(c: Camera) -> Camera:
            return eqx.tree_at(lambda c: (c.position, c.look_at), c, (c.position * s, c.look_at * s))

        changes["vertices"] = scene.vertices * s
        views = tuple(scaled(c) for c in views)
        unit_m = 1.0
    # dataclasses.replace, not eqx.tree_at: unit_m is static and sun may be None (neither is a leaf)
    scene = dataclasses.replace(scene, views=views, unit_m=float(unit_m), **changes)
    if cfg.up_axis not in (None, "y"):
        scene = transform_scene(scene, TO_Y_UP[cfg.up_axis])
    return scene
