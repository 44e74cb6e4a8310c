"""The bake-settings record on LightFieldProbes: JSON round trip, checks, and a pytree structure that
does not change with the seed or sample counts (so compiled shading code is shared across runs)."""

from __future__ import annotations

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import BAKE_SETTINGS_VERSION, BakeSettings, LightFieldProbes


def _settings(seed: int = 0, spp: int = 4, radiance: str = "path_traced", scene: str = "cornell_box"):
    return BakeSettings(
        path_depth=jnp.asarray(3, jnp.int32),
        spp=jnp.asarray(spp, jnp.int32),
        n_sub=jnp.asarray(2, jnp.int32),
        radiance_res=jnp.asarray(8, jnp.int32),
        specular=jnp.asarray(1.0 if radiance == "path_traced" else math.nan, jnp.float32),
        key=jnp.asarray(jax.random.key_data(jax.random.key(seed)), jnp.uint32),
        scene=scene,
        radiance=radiance,
    )


def _probes(bake=None, backface_shape=(2, 6, 6)):
    n, rb = 2, 6
    z = lambda *s: jnp.zeros((n, *s), jnp.float32)
    return LightFieldProbes(
        pos_world=z(3),
        active=jnp.ones(n, bool),
        inside=jnp.zeros(n, bool),
        radiance=z(rb, rb, 3),
        emission=z(rb, rb, 3),
        normal16=jnp.zeros((n, rb, rb, 2), jnp.int16),
        distance=z(rb, rb),
        irradiance=z(4, 4, 3),
        moments=z(4, 4, 2),
        far=jnp.float32(10.0),
        backface=jnp.zeros(backface_shape, bool),
        bake=bake,
    )


@pytest.mark.parametrize("radiance", ["path_traced", "custom"])
def test_settings_round_trip_through_json(radiance):
    s = _settings(seed=7, radiance=radiance)
    d = json.loads(json.dumps(s.to_dict(), allow_nan=False))  # plain JSON, no NaN
    assert d["version"] == BAKE_SETTINGS_VERSION and d["radiance"] == radiance
    assert d["specular"] == (1.0 if radiance == "path_traced" else None)
    back = BakeSettings.from_dict(d)
    assert back.to_dict() == s.to_dict()
    assert (back.scene, back.radiance, back.version) == (s.scene, s.radiance, s.version)
    for a, b in zip(jax.tree.leaves(s), jax.tree.leaves(back), strict=True):
        assert a.dtype == b.dtype
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_older_records_read_as_what_they_baked():
    """A version-2 record has no ``texel_rays``: its texels were jittered (and version 1 baked every
    lobe)."""
    d = _settings().to_dict()
    old = {k: v for k, v in d.items() if k not in ("texel_rays", "first_hit_lobes")} | {"version": 2}
    back = BakeSettings.from_dict(old)
    assert (back.texel_rays, back.first_hit_lobes, back.version) == ("jittered", "all", 2)
    assert BakeSettings.from_dict(d | {"texel_rays": "surfel"}).texel_rays == "surfel"


def test_bad_settings_and_backface_shape_are_refused():
    with pytest.raises(ValueError, match="radiance"):
        _settings(radiance="magic")
    with pytest.raises(ValueError, match="texel_rays"):
        BakeSettings.from_dict(_settings().to_dict() | {"texel_rays": "random"})
    # jaxtyping refuses it first where it checks (tests); __check_init__ everywhere else
    with pytest.raises((TypeError, ValueError), match="backface"):
        _probes(backface_shape=(2, 4, 4))
    with pytest.raises(KeyError):
        BakeSettings.from_dict({"scene": "x"})


def test_structure_does_not_depend_on_seed_or_counts():
    """Numbers are leaves, names static: runs that differ in seed or spp share one pytree structure (one
    compilation of every jitted function taking the probes); another scene is another structure."""
    a = _probes(_settings(seed=0, spp=4))
    b = _probes(_settings(seed=9, spp=16))
    assert jax.tree.structure(a) == jax.tree.structure(b)
    assert jax.tree.structure(a) != jax.tree.structure(_probes(_settings(scene="rooms")))
    assert _probes().bake is None  # probes built by hand carry no settings
