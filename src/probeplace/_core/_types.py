"""Pytree containers shared by every stage.

All geometry is in world space, right-handed, +Y up (glTF convention); lengths are in the scene's own
units (``Scene.unit_m`` metres per unit). Radiance is linear RGB in W·sr⁻¹·m⁻² up to a common scale.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int, UInt32

from ._errors import ConfigError
from .maths import unpack_normal


def _check_last(name: str, x, tail: tuple[int, ...]) -> None:
    if tuple(x.shape[len(x.shape) - len(tail) :]) != tail:
        raise ValueError(f"{name} must end in shape {tail}, got {tuple(x.shape)}")


class Materials(eqx.Module):
    """Material table; a triangle refers to a row by index (``Scene.tri_material``).

    Attributes:
        base_color: linear RGB albedo in [0, 1] (glTF ``baseColorFactor``).
        roughness: perceptual roughness in [0, 1] (glTF; GGX alpha = roughness²).
        metallic: metalness in [0, 1].
        emission: emitted radiance, linear RGB
            (glTF ``emissiveFactor`` × ``KHR_materials_emissive_strength``).
        names: one name per material (static).
    """

    base_color: Float[Array, "n_mat 3"]
    roughness: Float[Array, " n_mat"]
    metallic: Float[Array, " n_mat"]
    emission: Float[Array, "n_mat 3"]
    names: tuple[str, ...] = eqx.field(static=True)

    def __check_init__(self):
        n = len(self.names)
        _check_last("base_color", self.base_color, (n, 3))
        _check_last("emission", self.emission, (n, 3))
        _check_last("roughness", self.roughness, (n,))
        _check_last("metallic", self.metallic, (n,))


class Sun(eqx.Module):
    """A distant disk light.

    Attributes:
        direction: unit vector from the scene *towards* the sun (world frame).
        radiance: radiance of the sun's disk, linear RGB.
        angular_radius: half-angle of the disk in radians (the real sun: ~0.00465).
    """

    direction: Float[Array, "3"]
    radiance: Float[Array, "3"]
    angular_radius: Float[Array, ""]


class Camera(eqx.Module):
    """A pinhole camera in look-at form (up = +Y unless given)."""

    position: Float[Array, "3"]
    look_at: Float[Array, "3"]
    up: Float[Array, "3"]
    fov_y_deg: Float[Array, ""]
    name: str = eqx.field(static=True)


class Scene(eqx.Module):
    """A triangle scene with materials, lights and named views.

    Build it with :func:`probeplace.scene.build_scene` (which validates and repairs input) rather
    than by hand.

    Attributes:
        vertices: vertex positions, world frame.
        faces: vertex indices per triangle, counter-clockwise seen from the front side.
        corner_normals: shading normal at each triangle corner (crease-angle smoothed), unit length.
        tri_material: row of ``materials`` per triangle.
        tri_part: index into ``part_names`` per triangle (the glTF node / OBJ object it came from).
        materials: the material table.
        emissive_tris: indices of triangles whose material emits (the area lights).
        sun: optional distant sun; ``None`` when the scene is lit only by emitters / sky.
        sky_radiance: constant sky radiance seen by rays that leave the scene (zeros: no sky).
        views: named cameras that show the interior.
        name: scene name (static).
        part_names: names of the parts (static).
        unit_m: metres per scene unit (static), e.g. 0.001 for the Cornell box in millimetres.
    """

    vertices: Float[Array, "n_vert 3"]
    faces: Int[Array, "n_tri 3"]
    corner_normals: Float[Array, "n_tri 3 3"]
    tri_material: Int[Array, " n_tri"]
    tri_part: Int[Array, " n_tri"]
    materials: Materials
    emissive_tris: Int[Array, " n_emit"]
    sun: Sun | None
    sky_radiance: Float[Array, "3"]
    views: tuple[Camera, ...]
    name: str = eqx.field(static=True)
    part_names: tuple[str, ...] = eqx.field(static=True)
    unit_m: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        _check_last("vertices", self.vertices, (3,))
        _check_last("faces", self.faces, (3,))
        n_tri = self.faces.shape[-2]
        _check_last("corner_normals", self.corner_normals, (n_tri, 3, 3))
        _check_last("tri_material", self.tri_material, (n_tri,))
        _check_last("tri_part", self.tri_part, (n_tri,))

    @property
    def n_triangles(self) -> int:
        return int(self.faces.shape[-2])

    @property
    def triangles(self) -> Float[Array, "n_tri 3 3"]:
        """Per-triangle corner positions (a gather; cache it if used in a loop)."""
        return self.vertices[self.faces]

    @property
    def bounds(self) -> Float[Array, "2 3"]:
        """Axis-aligned bounding box, rows (min, max)."""
        return jnp.stack([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def has_light(self) -> bool:
        """True if anything emits: an emissive triangle, a sun or a non-black sky."""
        return bool(
            self.emissive_tris.shape[0] > 0 or self.sun is not None or float(jnp.max(self.sky_radiance)) > 0
        )

    def view(self, name: str) -> Camera:
        for cam in self.views:
            if cam.name == name:
                return cam
        raise KeyError(f"scene {self.name!r} has no view {name!r}; views: {[c.name for c in self.views]}")


def scene_box(
    scene: Scene | None, bounds=None, *, dtype: type[np.floating] | None = np.float64
) -> tuple[np.ndarray, np.ndarray]:
    """Host (lo, hi) corners of an axis-aligned box: the scene's (:attr:`Scene.bounds`) or ``bounds``.

    Args:
        scene: the scene whose vertex bounding box is wanted; unused (may be ``None``) with ``bounds``.
        bounds: an explicit (lo, hi) box, each anything NumPy reads as 3 numbers; checked, not clipped.
        dtype: NumPy dtype of the corners; ``None`` keeps the scene's (float32) for callers computing in
            its precision. float64 is exact: the corners are vertex coordinates.

    Returns:
        (lo, hi), two (3,) arrays, world frame, scene units.

    Raises:
        ConfigError: ``bounds`` has hi ≤ lo on some axis, or neither ``scene`` nor ``bounds`` is given.
        ValueError: ``bounds`` is not two corners of 3 numbers each.
    """
    if bounds is None:
        if scene is None:
            raise ConfigError("give a scene or explicit bounds")
        box = np.asarray(scene.bounds, dtype)
        return box[0], box[1]
    lo, hi = (np.asarray(b, dtype).reshape(3) for b in bounds)
    if not np.all(hi > lo):
        raise ConfigError(f"bounds need hi > lo per axis, got {lo} and {hi}")
    return lo, hi


class Hit(eqx.Module):
    """Closest-hit record for a batch of rays; misses have ``t = inf`` and ``tri = -1``.

    Attributes:
        t: distance along the (unit) ray direction.
        tri: triangle index, -1 on a miss.
        bary: barycentrics (u, v): the point is (1-u-v)·v0 + u·v1 + v·v2.
        geo_normal: geometric (face) normal, unit, on the triangle's front side (not flipped toward the ray).
        shading_normal: interpolated corner normal, unit.
        material: material row, -1 on a miss.
    """

    t: Float[Array, " n_rays"]
    tri: Int[Array, " n_rays"]
    bary: Float[Array, "n_rays 2"]
    geo_normal: Float[Array, "n_rays 3"]
    shading_normal: Float[Array, "n_rays 3"]
    material: Int[Array, " n_rays"]

    @property
    def hit(self) -> Bool[Array, " n_rays"]:
        return self.tri >= 0


class ProbeSet(eqx.Module):
    """Probe positions with an activity mask (fixed capacity so refiners never change shapes).

    Attributes:
        pos_world: probe centres, world frame.
        active: which rows are real probes.
        method: registry name of the placer that made the set (static).
    """

    pos_world: Float[Array, "n_probes 3"]
    active: Bool[Array, " n_probes"]
    method: str = eqx.field(static=True, default="manual")

    def __check_init__(self):
        _check_last("pos_world", self.pos_world, (3,))
        if self.active.shape != self.pos_world.shape[:-1]:
            raise ValueError(
                f"active must have shape {self.pos_world.shape[:-1]}, got {tuple(self.active.shape)}"
            )

    @property
    def capacity(self) -> int:
        return int(self.pos_world.shape[-2])

    @property
    def n_active(self) -> int:
        return int(jnp.sum(self.active))


#: Version of the :class:`BakeSettings` record (bumped when its fields or their meaning change).
BAKE_SETTINGS_VERSION = 3  # 2: first_hit_lobes; 3: texel_rays
#: Where a radiance texel's rays leave (``probes.BakeConfig.texel_rays``, :class:`BakeSettings`).
TEXEL_RAYS = ("jittered", "surfel")
#: What a texel's surface reflects toward the probe into ``radiance`` (``probes.path_traced_radiance``,
#: :class:`BakeSettings`).
FIRST_HIT_LOBES = ("diffuse", "all")


class BakeSettings(eqx.Module):
    """How a set of light-field probes was baked: recorded on the probes and in the baked file, checked
    by the evaluation (``probes.check_bake_settings``).

    Numbers are 0-d array leaves, not static fields, so that probes of runs that differ only in seed or
    sample counts share one pytree structure (and the compiled shading code that takes them); the names
    are static.

    Attributes:
        path_depth: longest path of each texel sample in segments, the probe → surface segment included
            (``render``'s ``max_depth`` convention). An evaluation whose camera paths have D segments
            needs ``path_depth = D − 1`` (``probes.bake_depth_for``). −1: the radiance was not path
            traced (a custom ``radiance_fn``), so there is no depth to check.
        spp: paths per texel ray (−1 for a custom radiance function).
        n_sub: rays per texel and axis (``n_sub``² per texel).
        radiance_res: interior resolution of the radiance maps.
        specular: the path tracer's dielectric specular factor (``render.RenderConfig.specular``);
            NaN for a custom radiance function.
        key: the raw words of the bake's PRNG key (``jax.random.key_data``), for reproduction.
        scene: name of the scene the probes were baked in (static).
        radiance: ``"path_traced"`` or ``"custom"`` (static).
        first_hit_lobes: what the surface a texel sees reflects toward the probe: ``"diffuse"`` (its
            diffuse lobe only: view-independent radiance, right for any viewer; the default since version
            2) or ``"all"`` (the whole BRDF: right only along the probe's own direction; version-1 files)
            (``render.RenderConfig.first_hit_lobes``; static).
        texel_rays: where a radiance texel's rays left: ``"jittered"`` (stratified over the texel; every
            version-1 and -2 file) or ``"surfel"`` (along its surfel's direction; recorded since version 3)
            (``probes.BakeConfig.texel_rays``; static).
        backend: the path tracer's backend, ``"jax"`` or ``"mitsuba"`` (``render.RenderConfig.backend``;
            the same estimator, so provenance only; static).
        version: :data:`BAKE_SETTINGS_VERSION` of the record (static).
    """

    path_depth: Int[Array, ""]
    spp: Int[Array, ""]
    n_sub: Int[Array, ""]
    radiance_res: Int[Array, ""]
    specular: Float[Array, ""]
    key: UInt32[Array, " k"]
    scene: str = eqx.field(static=True)
    radiance: str = eqx.field(static=True, default="path_traced")
    first_hit_lobes: str = eqx.field(static=True, default="all")
    backend: str = eqx.field(static=True, default="jax")
    texel_rays: str = eqx.field(static=True, default="jittered")
    version: int = eqx.field(static=True, default=BAKE_SETTINGS_VERSION)

    def __check_init__(self):
        if self.radiance not in ("path_traced", "custom"):
            raise ValueError(f"radiance must be 'path_traced' or 'custom', got {self.radiance!r}")
        if self.first_hit_lobes not in FIRST_HIT_LOBES:
            raise ValueError(
                f"first_hit_lobes must be one of {FIRST_HIT_LOBES}, got {self.first_hit_lobes!r}"
            )
        if self.backend not in ("jax", "mitsuba"):
            raise ValueError(f"backend must be 'jax' or 'mitsuba', got {self.backend!r}")
        if self.texel_rays not in TEXEL_RAYS:
            raise ValueError(f"texel_rays must be one of {TEXEL_RAYS}, got {self.texel_rays!r}")

    def to_dict(self) -> dict:
        """Plain JSON-ready values (the form stored in the baked file and in run metrics)."""
        return {
            "version": self.version,
            "scene": self.scene,
            "radiance": self.radiance,
            "first_hit_lobes": self.first_hit_lobes,
            "backend": self.backend,
            "texel_rays": self.texel_rays,
            "path_depth": int(self.path_depth),
            "spp": int(self.spp),
            "n_sub": int(self.n_sub),
            "radiance_res": int(self.radiance_res),
            "specular": None if math.isnan(float(self.specular)) else float(self.specular),
            "key": [int(k) for k in np.asarray(self.key).reshape(-1)],
        }

    @classmethod
    def from_dict(cls, d: dict) -> BakeSettings:
        """Inverse of :meth:`to_dict`.

        Raises:
            KeyError, TypeError, ValueError: a missing or malformed entry.
        """
        i32 = lambda k: jnp.asarray(int(d[k]), jnp.int32)
        spec = d["specular"]
        return cls(
            path_depth=i32("path_depth"),
            spp=i32("spp"),
            n_sub=i32("n_sub"),
            radiance_res=i32("radiance_res"),
            specular=jnp.asarray(math.nan if spec is None else float(spec), jnp.float32),
            key=jnp.asarray(np.asarray(d["key"], np.uint32).reshape(-1)),
            scene=str(d["scene"]),
            radiance=str(d["radiance"]),
            first_hit_lobes=str(d.get("first_hit_lobes", "all")),  # version 1 baked every lobe
            backend=str(d.get("backend", "jax")),  # files from before the Mitsuba backend
            texel_rays=str(d.get("texel_rays", "jittered")),  # versions 1-2 jittered every texel's rays
            version=int(d["version"]),
        )


class LightFieldProbes(eqx.Module):
    """Baked light-field probes (McGuire et al. 2017 §3): per probe, octahedral maps (Cigolle et al. 2014)
    *with a one-texel border* on every side so bilinear filtering is right across the octahedral edges
    (Luo 2022 §4.3.5; the DDGI layout). A map of interior resolution R is stored as (R+2)×(R+2).

    Each texel is one *surfel*: the first surface hit by the ray through the texel centre (McGuire §4).
    What it stores replaces "the rest of the path" from a shading point: light reflected toward the probe
    along paths of at most ``bake.path_depth`` segments (``probes.bake_depth_for``).

    Attributes:
        pos_world: probe centres, world frame.
        active: which probes are real (a ProbeSet's mask).
        inside: probes found inside geometry at bake time: they cannot reach the free space of the
            scene's views (``probes.BakeConfig.inside_test``); unusable for shading.
        radiance: radiance reflected toward the probe by the first surface hit in each texel's direction
            (direct + indirect, emission excluded: DESIGN.md "indirect means reflected"); zero where the
            ray escapes.
        emission: radiance emitted toward the probe by that surface, or the sky (and sun) radiance where
            the ray escapes: what a camera at the probe would call "emission" (docs/render.md).
        normal16: the unit shading normal of that surface, *oriented toward the probe* (``dot(n, −ω) > 0``
            for the texel direction ω: the side the probe sees, whatever the triangle's winding), as two
            octahedral snorm16 components (``_core.pack_normal``); read it as float32 with
            :attr:`normal` (zeros where the ray escapes) or :meth:`normal_at`.
        backface: True where the probe sees that surface's back side by its geometric normal (winding),
            so a one-sided sheet seen from behind can still be told; False where the ray escapes.
        distance: radial distance to that surface (float32); ``far`` where the ray escapes. The geometry
            maps (``distance``, ``normal16``, ``backface``) may have their own resolution, finer than the
            radiance maps' (``probes.BakeConfig.geometry_res``). The tracer builds its own min/max pyramids
            from them (``probes.make_tracer``), so none is stored here.
        irradiance: cosine-convolved irradiance E(n) for a receiver normal n = texel direction.
        moments: cosine-power filtered E[r] and E[r²] (McGuire §5.2), for the Chebyshev visibility test.
        far: the distance stored for escaping rays (a finite value beyond the scene).
        bake: how the probes were baked (:class:`BakeSettings`); ``None`` for probes built by hand or
            read from a file that predates recorded settings (the evaluation refuses those).
    """

    pos_world: Float[Array, "n_probes 3"]
    active: Bool[Array, " n_probes"]
    inside: Bool[Array, " n_probes"]
    radiance: Float[Array, "n_probes rb rb 3"]
    emission: Float[Array, "n_probes rb rb 3"]
    normal16: Int[Array, "n_probes gb gb 2"]
    distance: Float[Array, "n_probes gb gb"]
    irradiance: Float[Array, "n_probes ib ib 3"]
    moments: Float[Array, "n_probes mb mb 2"]
    far: Float[Array, ""]
    backface: Bool[Array, "n_probes gb gb"] | None = None
    bake: BakeSettings | None = None

    def __check_init__(self):
        _check_last("pos_world", self.pos_world, (3,))
        for name in ("radiance", "emission", "normal16", "distance", "irradiance", "moments"):
            m = getattr(self, name)
            if m.shape[-3 if m.ndim == 4 else -2] != m.shape[-2 if m.ndim == 4 else -1]:
                raise ValueError(f"{name} maps must be square, got {tuple(m.shape)}")
        _check_last("normal16", self.normal16, (2,))
        if self.normal16.dtype != jnp.int16:
            raise ValueError(f"normal16 must be int16 (_core.pack_normal), got {self.normal16.dtype}")
        if self.normal16.shape[:-1] != self.distance.shape:
            raise ValueError(
                f"normal16 {tuple(self.normal16.shape)} must match distance {tuple(self.distance.shape)}"
            )
        if self.backface is not None and self.backface.shape != self.distance.shape:
            raise ValueError(
                f"backface must have the distance map's shape {tuple(self.distance.shape)}, "
                f"got {tuple(self.backface.shape)}"
            )

    @property
    def normal(self) -> Float[Array, "n_probes gb gb 3"]:
        """Every normal map as float32 unit vectors (zeros where the ray escapes): 12 bytes a texel, so
        read one probe's rows or single texels (:meth:`normal_at`) where the set is large."""
        return unpack_normal(self.normal16, self.distance >= self.far)

    def normal_at(self, *index) -> Array:
        """The float32 normals of the texels ``normal16[index]`` (gathered, then unpacked)."""
        return unpack_normal(self.normal16[index], self.distance[index] >= self.far)

    @property
    def geometry_res(self) -> int:
        """Interior (borderless) resolution of the geometry maps (distance, normal, back face)."""
        return int(self.distance.shape[-1]) - 2

    @property
    def radiance_res(self) -> int:
        """Interior (borderless) resolution of the radiance / normal / distance maps."""
        return int(self.radiance.shape[-2]) - 2

    @property
    def irradiance_res(self) -> int:
        return int(self.irradiance.shape[-2]) - 2

    @property
    def moments_res(self) -> int:
        return int(self.moments.shape[-2]) - 2
