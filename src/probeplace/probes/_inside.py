"""Winding-independent "inside geometry" test for baked probes (``probes._bake`` module docstring).

A probe is *inside* when it cannot reach the free space the scene is viewed from. This is the exterior
flood fill of mesh repair (Ju 2004, "Robust repair of polygonal models", SIGGRAPH: inside/outside from
reachability of the exterior, valid for open, non-manifold and inconsistently oriented meshes), run on
the probes' own rays instead of a voxel grid, with the scene's views as extra seeds (a closed room that
is viewed from inside is free space). Triangle winding is never read.

* Each viewpoint (probe or camera) owns *waypoints*: points at ½ and 9/10 of the way along its
  texel-centre rays to their first hits — points of its own free space ("star" region).
* Two probes are linked when one has a clear line of sight to the other or to one of its waypoints:
  their star regions meet, so they share a free-space region. Each probe tests its ``neighbours``
  nearest probes. Mid-room waypoints are seen from most of a room, which links even sparse probe sets.
* Seeds: a probe with an escaping texel ray (it sees the sky or the outside through an opening), or a
  clear line of sight to a view camera or one of the camera's waypoints.
* A probe is inside when its linked group holds no seed. Inside a closed solid a probe sees only that
  solid's inner walls: no sky, no camera, no other probe's free space.

Cameras (:func:`points_in_solid`): the reach test takes the views as its seeds of free space, so it
cannot judge a view camera itself. A camera is judged by the winding instead, as the bake's ``backface``
test judges probes: from inside a closed solid every ray hits the solid's inner side. Only a point from
which no ray escapes is judged, so an open scene, or a shell seen from outside, never counts as solid.

Limits: a probe in free space that is sealed off from every view and from the sky (a closed void, a
sealed room without a camera) counts as inside; so does a free probe that sees neither the sky, a
camera, nor any reached probe (a very sparse set in a maze of rooms). A probe inside a solid that leaks
(a crack its texel rays or sight lines find) counts as free.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np


def _segments_clear(caster, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether each segment a→b is free of geometry (zero-length segments are)."""
    v = b - a
    length = np.linalg.norm(v, axis=-1)
    ok = length > 0
    clear = np.ones(len(a), bool)
    if ok.any():
        d = v[ok] / length[ok, None]
        a32, d32, t32 = (x.astype(np.float32) for x in (a[ok], d, length[ok]))
        clear[ok] = ~caster.occluded_host(a32, d32, t32)
    return clear


def _waypoints(origin: np.ndarray, dirs: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(w, 3) points of one viewpoint's free space: itself and ½, 9/10 of each finite ray (see module)."""
    fin = np.isfinite(t)
    d, tt = dirs[fin], t[fin, None]
    return np.concatenate([origin[None], origin + 0.5 * tt * d, origin + 0.9 * tt * d])


def probes_inside(
    pos: np.ndarray,
    dirs: np.ndarray,
    hit_t: np.ndarray,
    cameras: np.ndarray,
    caster,
    *,
    neighbours: int = 16,
    n_waypoints: int = 32,
) -> np.ndarray | None:
    """Winding-independent "inside geometry" test (module docstring).

    Args:
        pos: (n, 3) probe positions.
        dirs: (m, 3) unit ray directions shared by every probe (the texel centres).
        hit_t: (n, m) first-hit distance of each probe's rays; ``inf`` where a ray escapes.
        cameras: (c, 3) view camera positions (c may be 0).
        caster: an exact ray caster (its ``closest_hit`` and ``occluded`` queries).
        neighbours: probes each probe tests for a link.
        n_waypoints: rays per viewpoint that carry waypoints (a low-discrepancy subset of ``dirs``).

    Returns:
        (n,) bool, True = inside; ``None`` when nothing seeds free space (no escaping ray and no probe
        in sight of a camera or its waypoints: e.g. a closed scene without views), where this test
        cannot decide.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pos = np.asarray(pos, np.float64)
    dirs = np.asarray(dirs, np.float64)
    hit_t = np.asarray(hit_t, np.float64)
    n, m = hit_t.shape
    # a golden-ratio (low-discrepancy) subset of the rays: spread over the sphere whatever their order
    pick = np.unique((np.arange(min(n_waypoints, m)) * 0.6180339887498949 * m).astype(np.int64) % m)
    seed = ~np.isfinite(hit_t).all(axis=1)

    def sees_any(i: np.ndarray, points: list[np.ndarray]) -> np.ndarray:
        """For pairs (probe i[k], point set points[k]): whether the probe sees any of the points."""
        counts = np.array([len(p) for p in points])
        a = np.repeat(pos[i], counts, axis=0)
        clear = _segments_clear(caster, a, np.concatenate(points))
        owner = np.repeat(np.arange(len(i)), counts)
        return np.bincount(owner[clear], minlength=len(i)) > 0

    cams = np.asarray(cameras, np.float64).reshape(-1, 3)
    if len(cams):
        o = np.repeat(cams, len(pick), axis=0)
        h = caster.closest_hit(
            jnp.asarray(o, jnp.float32), jnp.asarray(np.tile(dirs[pick], (len(cams), 1)), jnp.float32)
        )
        t_cam = np.where(np.asarray(h.tri) >= 0, np.asarray(h.t, np.float64), np.inf).reshape(len(cams), -1)
        cam_wp = np.concatenate([_waypoints(c, dirs[pick], t) for c, t in zip(cams, t_cam, strict=True)])
        todo = np.flatnonzero(~seed)
        if len(todo):
            seed[todo] = sees_any(todo, [cam_wp] * len(todo))
    if not seed.any():
        return None
    k = min(neighbours, n - 1)
    if k < 1:
        return ~seed
    _, nb = cKDTree(pos).query(pos, k=k + 1)
    i = np.repeat(np.arange(n), k)
    j = np.asarray(nb)[:, 1:].reshape(-1)
    wp = [_waypoints(pos[q], dirs[pick], hit_t[q, pick]) for q in range(n)]
    linked = sees_any(i, [wp[q] for q in j])
    graph = coo_matrix((np.ones(int(linked.sum())), (i[linked], j[linked])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    return ~np.isin(label, label[seed])


def host_closest_hit(caster, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, triangle) of each ray's closest hit as NumPy arrays (``inf``, -1 on a miss). An Embree caster
    answers through its own host query, with no JAX op: the scene checks that use this run before
    anything compiles (``evaluate._scene_checks``); any other caster through ``closest_hit``."""
    from ..geometry import EmbreeCaster

    if isinstance(caster, EmbreeCaster):
        return caster.host_closest_hit(origins, dirs)
    hit = caster.closest_hit(jnp.asarray(origins, jnp.float32), jnp.asarray(dirs, jnp.float32))
    tri = np.asarray(hit.tri, np.int64)
    return np.where(tri >= 0, np.asarray(hit.t, np.float64), np.inf), tri


def face_normals(scene) -> np.ndarray:
    """(n_tri, 3) unnormalised front-face normals (counter-clockwise winding), NumPy."""
    v = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
    return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])


def points_in_solid(
    caster, scene, points: np.ndarray, *, n_dirs: int = 64, backface_share: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Whether each point is inside a closed solid of ``scene``, by the winding (module docstring,
    "Cameras"): none of its ``n_dirs`` rays (a Fibonacci sphere) escapes and more than ``backface_share``
    of their first hits are back faces (the bake's ``backface`` rule, ``BakeConfig.inside_backface_share``).

    Returns:
        ((n,) bool inside, (n,) float share of the rays that hit a back face).
    """
    from ..placement import fibonacci_directions

    pts = np.asarray(points, np.float64).reshape(-1, 3)
    dirs = fibonacci_directions(n_dirs).astype(np.float64)
    o = np.repeat(pts, n_dirs, axis=0)
    d = np.tile(dirs, (len(pts), 1))
    _, tri = host_closest_hit(caster, o, d)
    hit = tri >= 0
    back = hit & (np.sum(face_normals(scene)[np.maximum(tri, 0)] * d, axis=1) > 0)
    share = back.reshape(-1, n_dirs).mean(axis=1)
    return hit.reshape(-1, n_dirs).all(axis=1) & (share > backface_share), share
