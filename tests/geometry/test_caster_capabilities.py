"""Casters declare what they can do (``jittable``, ``occluded_host``); ``make_caster`` picks in one place."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import ConfigError
from probeplace.geometry import (
    BRUTE_FORCE_MAX_TRIANGLES,
    AbstractRayCaster,
    BruteForceCaster,
    BVHCaster,
    EmbreeCaster,
    EmbreeUnavailableError,
    make_caster,
)
from probeplace.geometry import _casters as casters_module
from probeplace.render import default_caster
from probeplace.scene import load_scene


def _rays(cornell, n=300, seed=0):
    rng = np.random.default_rng(seed)
    lo = np.asarray(cornell.vertices).min(0)
    hi = np.asarray(cornell.vertices).max(0)
    o = (lo + (hi - lo) * rng.uniform(0.1, 0.9, (n, 3))).astype(np.float32)
    d = rng.normal(size=(n, 3))
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    t_max = rng.uniform(0.05, 2.0, n).astype(np.float32) * float(np.max(hi - lo))
    return o, d, t_max


def test_every_caster_declares_whether_it_is_jittable():
    assert BruteForceCaster.jittable is True
    assert BVHCaster.jittable is True
    assert EmbreeCaster.jittable is False


def test_a_caster_without_the_capabilities_cannot_be_built(cornell):
    class Undeclared(AbstractRayCaster):
        def closest_hit(self, origins, directions, t_max=jnp.inf):
            raise NotImplementedError

        def occluded(self, origins, directions, t_max):
            raise NotImplementedError

        def occluded_host(self, origins, directions, t_max):
            raise NotImplementedError

    with pytest.raises(TypeError, match="abstract class attributes"):
        Undeclared()

    class NoHostQuery(AbstractRayCaster):
        jittable = False

        def closest_hit(self, origins, directions, t_max=jnp.inf):
            raise NotImplementedError

        def occluded(self, origins, directions, t_max):
            raise NotImplementedError

    with pytest.raises(TypeError, match="occluded_host"):
        NoHostQuery()


def test_capabilities_are_class_attributes_not_fields(cornell):
    import dataclasses

    for cls in (BruteForceCaster, BVHCaster, EmbreeCaster):
        assert "jittable" not in {f.name for f in dataclasses.fields(cls)}

    class Wrapper(AbstractRayCaster):  # a plain ``jittable = False`` declares it, as for Embree
        inner: BruteForceCaster
        jittable = False

        def closest_hit(self, origins, directions, t_max=jnp.inf):
            return self.inner.closest_hit(origins, directions, t_max)

        def occluded(self, origins, directions, t_max):
            return self.inner.occluded(origins, directions, t_max)

        def occluded_host(self, origins, directions, t_max):
            return self.inner.occluded_host(origins, directions, t_max)

    w = Wrapper(BruteForceCaster(cornell))
    assert w.jittable is False and [f.name for f in dataclasses.fields(w)] == ["inner"]


@pytest.mark.parametrize("backend", ["brute", "bvh", "embree"])
def test_occluded_host_is_occluded_on_the_host(cornell, backend):
    if backend == "embree":
        pytest.importorskip("embreex")
    caster = make_caster(cornell, backend)
    o, d, t_max = _rays(cornell)
    host = caster.occluded_host(o, d, t_max)
    assert isinstance(host, np.ndarray) and host.dtype == bool and host.shape == (len(o),)
    dev = np.asarray(caster.occluded(jnp.asarray(o), jnp.asarray(d), jnp.asarray(t_max)))
    np.testing.assert_array_equal(host, dev)
    assert 0 < host.sum() < len(o)  # the rays test both outcomes
    # every backend answers the same predicate (float32 rounding at t_max apart: none of these rays graze)
    np.testing.assert_array_equal(host, make_caster(cornell, "brute").occluded_host(o, d, t_max))


def test_auto_rule(cornell):
    pytest.importorskip("embreex")
    courtyard = load_scene("courtyard")
    assert cornell.n_triangles <= BRUTE_FORCE_MAX_TRIANGLES < courtyard.n_triangles
    expected = {
        ("host", "cornell"): EmbreeCaster,
        ("host", "courtyard"): EmbreeCaster,
        ("jit", "cornell"): BruteForceCaster,
        ("jit", "courtyard"): BVHCaster,
        ("render", "cornell"): BruteForceCaster,
        ("render", "courtyard"): EmbreeCaster,
    }
    scenes = {"cornell": cornell, "courtyard": courtyard}
    for (use, name), cls in expected.items():
        caster = make_caster(scenes[name], use=use)
        assert type(caster) is cls, (use, name)
        assert caster.jittable or use != "jit"
    # the path tracer's default is the "render" rule (as before: brute force for tiny scenes, else Embree)
    assert type(default_caster(cornell)) is BruteForceCaster
    assert type(default_caster(courtyard)) is EmbreeCaster
    with pytest.raises(ConfigError, match="unknown caster use"):
        make_caster(cornell, use="gpu")


def test_auto_without_embree_falls_back_to_the_bvh(cornell, monkeypatch):
    def unavailable(*args, **kwargs):
        raise EmbreeUnavailableError("embreex blocked by the test")

    monkeypatch.setattr(casters_module, "EmbreeCaster", unavailable)
    assert type(make_caster(cornell, use="host")) is BVHCaster
    assert type(make_caster(cornell, use="render")) is BruteForceCaster  # tiny: never needed Embree
    with pytest.raises(EmbreeUnavailableError):
        make_caster(cornell, "embree")


def test_binary_visibility_reads_the_capability(cornell):
    """A jittable caster goes through the padded jitted chunks, Embree through ``occluded_host``; both
    decide the same predicate."""
    pytest.importorskip("embreex")
    from probeplace.placement import binary_visibility, make_problem

    problem = make_problem(cornell, key=jax.random.key(0), n_samples=1500)
    lo, hi = np.asarray(problem.lo), np.asarray(problem.hi)
    pos = (lo + (hi - lo) * np.array([[0.3, 0.5, 0.4], [0.6, 0.2, 0.7]])).astype(np.float32)
    a = binary_visibility(problem, pos, caster=make_caster(cornell, "embree"))
    b = binary_visibility(problem, pos, caster=make_caster(cornell, "brute"))
    assert a.any()
    # float32 rounding of t_max may flip a handful of grazing rays between the two backends
    assert (a != b).mean() < 1e-3


def test_occluded_host_pads_batches_so_varying_sizes_share_one_program(cornell):
    """A JAX caster's host query pads its batch to a power of two (≥ 64) with rays that hit nothing: the
    bake's inside test and the fitness's camera test send batches of every size, and each size compiled
    ``occluded`` again (24 programs in ``make demo``). The answers are the unpadded query's."""
    from probeplace.geometry._raycast import _host_batch_size

    assert [_host_batch_size(n) for n in (0, 1, 64, 65, 65536, 65537)] == [64, 64, 64, 128, 65536, 131072]
    caster = make_caster(cornell, "brute")
    o, d, t_max = _rays(cornell)
    whole = np.asarray(caster.occluded(jnp.asarray(o), jnp.asarray(d), jnp.asarray(t_max)))
    caster.occluded_host(o[:65], d[:65], t_max[:65])  # the 128-ray program
    traces = BruteForceCaster.occluded._cached._cache_size()
    for n in (65, 100, 128):
        np.testing.assert_array_equal(caster.occluded_host(o[:n], d[:n], t_max[:n]), whole[:n])
    assert BruteForceCaster.occluded._cached._cache_size() == traces  # 65 … 128 rays: one program
    for n in (0, 1, 64):
        np.testing.assert_array_equal(caster.occluded_host(o[:n], d[:n], t_max[:n]), whole[:n])
    # a scalar t_max is broadcast to the rays
    np.testing.assert_array_equal(
        caster.occluded_host(o[:3], d[:3], 1e9), caster.occluded_host(o[:3], d[:3], [1e9] * 3)
    )
