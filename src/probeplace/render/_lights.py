"""Light sampling for next-event estimation: emissive triangles and the sun disk.

Area lights are the scene's emissive triangles, **one-sided** (they emit on the front face, the side
the counter-clockwise winding's normal points to). A light sample first picks area lights or the sun
(probability ``p_area``), then, for area lights, a triangle with probability ∝ area × luminance of its
radiance (∝ emitted power) and a uniform point on it. The sun is a disk of constant radiance with the
scene's angular radius, sampled uniformly in its cone. The sky is not light-sampled: it is constant,
and cosine/GGX sampling of the BRDF already matches it well.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float, Int

from .._core import ConfigError, Scene, luminance
from ._sampling import dot3, make_frame, sample_cone, sample_triangle, to_world


class LightTable(eqx.Module):
    """Precomputed light-sampling tables of one scene (build with :func:`light_table`).

    Attributes:
        v0, e1, e2: emissive triangles as a corner and two edges, world frame (n_emit ≥ 1: a scene
            without area lights gets one zero-power dummy row that is never chosen).
        normal: unit front normals of the emissive triangles.
        radiance: emitted radiance per emissive triangle.
        cdf: cumulative triangle-choice probabilities (last = 1).
        pdf_area_of_tri: per *scene* triangle, p_area · P(triangle) / area: the area density of
            sampling a point there (0 for non-emitters); for MIS of BRDF-sampled hits.
        p_area: probability of sampling area lights (vs the sun).
        sun_dir, sun_radiance: unit direction toward the sun and its disk radiance (zeros: no sun).
        sun_h: 1 − cos(angular radius) of the sun's cone.
    """

    v0: Float[Array, "n_emit 3"]
    e1: Float[Array, "n_emit 3"]
    e2: Float[Array, "n_emit 3"]
    normal: Float[Array, "n_emit 3"]
    radiance: Float[Array, "n_emit 3"]
    cdf: Float[Array, " n_emit"]
    pdf_area_of_tri: Float[Array, " n_tri"]
    p_area: Float[Array, ""]
    sun_dir: Float[Array, "3"]
    sun_radiance: Float[Array, "3"]
    sun_h: Float[Array, ""]


def light_table(scene: Scene) -> LightTable:
    """Light-sampling tables for ``scene`` (host-side numpy; call once per scene).

    If the scene has both area lights and a sun, each light sample picks either with probability ½.

    Raises:
        ConfigError: a sun with a non-positive angular radius (a delta light has no radiance to sample).
    """
    tris = np.asarray(scene.triangles, np.float64)
    emit = np.asarray(scene.emissive_tris)
    mats = np.asarray(scene.tri_material)
    emission = np.asarray(scene.materials.emission, np.float64)
    n_tri = tris.shape[0]
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    if emit.size:
        rad = emission[mats[emit]]
        power = area[emit] * np.asarray(luminance(jnp.asarray(rad)))
        if not power.sum() > 0:  # emission so dim its luminance is 0: fall back to area
            power = area[emit].copy()
        pmf = power / power.sum()
    else:
        emit = np.zeros(1, np.int64)
        rad = np.zeros((1, 3))
        pmf = np.zeros(1)
    has_area = bool(pmf.sum() > 0)
    has_sun = scene.sun is not None
    if has_sun:
        r = float(scene.sun.angular_radius)
        if not r > 0:
            raise ConfigError(f"sun.angular_radius must be > 0 radians to be sampled, got {r}")
        sun_h = 2.0 * np.sin(0.5 * r) ** 2  # 1 − cos r without cancellation
        sun_dir = np.asarray(scene.sun.direction, np.float64)
        sun_rad = np.asarray(scene.sun.radiance, np.float64)
    else:
        sun_h, sun_dir, sun_rad = 0.0, np.array([0.0, 0.0, 1.0]), np.zeros(3)
    p_area = 0.5 if (has_area and has_sun) else (1.0 if has_area else 0.0)
    pdf_area = np.zeros(n_tri)
    ok = area[emit] > 0
    pdf_area[emit[ok]] = p_area * pmf[ok] / area[emit][ok]
    t = tris[emit]
    normal = cross[emit] / np.maximum(np.linalg.norm(cross[emit], axis=1, keepdims=True), 1e-300)
    f32 = lambda x: jnp.asarray(np.asarray(x, np.float32))
    return LightTable(
        v0=f32(t[:, 0]),
        e1=f32(t[:, 1] - t[:, 0]),
        e2=f32(t[:, 2] - t[:, 0]),
        normal=f32(normal),
        radiance=f32(rad),
        cdf=f32(np.minimum(np.cumsum(pmf), 1.0)),
        pdf_area_of_tri=f32(pdf_area),
        p_area=f32(p_area),
        sun_dir=f32(sun_dir),
        sun_radiance=f32(sun_rad),
        sun_h=f32(sun_h),
    )


class LightSample(eqx.Module):
    """A light sample seen from a shading point.

    Attributes:
        wi: unit direction from the shading point toward the light.
        dist: distance to the sampled point (inf for the sun).
        radiance: emitted radiance arriving along ``-wi`` (0 if the back of a one-sided emitter faces us).
        pdf: solid-angle density of having sampled ``wi`` (light choice included).
    """

    wi: Float[Array, "3"]
    dist: Float[Array, ""]
    radiance: Float[Array, "3"]
    pdf: Float[Array, ""]


def sample_light(lights: LightTable, x: Float[Array, "3"], u: Float[Array, "4"]) -> LightSample:
    """Sample a light direction from point ``x`` with uniforms u = (light type, triangle, point₀, point₁)."""
    use_area = u[0] < lights.p_area
    # --- area light: triangle by the power CDF, uniform point, area → solid-angle density
    k = jnp.minimum(jnp.searchsorted(lights.cdf, u[1], side="right"), lights.cdf.shape[0] - 1)
    b = sample_triangle(u[2:4])
    y = lights.v0[k] + b[1] * lights.e1[k] + b[2] * lights.e2[k]
    d = y - x
    dist2 = dot3(d, d)
    dist = jnp.sqrt(dist2)
    wi_a = d / jnp.where(dist > 0, dist, 1.0)
    cos_l = -dot3(lights.normal[k], wi_a)
    area2 = jnp.linalg.norm(jnp.cross(lights.e1[k], lights.e2[k]))
    prob_k = lights.cdf[k] - jnp.where(k > 0, lights.cdf[jnp.maximum(k - 1, 0)], 0.0)
    ok_a = (cos_l > 0) & (dist > 0) & (area2 > 0) & (prob_k > 0)
    pdf_a = jnp.where(ok_a, lights.p_area * prob_k * 2.0 * dist2 / jnp.where(ok_a, area2 * cos_l, 1.0), 0.0)
    # --- sun: uniform in its cone
    t, bt = make_frame(lights.sun_dir)
    wi_s = to_world(sample_cone(u[2:4], lights.sun_h), t, bt, lights.sun_dir)
    ok_s = lights.sun_h > 0
    pdf_s = jnp.where(ok_s, (1.0 - lights.p_area) / (2.0 * jnp.pi * jnp.where(ok_s, lights.sun_h, 1.0)), 0.0)
    rad_a = jnp.where(ok_a, lights.radiance[k], 0.0)
    return LightSample(
        wi=jnp.where(use_area, wi_a, wi_s),
        dist=jnp.where(use_area, dist, jnp.inf),
        radiance=jnp.where(use_area, rad_a, lights.sun_radiance),
        pdf=jnp.where(use_area, pdf_a, pdf_s),
    )


def area_light_pdf(
    lights: LightTable,
    tri: Int[Array, ""],
    dist: Float[Array, ""],
    cos_light: Float[Array, ""],
) -> Float[Array, ""]:
    """Solid-angle density with which :func:`sample_light` picks a point on scene triangle ``tri`` seen
    at distance ``dist`` under cosine ``cos_light`` (emitter side); 0 for non-emitters or back faces."""
    pa = lights.pdf_area_of_tri[jnp.maximum(tri, 0)]
    ok = (tri >= 0) & (cos_light > 0) & (pa > 0)
    return jnp.where(ok, pa * dist * dist / jnp.where(ok, cos_light, 1.0), 0.0)


def sun_hit(lights: LightTable, direction: Float[Array, "3"]) -> tuple[Bool[Array, ""], Float[Array, ""]]:
    """(does ``direction`` fall in the sun's disk, the sun-sampling solid-angle density there).

    Tested as |d − s|² ≤ 2h (= 2 − 2 cos θmax), which keeps float32 precision for a 0.27° disk where
    comparing cosines near 1 would not.
    """
    diff = direction - lights.sun_dir
    inside = (lights.sun_h > 0) & (dot3(diff, diff) <= 2.0 * lights.sun_h)
    ok = lights.sun_h > 0
    pdf = jnp.where(ok, (1.0 - lights.p_area) / (2.0 * jnp.pi * jnp.where(ok, lights.sun_h, 1.0)), 0.0)
    return inside, pdf
