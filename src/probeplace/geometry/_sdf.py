"""The signed-distance grid and its differentiable trilinear lookup.

The grid samples a signed distance on a regular lattice in the world frame: lattice point (i, j, k) sits
at ``origin + voxel_size·(i, j, k)``. Values are negative inside solids and positive in free space
(what "inside" means for open scenes: :mod:`probeplace.geometry._sdf_sign` and docs/sdf.md). Within the
exact band (``band`` voxels of the surface) a value is the exact distance to the nearest triangle; beyond
it, a value is a *lower bound* of the distance (never larger than the truth), so sphere tracing with it
never oversteps (Hart 1996, "Sphere tracing", §2: any under-estimate of the distance is a safe step).

Trilinear interpolation of exact distances differs from the true distance by at most h√3/2 (h the voxel
size): |Σ wᵢ d(xᵢ) − d(p)| ≤ Σ wᵢ |xᵢ − p| ≤ h√3/2 by the 1-Lipschitz property, the bound reached at a
cell centre. Every accuracy statement downstream (hit distances, test tolerances) derives from it.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int16

from .._core import next_pow2

# Corner offsets of a cell, in the order of the flat gather below: bit 2 = x, bit 1 = y, bit 0 = z.
_CORNERS = tuple((c >> 2 & 1, c >> 1 & 1, c & 1) for c in range(8))


class SDFGrid(eqx.Module):
    """A signed-distance lattice (see the module docstring for the sign and accuracy contract).

    Attributes:
        values: signed distance at lattice points, scene units; float32 from :func:`build_sdf`.
        origin: world position of ``values[0, 0, 0]``.
        voxel_size: lattice spacing h, scene units.
        trace: the sphere tracer's compact copy (int16, decode with :func:`decode_trace`): the same
            magnitudes in units of h/128, rounded toward zero and clamped at 128 voxels (both keep it a
            lower bound), but signed by the side of the nearest face (negative behind a face, whatever
            the component) so that a one-sided sheet has a zero crossing; beyond the band it has the sign
            of ``values``. The least significant bit flags "thin" lattice points: a face seen from the
            front and one seen from behind are within 1.5 voxels (a plate thinner than the lattice, two
            opposite layers, a thin rod), where the tracer accepts a local minimum as a hit. ``None``:
            the tracer reads ``values`` (no sheets, no thin flags) — for hand-made grids.
        band: half-width of the exact band, voxels (static); beyond it values are lower bounds ≥ band·h.
        mesh_hash: hash of the mesh arrays and build settings the grid was built from (static).
    """

    values: Float[Array, "nx ny nz"]
    origin: Float[Array, "3"]
    voxel_size: Float[Array, ""]
    trace: Int16[Array, "nx ny nz"] | None = None
    band: float = eqx.field(static=True, default=2.0)
    mesh_hash: str = eqx.field(static=True, default="")

    def __check_init__(self):
        if self.values.ndim != 3 or min(self.values.shape) < 2:
            raise ValueError(
                f"values must be a 3-D lattice with ≥ 2 points per axis, got {self.values.shape}"
            )
        if self.origin.shape != (3,):
            raise ValueError(f"origin must have shape (3,), got {self.origin.shape}")
        if self.trace is not None and self.trace.shape != self.values.shape:
            raise ValueError(
                f"trace must have the shape of values {self.values.shape}, got {self.trace.shape}"
            )
        if self.voxel_size.shape != ():
            raise ValueError(f"voxel_size must be a scalar, got shape {self.voxel_size.shape}")

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(int(s) for s in self.values.shape)  # type: ignore[return-value]

    @property
    def upper(self) -> Float[Array, "3"]:
        """World position of the last lattice point (the grid box is [origin, upper])."""
        return self.origin + self.voxel_size * (jnp.asarray(self.values.shape, self.origin.dtype) - 1)


# Tracer encoding: value = (code >> 1) · h / TRACE_SCALE, thin flag = code & 1.
TRACE_SCALE = 128
_TRACE_MAX = (1 << 14) - 1


def encode_trace(oriented_vox: np.ndarray, thin: np.ndarray) -> np.ndarray:
    """int16 tracer codes from an oriented distance in voxels and thin flags (host, numpy).

    Magnitudes are rounded toward zero and clamped, so decoded values never exceed the input's.
    """
    q = np.clip(np.trunc(oriented_vox * TRACE_SCALE), -_TRACE_MAX, _TRACE_MAX).astype(np.int16)
    return (q * 2 + thin.astype(np.int16)).astype(np.int16)


def decode_trace(code: Array, voxel_size: Array) -> tuple[Array, Array]:
    """(value in scene units, thin flag) of tracer codes; the value has ``voxel_size``'s dtype."""
    code = code.astype(jnp.int32)
    return (code >> 1).astype(voxel_size.dtype) * (voxel_size / TRACE_SCALE), (code & 1) == 1


def _cell(grid: SDFGrid, p: Float[Array, "3"]):
    """Clamped voxel coordinates of p, the cell's base index, fractions and the distance to the box."""
    dtype = p.dtype
    h = grid.voxel_size.astype(dtype)
    u = (p - grid.origin.astype(dtype)) / h
    hi = jnp.asarray(grid.values.shape, dtype) - 1
    uc = jnp.clip(u, 0.0, hi)
    outside = (u - uc) * h
    i0 = jnp.clip(jnp.floor(uc), 0.0, hi - 1)
    frac = uc - i0
    return i0.astype(jnp.int32), frac, outside


def _gather_corners(grid: SDFGrid, i0) -> Array:
    _, ny, nz = grid.values.shape
    flat = grid.values.reshape(-1)
    base = (i0[0] * ny + i0[1]) * nz + i0[2]
    offs = jnp.asarray([(a * ny + b) * nz + c for a, b, c in _CORNERS], jnp.int32)
    return flat[base + offs]  # (8,)


def _trilinear(v8: Array, f: Array) -> Array:
    v = v8.reshape(2, 2, 2)
    v = v[0] * (1 - f[0]) + v[1] * f[0]
    v = v[0] * (1 - f[1]) + v[1] * f[1]
    return v[0] * (1 - f[2]) + v[1] * f[2]


def _outside_bound(v: Array, e: Array) -> Array:
    """Extend an in-box value v to a point at offset e outside the box.

    The nearest surface point s lies in the box, so the angle at the box point q between p − q and s − q is
    ≥ 90° and |p − s|² ≥ |e|² + d(q)²: sign(v)·√(|e|² + v²) stays a lower bound of |d(p)| (v ≤ d(q)).
    The plain sum |e| + v would over-estimate. Differentiable; equals v on the box.
    """
    e2 = jnp.sum(e * e)
    r2 = e2 + v * v
    safe = jnp.where(r2 > 0, r2, 1.0)
    ext = jnp.where(v < 0, -1.0, 1.0) * jnp.sqrt(safe)
    return jnp.where(e2 > 0, ext, v)


def sdf_value(grid: SDFGrid, p: Float[Array, "3"]) -> Float[Array, ""]:
    """Signed distance at one point by trilinear interpolation; differentiable in ``p`` and ``grid.values``.

    Points outside the grid box are clamped to it and extended with :func:`_outside_bound`, so the value
    stays a lower bound of the distance. Accuracy inside the exact band: within h√3/2 of the true signed
    distance (module docstring). The result has ``p``'s dtype (the grid's values are cast after the gather).

    Args:
        grid: the SDF.
        p: query point, world frame.

    Returns:
        Scalar signed distance, scene units.
    """
    i0, f, e = _cell(grid, p)
    v = _trilinear(_gather_corners(grid, i0).astype(p.dtype), f)
    return _outside_bound(v, e)


def sdf_value_and_grad(grid: SDFGrid, p: Float[Array, "3"]) -> tuple[Float[Array, ""], Float[Array, "3"]]:
    """:func:`sdf_value` and its gradient with respect to ``p`` (the trilinear gradient, piecewise bilinear).

    Where the grid is an exact distance the gradient has unit length up to the interpolation error; it is
    zero-safe (finite) everywhere, including on cell faces and on the box boundary.
    """
    return jax.value_and_grad(sdf_value, argnums=1)(grid, p)


@eqx.filter_jit
def _sdf_rows(grid: SDFGrid, pos: Float[Array, "n 3"]) -> Float[Array, " n"]:
    return jax.vmap(sdf_value, in_axes=(None, 0))(grid, pos)


def lookup_sdf(grid: SDFGrid, pos: np.ndarray | Array) -> np.ndarray:
    """Signed distance at many points, for host code: :func:`sdf_value` of each row, NumPy in and out.

    One jitted call whose rows are padded (with the origin) to a power of two ≥ 8, so callers with
    varying counts (a budget search's candidate grids, a refinement's new probes) share a few
    compilations. Not differentiable (the result is NumPy); traced code vmaps :func:`sdf_value` itself.

    Args:
        grid: the SDF.
        pos: query points, world frame; any shape that reshapes to (n, 3); cast to float32.

    Returns:
        (n,) float32 signed distances, scene units.
    """
    p = np.asarray(pos, np.float32).reshape(-1, 3)
    n = len(p)
    padded = np.zeros((next_pow2(n, lo=8), 3), np.float32)
    padded[:n] = p
    return np.asarray(_sdf_rows(grid, jnp.asarray(padded)))[:n]
