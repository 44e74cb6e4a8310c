"""Shared test helpers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# CI has ../shared beside the checkout; a user's clone may not. Tests that need an external scene
# ask for it through this fixture and are skipped with the reason when it is absent.
SHARED_SCENES = Path(
    os.environ.get("PROBEPLACE_SHARED_SCENES", Path(__file__).resolve().parents[2] / "shared" / "scenes")
)


def shared_scene_path(name: str) -> Path:
    """Path of an external scene from ../shared/scenes; skips the test with the reason if absent."""
    path = SHARED_SCENES / name
    if not path.exists():
        pytest.skip(f"external scene {name} not found in {SHARED_SCENES} (set PROBEPLACE_SHARED_SCENES)")
    return path


def grid_probe_set(scene, dims):
    """A ProbeSet at the cell centres of a ``dims`` (nx, ny, nz) grid over the scene's bounds, all active
    (as benchmarks/tracer.py places its grids). JAX is imported here, not by the module: CLI tests import
    it too."""
    import jax.numpy as jnp
    import numpy as np

    from probeplace._core import ProbeSet

    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    axes = [(np.arange(n) + 0.5) / n for n in dims]
    pos = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo
    return ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))


def albedo_lit(scene, caster):
    """A stand-in for a path-traced bake's radiance (``probes.RadianceFn``; one compile less): each
    surface a texel ray hits reflects 0.3 × its albedo, no emission."""
    import jax.numpy as jnp

    albedo = scene.materials.base_color

    def radiance(o, d, k):
        h = caster.closest_hit(o, d)
        rad = jnp.where((h.tri >= 0)[:, None], 0.3 * albedo[jnp.maximum(h.material, 0)], 0.0)
        return rad.astype(o.dtype), jnp.zeros_like(o)

    return radiance
