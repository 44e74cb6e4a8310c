"""Probe baking plumbing and pre-filters, against closed forms: ray–box distances in a cube room,
irradiance of constant and linear radiance, moments of a constant distance, a NumPy MIP reference,
lossless save/load, and the inside-geometry flag."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError, ProbeplaceError, ProbeSet, strip_border, texel_directions
from probeplace.geometry import BruteForceCaster
from probeplace.probes import (
    BakeConfig,
    bake_probes,
    distance_moments,
    irradiance_map,
    load_probes,
    mip_chains,
    save_probes,
)
from probeplace.scene import build_scene, make_materials
from probeplace.scene._primitives import box

ROOM_LO, ROOM_HI = np.array([0.0, 0.0, 0.0]), np.array([4.0, 3.0, 5.0])
BLOCK_LO, BLOCK_HI = np.array([0.5, 0.0, 0.5]), np.array([1.5, 1.0, 1.5])


@pytest.fixture(scope="module")
def room():
    """A closed cube room (faces turned inward) with a solid block (faces outward) in one corner."""
    rv, rf = box(ROOM_LO, ROOM_HI)
    bv, bf = box(BLOCK_LO, BLOCK_HI)
    v = np.concatenate([rv, bv])
    f = np.concatenate([rf[:, ::-1], bf + len(rv)])
    mats = make_materials(["wall", "block"], np.array([[0.5, 0.5, 0.5], [0.8, 0.2, 0.2]]))
    mat = np.r_[np.zeros(len(rf), int), np.ones(len(bf), int)]
    return build_scene("test_room", v, f, mat, mats)


def _constant_radiance(value):
    def fn(origins, directions, key):
        n = origins.shape[0]
        return jnp.full((n, 3), value, origins.dtype), jnp.zeros((n, 3), origins.dtype)

    return fn


def _ray_box_exit(o, d, lo, hi):
    """Closed form: distance from a point inside an axis-aligned box to its boundary along d."""
    with np.errstate(divide="ignore"):
        t = np.where(d > 0, (hi - o) / d, np.where(d < 0, (lo - o) / d, np.inf))
    return t.min(axis=-1)


def test_bake_geometry_maps_match_closed_form(room, getkey):
    p = np.array([[3.0, 2.0, 3.5]], np.float32)  # in the room, away from the block's shadow cone? no matter
    probes = ProbeSet(pos_world=jnp.asarray(p), active=jnp.ones(1, bool))
    cfg = BakeConfig(radiance_res=16, irradiance_res=4, moments_res=4, n_sub=1, progress=False)
    lf = bake_probes(
        room,
        probes,
        caster=BruteForceCaster(room),
        radiance_fn=_constant_radiance(0.25),
        key=getkey(),
        config=cfg,
    )
    d = np.asarray(texel_directions(16, jnp.float64)).reshape(-1, 3)
    t_room = _ray_box_exit(p[0].astype(np.float64), d, ROOM_LO, ROOM_HI)
    got = np.asarray(strip_border(lf.distance[..., None]))[0, ..., 0].reshape(-1)
    # Texels whose centre ray meets the block are closer than the room wall; everything else is exact.
    clear = np.isclose(got, t_room, rtol=1e-5)
    assert clear.mean() > 0.9
    assert np.all(got[~clear] < t_room[~clear])
    # Normals of wall hits point into the room, against the ray.
    n = np.asarray(strip_border(lf.normal))[0].reshape(-1, 3)
    assert np.all(np.sum(n * d, axis=-1) < 0)
    # Radiance plumbing: a constant radiance function gives a constant map and E = π L.
    np.testing.assert_allclose(np.asarray(lf.radiance), 0.25, rtol=1e-6)
    np.testing.assert_allclose(np.asarray(lf.irradiance), np.pi * 0.25, rtol=2e-3)
    assert not bool(lf.inside[0])
    assert lf.radiance.shape == (1, 18, 18, 3) and lf.irradiance.shape == (1, 6, 6, 3)
    assert lf.radiance.dtype == jnp.float32


def test_probe_inside_a_solid_is_flagged(room, getkey):
    p = np.array([[1.0, 0.5, 1.0], [3.0, 1.5, 3.0]], np.float32)  # inside the block; in free space
    probes = ProbeSet(pos_world=jnp.asarray(p), active=jnp.ones(2, bool))
    cfg = BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=1, progress=False)
    lf = bake_probes(
        room,
        probes,
        caster=BruteForceCaster(room),
        radiance_fn=_constant_radiance(0.0),
        key=getkey(),
        config=cfg,
    )
    assert np.asarray(lf.inside).tolist() == [True, False]


def test_irradiance_of_linear_radiance_is_closed_form():
    # ∫ (a·ω) max(0, n·ω) dω = (2π/3) a·n for every unit n.
    a = np.array([0.3, -0.5, 0.8])
    res = 64
    d = np.asarray(texel_directions(res, jnp.float64))
    lin = np.broadcast_to((d @ a)[..., None], (res, res, 3))[None]
    e = np.asarray(irradiance_map(jnp.asarray(lin), 8))[0, ..., 0]
    n = np.asarray(texel_directions(8, jnp.float64))
    np.testing.assert_allclose(e, 2 * np.pi / 3 * (n @ a), atol=5e-3)


def test_moments_of_constant_distance_and_mips_match_numpy(getkey):
    dist = jnp.full((2, 16, 16), 3.0, jnp.float64)
    m = np.asarray(distance_moments(dist, 4, 50.0))
    np.testing.assert_allclose(m[..., 0], 3.0, rtol=1e-12)
    np.testing.assert_allclose(m[..., 1], 9.0, rtol=1e-12)
    x = jax.random.uniform(getkey(), (2, 8, 8), jnp.float64)
    mins, maxs = mip_chains(x)
    assert [m.shape[1] for m in mins] == [4, 2, 1]
    xn = np.asarray(x)
    np.testing.assert_array_equal(np.asarray(mins[0]), xn.reshape(2, 4, 2, 4, 2).min(axis=(2, 4)))
    np.testing.assert_array_equal(np.asarray(maxs[-1])[:, 0, 0], xn.max(axis=(1, 2)))


def test_save_load_round_trip_is_lossless(room, tmp_path, getkey):
    probes = ProbeSet(pos_world=jnp.asarray([[2.0, 1.5, 2.5]], jnp.float32), active=jnp.ones(1, bool))
    cfg = BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=2, progress=False)
    lf = bake_probes(
        room,
        probes,
        caster=BruteForceCaster(room),
        radiance_fn=_constant_radiance(1.0),
        key=getkey(),
        config=cfg,
    )
    path = save_probes(tmp_path / "p.npz", lf)
    back = load_probes(path)
    for a, b in zip(jax.tree.leaves(lf), jax.tree.leaves(back), strict=True):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ProbeplaceError, match="not a readable"):
        load_probes(tmp_path / "bad.npz")
    with pytest.raises(ProbeplaceError, match="not found"):
        load_probes(tmp_path / "missing.npz")


@pytest.mark.parametrize(
    "kwargs", [{"radiance_res": 12}, {"n_sub": 0}, {"moment_power": -1.0}, {"inside_backface_share": 1.5}]
)
def test_bad_config_is_a_clear_error(kwargs):
    with pytest.raises(ConfigError, match="BakeConfig"):
        BakeConfig(**kwargs)


def test_nan_probe_position_is_a_clear_error(room, getkey):
    probes = ProbeSet(pos_world=jnp.asarray([[np.nan, 1.0, 1.0]], jnp.float32), active=jnp.ones(1, bool))
    with pytest.raises(ConfigError, match="finite"):
        bake_probes(
            room,
            probes,
            caster=BruteForceCaster(room),
            radiance_fn=_constant_radiance(0.0),
            key=getkey(),
            config=BakeConfig(radiance_res=8, progress=False),
        )


def test_contact_sheet_is_a_png_with_one_row_per_probe(room, tmp_path, getkey):
    from PIL import Image

    from probeplace.probes import save_contact_sheet

    p = jnp.asarray([[2.0, 1.5, 2.5], [3.0, 2.0, 4.0]], jnp.float32)
    lf = bake_probes(
        room,
        ProbeSet(pos_world=p, active=jnp.ones(2, bool)),
        caster=BruteForceCaster(room),
        radiance_fn=_constant_radiance(0.5),
        key=getkey(),
        config=BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=1, progress=False),
    )
    out = save_contact_sheet(lf, tmp_path / "sheet.png")
    with Image.open(out) as im:
        w, h = im.size
    assert w > h > 2 * 100  # six columns, two rows of ~190 px


def test_path_traced_bake_matches_the_furnace_closed_form(getkey):
    """Inside a closed box whose walls all emit L_e and reflect albedo ρ (Lambert), a probe sees
    emission L_e in every direction and reflected radiance ρL_e + ρ²L_e with paths of at most three
    segments (no Russian roulette before depth 5): an exact oracle for every texel of every map."""
    from probeplace.probes import path_traced_radiance
    from probeplace.render import default_caster

    rho, le = 0.5, 1.0
    v, f = box((0.0, 0.0, 0.0), (2.0, 2.0, 2.0))
    mats = make_materials(["wall"], np.full((1, 3), rho), emission=np.full((1, 3), le))
    scene = build_scene("furnace", v, f[:, ::-1], np.zeros(len(f), int), mats)
    caster = default_caster(scene)
    probes = ProbeSet(pos_world=jnp.asarray([[0.7, 1.1, 1.3]], jnp.float32), active=jnp.ones(1, bool))
    lf = bake_probes(
        scene,
        probes,
        caster=caster,
        radiance_fn=path_traced_radiance(scene, spp=32, max_depth=3, specular=0.0, caster=caster),
        key=getkey(),
        config=BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=2, progress=False),
    )
    emission = np.asarray(strip_border(lf.emission))
    reflected = np.asarray(strip_border(lf.radiance))
    np.testing.assert_allclose(emission, le, rtol=1e-5)
    expected = rho * le + rho**2 * le
    assert abs(reflected.mean() - expected) < 0.01 * expected  # 64 texels × 128 paths
    assert np.abs(reflected - expected).max() < 0.15 * expected  # per texel: 128 paths
    # Irradiance from reflected radiance: E = π · const for every receiver normal.
    np.testing.assert_allclose(np.asarray(lf.irradiance).mean(), np.pi * reflected.mean(), rtol=0.02)
