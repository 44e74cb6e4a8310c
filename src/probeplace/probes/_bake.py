"""Bake light-field probes (McGuire et al. 2017 §3) for any :class:`~probeplace._core.ProbeSet`.

Per probe and interior texel of the radiance map (octahedral, Cigolle 2014; ``_core.maths._octahedral``):

* the **geometry** maps — radial distance and shading normal — come from the ray through the texel
  *centre*, so each texel is one surfel (McGuire §4: "each octahedral texel describes a planar patch");
* the **radiance** maps average ``n_sub``² rays per texel, each path traced by the reference renderer
  (issue 3: "radiance from path tracing along each texel's direction"). By default
  (``BakeConfig.texel_rays="jittered"``) the rays are spread over the texel with stratified sub-texel
  jitter (issue 3's box filter: the texel's area average). ``"surfel"`` sends every ray of a texel along
  its *surfel's* direction — the geometry texel holding the radiance texel's centre
  (``_core.surfel_texels``) — so a texel stores the light of the very surface the depth-aware glossy read
  tests (``_glossy``). Which is better depends on the rays a texel gets (issue 33, experiments/README.md
  §2 "Radiance along the surfel's ray"): with **one** ray a texel a jittered ray is a random point of the
  texel, so near a shadow edge the texel holds sun or shade by its jitter while its surfel is the centre's;
  on Crytek Sponza (64² radiance, 512² geometry, 8 paths) the surfel's ray lowered the glossy MSE on every
  grid cell and seed (−37 % on the 16×8×8 grid, −7 to −25 % on the 8×4×4 grid's five seeds). With 4×4
  jittered rays (``sponza_comparison``) the average read better than 32 paths along the surfel's ray for
  three of four methods on seed 0: a point value is all sun or all shade where a read lands wrong, the
  average hedges. What the
  renderer calls ``direct + diffuse_indirect + glossy_indirect`` for a camera at the probe is the light
  *reflected* toward the probe (stored in ``radiance``); its ``emission`` (emitters and sky seen
  directly) is stored apart (DESIGN.md "indirect means reflected").

**Path depth — one definition** (:func:`bake_depth_for`). ``render``'s ``max_depth`` counts path
segments, the camera ray included. A probe texel replaces "the rest of the path" from a shading point
x₁: the reference's diffuse and glossy indirect at x₁ are paths x₁ → x₂ → … of at most D − 1 segments
when the camera paths have D, so a texel stores the radiance reflected toward the probe along paths of
at most **D − 1** segments (the probe → surface segment counted as the first, like x₁ → x₂). The
evaluation's CRN glossy reference traces its secondary rays with the same depth. The depth, the
sample counts, the scene and the key are recorded on the probes (:class:`~probeplace._core.BakeSettings`)
and checked by :func:`check_bake_settings` when probes are evaluated.

**What a texel stores is view-independent** (``path_traced_radiance(first_hit_lobes="diffuse")``, the
default): the surface a texel sees reflects toward the probe by its *diffuse lobe only*; bounces beyond
it keep the whole BRDF. A texel is read by viewers in other directions than the probe's, so a glossy
highlight toward the probe would be handed to viewers that never see it: on Crytek Sponza (sunlit floor,
roughness 0.22) baking every lobe made a perfect trace's glossy error 3.2× larger and its mean 20 % too
bright (16×8×8 grid, 32² maps). The specular lobe of that surface toward the viewer is then missing from
the estimate; the evaluation reports that share (``mse_glossy_view_dependence``). The irradiance maps
(diffuse shading) are integrated from every lobe's radiance, from the same paths.

**Surfels are oriented toward the probe**: the stored normal faces the probe whatever the winding,
and the ``backface`` map keeps which side (by the geometric normal) the probe saw.

**Inside geometry** (``BakeConfig.inside_test``, default ``"reach"``; ``probes._inside``): a probe is
*inside* when it cannot reach the free space the scene is viewed from — none of its texel-centre rays
escapes the scene, it sees no view camera nor the free space around one, and no chain of probes whose
free-space regions meet leads to one that does. This is the exterior flood fill of mesh repair (Ju 2004,
"Robust repair of polygonal models": inside/outside from reachability, which holds for open,
non-manifold and inconsistently oriented input), run on the probes' own rays with the views and the sky
as seeds. It never reads triangle winding. On 8×4×4 grids it flags exactly the probes the back-face test
flags where the winding is consistent (Cornell box 9, rooms 25, temple 16, courtyard 0 of 128). Ray
parity (Nooruddin & Turk 2003) was measured and rejected: it needs closed solids, and single-sheet walls
(the Cornell box's) make a room's interior "odd" — 84 of 128 probes of that grid had an odd crossing
count in more than 3/4 of 26 directions.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core import (
    BAKE_SETTINGS_VERSION,
    FIRST_HIT_LOBES,
    TEXEL_RAYS,
    BakeSettings,
    ConfigError,
    LightFieldProbes,
    ProbeSet,
    Scene,
    SceneError,
    add_border,
    check_memory,
    check_target,
    dot3,
    fill_border,
    jittered_texel_directions,
    pack_normal,
    padded_count,
    scene_box,
    surfel_directions,
    texel_directions,
)
from .._core.runtime import check_settings, progress_bar, setting
from ._filter import distance_moments, irradiance_map
from ._inside import probes_inside

log = logging.getLogger(__name__)

#: ``radiance_fn(origins, directions, key) -> (reflected, emitted)`` or ``(reflected, emitted,
#: reflected_every_lobe)``, each (n, 3): radiance arriving at each origin along -direction, split as in
#: the module docstring. ``reflected`` fills the radiance maps (glossy reads); the irradiance maps are
#: integrated from ``reflected_every_lobe`` when given (the view-independent split), else ``reflected``.
RadianceFn = Callable[[Float[Array, "n 3"], Float[Array, "n 3"], jax.Array], tuple[Array, ...]]


#: Camera path depth of the evaluation when none is given (``evaluate.EvalConfig.max_depth``'s default);
#: :func:`path_traced_radiance`'s default depth is :func:`bake_depth_for` of it.
DEFAULT_EVAL_MAX_DEPTH = 8


def bake_depth_for(eval_max_depth: int) -> int:
    """The path depth a bake must use for an evaluation (or reference render) whose camera paths have
    ``eval_max_depth`` segments: ``eval_max_depth − 1`` (module docstring, "Path depth").

    A probe texel stands for the rest of a camera path after its first bounce, so its paths have one
    segment fewer; the evaluation's CRN glossy reference traces its secondary rays with this depth too.

    Raises:
        ConfigError: ``eval_max_depth`` is not an int ≥ 2 (a texel path needs a segment).
    """
    if (
        isinstance(eval_max_depth, bool)
        or not isinstance(eval_max_depth, int | np.integer)
        or eval_max_depth < 2
    ):
        raise ConfigError(f"eval max_depth must be an int ≥ 2 for a probe bake, got {eval_max_depth!r}")
    return int(eval_max_depth) - 1


@dataclasses.dataclass(frozen=True, eq=False)
class PathTracedRadiance:
    """The reference path tracer as a :data:`RadianceFn` (built by :func:`path_traced_radiance`); its
    settings are read by :func:`bake_probes` into the probes' :class:`~probeplace._core.BakeSettings`."""

    scene: Scene
    spp: int
    max_depth: int
    specular: float
    caster: object = None
    first_hit_lobes: str = "diffuse"
    backend: str = "jax"

    def __call__(self, origins, directions, key):
        from ..render import trace_rays

        r = trace_rays(
            self.scene,
            origins,
            directions,
            spp=self.spp,
            key=key,
            max_depth=self.max_depth,
            specular=self.specular,
            caster=self.caster,
            backend=self.backend,
        )
        # on the host: the bake reads the result back anyway, and eager jnp arithmetic would compile a
        # program per operation and ray count (issue 32)
        mean = np.asarray(r.mean)
        c = lambda name: mean[:, r.components.index(name)]
        emitted = c("emission")
        every_lobe = c("full") - emitted
        if self.first_hit_lobes == "all":
            return every_lobe, emitted
        # the diffuse lobe's share of what the surface reflects (render._integrator: "glossy_direct")
        diffuse_lobe = c("direct") - c("glossy_direct") + c("diffuse_indirect")
        return diffuse_lobe, emitted, every_lobe


def path_traced_radiance(
    scene: Scene,
    *,
    spp: int = 16,
    max_depth: int = bake_depth_for(DEFAULT_EVAL_MAX_DEPTH),
    specular: float = 1.0,
    first_hit_lobes: str = "diffuse",
    caster=None,
    backend: str = "jax",
) -> PathTracedRadiance:
    """The reference path tracer as a :data:`RadianceFn`: ``render.trace_rays`` split into reflected
    (direct + diffuse indirect + glossy indirect) and emitted (emission, sky) radiance.

    ``spp`` paths per ray; with ``n_sub``² rays per texel a texel averages ``spp·n_sub²`` paths.
    Each call uses a fresh random stream from its key, so batches are independent.

    Args:
        scene: the scene.
        spp: paths per ray.
        max_depth: path segments per texel sample, the probe → surface segment included. Pass
            ``bake_depth_for(D)`` for an evaluation with camera depth D (the default is that of
            :data:`DEFAULT_EVAL_MAX_DEPTH`); a mismatch is refused when the probes are evaluated.
        specular: dielectric specular factor (``render.RenderConfig.specular``; the evaluation uses 1).
        first_hit_lobes: ``"diffuse"`` (default): the surface a texel sees reflects toward the probe by
            its diffuse lobe only — view-independent radiance, which any viewer may read (DDGI's choice);
            deeper bounces keep the whole BRDF. ``"all"``: the whole BRDF, so a glossy surface's highlight
            toward the *probe* is stored and handed to viewers who would not see it (on Sponza's sunlit
            floor, roughness 0.22, this made a perfect trace's glossy MSE 3.2× larger, issue 16).
        caster: ray caster (default ``render.default_caster``; ``backend="jax"`` only).
        backend: ``"jax"`` (default) or ``"mitsuba"`` (``render.RenderConfig.backend``: the same
            estimator and random numbers compiled by Mitsuba 3 on the CPU, several times faster there), or
            ``"auto"`` (``render.resolve_backend``; a ``caster`` is then used only if JAX is picked).

    Raises:
        SceneError: the scene has no light (every baked map would be black).
        ConfigError: ``spp`` or ``max_depth`` not a positive int, ``specular`` outside [0, 1], unknown
            ``first_hit_lobes``, unknown ``backend`` or a ``caster`` with ``backend="mitsuba"``.
    """
    if not scene.has_light:
        raise SceneError(
            f"scene {scene.name!r} has no light (no emissive material, sun or sky): path-traced probe "
            "radiance would be all black; add a light"
        )
    for name, v in (("spp", spp), ("max_depth", max_depth)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
            raise ConfigError(f"path_traced_radiance: {name} must be a positive int, got {v!r}")
    if not 0.0 <= float(specular) <= 1.0:
        raise ConfigError(f"path_traced_radiance: specular must be in [0, 1], got {specular!r}")
    if first_hit_lobes not in FIRST_HIT_LOBES:
        raise ConfigError(
            f"path_traced_radiance: first_hit_lobes must be one of {FIRST_HIT_LOBES}, got {first_hit_lobes!r}"
        )
    from ..render import resolve_backend

    requested, backend = backend, resolve_backend(backend, "path_traced_radiance: backend")
    if backend == "mitsuba" and requested == "auto":
        caster = None  # a caster only speeds the JAX path tracer up; Mitsuba casts with Embree
    if backend == "mitsuba" and caster is not None:
        raise ConfigError(
            "path_traced_radiance: a caster is a backend='jax' option (Mitsuba casts with Embree)"
        )
    return PathTracedRadiance(
        scene, int(spp), int(max_depth), float(specular), caster, first_hit_lobes, backend
    )


INSIDE_TESTS = ("reach", "backface", "none")


@dataclasses.dataclass(frozen=True, kw_only=True)
class BakeConfig:
    """Bake settings.

    Attributes:
        radiance_res: interior resolution of the radiance / emission maps (a power of two, for the MIP
            chains); ``None`` derives it with :func:`default_radiance_res`.
        geometry_res: interior resolution of the geometry maps — distance, normal, back-face, and the
            distance MIPs the tracer marches (a power of two); ``None``: ``radiance_res``. Finer geometry
            costs one exact ray per texel, no path tracing: it lets the tracer resolve depth
            discontinuities the radiance texels would blur (issue 16: Sponza 16×8×8, 64² radiance,
            unresolved 0.116 → 0.075 with 128² geometry).
        irradiance_res: interior resolution of the irradiance map (McGuire §3: low frequency, 8 is
            DDGI's choice).
        moments_res: interior resolution of the distance-moment map (DDGI uses 16).
        n_sub: ``n_sub``² rays per radiance texel (each traces ``spp`` paths).
        texel_rays: where a radiance texel's rays leave: ``"jittered"`` (default): stratified, jittered
            over the texel (the texel's area average, issue 3); ``"surfel"``: all along the direction of
            the texel's surfel (``_core.surfel_texels``), so the texel holds the light of the surface its
            surfel describes and ``n_sub``² only multiplies the paths — better with one ray a texel,
            worse than a 4×4 jittered average on ``sponza_comparison`` (module docstring).
        moment_power: exponent p of the cosine-power lobe for the moments (McGuire §5.2 gives no value;
            DDGI's reference implementation filters distance with a sharp lobe, we default to 50).
        inside_test: how ``inside`` is decided: ``"reach"`` (default; winding-independent: the probe
            cannot reach the views' free space, :func:`probes_inside`), ``"backface"`` (more than
            ``inside_backface_share`` of the texel-centre rays first hit a back face: needs consistent
            winding) or ``"none"`` (no probe is inside).
        inside_neighbours: probes each probe tests for a line of sight in the ``"reach"`` test (its
            nearest ones; all pairs when there are fewer).
        inside_res: the ``"reach"`` test's rays: the texel centres of an ``inside_res``² map (every k-th
            geometry texel per axis when the geometry maps are finer). A probe inside a solid that leaks
            counts as free once one of its rays finds the crack (:func:`probes_inside`), so the verdict
            must not depend on the map resolution: on Crytek Sponza's 16×8×8 grid, the reach test on all
            of 512² geometry texels found cracks for 776 probes in walls and roof (16 inside, against 792 with
            128² rays; issue 33).
        inside_backface_share: the ``"backface"`` threshold; also the ``"reach"`` test's fallback when no
            probe escapes the scene or sees a view camera (a closed scene without views: then nothing
            but the winding tells a room from a solid).
        probes_per_batch: probes traced at once (memory ≈ probes × res² × n_sub² × 200 bytes).
        quality: scales the derived radiance resolution.
        noise_target: when the bake's paths per texel ray are chosen (``spp="auto"``,
            :func:`choose_bake_spp`): the relative noise of the radiance maps to reach, the RMS seed-to-seed
            difference of a texel over the RMS radiance (0.05: 5 %).
        pilot_spp: paths per texel ray of the pilot bakes that measure the noise (``spp="auto"``).
        max_spp: the most paths per texel ray a chosen count may reach (``spp="auto"``).
        progress: show a progress bar.
    """

    radiance_res: int | None = setting(None, lo=2)  # and a power of two (__post_init__)
    geometry_res: int | None = setting(None, lo=2)  # and a power of two (__post_init__)
    irradiance_res: int = setting(8, lo=1)
    moments_res: int = setting(16, lo=1)
    n_sub: int = setting(2, lo=1)
    texel_rays: str = setting("jittered", choices=TEXEL_RAYS)
    moment_power: float = setting(50.0, lo=0.0, lo_open=True)
    inside_test: str = setting("reach", choices=INSIDE_TESTS)
    inside_neighbours: int = setting(16, lo=1)
    inside_res: int = setting(128, lo=1)
    inside_backface_share: float = setting(0.5, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    probes_per_batch: int = setting(8, lo=1)
    quality: float = setting(1.0, lo=0.0, lo_open=True)
    noise_target: float = setting(0.05, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    pilot_spp: int = setting(1, lo=1)
    max_spp: int = setting(256, lo=1)  # and ≥ pilot_spp (__post_init__)
    progress: bool = True

    def __post_init__(self):
        """The declared ranges and choices (``_core.runtime.check_settings``), then what is not a range."""
        check_settings(self)
        for name in ("radiance_res", "geometry_res"):
            v = getattr(self, name)
            if v is not None and v & (v - 1):
                raise ConfigError(f"BakeConfig.{name} must be a power of two ≥ 2, got {v!r}")
        # max_spp ≥ pilot_spp (the ranges it checks too are the declared ones)
        check_target(
            "BakeConfig", noise_target=self.noise_target, pilot_spp=self.pilot_spp, max_spp=self.max_spp
        )


def batch_ray_bytes(n_probes: int, res: int, n_sub: int) -> int:
    """Working memory of one batch's radiance rays: ``n_probes`` × res² × n_sub² paths at ~200 bytes a
    path (``BakeConfig.probes_per_batch``); the bake's and its pilot's memory checks both count it."""
    return n_probes * res * res * n_sub**2 * 200


def map_resolutions(scene: Scene, config: BakeConfig) -> tuple[int, int]:
    """(radiance, geometry) map resolutions a bake of ``scene`` at ``config`` uses: the radiance maps'
    from the scene's size unless given, the geometry maps' the radiance maps' unless given."""
    res = config.radiance_res or default_radiance_res(scene, quality=config.quality)
    return res, config.geometry_res or res


def probe_bytes(scene: Scene, config: BakeConfig) -> int:
    """Bytes one baked probe holds at ``config`` (its maps as :class:`LightFieldProbes` stores them: float32
    radiance, emission, irradiance, moments and distance, the two int16 normal components
    (``_core.maths._packed``) and the back-face bytes, all with their one-texel borders; position and flags):
    what a memory budget divides by (``placement.space._budget.count_for_memory``)."""
    res, geo = map_resolutions(scene, config)
    floats = 2 * (res + 2) ** 2 * 3  # radiance, emission
    floats += (config.irradiance_res + 2) ** 2 * 3 + (config.moments_res + 2) ** 2 * 2
    geometry = (geo + 2) ** 2 * (4 + 2 * 2 + 1)  # float32 distance, two int16 normal components, back face
    return 4 * (floats + 3) + geometry + 2  # + position; + active/inside bytes


def default_radiance_res(scene: Scene, *, quality: float = 1.0) -> int:
    """Radiance-map resolution so that a texel's footprint at the typical probe-to-wall distance is about
    one surface-sample spacing (the scene's own feature scale), rounded to a power of two in [16, 128].

    A texel subtends ≈ √(4π)/R rad; at distance d its footprint is ≈ 3.5 d / R. The typical distance is
    taken as a quarter of the bounding-box diagonal, the spacing from ``geometry.default_sample_spacing``.
    McGuire §3 found no gain above 128² and good results from 32².
    """
    from ..geometry import default_sample_spacing

    lo, hi = scene_box(scene, dtype=None)
    d = 0.25 * float(np.linalg.norm(hi - lo))
    spacing = default_sample_spacing(scene, quality=quality)
    r = 3.5 * d / spacing
    return int(2 ** np.clip(np.round(np.log2(max(r, 1.0))), 4, 7))


#: A probe farther outside the scene box than this many times the box's largest side is not a probe of this
#: scene. Why a whole size: a set made for this scene stays within a fraction of it (placement keeps probes
#: in the box; a hand-placed probe in front of an opening or above an open court is a fraction of the size
#: out; the tracer tests' single quad keeps its probe half the quad's size away), while a set made for
#: another scene or in other units is off by the scale between them (mm against m: 1000×) or by where the
#: other scene stands. One size leaves both kinds well clear of the line.
PROBES_OUTSIDE_MARGIN = 1.0
#: Refused when more than this share of the active probes lie that far out. A stray probe or two (a typo
#: in a hand-made set) is baked with the warning of :func:`_warn_probe_layout`; a tenth or more of the set
#: means it was made in another frame, and each of those probes costs a full bake for no receiver.
PROBES_OUTSIDE_SHARE = 0.1


def _vec(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{float(v):.4g}" for v in x) + "]"


def check_probes_in_scene(
    pos: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    what: str,
    *,
    scene: str | None = None,
    fix: str = "the probes were made for another scene or in other units; place probes in this scene",
) -> None:
    """Refuse a probe set that does not belong to the scene: more than :data:`PROBES_OUTSIDE_SHARE` of
    ``pos`` (the active probes) lie farther outside the box ``lo``–``hi`` than :data:`PROBES_OUTSIDE_MARGIN`
    times its largest side. One line: ``what``, the count, the scene (``scene``, a name) and ``fix``.

    Raises:
        ConfigError: see above (cheap: no geometry is read, so callers run it before any slow work).
    """
    pos = np.asarray(pos, np.float64).reshape(-1, 3)
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    size = float(np.max(hi - lo))
    if len(pos) == 0 or not size > 0:
        return
    beyond = np.maximum(np.maximum(lo - pos, pos - hi), 0.0).max(axis=1)  # per-axis distance out of the box
    far = beyond > PROBES_OUTSIDE_MARGIN * size
    if far.sum() > PROBES_OUTSIDE_SHARE * len(pos):
        whose = f"{scene}'s" if scene is not None else "the scene's"
        raise ConfigError(
            f"{what}: {int(far.sum())} of {len(pos)} probes lie outside {whose} bounds {_vec(lo)}–{_vec(hi)} "
            f"by more than its size ({size:.4g}); {fix}"
        )


def _warn_probe_layout(pos: np.ndarray, lo: np.ndarray, hi: np.ndarray, what: str, **scene) -> None:
    """Refuse probes of another scene (:func:`check_probes_in_scene`, ``scene`` its keywords), then log
    (not refuse) duplicate probes and probes outside the scene box: both are legal but usually a mistake —
    duplicates cost work for no gain, outside probes see the scene from beyond its bounds."""
    check_probes_in_scene(pos, lo, hi, what, **scene)
    n_dup = len(pos) - len(np.unique(pos, axis=0))
    if n_dup:
        log.warning("%s: %d of %d probe positions are duplicates", what, n_dup, len(pos))
    out = ((pos < lo) | (pos > hi)).any(axis=1)
    if out.any():
        log.warning(
            "%s: %d of %d probes lie outside the scene bounds %s–%s", what, out.sum(), len(pos), lo, hi
        )


def _texel_surfels(hit, d, far):
    """(distance, packed normal, back face) of each texel-centre ray's hit: ``far`` and a zero normal on a
    miss. The side the probe sees is the renderer's rule (the geometric normal decides), then the shading
    normal on that side; where interpolation bends it past the ray (grazing texels), the geometric one.
    Normals are packed here (``_core.pack_normal``), so no float32 normal map is kept. Run inside the
    caster's program (``closest_hit_map``: one program over a batch's 2 M rays at 512², issue 33)."""
    is_hit = hit.tri >= 0
    back = is_hit & (dot3(hit.geo_normal, d) > 0)
    side = jnp.where(back, -1.0, 1.0).astype(d.dtype)[:, None]
    n_or = hit.shading_normal * side
    n_or = jnp.where((dot3(n_or, d) < 0)[:, None], n_or, hit.geo_normal * side)
    return jnp.where(is_hit, hit.t, far), pack_normal(jnp.where(is_hit[:, None], n_or, 0.0)), back


# The texel-centre rays go to the caster in 4×4 tiles of one probe's map, 16 consecutive rays a tile: one
# coherent Embree packet (geometry/_embree_packets.py: 13.0 against 6.1 M rays/s on Sponza, 2 threads;
# 8.2 M rays/s in 16×1 rows). A map whose side is no multiple of 4 goes row by row.
_TILE = 4


def _tile(g: int) -> int:
    return _TILE if g % _TILE == 0 else 1


def _to_tiles(maps: np.ndarray) -> np.ndarray:
    """(G, G, *c) texel maps → (G², *c) in tile order: the 4×4 tiles row by row, each tile's texels
    row by row."""
    g, t = maps.shape[0], _tile(maps.shape[0])
    c = maps.shape[2:]
    x = maps.reshape(g // t, t, g // t, t, *c).swapaxes(1, 2)
    return x.reshape(g * g, *c)


def _from_tiles(flat: np.ndarray, b: int, g: int) -> np.ndarray:
    """:func:`_to_tiles`' inverse for ``b`` probes: (b·G², *c) in tile order → (b, G, G, *c)."""
    t = _tile(g)
    c = flat.shape[1:]
    return flat.reshape(b, g // t, g // t, t, t, *c).swapaxes(2, 3).reshape(b, g, g, *c)


def _bake_batch(
    pos: np.ndarray,
    caster,
    radiance_fn: RadianceFn,
    res: int,
    geo_res: int,
    centre_dirs: np.ndarray,
    config: BakeConfig,
    far: float,
    key: jax.Array,
):
    """One batch of probes (``pos``, (b, 3)): the geometry maps' texel-centre surfels as flat (b·G²)
    arrays in tile order (distance, packed normal, back face), then the radiance maps. ``centre_dirs``:
    the G² texel directions in tile order (:func:`_to_tiles`) repeated for a full batch, built once a bake
    (a shorter last batch reads its head); the rays stay host (NumPy) arrays, which Embree reads as they
    are and a JAX caster converts once."""
    b, g2 = pos.shape[0], geo_res * geo_res
    dirs = centre_dirs[: b * g2]
    origins = np.repeat(pos, g2, axis=0)
    # normals packed batch by batch (a 1024-probe set at 512² would be 3 GiB of float32 normals)
    geometry = caster.closest_hit_map(
        _texel_surfels, origins, dirs, dirs, jnp.float32(far), coherent=_tile(geo_res) == _TILE
    )
    k_dir, k_rad = jax.random.split(key)
    radiance = texel_radiance(jnp.asarray(pos), radiance_fn, res, geo_res, config, k_dir, k_rad)
    return geometry, radiance


def texel_ray_directions(
    b: int, res: int, geo_res: int, config: BakeConfig, k_dir: jax.Array
) -> Float[Array, "rays 3"]:
    """The radiance rays of ``b`` probes, (b·res²·n_sub², 3) in probe, row, column, ray order, placed by
    ``config.texel_rays`` (:class:`BakeConfig`): along each texel's surfel direction (``geo_res``: the
    geometry maps' resolution), or jittered with ``k_dir``."""
    sub = config.n_sub * config.n_sub
    if config.texel_rays == "surfel":
        dirs = surfel_directions(res, geo_res)
        return jnp.broadcast_to(dirs[None, :, :, None], (b, res, res, sub, 3)).reshape(-1, 3)
    jitter = lambda k: jittered_texel_directions(res, config.n_sub, key=k)
    return jax.vmap(jitter)(jax.random.split(k_dir, b)).reshape(-1, 3)


def texel_radiance(
    pos: Float[Array, "b 3"],
    radiance_fn: RadianceFn,
    res: int,
    geo_res: int,
    config: BakeConfig,
    k_dir: jax.Array,
    k_rad: jax.Array,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (b, res, res, 3) radiance, emission and every-lobe maps of the probes at ``pos``: the mean of
    ``n_sub``² rays per texel (:func:`texel_ray_directions`; ``k_dir`` draws the jitter), path traced with
    ``k_rad``. Two keys, so that the bake's pilot (``_bake_samples``) can hold the jitter and draw new
    paths."""
    b = pos.shape[0]
    sub = config.n_sub * config.n_sub
    dirs = texel_ray_directions(b, res, geo_res, config, k_dir)
    sub_origins = jnp.repeat(pos, res * res * sub, axis=0)
    out = radiance_fn(sub_origins, dirs, k_rad)
    per_texel = lambda x: np.asarray(x).reshape(b, res, res, sub, 3).mean(axis=3)
    radiance, emission = per_texel(out[0]), per_texel(out[1])
    every_lobe = per_texel(out[2]) if len(out) > 2 else radiance  # :data:`RadianceFn`
    return radiance, emission, every_lobe


def padded_capacity(n: int) -> int:
    """The capacity a set of ``n`` probes is padded to before a bake (:func:`pad_probes`): a power of two
    from 8 to 64, then a multiple of 64. Bake, tracer and shading programs are compiled per probe count;
    with a few capacities a new budget, seed or method reuses them (issue 32)."""
    return padded_count(n, lo=8, step=64)


def pad_probes(probes: ProbeSet) -> ProbeSet:
    """``probes`` with inactive rows (copies of the first probe) up to :func:`padded_capacity`. Inactive
    probes are masked out of the bake, the tracer and the shading: the results do not change, but the
    stored set has the padded rows (``active`` False)."""
    pad = padded_capacity(probes.capacity) - probes.capacity
    if pad <= 0:
        return probes
    return ProbeSet(
        pos_world=jnp.concatenate([probes.pos_world, jnp.repeat(probes.pos_world[:1], pad, axis=0)]),
        active=jnp.concatenate([probes.active, jnp.zeros(pad, bool)]),
        method=probes.method,
    )


def bake_probes(
    scene: Scene,
    probes: ProbeSet,
    *,
    caster,
    radiance_fn: RadianceFn,
    key: jax.Array,
    config: BakeConfig = BakeConfig(),
) -> LightFieldProbes:
    """Bake every probe of ``probes`` (inactive rows too, so shapes stay fixed; they are masked later).

    Args:
        scene: the scene (for the far distance, the derived resolution and the views).
        probes: probe positions, world frame.
        caster: an exact ray caster (``geometry.make_caster``) for the texel-centre geometry rays and the
            inside test.
        radiance_fn: path-traced radiance along rays, split into (reflected, emitted); see
            :data:`RadianceFn` and :func:`path_traced_radiance` (whose depth, spp and specular factor are
            recorded in the probes' :class:`~probeplace._core.BakeSettings`; any other function is
            recorded as ``"custom"``).
        key: PRNG key for jitter and path sampling.
        config: resolutions, filters and the inside test.

    Returns:
        The baked :class:`LightFieldProbes`; float32, maps with one-texel borders, ``bake`` settings set.

    Raises:
        ConfigError: bad probe positions (NaN/inf), empty set or configuration; probes of another scene
            (:func:`check_probes_in_scene`).
        ResourceError: one batch plus the output maps would not fit in memory (checked before allocating).

    Duplicate probes and probes outside the scene bounds are baked as given, with a logged warning; a set
    of another scene (more than a tenth of it farther out than the scene's size) is refused.
    """
    pos = np.asarray(probes.pos_world, np.float32)
    if not np.isfinite(pos).all():
        raise ConfigError(f"probe positions must be finite; {int((~np.isfinite(pos)).any(-1).sum())} are not")
    if pos.shape[0] == 0:
        raise ConfigError("cannot bake an empty probe set")
    res, geo_res = map_resolutions(scene, config)
    lo, hi = scene_box(scene, dtype=None)
    far = float(2.0 * np.linalg.norm(hi - lo))

    # a set of another scene is refused before the memory check and any ray (inactive rows are padding)
    _warn_probe_layout(pos[np.asarray(probes.active)], lo, hi, "bake", scene=scene.name)
    n = pos.shape[0]
    bsz = config.probes_per_batch
    # Refuse up front (issue 9): one batch's rays (~200 bytes per path, see BakeConfig) plus the output
    # maps (radiance, emission 3 floats each, kept as NumPy and as JAX copies). Geometry maps per texel:
    # the float32 distance, the packed normal (2 × int16) and the back-face byte — 9 bytes, once (the
    # JAX arrays share the host buffers, :func:`_host_maps`), and one chunk of the moments' pass.
    need = (
        batch_ray_bytes(min(bsz, n), res, config.n_sub)
        + n * (res + 2) ** 2 * 6 * 4 * 2
        + n * (geo_res + 2) ** 2 * (4 + 4 + 1)
        + _moments_pass_bytes(n, geo_res, config.moments_res)
    )
    check_memory(
        need,
        f"bake of {n} probes at radiance_res={res}, geometry_res={geo_res}, n_sub={config.n_sub}, "
        f"probes_per_batch={bsz}",
        "lower radiance_res, geometry_res, n_sub or probes_per_batch",
    )
    # The bordered geometry maps, their interiors written batch by batch and their rings filled at the end
    # (issue 33: concatenating and bordering 9 bytes a texel took ~2 s of a 128-probe bake at 512²), and
    # the texel-centre directions, built once for a full batch.
    gb = geo_res + 2
    distance_b = _host_maps((n, gb, gb), np.float32)
    normal_b = _host_maps((n, gb, gb, 2), np.int16)
    backface_b = _host_maps((n, gb, gb), bool)
    distance, normal, backface = (a[:, 1:-1, 1:-1] for a in (distance_b, normal_b, backface_b))
    texel_dirs = _to_tiles(np.asarray(texel_directions(geo_res), np.float32))
    centre_dirs = np.tile(texel_dirs, (min(bsz, n), 1))
    parts: list[tuple] = []
    keys = jax.random.split(key, (n + bsz - 1) // bsz)
    bar = progress_bar(total=n, desc=f"bake {res}² probes", unit="probe", disable=not config.progress)
    for i, start in enumerate(range(0, n, bsz)):
        rows = slice(start, min(start + bsz, n))
        geometry, radiance = _bake_batch(
            pos[rows], caster, radiance_fn, res, geo_res, centre_dirs, config, far, keys[i]
        )
        for out, g in zip((distance, normal, backface), geometry, strict=True):
            out[rows] = _from_tiles(np.asarray(g), rows.stop - start, geo_res)
        parts.append(radiance)
        bar.update(rows.stop - start)
    bar.close()
    radiance, emission, every_lobe = (np.concatenate(x) for x in zip(*parts, strict=True))
    inside = _inside(scene, pos, geo_res, distance, far, backface, caster, config)
    if inside.any():
        log.warning(
            "%d of %d probes are inside geometry (inside_test=%s)", inside.sum(), n, config.inside_test
        )

    f32 = lambda x: jnp.asarray(x, jnp.float32)
    # Irradiance integrates what arrives at the probe from every lobe: a receiver near the probe gets the
    # surfaces' specular reflection too (a furnace's walls: −3 % of its diffuse indirect without it).
    irr = irradiance_map(f32(every_lobe), config.irradiance_res)
    mom = _chunked_moments(distance, config)
    for a in (distance_b, normal_b, backface_b):
        fill_border(a)
    return LightFieldProbes(
        pos_world=f32(pos),
        active=jnp.asarray(probes.active),
        inside=jnp.asarray(inside),
        radiance=add_border(f32(radiance)),
        emission=add_border(f32(emission)),
        normal16=jax.device_put(normal_b),
        distance=jax.device_put(distance_b),
        irradiance=add_border(irr),
        moments=add_border(mom),
        far=jnp.float32(far),
        backface=jax.device_put(backface_b),
        bake=_settings(scene, radiance_fn, res, config, key),
    )


def _host_maps(shape: tuple[int, ...], dtype) -> np.ndarray:
    """An uninitialised host array on a 64-byte boundary: ``jax.device_put`` on the CPU then shares its
    buffer instead of copying it (``jnp.asarray`` always copies, and NumPy's own large arrays sit 16 bytes
    off a boundary). Issue 33: a 1024-probe set's geometry maps at 1024² are 9.7 GB; twice would not fit
    a 24 GiB machine. Elsewhere the put is one copy, as before."""
    n = math.prod(shape) * np.dtype(dtype).itemsize
    raw = np.empty(n + 64, np.uint8)
    skip = -raw.ctypes.data % 64
    return raw[skip : skip + n].view(dtype).reshape(shape)


# Distance a moments' pass reads at once: 256 probes at 512² (1 MiB a probe; a 128-probe set in one pass,
# as before), 64 at 1024², beside the 9.7 GB maps of 1,024 probes and the lobe matrix's 1 GiB.
_MOMENTS_PASS_BYTES = 1 << 28


def _moments_pass_probes(geo_res: int) -> int:
    """Probes a moments' pass takes at geometry resolution ``geo_res``."""
    return max(1, _MOMENTS_PASS_BYTES // (geo_res * geo_res * 4))


def _moments_pass_bytes(n: int, geo_res: int, moments_res: int) -> int:
    """Peak bytes of one pass of :func:`_chunked_moments`: the pass's distances and their squares, and the
    lobe matrix with its cosine table (float32)."""
    return min(n, _moments_pass_probes(geo_res)) * geo_res**2 * 4 * 2 + moments_res**2 * geo_res**2 * 4 * 2


def _chunked_moments(distance: np.ndarray, config: BakeConfig) -> Array:
    """:func:`distance_moments` of the host maps ``distance`` (n, G, G), a pass of at most
    :data:`_MOMENTS_PASS_BYTES` at a time: the rows are independent, so the passes' results are the
    whole set's. Every pass but a shorter last one has one shape (one compiled program)."""
    step = _moments_pass_probes(distance.shape[1])
    moments = lambda d: distance_moments(jnp.asarray(d), config.moments_res, config.moment_power)
    return jnp.concatenate([moments(distance[i : i + step]) for i in range(0, len(distance), step)])


def _inside(scene, pos, res: int, distance, far: float, backface, caster, config: BakeConfig) -> np.ndarray:
    """The ``inside`` flags by ``config.inside_test`` (see :class:`BakeConfig`); ``distance`` is the
    (n, res, res) texel-centre hit distance, ``far`` where the ray escapes."""
    if config.inside_test == "none":
        return np.zeros(len(pos), bool)
    if config.inside_test == "reach":
        cams = np.asarray([np.asarray(c.position, np.float64) for c in scene.views]).reshape(-1, 3)
        # as many rays as an inside_res² map (every k-th texel per axis): the chance to find a crack must
        # not grow with the geometry maps' resolution (BakeConfig.inside_res)
        k = max(1, res // config.inside_res)
        dirs = np.asarray(texel_directions(res), np.float64)[::k, ::k].reshape(-1, 3)
        hit_t = distance.reshape(len(pos), res, res)[:, ::k, ::k]
        hit_t = np.where(hit_t < far, hit_t, np.inf)
        inside = probes_inside(
            pos, dirs, hit_t.reshape(len(pos), -1), cams, caster, neighbours=config.inside_neighbours
        )
        if inside is not None:
            return inside
        log.warning(
            "inside test: no probe escapes the scene or sees a view camera (a closed scene without "
            "views?), so nothing tells free space from solid; falling back to the back-face test, "
            "which trusts the triangles' winding"
        )
    share = backface.reshape(len(pos), -1).mean(axis=1)
    return share > config.inside_backface_share


def _settings(scene: Scene, radiance_fn, res: int, config: BakeConfig, key) -> BakeSettings:
    i32 = lambda v: jnp.asarray(v, jnp.int32)
    k = jnp.asarray(key)
    words = jax.random.key_data(k) if jnp.issubdtype(k.dtype, jax.dtypes.prng_key) else k
    common = dict(
        n_sub=i32(config.n_sub),
        radiance_res=i32(res),
        key=jnp.asarray(words, jnp.uint32).reshape(-1),
        texel_rays=config.texel_rays,
    )
    if isinstance(radiance_fn, PathTracedRadiance):
        return BakeSettings(
            path_depth=i32(radiance_fn.max_depth),
            spp=i32(radiance_fn.spp),
            specular=jnp.asarray(radiance_fn.specular, jnp.float32),
            scene=scene.name,
            radiance="path_traced",
            first_hit_lobes=radiance_fn.first_hit_lobes,
            backend=radiance_fn.backend,
            **common,
        )
    return BakeSettings(
        path_depth=i32(-1),
        spp=i32(-1),
        specular=jnp.asarray(jnp.nan, jnp.float32),
        scene=scene.name,
        radiance="custom",
        **common,
    )


def check_probe_scene(
    recorded: str, evaluated: str, *, made: str, fix: str, what: str = "the probes"
) -> None:
    """Refuse probes made in another scene than the one they are evaluated in: the scene a baked ``.npz``
    records (:func:`check_bake_settings`) and the one a ProbeSet file records (``probeplace evaluate``).

    Raises:
        ConfigError: ``recorded != evaluated``; one line naming both and ``fix``.
    """
    if recorded != evaluated:
        raise ConfigError(
            f"{what} were {made} in scene {recorded!r} but are evaluated in {evaluated!r}; {fix}"
        )


def check_bake_settings(
    lf: LightFieldProbes, *, scene_name: str, eval_max_depth: int, specular: float = 1.0
) -> None:
    """Refuse probes whose bake does not match the evaluation they are about to be used in.

    Checks, in order: the probes carry settings (files saved before settings were recorded, and probes
    built by hand, do not), the scene name, the path depth (:func:`bake_depth_for`), the specular factor.
    Probes baked with a custom radiance function have no depth or specular factor to check.

    Args:
        lf: the probes.
        scene_name: the evaluated scene's name.
        eval_max_depth: the evaluation's camera path depth D (segments).
        specular: the evaluation's dielectric specular factor (the evaluation renders with 1).

    Raises:
        ConfigError: a mismatch or missing settings; one line naming both values and the fix.
    """
    b = lf.bake
    if b is None:
        raise ConfigError(
            "the probes carry no bake settings: the file predates recorded bake settings (or the probes were "
            "built by hand), so their path depth is unknown; re-bake them (probeplace evaluate --probes "
            "<ProbeSet .json> --save-baked <file.npz>, or probes.bake_probes)"
        )
    if b.version > BAKE_SETTINGS_VERSION:
        raise ConfigError(
            f"the probes' bake settings are version {b.version}, newer than this probeplace reads "
            f"({BAKE_SETTINGS_VERSION}); update probeplace"
        )
    fix = f"evaluate them in {b.scene!r} or bake the probe set in {scene_name!r}"
    check_probe_scene(b.scene, scene_name, made="baked", fix=fix)
    if b.radiance != "path_traced":
        return
    want = bake_depth_for(eval_max_depth)
    got = int(b.path_depth)
    if got != want:
        raise ConfigError(
            f"the probes were baked with path depth {got} but evaluation max_depth={eval_max_depth} needs "
            f"{want} (= max_depth − 1: a texel replaces the rest of a camera path); re-bake with "
            f"--max-depth {eval_max_depth} (experiment: tracer.max_depth) or evaluate with "
            f"--max-depth {got + 1}"
        )
    if not math.isclose(float(b.specular), float(specular), abs_tol=1e-6):
        raise ConfigError(
            f"the probes were baked with specular={float(b.specular):g} but the evaluation renders "
            f"specular={float(specular):g}; re-bake with path_traced_radiance(specular={float(specular):g})"
        )
