"""A simple, slow NumPy float64 reference of the single-probe light-field trace (McGuire et al. 2017 §4.1),
standing alone: it shares no step code with the two engines (``_march``, ``_surfels``, ``_trace``,
``_wavefront``), so a bug in a step they share shows as a disagreement with it
(``tests/probes/test_trace_simple.py``).

It reads the probe's geometry map as McGuire's radial-distance field alone — the nearest texel's stored
distance, no surfel planes, cells, bounds or hierarchy — and marches the ray in small uniform steps in t.
Exact where the stored distance is (a texel's centre); elsewhere off by what a texel can hide, which is
what a test's tolerance must allow (the test argues it from the texel's angular size).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..._core import strip_border
from ._status import TraceStatus

#: Bisection steps refining a crossing: the bracket, a step of at most a texel's footprint, ends below
#: 2^-50 of it (float64 rounding of t).
_BISECTIONS = 50


def _oct_encode(w: np.ndarray) -> np.ndarray:
    """Unit direction(s) → octahedral uv ∈ [−1, 1]²: a NumPy copy of ``_core.oct_encode`` (Cigolle et al.
    2014, Listing 6): the march runs in NumPy float64 throughout."""
    p = w[..., :2] / np.sum(np.abs(w), axis=-1, keepdims=True)
    folded = (1.0 - np.abs(p[..., ::-1])) * np.where(p >= 0, 1.0, -1.0)
    return np.where(w[..., 2:3] < 0, folded, p)


def _oct_decode(uv: np.ndarray) -> np.ndarray:
    """Octahedral uv → unit direction: a NumPy copy of ``_core.oct_decode``."""
    u, v = uv[..., 0], uv[..., 1]
    z = 1.0 - np.abs(u) - np.abs(v)
    x = np.where(z < 0, (1.0 - np.abs(v)) * np.where(u >= 0, 1.0, -1.0), u)
    y = np.where(z < 0, (1.0 - np.abs(u)) * np.where(v >= 0, 1.0, -1.0), v)
    q = np.stack([x, y, z], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


@functools.cache
def min_texel_angle(res: int) -> float:
    """The smallest angle (radians) between the centres of two neighbouring texels of a ``res``² map:
    a step turning the ray's direction seen from the probe by a fraction of it skips no texel."""
    c = (np.arange(res) + 0.5) * (2.0 / res) - 1.0
    vv, uu = np.meshgrid(c, c, indexing="ij")  # row ↔ v, column ↔ u (``_core.texel_uv``)
    w = _oct_decode(np.stack([uu, vv], axis=-1))
    cos = np.concatenate([np.sum(w[1:] * w[:-1], -1).ravel(), np.sum(w[:, 1:] * w[:, :-1], -1).ravel()])
    return float(np.arccos(np.clip(cos, -1.0, 1.0)).min())


def trace_probe_simple(
    lf,
    probe: int,
    origin,
    direction,
    t_max: int | float,
    *,
    step: int | float | None = None,
    thickness: int | float = 0.015,
) -> tuple[TraceStatus, float]:
    """Single-probe trace of ONE ray over [0, ``t_max``] through probe ``probe`` of ``lf``
    (``LightFieldProbes``), McGuire 2017 §4.1 in its plainest form.

    Seen from the probe at p, the ray's point x is *in front* of the stored surface while
    |x − p| < r, r the distance stored in the texel of x's direction (nearest texel, border stripped; a
    texel whose bake ray escaped, distance ≈ ``far``, holds no surface: r = ∞). The ray is sampled every
    ``step`` in t. At the first sample *behind* (|x − p| ≥ r) the crossing is refined by bisection
    between it and the sample before; at the behind end of the bracket the stored surface point
    p + r·ω lies on x's line of sight, |x − p| − r behind x:

    * within ``thickness``·r (McGuire's surface thickness, relative to the distance; 1.5 % as the
      tracer's default): the ray reached the surface the probe sees — HIT at that t;
    * farther: the ray crossed a jump of the stored distance, i.e. went behind something nearer the probe
      (an occluder's silhouette) — UNKNOWN, the probe cannot tell what lies there; t is the last point
      seen free (the front end of the bracket). A ray whose origin the probe does not see: UNKNOWN at 0;
    * no sample behind up to ``t_max`` (pass where the ray leaves the scene's box: nothing lies beyond):
      MISS at ``t_max``.

    Limits of the model, not of the march: distances alone cannot tell a plane seen obliquely, whose stored
    distance jumps by ≈ r·tan θ·(a texel's angle) between neighbouring texels, from an occluder's edge, so
    a crossing at such a jump beyond the thickness is UNKNOWN too; and a texel's centre sample stands for
    the whole texel, so a hit lies off the true surface by up to r × the texel's angular radius — far off
    in t along a ray that meets the surface at a grazing angle (or runs close beside it).

    Step (default): a quarter of the smallest angle between neighbouring texel centres
    (:func:`min_texel_angle`) times max(ρ, r_min) — ρ the ray's closest approach to the probe, r_min the
    nearest stored surface. Where |x − p| < r_min every texel is in front, and elsewhere the direction seen
    from the probe turns at most about a quarter texel a step: no texel is stepped over, only a sliver
    cut off a texel's corner can be. The radial distance moves at most a step, and within one texel
    |x − p| is convex in t, so there the ray passes behind once and stays.

    Returns:
        (``TraceStatus`` MISS / HIT / UNKNOWN, t).
    """
    dist = np.asarray(strip_border(lf.distance[probe][..., None]), np.float64)[..., 0]
    res = dist.shape[0]
    r_map = np.where(dist < 0.999 * float(lf.far), dist, np.inf)  # the tracer's own no-surface cut
    p = np.asarray(lf.pos_world, np.float64)[probe]
    o = np.asarray(origin, np.float64)
    d = np.asarray(direction, np.float64)
    d = d / np.linalg.norm(d)
    t_max = float(t_max)
    if not np.isfinite(r_map).any():
        return TraceStatus.MISS, t_max
    if step is None:
        t_close = min(max(float(np.dot(p - o, d)), 0.0), t_max)
        rho = float(np.linalg.norm(o + t_close * d - p))
        step = 0.25 * min_texel_angle(res) * max(rho, float(r_map.min()))

    def behind(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(|x − p| − r, r) at the ray's points ``t`` (1-D)."""
        rel = o + t[..., None] * d - p
        rad = np.linalg.norm(rel, axis=-1)
        # x = p: any direction will do (+z), radius 0 is in front of every surface
        w = np.where(rad[..., None] > 0, rel / np.maximum(rad, 1e-300)[..., None], [0.0, 0.0, 1.0])
        ij = np.clip(np.floor((_oct_encode(w) + 1.0) * (res / 2.0)), 0, res - 1).astype(np.int64)
        r = r_map[ij[..., 1], ij[..., 0]]  # row ↔ v, column ↔ u
        return rad - r, r

    t = np.append(np.arange(math.ceil(t_max / step)) * step, t_max)
    k = np.flatnonzero(behind(t)[0] >= 0)
    if len(k) == 0:
        return TraceStatus.MISS, t_max
    if k[0] == 0:
        return TraceStatus.UNKNOWN, 0.0
    ta, tb = float(t[k[0] - 1]), float(t[k[0]])
    for _ in range(_BISECTIONS):
        tm = 0.5 * (ta + tb)
        if behind(np.array([tm]))[0][0] >= 0:
            tb = tm
        else:
            ta = tm
    gap, r = behind(np.array([tb]))
    if gap[0] <= thickness * r[0]:
        return TraceStatus.HIT, tb
    return TraceStatus.UNKNOWN, ta
