"""Uniform probe grid baseline: resolution, offset, jitter, and what to do with probes inside geometry.

The classic irradiance-volume grid (the baseline of every placement paper) puts probes on a lattice over
the scene box regardless of the geometry, so some land inside solids and shade nearby surfaces with
black (the "classic failure"). Three choices (``inside=``):

* ``"keep"``: leave them (the failure, for comparisons);
* ``"disable"``: keep the rows but set ``active=False`` (what a DDGI probe-classification pass does);
* ``"relocate"``: move each one to the nearest free point (DDGI probe relocation, Majercik et al. 2019
  "Dynamic Diffuse Global Illumination with Ray-Traced Irradiance Fields" §5 / Majercik 2021 "Scaling
  Probe-Based Real-Time Dynamic Global Illumination for Production" §3.1): Newton steps along the SDF
  gradient, ``p ← p + (target − d(p))·∇d/|∇d|``, until ``d(p) > clearance``. Probes that do not get
  there within ``max_steps`` (zero gradient deep inside a solid, or a non-distance SDF region) are
  disabled and counted as failures.

"Inside" means a negative signed distance at the probe (the SDF's sign contract, docs/sdf.md).

Resolution is either per-axis counts (``dims``: probes at the cell centres of a dims split of the box,
exactly :func:`probeplace.placement.space._grid.uniform_grid`) or a ``spacing`` (``⌈side/spacing⌉`` probes per
axis, :func:`~probeplace.placement.space._grid.grid_dims`, spaced exactly ``spacing`` apart and centred in the
box). ``offset`` shifts the lattice by a fraction of a cell; ``jitter`` adds a uniform random offset of
up to ``±jitter/2`` cells per probe and axis.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..._core import ConfigError, ProbeSet, Scene, scene_box
from ...geometry import SDFGrid, build_sdf, lookup_sdf

# The relocation lives with the rest of valid-space handling (docs/placement.md "Valid space").
from ..space import grid_dims, relocate_out, uniform_grid

INSIDE_CHOICES = ("keep", "disable", "relocate")


@dataclasses.dataclass(frozen=True, eq=False)
class UniformGridResult:
    """A uniform grid and its inside-geometry bookkeeping.

    Attributes:
        probes: the probe set (``method="uniform"``); rows in lattice order, x fastest.
        dims: probes per axis.
        spacing: lattice spacing per axis, scene units (3,).
        inside: which probes were inside geometry at their lattice position (n,).
        relocated: which probes were moved to free space (n,) (all False unless ``inside="relocate"``).
        n_inside: count of ``inside``.
        n_disabled: probes made inactive (inside with ``"disable"``, failed relocations with
            ``"relocate"``).
        n_relocated: count of ``relocated``.
        n_failed: relocations that did not reach the clearance (disabled).
    """

    probes: ProbeSet
    dims: tuple[int, int, int]
    spacing: np.ndarray
    inside: np.ndarray
    relocated: np.ndarray
    n_inside: int
    n_disabled: int
    n_relocated: int
    n_failed: int


def lattice(
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    dims=None,
    spacing: float | int | None = None,
    offset=(0.0, 0.0, 0.0),
) -> tuple[np.ndarray, tuple[int, int, int], np.ndarray]:
    """Lattice positions (n, 3) float32 (x fastest), dims and per-axis spacing (module docstring)."""
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo):
        raise ConfigError(f"grid bounds must be two 3-vectors with hi > lo, got {lo} and {hi}")
    if (dims is None) == (spacing is None):
        raise ConfigError("give exactly one of dims (probes per axis) and spacing")
    off = np.broadcast_to(np.asarray(offset, np.float64), (3,))
    if not np.all(np.isfinite(off)):
        raise ConfigError(f"offset must be finite, got {offset}")
    if dims is not None:
        d = tuple(int(x) for x in np.broadcast_to(np.asarray(dims), (3,)))
        if min(d) < 1:
            raise ConfigError(f"dims must be ≥ 1 per axis, got {dims}")
        step = (hi - lo) / np.asarray(d, np.float64)
        pos = uniform_grid(lo, hi, d).astype(np.float64)  # type: ignore[arg-type]
    else:
        d = grid_dims(lo, hi, float(spacing))  # type: ignore[arg-type]
        step = np.full(3, float(spacing))
        centre = 0.5 * (lo + hi)
        axes = [centre[a] + (np.arange(d[a]) - 0.5 * (d[a] - 1)) * step[a] for a in range(3)]
        z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")
        pos = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return (pos + off * step).astype(np.float32), d, step  # type: ignore[return-value]


def uniform_probe_grid(
    scene: Scene | None = None,
    *,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
    dims=None,
    spacing: float | int | None = None,
    offset=(0.0, 0.0, 0.0),
    jitter: float | int = 0.0,
    key: jax.Array | None = None,
    inside: str = "keep",
    sdf: SDFGrid | None = None,
    clearance: float | int | None = None,
    max_steps: int = 16,
) -> UniformGridResult:
    """A uniform probe grid over the scene box (module docstring).

    Args:
        scene: the scene (its bounding box is the default ``bounds``; its SDF is built when needed and
            ``sdf`` is not given). May be ``None`` with ``bounds`` and ``inside="keep"``.
        bounds: (lo, hi) of the grid box; default the scene's bounding box.
        dims: probes per axis (cell centres of a dims split of the box); or
        spacing: lattice spacing, scene units (⌈side/spacing⌉ probes per axis, centred).
        offset: lattice shift, fraction of a cell per axis (scalar or 3-vector).
        jitter: per-probe random shift, uniform in ±jitter/2 cells per axis, in [0, 1]; needs ``key``.
        key: PRNG key for the jitter.
        inside: ``"keep"``, ``"disable"`` or ``"relocate"`` probes with negative SDF.
        sdf: the scene's SDF (built with :func:`probeplace.geometry.build_sdf` if needed and absent).
        clearance: free distance relocated probes must reach, scene units; default one SDF voxel (which,
            with trilinear error ≤ h√3/2, guarantees a positive true distance).
        max_steps: relocation Newton steps.

    Returns:
        The grid and its counts.

    Raises:
        ConfigError: bad resolution, offset, jitter, key, inside choice or clearance.
    """
    if inside not in INSIDE_CHOICES:
        raise ConfigError(f"inside must be one of {INSIDE_CHOICES}, got {inside!r}")
    if not (0.0 <= float(jitter) <= 1.0):
        raise ConfigError(f"jitter must be in [0, 1] (a fraction of a cell), got {jitter}")
    if jitter > 0 and key is None:
        raise ConfigError("jitter > 0 needs a PRNG key (key=jax.random.key(...))")
    if bounds is None:
        bounds = scene_box(scene)
    pos, d, step = lattice(bounds[0], bounds[1], dims=dims, spacing=spacing, offset=offset)
    if jitter > 0:
        u = np.asarray(jax.random.uniform(key, pos.shape, jnp.float32, -0.5, 0.5), np.float64)  # type: ignore[arg-type]
        pos = (pos + jitter * u * step).astype(np.float32)
    n = len(pos)
    active = np.ones(n, bool)
    is_inside = np.zeros(n, bool)
    relocated = np.zeros(n, bool)
    n_failed = 0
    if inside != "keep" or sdf is not None or scene is not None:
        if sdf is None:
            if scene is None:
                raise ConfigError(f"inside={inside!r} needs a scene or an sdf")
            sdf = build_sdf(scene)
        vals = lookup_sdf(sdf, pos)  # PERF: padded rows, so a budget search's many grids share compiles
        is_inside = vals < 0
    if inside == "disable":
        active &= ~is_inside
    elif inside == "relocate" and is_inside.any():
        c = float(sdf.voxel_size) if clearance is None else float(clearance)  # type: ignore[union-attr]
        if not (np.isfinite(c) and c > 0):
            raise ConfigError(f"clearance must be positive, got {clearance}")
        idx = np.flatnonzero(is_inside)
        lo, hi = (np.asarray(b, np.float64) for b in bounds)
        moved, ok = relocate_out(sdf, pos[idx], c, int(max_steps), lo, hi)  # type: ignore[arg-type]
        pos = pos.copy()
        pos[idx[ok]] = moved[ok]
        relocated[idx[ok]] = True
        active[idx[~ok]] = False
        n_failed = int((~ok).sum())
    probes = ProbeSet(jnp.asarray(pos, jnp.float32), jnp.asarray(active), method="uniform")
    return UniformGridResult(
        probes=probes,
        dims=d,
        spacing=step,
        inside=is_inside,
        relocated=relocated,
        n_inside=int(is_inside.sum()),
        n_disabled=int((~active).sum()),
        n_relocated=int(relocated.sum()),
        n_failed=n_failed,
    )
