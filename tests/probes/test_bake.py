"""Probe baking plumbing and pre-filters, against closed forms: ray–box distances in a cube room,
irradiance of constant and linear radiance, moments of a constant distance, a NumPy MIP reference,
lossless save/load, surfels oriented toward the probe, the inside-geometry flag (winding-independent),
and the bake settings recorded on the probes and checked against an evaluation."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import (
    BakeSettings,
    ConfigError,
    ProbeplaceError,
    ProbeSet,
    strip_border,
    surfel_texels,
    texel_directions,
)
from probeplace.geometry import BruteForceCaster, EmbreeCaster
from probeplace.probes import (
    BakeConfig,
    bake_depth_for,
    bake_probes,
    check_bake_settings,
    distance_moments,
    irradiance_map,
    load_probes,
    pad_probes,
    padded_capacity,
    path_traced_radiance,
    probe_bytes,
    save_probes,
)
from probeplace.scene import build_scene, make_camera, make_materials
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


@pytest.mark.parametrize("caster", ["brute", "embree"])
def test_bake_geometry_maps_match_closed_form(room, getkey, caster):
    """The texel rays go in 4×4 tiles (Embree's coherent packets where they are available): each map
    texel still holds its own direction's hit."""
    p = np.array([[3.0, 2.0, 3.5]], np.float32)  # in the room, away from the block's shadow cone? no matter
    probes = ProbeSet(pos_world=jnp.asarray(p), active=jnp.ones(1, bool))
    cfg = BakeConfig(radiance_res=16, irradiance_res=4, moments_res=4, n_sub=1, progress=False)
    lf = bake_probes(
        room,
        probes,
        caster=BruteForceCaster(room) if caster == "brute" else EmbreeCaster(room),
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


def _direction_radiance(origins, directions, key):
    """A custom radiance function that stores each ray's direction, mapped to [0, 1]."""
    return 0.5 * directions + 0.5, jnp.zeros_like(directions)


@pytest.mark.isa  # a float32 map against a float64 oracle, with a tolerance rounding could break
@pytest.mark.parametrize("res,geo", [(8, 8), (8, 32)])
def test_surfel_rays_leave_along_the_surfel_the_glossy_read_tests(room, getkey, res, geo):
    """``texel_rays="surfel"``: every ray of a radiance texel leaves along the direction of the geometry
    texel holding its centre (oracle: ``texel_directions`` at ``surfel_texels``, float64), and that is
    the direction of the surfel the depth-aware read tests (``_glossy._surfel_maps``: its point over its
    distance). A mean of n_sub² equal float32 values is exact, so the maps hold the float32 direction:
    within a few float32 ulps of the float64 oracle (``oct_decode``'s normalisation, under any instruction
    set; 2e-6 is 16 ulps at 1), far below the 0.05 rad between neighbouring geometry texels.
    ``"jittered"`` rays differ from it."""
    from probeplace.probes._glossy import _surfel_maps

    probes = ProbeSet(pos_world=jnp.asarray([[3.0, 2.0, 3.5]], jnp.float32), active=jnp.ones(1, bool))
    common = dict(radiance_res=res, geometry_res=geo, irradiance_res=4, moments_res=4, n_sub=2)

    def bake(rays: str):
        config = BakeConfig(texel_rays=rays, progress=False, **common)
        caster = EmbreeCaster(room)
        return bake_probes(
            room, probes, caster=caster, radiance_fn=_direction_radiance, key=getkey(), config=config
        )

    lf = bake("surfel")
    assert lf.bake.texel_rays == "surfel" and lf.bake.to_dict()["texel_rays"] == "surfel"
    stored = 2.0 * np.asarray(strip_border(lf.radiance))[0].astype(np.float64) - 1.0
    idx = surfel_texels(res, geo)
    expected = np.asarray(texel_directions(geo, jnp.float64))[idx[:, None], idx[None, :]]
    np.testing.assert_allclose(stored, expected, atol=2e-6)
    point, _ = _surfel_maps(lf, res)
    point = np.asarray(strip_border(point))[0].astype(np.float64)
    read_dir = point / np.linalg.norm(point, axis=-1, keepdims=True)
    np.testing.assert_allclose(read_dir, expected, atol=2e-6)
    jittered = 2.0 * np.asarray(strip_border(bake("jittered").radiance))[0] - 1.0
    assert np.abs(jittered - expected).max() > 1e-3


@pytest.mark.slow  # ~25 s; tests/probes/test_trace.py checks the tracer on separate geometry maps by default
def test_geometry_maps_have_their_own_resolution(room, getkey):
    """Geometry maps at 16² beside 8² radiance: the same distances, normals and inside flags as a bake
    whose radiance is 16² too (geometry is exact rays, no sampling), and the tracer — which reads only
    the geometry — gives identical answers on both."""
    from probeplace.probes import make_tracer, trace_light_field

    p = np.array([[3.0, 2.0, 3.5], [2.5, 1.2, 1.0], [1.0, 0.5, 1.0]], np.float32)  # the last in the block
    probes = ProbeSet(pos_world=jnp.asarray(p), active=jnp.ones(3, bool))
    common = dict(irradiance_res=4, moments_res=4, n_sub=1, progress=False)
    bake = lambda **kw: bake_probes(
        room,
        probes,
        caster=BruteForceCaster(room),
        radiance_fn=_constant_radiance(0.25),
        key=getkey(),
        config=BakeConfig(**common, **kw),
    )
    split, same = bake(radiance_res=8, geometry_res=16), bake(radiance_res=16)
    assert split.radiance.shape == (3, 10, 10, 3) and split.distance.shape == (3, 18, 18)
    assert split.normal.shape == (3, 18, 18, 3) and split.backface.shape == (3, 18, 18)
    for name in ("distance", "normal", "backface", "inside", "moments"):
        np.testing.assert_array_equal(np.asarray(getattr(split, name)), np.asarray(getattr(same, name)), name)
    rng = np.random.default_rng(0)
    o = jnp.asarray(rng.uniform(ROOM_LO + 0.6, ROOM_HI - 0.2, (256, 3)), jnp.float32)
    d = rng.normal(size=(256, 3))
    d = jnp.asarray(d / np.linalg.norm(d, axis=1, keepdims=True), jnp.float32)
    r_split = trace_light_field(make_tracer(split, room.bounds), o, d)
    r_same = trace_light_field(make_tracer(same, room.bounds), o, d)
    np.testing.assert_array_equal(np.asarray(r_split.status), np.asarray(r_same.status))
    np.testing.assert_array_equal(np.asarray(r_split.t), np.asarray(r_same.t))
    assert np.asarray(r_split.hit).mean() > 0.5  # the rays do hit walls: the comparison has content


@pytest.mark.parametrize("g", [4, 8, 12, 6, 5])
def test_tile_order_round_trips(g):
    """The bake's tile order (4×4 tiles, or rows where G is no multiple of 4) is a permutation of the
    texels, undone by ``_from_tiles`` for several probes at once, with channels."""
    from probeplace.probes._bake import _from_tiles, _to_tiles

    maps = np.arange(3 * g * g * 2).reshape(3, g, g, 2)
    flat = np.concatenate([_to_tiles(m) for m in maps])
    np.testing.assert_array_equal(_from_tiles(flat, 3, g), maps)
    if g % 4 == 0:  # the first 16 rays are the top-left 4×4 tile
        np.testing.assert_array_equal(np.sort(flat[:16, 0]), np.sort(maps[0, :4, :4, 0].ravel()))


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


def test_moments_of_constant_distance_match_numpy():
    dist = jnp.full((2, 16, 16), 3.0, jnp.float64)
    m = np.asarray(distance_moments(dist, 4, 50.0))
    np.testing.assert_allclose(m[..., 0], 3.0, rtol=1e-12)
    np.testing.assert_allclose(m[..., 1], 9.0, rtol=1e-12)


def test_moments_in_passes_are_the_whole_sets(monkeypatch):
    """The bake's moments pass by pass (``_chunked_moments``: 3 probes a pass here, the last pass 1) equal
    one pass over all 7: rows are independent. Tolerance: a different matrix shape may sum a row's
    16² products in another order, float32 eps × 256 terms of one sign."""
    from probeplace.probes import _bake

    rng = np.random.default_rng(0)
    dist = rng.uniform(0.5, 4.0, (7, 16, 16)).astype(np.float32)
    monkeypatch.setattr(_bake, "_MOMENTS_PASS_BYTES", 3 * 16 * 16 * 4)
    got = np.asarray(_bake._chunked_moments(dist, BakeConfig()))
    whole = np.asarray(
        distance_moments(jnp.asarray(dist), BakeConfig().moments_res, BakeConfig().moment_power)
    )
    assert got.shape == whole.shape == (7, 16, 16, 2)
    np.testing.assert_allclose(got, whole, rtol=256 * 2**-23)


def test_host_maps_are_aligned_for_jax_to_share():
    from probeplace.probes import _bake

    a = _bake._host_maps((3, 5, 5, 2), np.int16)
    assert a.shape == (3, 5, 5, 2) and a.dtype == np.int16 and a.ctypes.data % 64 == 0
    a[:] = 7
    assert (np.asarray(jax.device_put(a)) == 7).all()


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
    # every leaf (maps, backface, the settings' numbers) and the static structure (settings' names)
    assert jax.tree.structure(back) == jax.tree.structure(lf)
    for a, b in zip(jax.tree.leaves(lf), jax.tree.leaves(back), strict=True):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert back.bake.to_dict() == lf.bake.to_dict()
    assert back.bake.scene == "test_room" and back.bake.radiance == "custom"
    # a memory budget divides by probe_bytes: the bytes the baked arrays of one probe really hold
    held = sum(np.asarray(a).nbytes for a in jax.tree.leaves(lf) if np.ndim(a) and a.shape[0] == 1)
    assert probe_bytes(room, cfg) == held
    assert int(back.bake.n_sub) == 2 and int(back.bake.radiance_res) == 8
    # a file of format 1 (float32 normals, distance MIPs) loads, its normals packed as a bake packs them
    v1 = {k: np.asarray(getattr(lf, k)) for k in ("pos_world", "active", "inside", "radiance", "emission")}
    v1 |= {k: np.asarray(getattr(lf, k)) for k in ("distance", "irradiance", "moments", "far", "backface")}
    v1 |= {"normal": np.asarray(lf.normal), "format": np.asarray("probeplace.LightFieldProbes/1")}
    v1 |= {"distance_min_mip1": np.zeros((1, 4, 4), np.float32), "distance_max_mip1": np.zeros((1, 4, 4))}
    np.savez(tmp_path / "v1.npz", **v1)
    old = load_probes(tmp_path / "v1.npz")
    np.testing.assert_array_equal(np.asarray(old.distance), np.asarray(lf.distance))
    np.testing.assert_allclose(np.asarray(old.normal), np.asarray(lf.normal), atol=1e-4)
    assert old.normal16.dtype == jnp.int16 and old.bake is None
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ProbeplaceError, match="not a readable"):
        load_probes(tmp_path / "bad.npz")
    with pytest.raises(ProbeplaceError, match="not found"):
        load_probes(tmp_path / "missing.npz")


@pytest.mark.parametrize(
    "kwargs",
    [
        {"radiance_res": 12},
        {"geometry_res": 24},
        {"geometry_res": True},
        {"n_sub": 0},
        {"moment_power": -1.0},
        {"inside_backface_share": 1.5},
        {"inside_test": "parity"},
        {"inside_neighbours": 0},
    ],
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


FURNACE_RHO, FURNACE_LE, FURNACE_DEPTH = 0.5, 1.0, 3


@pytest.fixture(scope="module")
def furnace():
    """A closed box whose walls all emit L_e and reflect albedo ρ (Lambert), a camera inside, one probe
    baked with the path tracer at depth 3 (the depth of an evaluation with max_depth 4)."""
    from probeplace.render import default_caster

    v, f = box((0.0, 0.0, 0.0), (2.0, 2.0, 2.0))
    mats = make_materials(["wall"], np.full((1, 3), FURNACE_RHO), emission=np.full((1, 3), FURNACE_LE))
    cam = make_camera((1.0, 1.0, 0.2), (1.0, 1.0, 2.0), 60.0, "inside")
    scene = build_scene("furnace", v, f[:, ::-1], np.zeros(len(f), int), mats, views=(cam,))
    caster = default_caster(scene)
    probes = ProbeSet(pos_world=jnp.asarray([[0.7, 1.1, 1.3]], jnp.float32), active=jnp.ones(1, bool))
    lf = bake_probes(
        scene,
        probes,
        caster=caster,
        radiance_fn=path_traced_radiance(scene, spp=32, max_depth=FURNACE_DEPTH, specular=0.0, caster=caster),
        key=jax.random.key(5),
        config=BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=2, progress=False),
    )
    return scene, lf


def test_path_traced_bake_matches_the_furnace_closed_form(furnace):
    """Inside the furnace box a probe sees emission L_e in every direction and reflected radiance
    ρL_e + ρ²L_e with paths of at most three segments (no Russian roulette before depth 5): an exact
    oracle for every texel of every map."""
    _, lf = furnace
    rho, le = FURNACE_RHO, FURNACE_LE
    emission = np.asarray(strip_border(lf.emission))
    reflected = np.asarray(strip_border(lf.radiance))
    np.testing.assert_allclose(emission, le, rtol=1e-5)
    expected = rho * le + rho**2 * le
    assert abs(reflected.mean() - expected) < 0.01 * expected  # 64 texels × 128 paths
    assert np.abs(reflected - expected).max() < 0.15 * expected  # per texel: 128 paths
    # Irradiance from reflected radiance: E = π · const for every receiver normal.
    np.testing.assert_allclose(np.asarray(lf.irradiance).mean(), np.pi * reflected.mean(), rtol=0.02)


def test_path_depth_rule_is_one_definition():
    """A texel replaces the rest of a camera path after its first bounce: one segment fewer."""
    assert [bake_depth_for(d) for d in (2, 3, 4, 8)] == [1, 2, 3, 7]
    for bad in (1, 0, -3):  # (non-ints are refused too; beartype checks the annotation in tests)
        with pytest.raises(ConfigError, match="max_depth"):
            bake_depth_for(bad)


def test_bake_settings_are_recorded_and_round_trip(furnace, tmp_path):
    _, lf = furnace
    b = lf.bake
    assert (b.scene, b.radiance) == ("furnace", "path_traced")
    assert (int(b.path_depth), int(b.spp), int(b.n_sub), int(b.radiance_res)) == (FURNACE_DEPTH, 32, 2, 8)
    assert float(b.specular) == 0.0
    np.testing.assert_array_equal(np.asarray(b.key), np.asarray(jax.random.key_data(jax.random.key(5))))
    back = load_probes(save_probes(tmp_path / "f.npz", lf))
    assert back.bake.to_dict() == b.to_dict()
    # the evaluation that matches (camera depth = path depth + 1, same specular factor) is accepted
    check_bake_settings(back, scene_name="furnace", eval_max_depth=FURNACE_DEPTH + 1, specular=0.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (
            {"eval_max_depth": 8, "specular": 0.0},
            r"baked with path depth 3 but evaluation max_depth=8 needs 7 .*--max-depth 8 .*--max-depth 4",
        ),
        ({"eval_max_depth": 4}, r"baked with specular=0 but the evaluation renders specular=1"),
        ({"scene_name": "cornell_box", "eval_max_depth": 4, "specular": 0.0}, r"baked in scene 'furnace'"),
    ],
)
def test_mismatched_evaluation_is_refused(furnace, kwargs, match):
    _, lf = furnace
    with pytest.raises(ConfigError, match=match) as e:
        check_bake_settings(lf, **{"scene_name": "furnace", **kwargs})
    assert "\n" not in str(e.value)  # one line


def test_evaluate_refuses_a_mismatched_bake_before_rendering(furnace):
    from probeplace.evaluate import EvalConfig, evaluate

    scene, lf = furnace
    with pytest.raises(ConfigError, match="path depth 3 but evaluation max_depth=8"):
        evaluate(scene, lf, view="inside", config=EvalConfig(width=4, height=4, max_depth=8))


def test_old_file_without_settings_is_refused(furnace, tmp_path):
    """A file saved before bake settings were recorded still loads (export, inspection) but is refused
    for evaluation, naming the fix."""
    _, lf = furnace
    path = save_probes(tmp_path / "new.npz", lf)
    with np.load(path) as z:
        old = {k: z[k] for k in z.files if k not in ("bake_settings", "backface")}
    np.savez(tmp_path / "old.npz", **old)
    back = load_probes(tmp_path / "old.npz")
    assert back.bake is None and back.backface is None
    with pytest.raises(ConfigError, match=r"predates recorded bake settings.*re-bake"):
        check_bake_settings(back, scene_name="furnace", eval_max_depth=4)


def test_cli_refuses_a_baked_file_of_another_depth(tmp_path, capsys, getkey):
    """``probeplace evaluate --probes x.npz`` checks the file's settings before rendering anything."""
    from probeplace.cli import main
    from probeplace.scene import load_scene

    scene = load_scene("cornell_box")
    lf = bake_probes(
        scene,
        ProbeSet(pos_world=jnp.asarray([[278.0, 400.0, 280.0]], jnp.float32), active=jnp.ones(1, bool)),
        caster=BruteForceCaster(scene),
        radiance_fn=_constant_radiance(0.1),
        key=getkey(),
        config=BakeConfig(radiance_res=4, irradiance_res=4, moments_res=4, n_sub=1, progress=False),
    )
    wrong = eqx.tree_at(
        lambda m: m.bake,
        lf,
        BakeSettings(
            path_depth=jnp.asarray(3, jnp.int32),
            spp=jnp.asarray(4, jnp.int32),
            n_sub=jnp.asarray(1, jnp.int32),
            radiance_res=jnp.asarray(4, jnp.int32),
            specular=jnp.asarray(1.0, jnp.float32),
            key=jnp.zeros(2, jnp.uint32),
            scene="cornell_box",
        ),
    )
    path = save_probes(tmp_path / "d3.npz", wrong)
    argv = ["evaluate", "--scene", "cornell_box", "--probes", str(path), "--out", str(tmp_path / "ev")]
    assert main([*argv, "--max-depth", "8"]) == 2
    err = capsys.readouterr().err
    assert "path depth 3 but evaluation max_depth=8 needs 7" in err and err.count("\n") == 1
    assert not (tmp_path / "ev").exists()
    # inputs are checked before anything is loaded or baked
    assert main([*argv, "--max-depth", "2"]) == 2
    assert "EvalConfig.max_depth must be ≥ 3, got 2" in capsys.readouterr().err
    assert main([*argv, "--save-baked", str(tmp_path / "x.npz")]) == 2
    assert "already baked" in capsys.readouterr().err


def test_cli_checks_backend_and_geometry_res_before_loading(tmp_path, capsys, monkeypatch):
    import probeplace.render as render
    from probeplace.cli import main

    def no_llvm():
        raise ImportError("backend='mitsuba': no LLVM here")

    # patched on the public face the command reads it from (a lazy name, cached there once read)
    monkeypatch.setattr(render, "load_mitsuba", no_llvm)
    probes = tmp_path / "p.json"  # never read: the checks come first
    argv = ["evaluate", "--scene", "no_such_scene", "--probes", str(probes), "--out", str(tmp_path / "ev")]
    assert main([*argv, "--backend", "mitsuba"]) == 2
    err = capsys.readouterr().err
    assert "--backend mitsuba" in err and "no LLVM here" in err and err.count("\n") == 1
    assert main([*argv, "--geometry-res", "24"]) == 2
    assert "geometry_res must be a power of two" in capsys.readouterr().err
    assert not (tmp_path / "ev").exists()


def _quad_scene(z: float = 1.0):
    """One unit quad in the plane z = ``z`` whose winding makes its geometric normal +Z (a one-sided
    sheet), no light (the geometry maps need none)."""
    v = np.array([[-1.0, -1.0, z], [1.0, -1.0, z], [1.0, 1.0, z], [-1.0, 1.0, z]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    mats = make_materials(["sheet"], np.array([[0.5, 0.5, 0.5]]))
    return build_scene("sheet", v, f, np.zeros(2, int), mats)


def test_stored_normal_faces_the_probe_and_backface_is_marked(getkey):
    """A probe behind a one-sided quad (z < 1, geometric normal +Z) sees its back: the stored normal is
    flipped to face the probe and every texel that hits the quad is marked ``backface``; a probe in
    front sees the front: same normal direction toward it, no back face."""
    scene = _quad_scene()
    p = jnp.asarray([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]], jnp.float32)  # behind, in front
    lf = bake_probes(
        scene,
        ProbeSet(pos_world=p, active=jnp.ones(2, bool)),
        caster=BruteForceCaster(scene),
        radiance_fn=_constant_radiance(0.0),
        key=getkey(),
        config=BakeConfig(radiance_res=16, irradiance_res=4, moments_res=4, n_sub=1, progress=False),
    )
    d = np.asarray(texel_directions(16, jnp.float64)).reshape(-1, 3)
    n = np.asarray(strip_border(lf.normal)).reshape(2, -1, 3)
    back = np.asarray(lf.backface)[:, 1:-1, 1:-1].reshape(2, -1)
    hit = np.asarray(strip_border(lf.distance[..., None]))[..., 0].reshape(2, -1) < float(lf.far)
    assert hit.sum(axis=1).min() > 10
    for i, expect_back in ((0, True), (1, False)):
        facing = np.sum(n[i] * -d, axis=-1)
        assert np.all(facing[hit[i]] > 0), i
        np.testing.assert_allclose(np.abs(n[i][hit[i], 2]), 1.0, atol=1e-6)  # ±Z, the quad's plane
        assert np.all(back[i][hit[i]] == expect_back) and not back[i][~hit[i]].any()
        assert np.all(n[i][~hit[i]] == 0.0)
    # the bordered maps keep the layout: border texels copy interior ones
    assert lf.backface.shape == lf.distance.shape and lf.backface.dtype == jnp.bool_


def _solid_box_scene(winding: str, *, views=()):
    """A closed solid box (outward faces when ``winding == "consistent"``; every face flipped; or every
    other face flipped) standing in open space."""
    v, f = box((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    if winding == "flipped":
        f = f[:, ::-1]
    elif winding == "half":
        f = np.where((np.arange(len(f)) % 2 == 0)[:, None], f[:, ::-1], f)
    mats = make_materials(["stone"], np.array([[0.5, 0.5, 0.5]]))
    return build_scene(f"box_{winding}", v, f, np.zeros(len(f), int), mats, views=views)


def _inside_flags(scene, pos, getkey, **cfg):
    lf = bake_probes(
        scene,
        ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool)),
        caster=BruteForceCaster(scene),
        radiance_fn=_constant_radiance(0.0),
        key=getkey(),
        config=BakeConfig(radiance_res=8, irradiance_res=4, moments_res=4, n_sub=1, progress=False, **cfg),
    )
    return np.asarray(lf.inside).tolist()


@pytest.mark.parametrize("winding", ["consistent", "flipped", "half"])
def test_inside_a_closed_box_whatever_its_winding(winding, getkey):
    """The reach test reads no winding: inside the box is inside, outside is not, for consistent, fully
    flipped and half-flipped faces. (The back-face test misses the probe inside the flipped box.)"""
    scene = _solid_box_scene(winding)
    pos = [[0.4, 0.55, 0.45], [2.0, 0.5, 0.5], [0.5, 1.6, -0.7]]  # inside, two outside
    assert _inside_flags(scene, pos, getkey) == [True, False, False]
    if winding == "flipped":
        assert _inside_flags(scene, pos, getkey, inside_test="backface") == [False, False, False]
    assert _inside_flags(scene, pos, getkey, inside_test="none") == [False, False, False]


@pytest.mark.parametrize("winding", ["consistent", "half"])
def test_inside_in_a_closed_room_seen_from_a_camera(room, winding, getkey):
    """A closed room (single-sheet walls, nothing escapes): the view camera inside seeds free space, so
    the room's probes are free and the block's probe is inside, with the room's and the block's faces
    half flipped too. Without a view a closed scene has no free-space seed and the test falls back on
    the winding (``test_probe_inside_a_solid_is_flagged``)."""
    v, f = np.asarray(room.vertices), np.asarray(room.faces)
    if winding == "half":
        f = np.where((np.arange(len(f)) % 2 == 0)[:, None], f[:, ::-1], f)
    cam = make_camera((3.5, 1.5, 0.5), (2.0, 1.5, 4.0), 60.0, "view")
    scene = build_scene("room_view", v, f, np.asarray(room.tri_material), room.materials, views=(cam,))
    pos = [[1.0, 0.5, 1.0], [3.0, 1.5, 3.0], [0.3, 2.7, 4.7], [3.7, 0.2, 0.3]]  # block, room ×3
    assert _inside_flags(scene, pos, getkey) == [True, False, False, False]


def test_inside_verdict_does_not_grow_leaky_with_the_geometry_resolution(getkey):
    """A solid box whose top has a slit 0.02 wide (a crack between two slabs): from the probe at its
    centre, 64² texel-centre rays find the slit and the probe counts as free (the reach test's stated
    limit), 8² rays do not. With ``inside_res`` 8 a 64² bake casts the reach test's rays as an 8² one does
    (every 8th texel per axis), and keeps the 8² verdict: on Crytek Sponza 512² rays found cracks for 776
    of the 792 grid probes in walls and roof."""
    slabs = [((0, 0, 0), (1, 0.05, 1)), ((0, 0, 0), (0.05, 1, 1)), ((0.95, 0, 0), (1, 1, 1))]
    slabs += [((0, 0, 0), (1, 1, 0.05)), ((0, 0, 0.95), (1, 1, 1))]
    slabs += [((0, 0.95, 0), (0.49, 1, 1)), ((0.51, 0.95, 0), (1, 1, 1))]  # the top, slit at x = 0.5
    parts = [box(np.asarray(lo, float), np.asarray(hi, float)) for lo, hi in slabs]
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    v = np.concatenate([v for v, _ in parts])
    f = np.concatenate([f + o for (_, f), o in zip(parts, offsets, strict=True)])
    mats = make_materials(["stone"], np.array([[0.5, 0.5, 0.5]]))
    scene = build_scene("slit_box", v, f, np.zeros(len(f), int), mats)
    pos = [[0.5, 0.5, 0.5], [2.0, 0.5, 0.5]]  # inside, outside
    assert _inside_flags(scene, pos, getkey) == [True, False]  # 8² geometry
    assert _inside_flags(scene, pos, getkey, geometry_res=64, inside_res=64) == [False, False]
    assert _inside_flags(scene, pos, getkey, geometry_res=64, inside_res=8) == [True, False]


def test_inside_agrees_with_the_winding_where_the_winding_is_right(cornell, getkey):
    """The Cornell box's winding is consistent, so the back-face test is right there: both tests flag the
    same probes of a 4×4×4 grid (those in the two blocks)."""
    lo, hi = (np.asarray(b, np.float64) for b in cornell.bounds)
    ax = [(np.arange(4) + 0.5) / 4] * 3
    pos = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo
    reach = _inside_flags(cornell, pos, getkey)
    back = _inside_flags(cornell, pos, getkey, inside_test="backface")
    assert reach == back and 0 < sum(reach) < 8


def test_experiment_config_has_one_path_depth():
    """The runner bakes at ``bake_depth_for(tracer.max_depth)``: there is no bake depth to disagree with
    the evaluation's, and an old config that sets one is refused naming both keys."""
    import dataclasses

    from probeplace.experiment import BakeStage as BakeSchema
    from probeplace.experiment import to_config

    assert "max_depth" not in {f.name for f in dataclasses.fields(BakeSchema)}
    with pytest.raises(ConfigError, match=r"bake\.max_depth=4: .*tracer\.max_depth − 1"):
        to_config({"bake": {"max_depth": 4}, "tracer": {"max_depth": 4}})


def test_padding_to_a_capacity_changes_no_real_probe(room, getkey):
    """Probe counts are padded to a few capacities (8, 16, 32, 64, then multiples of 64) so that programs
    compiled for one count serve the next (issue 32); the padding rows are inactive and every real
    probe's maps are those of the unpadded bake."""
    caps = {n: padded_capacity(n) for n in (1, 5, 8, 9, 16, 17, 33, 64, 65, 128, 129, 200)}
    want = {1: 8, 5: 8, 8: 8, 9: 16, 16: 16, 17: 32, 33: 64, 64: 64, 65: 128, 128: 128, 129: 192}
    assert caps == want | {200: 256}
    pos = np.array([[2.0, 1.5, 2.5], [3.0, 2.0, 1.0], [1.0, 2.5, 3.0]], np.float32)
    probes = ProbeSet(pos_world=jnp.asarray(pos), active=jnp.ones(3, bool))
    padded = pad_probes(probes)
    assert padded.capacity == 8 and int(padded.n_active) == 3
    np.testing.assert_array_equal(np.asarray(padded.pos_world)[:3], pos)
    assert pad_probes(padded) is padded  # already at a capacity
    cfg = BakeConfig(radiance_res=4, irradiance_res=2, moments_res=2, n_sub=1, progress=False)
    kw = dict(caster=BruteForceCaster(room), radiance_fn=_constant_radiance(0.25), config=cfg)
    key = getkey()
    a = bake_probes(room, probes, key=key, **kw)
    b = bake_probes(room, padded, key=key, **kw)
    assert not np.asarray(b.active)[3:].any()
    # the same exact rays per real probe; only the batch around them differs (a few ulps at most of t)
    for f in ("distance", "normal", "radiance", "irradiance", "moments"):
        got, want = np.asarray(getattr(b, f))[:3], np.asarray(getattr(a, f))
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(b.inside)[:3], np.asarray(a.inside))
