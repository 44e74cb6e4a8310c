"""Pinhole camera rays.

Image convention: pixel index = row · width + column, row 0 at the *top*; a pixel is the unit square
[col, col+1) × [row, row+1) in raster space and a sample at sub-pixel offset u lands at (col + u₀,
row + u₁): a box reconstruction filter, the one Mitsuba's ``box`` rfilter uses, so both renderers
estimate the same pixel integral. The camera looks along ``look_at − position``; raster +x maps to the
camera's right (forward × up), raster +y (down the image) to −up; the vertical field of view spans the
image height.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._core import Camera, safe_normalize


def camera_basis(camera: Camera) -> tuple[Float[Array, "3"], Float[Array, "3"], Float[Array, "3"]]:
    """(forward, right, up) unit vectors of a camera, world frame, right-handed (right = forward × up)."""
    fwd = safe_normalize(camera.look_at - camera.position)
    right = safe_normalize(jnp.cross(fwd, camera.up))
    up = jnp.cross(right, fwd)
    return fwd, right, up


def camera_ray(
    camera: Camera,
    width: int | Int[Array, ""],
    height: int | Int[Array, ""],
    pixel: Int[Array, ""],
    u: Float[Array, "2"],
) -> tuple[Float[Array, "3"], Float[Array, "3"]]:
    """(origin, unit direction) of the camera ray through pixel ``pixel`` at sub-pixel offset ``u``.

    ``u`` are the dims (1, 2) of :func:`~probeplace.render.path_uniforms` at bounce 0 in the path
    tracer, so a renderer that wants the reference's primary rays calls this with the same numbers.
    """
    fwd, right, up = camera_basis(camera)
    w_i = jnp.asarray(width, jnp.int32)
    row = (pixel // w_i).astype(u.dtype)
    col = (pixel % w_i).astype(u.dtype)
    w = w_i.astype(u.dtype)
    h = jnp.asarray(height).astype(u.dtype)
    tan_y = jnp.tan(0.5 * jnp.deg2rad(camera.fov_y_deg)).astype(u.dtype)
    tan_x = tan_y * (w / h)
    x = (2.0 * (col + u[0]) / w - 1.0) * tan_x
    y = (1.0 - 2.0 * (row + u[1]) / h) * tan_y
    d = safe_normalize(fwd + x * right + y * up)
    return camera.position.astype(u.dtype), d


def camera_rays(
    camera: Camera,
    width: int | Int[Array, ""],
    height: int | Int[Array, ""],
    pixels: Int[Array, " n"],
    u: Float[Array, "n 2"],
) -> tuple[Float[Array, "n 3"], Float[Array, "n 3"]]:
    """Batched :func:`camera_ray`."""
    return jax.vmap(camera_ray, in_axes=(None, None, None, 0, 0))(camera, width, height, pixels, u)
