"""A scene's views and lights, checked before anything is rendered (issue 31).

A view camera inside solid geometry renders black, and so does a view that no light reaches; both used to
be found only after minutes of baking and rendering. These checks run after the scene is loaded and
before any bake or render (``probeplace evaluate``; :func:`check_views_and_lights` for other callers), on
an Embree caster of the host and a few thousand rays: well under a second for the built-in scenes.

* **Cameras** (refused): a camera from which no ray escapes and most first hits are back faces
  (``probes._inside.points_in_solid``). Refused for the rendered view and for every camera a config layer
  sets (sidecar, ``--camera``, ``KNOWN_SCENES``: a mistake in a file the user wrote); a file's own or a
  derived view elsewhere is only warned about.
* **Lights** (warned): the share of the surface points the views see (pixel-centre rays) that each light
  reaches directly: the sun by a shadow ray toward it, the sky by a few rays over the hemisphere, the
  emitters by shadow rays to points on them. A light that reaches none of them gives the images nothing
  but what bounces in from surfaces no view sees, which in a closed room is nothing at all.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from .._core import ConfigError, Scene

log = logging.getLogger(__name__)

#: Pixel-centre rays per image side and view for the light reach (24² × 4 views ≈ 2.3k points).
VIEW_RES = 24
#: Sky rays per seen point (a Fibonacci sphere folded onto its hemisphere), and the points on emitters
#: it sends a shadow ray to: a few thousand rays in all.
SKY_RAYS = 8
EMITTER_RAYS = 4


def host_caster(scene: Scene):
    """The checks' caster: Embree, built directly rather than by ``geometry.make_caster`` (whose pick for a
    renderer is the JAX brute-force caster on small scenes: a compile; and which the tests' ``no_slow_work``
    fixture blocks as the start of slow work), or ``None`` without embreex (the checks are then skipped).
    Building Embree's BVH takes milliseconds here, and its host queries run no JAX op."""
    from ..geometry import EmbreeCaster, EmbreeUnavailableError

    try:
        return EmbreeCaster(scene)
    except EmbreeUnavailableError:
        log.info("embreex is not available: the view and light checks are skipped")
        return None


def _fmt(v) -> str:
    return "[" + ", ".join(f"{float(x):.4g}" for x in np.asarray(v).reshape(-1)) + "]"


def check_view_cameras(scene: Scene, caster, layers=(), scene_file=None, view: str | None = None) -> None:
    """Refuse a camera inside solid geometry (module docstring).

    Args:
        scene: the loaded scene.
        caster: an exact caster of it.
        layers: its config layers (``scene.scene_layers``), to name the file a camera is from.
        scene_file: the scene file (``None``: a built-in), for cameras no layer sets.
        view: the view about to be rendered (``None``: none in particular).

    Raises:
        ConfigError: one line naming the sidecar (or file), the camera, its position and the fix.
    """
    from ..probes import BakeConfig, points_in_solid
    from ..scene import camera_origin

    if not scene.views:
        return
    pos = np.stack([np.asarray(c.position, np.float64) for c in scene.views])
    inside, share = points_in_solid(caster, scene, pos, backface_share=BakeConfig.inside_backface_share)
    for cam, bad, sh in zip(scene.views, inside, share, strict=True):
        if not bad:
            continue
        origin = camera_origin(layers, cam.name)
        why = f"is inside solid geometry (no ray from it escapes and {sh:.0%} of them hit a back face)"
        if origin is not None:
            source, spec = origin
            raise ConfigError(
                f"{source}: cameras.{cam.name}: position {_fmt(spec.position)} {why}; its images would be "
                "black: move position into free space (units and axes of the scene file)"
            )
        where = f"{scene_file or scene.name}: view {cam.name!r} at {_fmt(cam.position)} {why}"
        if cam.name == view:
            raise ConfigError(
                f"{where}; its images would be black: evaluate another --view, or give it a position in free "
                f"space in the scene's sidecar (cameras: {{{cam.name}: {{position: ..., look_at: ...}}}})"
            )
        log.warning("%s; do not render it", where)


def _pixel_rays(cam, res: int) -> tuple[np.ndarray, np.ndarray]:
    """(origins, unit directions) through the ``res``² pixel centres of a square image: the renderer's
    pinhole (``render._camera``), in NumPy, since these checks run before anything compiles."""
    pos, look, up = (np.asarray(x, np.float64) for x in (cam.position, cam.look_at, cam.up))
    fwd = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    tan = math.tan(0.5 * math.radians(float(cam.fov_y_deg)))
    c = ((np.arange(res) + 0.5) * 2.0 / res - 1.0) * tan
    x, y = np.meshgrid(c, -c)
    d = fwd + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    return np.broadcast_to(pos, d.shape), d / np.linalg.norm(d, axis=1, keepdims=True)


def _first_hits(scene: Scene, caster, res: int) -> tuple[np.ndarray, np.ndarray]:
    """(points, unit normals facing the viewer) of the pixel-centre rays of every view that hit."""
    from ..probes import face_normals, host_closest_hit

    ng = face_normals(scene)
    ng /= np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-300)
    pts, nrm = [], []
    for cam in scene.views:
        o, d = _pixel_rays(cam, res)
        t, tri = host_closest_hit(caster, o, d)
        ok = tri >= 0
        n = ng[tri[ok]]
        pts.append(o[ok] + t[ok, None] * d[ok])
        nrm.append(n * -np.sign(np.sum(n * d[ok], axis=1, keepdims=True) + 1e-30))  # the side seen
    return np.concatenate(pts), np.concatenate(nrm)


def _clear(caster, origins, dirs, t_max) -> np.ndarray:
    """Whether each ray reaches ``t_max`` unblocked (a host query: NumPy in and out)."""
    t = np.broadcast_to(np.asarray(t_max, np.float64), (len(origins),))
    return ~np.asarray(caster.occluded_host(origins, dirs, t), bool)


def light_reach(scene: Scene, caster, *, res: int = VIEW_RES) -> tuple[int, dict[str, int]]:
    """How many of the surface points the views see each light reaches directly (module docstring).

    Returns:
        (points, {light: points reached}) for the lights the scene has: ``"sun"``, ``"sky"``, ``"emitters"``.
    """
    from ..placement import fibonacci_directions

    p, n = _first_hits(scene, caster, res)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    p = p + 1e-4 * float(np.linalg.norm(hi - lo)) * n  # off the surface, on the viewer's side
    reach: dict[str, int] = {}
    if len(p) == 0:
        return 0, reach
    if scene.sun is not None:
        s = np.asarray(scene.sun.direction, np.float64)
        facing = n @ s > 0
        reach["sun"] = int((facing & _clear(caster, p, np.broadcast_to(s, p.shape), np.inf)).sum())
    if float(np.max(np.asarray(scene.sky_radiance))) > 0:
        f = fibonacci_directions(SKY_RAYS).astype(np.float64)  # folded onto each point's hemisphere
        d = f[None] * np.sign(np.einsum("kc,nc->nk", f, n) + 1e-30)[..., None]
        esc = _clear(caster, np.repeat(p, len(f), axis=0), d.reshape(-1, 3), np.inf)
        reach["sky"] = int(esc.reshape(len(p), -1).any(axis=1).sum())
    if scene.emissive_tris.shape[0] > 0:
        tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)[np.asarray(scene.emissive_tris)]]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = np.linalg.norm(cross, axis=1)
        rng = np.random.default_rng(0)  # a fixed sample: the check says the same thing on every run
        k = rng.choice(len(tri), size=(len(p), EMITTER_RAYS), p=area / area.sum())
        a, b = rng.random((2, len(p), EMITTER_RAYS, 1))
        a, b = np.where(a + b > 1, 1 - a, a), np.where(a + b > 1, 1 - b, b)
        q = tri[k, 0] + a * (tri[k, 1] - tri[k, 0]) + b * (tri[k, 2] - tri[k, 0])
        w = q - p[:, None]
        dist = np.linalg.norm(w, axis=-1)
        w = w / np.maximum(dist, 1e-30)[..., None]
        # emitters shine from their front face only (render._lights)
        front = (np.einsum("nkc,nkc->nk", cross[k], w) < 0) & (np.einsum("nc,nkc->nk", n, w) > 0)
        clear = _clear(caster, np.repeat(p, EMITTER_RAYS, axis=0), w.reshape(-1, 3), (dist * 0.999).ravel())
        reach["emitters"] = int((front & clear.reshape(len(p), -1)).any(axis=1).sum())
    return len(p), reach


def warn_unreached_lights(scene: Scene, caster, scene_file=None) -> dict[str, int]:
    """Warn, naming the figure and the sidecar keys to change, for each light that reaches none of the
    surface points the views see (:func:`light_reach`); returns the reach."""
    from ..scene import sidecar_path

    total, reach = light_reach(scene, caster)
    where = (
        f"in {sidecar_path(scene_file).name}" if scene_file is not None else "with --sun / --sky (overrides)"
    )
    views = ", ".join(c.name for c in scene.views)
    for light, n in reach.items():
        if n or not total:
            continue
        if light == "sun":
            el = math.degrees(math.asin(float(np.clip(np.asarray(scene.sun.direction)[1], -1, 1))))
            below = ", below the horizon" if el < 0 else ""
            fix = f"raise sun.elevation or turn sun.azimuth toward an opening {where}, or add sky / emitters"
            what = f"the sun (elevation {el:.0f}°{below})"
        elif light == "sky":
            fix = f"add a sun through an opening or emitters {where}"
            what = "the sky"
        else:
            fix = f"add emitters the views see, a sun or a sky {where}"
            what = "the emitters"
        log.warning(
            "%s: %s reaches 0 of the %d surface points the views (%s) see: it lights them only through "
            "bounces off surfaces no view sees, which in a closed room is nothing; %s",
            scene.name,
            what,
            total,
            views,
            fix,
        )
    return reach


def check_views_and_lights(
    scene: Scene, name_or_path, overrides=None, *, view: str | None = None, caster=None
) -> None:
    """Both checks of the module docstring for a scene loaded by ``load_scene(name_or_path, overrides=...)``
    (an Embree caster of its own unless ``caster`` is given).

    Raises:
        ConfigError: a camera inside solid geometry (:func:`check_view_cameras`).
    """
    from ..scene import scene_layers

    caster = caster if caster is not None else host_caster(scene)
    if caster is None:
        return
    scene_file, layers = scene_layers(name_or_path, overrides)
    check_view_cameras(scene, caster, layers, scene_file, view=view)
    warn_unreached_lights(scene, caster, scene_file)
