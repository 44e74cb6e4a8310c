"""Determinism (issue 9): the same config and seed give bit-identical probe sets for every placer in
``placement.METHODS``, and bit-identical bake maps and render images for the same key.

Oracle: the first run. Two runs in one process (the second sees warm jit and SDF caches, so a cache that
changed results would show), and under ``slow`` one run in a fresh subprocess.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from probeplace.placement import METHODS, REFINERS, place

# Small settings per method so the default run stays fast; the slow variants use the same ones.
OPTIONS: dict[str, dict] = {
    "skeleton": dict(budget=4),
    "medial": dict(budget=4),
    "skeleton+medial": dict(budget=4),
    "grid": dict(options={"dims": (3, 3, 3), "inside": "disable"}),
    "lod-grid": dict(options={"base_divisions": (2, 2, 2), "levels": 2}),
    "vardis": dict(
        budget=8, options={"dense_probes": 64, "n_eval": 64, "n_dirs": 64, "spp": 2, "max_depth": 3}
    ),
}
# Default run: the three seeders (seconds each); grid / lod-grid (~20 s: their own coverage compile) and
# vardis (~40 s: path-traced probe values) run under ``-m slow``.
FAST = ("skeleton", "medial", "skeleton+medial")


def _digest(probes) -> str:
    pos = np.ascontiguousarray(np.asarray(probes.pos_world))
    act = np.ascontiguousarray(np.asarray(probes.active))
    return hashlib.sha256(pos.tobytes() + act.tobytes() + str(pos.dtype).encode()).hexdigest()


def _run(scene, method, seed=3, **extra):
    placed = place(scene, method=method, seed=seed, **{**OPTIONS.get(method, {}), **extra})
    return placed.probes, placed.metadata


def _assert_same(a, b):
    np.testing.assert_array_equal(np.asarray(a.pos_world), np.asarray(b.pos_world))
    np.testing.assert_array_equal(np.asarray(a.active), np.asarray(b.active))
    assert _digest(a) == _digest(b)


def _params():
    out = []
    for m in METHODS:
        marks = [] if m in FAST else [pytest.mark.slow]
        out.append(pytest.param(m, id=m, marks=marks))
    return out


@pytest.mark.parametrize("method", _params())
def test_placer_is_bit_identical_for_the_same_seed(cornell, method):
    a, meta_a = _run(cornell, method)
    b, meta_b = _run(cornell, method)
    _assert_same(a, b)
    for key in ("coverage", "n_probes"):
        if key in meta_a:
            assert meta_a[key] == meta_b[key], key


@pytest.mark.slow
@pytest.mark.parametrize("refiner", REFINERS)
def test_refined_placement_is_bit_identical(cornell, refiner):
    a, _ = _run(cornell, "skeleton", refiner=refiner, n_opt_samples=300)
    b, _ = _run(cornell, "skeleton", refiner=refiner, n_opt_samples=300)
    _assert_same(a, b)


_CHILD = """
import hashlib, json, sys
import jax
import numpy as np
jax.config.update("jax_enable_x64", {x64!r})
from probeplace.scene import cornell_box
from probeplace.placement import place
sys.path.insert(0, {root!r})
from tests.reliability.test_determinism import OPTIONS, _digest
out = {{}}
for m in {methods!r}:
    out[m] = _digest(place(cornell_box(), method=m, seed=3, **OPTIONS[m]).probes)
print(json.dumps(out))
"""


@pytest.mark.slow
def test_fresh_process_gives_the_same_probe_sets(cornell, tmp_path):
    """A fresh interpreter with an empty SDF cache reproduces the in-process digests (no cache effect).
    The child enables x64 like tests/conftest.py: see the next test for why that matters."""
    root = str(Path(__file__).resolve().parents[2])
    methods = list(FAST)
    env = {**__import__("os").environ, "PROBEPLACE_CACHE_DIR": str(tmp_path)}
    r = subprocess.run(
        [sys.executable, "-c", _CHILD.format(root=root, methods=methods, x64=True)],
        capture_output=True, text=True, timeout=600, cwd=root, env=env,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    child = json.loads(r.stdout.strip().splitlines()[-1])
    for m in methods:
        assert child[m] == _digest(_run(cornell, m)[0]), m


@pytest.mark.slow
@pytest.mark.xfail(
    reason="medial seeds depend on jax_enable_x64 (~0.1 mm–1 mm moves in the Cornell box): some library "
    "code in placement/skeleton/_seeds.py is not float32-clean; reported to the lead",
    strict=False,
)
def test_placement_does_not_depend_on_x64(tmp_path):
    """Library code is float32 (STYLE §4): the same placement with x64 off (users) and on (tests)."""
    root = str(Path(__file__).resolve().parents[2])
    env = {**__import__("os").environ, "PROBEPLACE_CACHE_DIR": str(tmp_path)}
    out = []
    for x64 in (False, True):
        r = subprocess.run(
            [sys.executable, "-c", _CHILD.format(root=root, methods=list(FAST), x64=x64)],
            capture_output=True, text=True, timeout=600, cwd=root, env=env,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr[-3000:]
        out.append(json.loads(r.stdout.strip().splitlines()[-1]))
    assert out[0] == out[1]


# ------------------------------------------------------------------------------------- bake / render
def _leaves_equal(a, b):
    la, lb = jax.tree_util.tree_leaves(a), jax.tree_util.tree_leaves(b)
    assert len(la) == len(lb)
    for x, y in zip(la, lb, strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


@pytest.mark.parametrize("texel_rays", ["surfel", "jittered"])
def test_bake_is_bit_identical_for_the_same_key(cornell, texel_rays):
    """The key draws the radiance function's samples (paths) and, for ``"jittered"`` texel rays, the
    texel directions: same key → the same maps, bit for bit; another key → different radiance maps (so the
    comparison is not vacuous). Same layout as the ``cornell_baked`` fixture, so the caster's compile is
    shared."""
    from .catalogue import bake

    def radiance(o, d, k):  # direction-dependent (the jitter shows) and drawing from its key (as paths do)
        n = o.shape[0]
        u = jax.random.uniform(k, (n, 1), o.dtype)
        return (d * 0.5 + 0.5 + 0.01 * u).astype(o.dtype), jax.numpy.zeros((n, 3), o.dtype)

    from .conftest import cornell_probes

    pos = cornell_probes(cornell)[:2]
    run = lambda k: bake(
        cornell, pos, radiance_res=16, radiance_fn=radiance, key=jax.random.key(k), texel_rays=texel_rays
    )
    a, b, c = run(5), run(5), run(6)
    _leaves_equal(a, b)
    assert not np.array_equal(np.asarray(a.radiance), np.asarray(c.radiance))


@pytest.mark.slow
def test_path_traced_bake_and_render_are_bit_identical(cornell):
    from probeplace._core import ProbeSet
    from probeplace.geometry import BruteForceCaster
    from probeplace.probes import BakeConfig, bake_probes, path_traced_radiance
    from probeplace.render import RenderConfig, render

    from .conftest import cornell_probes

    caster = BruteForceCaster(cornell)
    probes = ProbeSet(
        pos_world=jax.numpy.asarray(cornell_probes(cornell)[:2]), active=jax.numpy.ones(2, bool)
    )
    cfg = BakeConfig(
        radiance_res=8, irradiance_res=4, moments_res=4, n_sub=1, probes_per_batch=1, progress=False
    )
    fn = path_traced_radiance(cornell, spp=2, max_depth=3, caster=caster)
    bake = lambda: bake_probes(
        cornell, probes, caster=caster, radiance_fn=fn, key=jax.random.key(1), config=cfg
    )
    _leaves_equal(bake(), bake())
    rc = RenderConfig(width=8, height=8, spp=2, max_depth=3, progress=False)
    _leaves_equal(render(cornell, "front", rc, key=7), render(cornell, "front", rc, key=7))


@pytest.mark.slow  # the path tracer's compile: ~20 s on 2 cores
def test_render_is_bit_identical_for_the_same_key(cornell):
    from probeplace.render import RenderConfig, render

    rc = RenderConfig(width=6, height=4, spp=2, max_depth=2, progress=False)
    a = render(cornell, "front", rc, key=11)
    b = render(cornell, "front", rc, key=11)
    c = render(cornell, "front", rc, key=12)
    _leaves_equal(a, b)
    assert not np.array_equal(np.asarray(a.mean), np.asarray(c.mean))
