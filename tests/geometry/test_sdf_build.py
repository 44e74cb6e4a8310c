"""SDF build: values against closed forms and libigl, sign conventions, conservativeness, cache, errors."""

from __future__ import annotations

import igl
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError, ResourceError
from probeplace.geometry import _sdf_build, build_sdf, default_voxel_size, sdf_value
from probeplace.scene import cornell_box
from tests.reference import sdf_scenes as ref

# Lattice values are exact up to float32 arithmetic in voxel coordinates (|x| ≲ 2⁸ voxels, a few
# operations: ~2⁸·2⁻²³·8 ≈ 2.5·10⁻⁴ voxel) and the key's distance quantisation (band/2¹⁸ voxel).
LATTICE_ATOL_VOX = 2.5e-4
# Trilinear interpolation of a 1-Lipschitz field is within h·√3/2 of it (docs/sdf.md).
INTERP_VOX = np.sqrt(3.0) / 2


def _lattice_points(grid, idx):
    ijk = np.stack(np.unravel_index(idx, grid.shape), axis=1)
    return np.asarray(grid.origin, np.float64) + float(grid.voxel_size) * ijk


def _true_unsigned(scene, p):
    sq, _, _ = igl.point_mesh_squared_distance(
        p, np.asarray(scene.vertices, np.float64), np.asarray(scene.faces, np.int64)
    )
    return np.sqrt(sq)


def test_sphere_lattice_and_interpolated_values_match_closed_form():
    grid, h = ref.sphere_sdf(), 0.05
    sag = ref.sphere_sagitta()  # the mesh is inscribed: it differs from the sphere by at most this
    vals = np.asarray(grid.values).reshape(-1)
    band = np.flatnonzero(np.abs(vals) < grid.band * h * (1 - 1e-6))  # the floor value band·h is a bound
    p = _lattice_points(grid, band)
    exact = np.linalg.norm(p, axis=1) - 1.0
    np.testing.assert_allclose(vals[band], exact, rtol=0, atol=sag + LATTICE_ATOL_VOX * h)
    # Interpolated, at random points within a voxel of the surface.
    rng = np.random.default_rng(0)
    d = rng.normal(size=(500, 3))
    q = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.95, 1.05, (500, 1))
    got = np.asarray(jax.vmap(lambda x: sdf_value(grid, x))(jnp.asarray(q, jnp.float32)))
    exact = np.linalg.norm(q, axis=1) - 1.0
    np.testing.assert_allclose(got, exact, rtol=0, atol=sag + (INTERP_VOX + LATTICE_ATOL_VOX) * h)


def test_box_lattice_values_are_exact():
    grid, h = ref.box_sdf(), 0.05
    vals = np.asarray(grid.values).reshape(-1)
    band = np.flatnonzero(np.abs(vals) < grid.band * h * (1 - 1e-6))  # the floor value band·h is a bound
    p = _lattice_points(grid, band)
    np.testing.assert_allclose(vals[band], ref.box_distance(p), rtol=0, atol=LATTICE_ATOL_VOX * h)


@pytest.mark.parametrize("which", ["sphere", "box", "cornell"])
def test_values_never_exceed_true_distance(which):
    """Everywhere on the lattice |value| ≤ true unsigned distance (libigl), equal within the band."""
    scene, grid = {
        "sphere": (ref.sphere_scene(), ref.sphere_sdf()),
        "box": (ref.box_scene(), ref.box_sdf()),
        "cornell": (cornell_box(), ref.cornell_sdf()),
    }[which]
    h = float(grid.voxel_size)
    vals = np.asarray(grid.values, np.float64).reshape(-1)
    idx = np.random.default_rng(1).integers(0, vals.size, 4000)
    true = _true_unsigned(scene, _lattice_points(grid, idx))
    assert np.all(np.abs(vals[idx]) <= true + LATTICE_ATOL_VOX * h)
    band = true <= grid.band * h * (1 - 1e-6)
    np.testing.assert_allclose(np.abs(vals[idx][band]), true[band], rtol=0, atol=LATTICE_ATOL_VOX * h)


def test_closed_mesh_sign():
    grid = ref.sphere_sdf()
    rng = np.random.default_rng(2)
    d = rng.normal(size=(400, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = rng.uniform(0.0, 0.9, (400, 1))  # inside, up to 5 voxels deep... and deeper than the band
    inside = np.asarray(jax.vmap(lambda x: sdf_value(grid, x))(jnp.asarray(d * r, jnp.float32)))
    outside = np.asarray(jax.vmap(lambda x: sdf_value(grid, x))(jnp.asarray(d * (2.2 - r), jnp.float32)))
    assert np.all(inside < 0) and np.all(outside > 0)


def test_open_cornell_box_interior_is_free_and_blocks_are_solid():
    """Documented behaviour for an open scene (docs/sdf.md): walls are one-sided sheets of one component
    whose own winding number stays below 1/2, so the room (open front) and the space behind the walls are
    free space (positive); the two closed blocks are solid (negative) although the whole-mesh winding number
    inside them is only ~0.1-0.2 (the inward-facing room contributes ≈ -0.8)."""
    grid = ref.cornell_sdf()
    pts = {
        "room centre": ((278, 420, 280), 1),
        "near open front": ((278, 274, 20), 1),
        "behind back wall": ((278, 274, 575), 1),
        "below floor": ((278, -10, 280), 1),
        "in short block": ((185, 80, 170), -1),
        "in tall block": ((370, 160, 350), -1),
    }
    for name, (p, sign) in pts.items():
        v = float(sdf_value(grid, jnp.asarray(p, jnp.float32)))
        assert np.sign(v) == sign, f"{name}: {v}"


def test_cornell_sign_matches_per_component_winding_rule():
    """Away from surfaces the sign equals the rule: inside ⟺ max over components of w_C > 1/2."""
    scene, grid = cornell_box(), ref.cornell_sdf()
    v, f = np.asarray(scene.vertices, np.float64), np.asarray(scene.faces, np.int64)
    comp, n_comp = _sdf_build.weld_components(v, f)
    rng = np.random.default_rng(3)
    p = rng.uniform(v.min(0) - 30, v.max(0) + 30, (3000, 3))
    p = p[_true_unsigned(scene, p) > 3 * float(grid.voxel_size)]
    w = np.max([igl.winding_number(v, f[comp == c], p) for c in range(n_comp)], axis=0)
    got = np.asarray(jax.vmap(lambda x: sdf_value(grid, x))(jnp.asarray(p, jnp.float32)))
    np.testing.assert_array_equal(got < 0, w > 0.5)


def _block_lattice_signs():
    """Lattice points around the Cornell blocks more than a voxel from any surface: (points, SDF value,
    max per-component winding number). Every lattice point, not random ones: the band's outer rim is one
    voxel thin."""
    scene, grid = cornell_box(), ref.cornell_sdf()
    v, f = np.asarray(scene.vertices, np.float64), np.asarray(scene.faces, np.int64)
    comp, n_comp = _sdf_build.weld_components(v, f)
    h, o = float(grid.voxel_size), np.asarray(grid.origin, np.float64)
    values = np.asarray(grid.values)
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in values.shape], indexing="ij"), -1).reshape(-1, 3)
    p = o + idx * h
    near_blocks = (p[:, 1] < 345) & (p[:, 0] > 60) & (p[:, 0] < 450) & (p[:, 2] > 50) & (p[:, 2] < 430)
    idx, p = idx[near_blocks], p[near_blocks]
    far = _true_unsigned(scene, p) > 1.01 * h
    idx, p = idx[far], p[far]
    w = np.max([igl.fast_winding_number(v, f[comp == c], p) for c in range(n_comp)], axis=0)
    return p, values[idx[:, 0], idx[:, 1], idx[:, 2]], w


def test_cornell_block_interiors_are_negative_on_every_lattice_point():
    """A block's bottom face coincides with the floor; this once left a one-voxel layer of positive
    values at the band's outer rim inside both blocks (the rim now takes its sign from the deep fill)."""
    p, got, w = _block_lattice_signs()
    wrong = (w > 0.5) & (got >= 0)
    assert (w > 0.5).sum() > 1000
    assert wrong.sum() == 0, f"{wrong.sum()} lattice points inside a block are positive, e.g. {p[wrong][:3]}"


@pytest.mark.xfail(
    strict=True,
    reason="known bug: ~55 lattice points just outside the short block's "
    "top edges (1-2 voxels away) read negative; see docs/sdf.md 'Known sign errors'",
)
def test_cornell_lattice_points_outside_the_blocks_are_positive():
    p, got, w = _block_lattice_signs()
    wrong = (w <= 0.5) & (got < 0)
    assert wrong.sum() == 0, (
        f"{wrong.sum()} lattice points outside the blocks are negative, e.g. {p[wrong][:3]}"
    )


def test_float32_out():
    grid = ref.box_sdf()
    assert grid.values.dtype == jnp.float32 and grid.origin.dtype == jnp.float32
    assert grid.trace is not None and grid.trace.dtype == jnp.int16
    assert sdf_value(grid, jnp.zeros(3, jnp.float32)).dtype == jnp.float32


def test_cache_hit_on_second_build(tmp_path, monkeypatch):
    scene = ref.box_scene()
    first = build_sdf(scene, voxel_size=0.1, cache_dir=tmp_path)
    files = list(tmp_path.glob("*.npz"))
    assert len(files) == 1 and not list(tmp_path.glob("*.tmp*"))

    def boom(*a, **k):
        raise AssertionError("rasterized again instead of reading the cache")

    monkeypatch.setattr(_sdf_build, "rasterize_band", boom)
    second = build_sdf(scene, voxel_size=0.1, cache_dir=tmp_path)
    np.testing.assert_array_equal(np.asarray(first.values), np.asarray(second.values))
    np.testing.assert_array_equal(np.asarray(first.trace), np.asarray(second.trace))
    assert second.mesh_hash == first.mesh_hash
    # Another voxel size is another key.
    monkeypatch.undo()
    build_sdf(scene, voxel_size=0.11, cache_dir=tmp_path)
    assert len(list(tmp_path.glob("*.npz"))) == 2


def test_cache_dir_from_environment(tmp_path, monkeypatch):
    monkeypatch.setenv("PROBEPLACE_CACHE_DIR", str(tmp_path))
    build_sdf(ref.box_scene(), voxel_size=0.1)
    assert len(list((tmp_path / "sdf").glob("*.npz"))) == 1


def test_absurd_resolution_is_refused_with_estimate():
    with pytest.raises(ResourceError, match=r"GiB"):
        build_sdf(cornell_box(), voxel_size=0.2, cache_dir=False)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_bad_voxel_size(bad):
    with pytest.raises(ConfigError, match="voxel_size"):
        build_sdf(ref.box_scene(), voxel_size=bad, cache_dir=False)


def test_default_voxel_size_follows_rule():
    """Cornell: the extent term (longest side / 128) binds; quality scales it."""
    scene = cornell_box()
    ext = np.ptp(np.asarray(scene.vertices, np.float64), axis=0).max()
    assert default_voxel_size(scene) == pytest.approx(ext / 128, rel=5e-3)  # 3 significant digits
    assert default_voxel_size(scene, quality=2.0) == pytest.approx(ext / 256, rel=5e-3)
    with pytest.raises(ConfigError):
        default_voxel_size(scene, quality=0.0)
