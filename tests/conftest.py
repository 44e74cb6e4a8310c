"""Test configuration: float64 available, strict promotion (STYLE §4), shared fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")

# JAX's persistent compilation cache (issue 32; probeplace._core.runtime._jax_cache): the suite keeps every
# compiled program in .cache/jax/<jax version tag> of this checkout (gitignored; one machine's, never
# shared), so a second `make test` loads what the first compiled. $PROBEPLACE_JAX_CACHE (a folder, or `off`)
# overrides it; child processes (the CLI and runner tests) inherit the setting. Tests that measure compile
# time use the ``no_persistent_cache`` fixture. XLA_FLAGS (make test-isa's --xla_cpu_max_isa) is part of
# JAX's cache key.
from probeplace._core.runtime._jax_cache import ENV as _JAX_CACHE_ENV  # noqa: E402
from probeplace._core.runtime._jax_cache import enable_compilation_cache  # noqa: E402

TEST_JAX_CACHE = Path(__file__).resolve().parents[1] / ".cache" / "jax"
enable_compilation_cache(os.environ.get(_JAX_CACHE_ENV) or str(TEST_JAX_CACHE))


def pytest_configure(config):
    # Two workers compiling the same program at once: one may read the entry while the other writes it (JAX
    # writes it in place). JAX then warns and compiles the program itself: a warning to show, not a failure.
    config.addinivalue_line("filterwarnings", "default:Error reading persistent compilation cache entry")


@pytest.fixture
def no_persistent_cache():
    """No persistent compilation cache inside the test: compile time measured is real compile time."""
    from probeplace._core.runtime._jax_cache import persistent_cache_disabled

    with persistent_cache_disabled():
        yield


#: The heaviest test files, heaviest first (worker seconds on 2 cores, measured 2026-12-02: 230–430 for the
#: first two, 110–190 for the rest). They are collected first so that pytest-xdist's ``--dist loadfile``
#: hands them out first: a long file handed out last runs alone while the other worker idles (the suite
#: took 17+ min on CI's 2 cores in collection order, ~13 min of work per worker).
HEAVY_FIRST = (
    "tests/probes/test_trace.py",
    "tests/probes/test_trace_cornell.py",
    "tests/probes/test_wavefront.py",
    "tests/probes/test_bake.py",
    "tests/probes/test_shade.py",
    "tests/evaluate/test_evaluate.py",
    "tests/geometry/test_sdf_trace.py",
    "tests/render/test_render.py",
    "tests/geometry/test_raycast_backends.py",
    "tests/evaluate/test_energy.py",
    "tests/placement/test_seeds_refine.py",
    "tests/placement/test_refiners_toy.py",
    "tests/placement/test_budget.py",
)


def pytest_collection_modifyitems(config, items):
    """Heaviest files first (:data:`HEAVY_FIRST`); the order inside a file and of the other files is
    kept (a stable sort). Every worker collects the same order, as xdist requires."""
    rank = {path: i for i, path in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


@pytest.fixture
def getkey():
    """A fresh PRNG key per call, deterministic per test."""
    key = jax.random.key(0)

    def _next():
        nonlocal key
        key, sub = jax.random.split(key)
        return sub

    return _next


@pytest.fixture(scope="session")
def cornell():
    from probeplace.scene import cornell_box

    return cornell_box()


@pytest.fixture
def no_slow_work(monkeypatch):
    """The slow stages — SDF and caster builds, placement, bake, evaluation — fail the test if a
    command reaches them: a refusal must come before any of them (a clock-free invariant; wall time
    on a shared machine is noise). The commands import these lazily from their packages, so patching
    the package attribute reaches them."""
    import probeplace.evaluate
    import probeplace.geometry
    import probeplace.placement
    import probeplace.probes
    import probeplace.render

    def boom(*a, **k):
        raise AssertionError("the command started slow work before refusing its input")

    for module, name in (
        (probeplace.geometry, "build_sdf"),
        (probeplace.geometry, "make_caster"),
        (probeplace.render, "default_caster"),
        (probeplace.placement, "place"),
        (probeplace.probes, "bake_probes"),
        (probeplace.evaluate, "evaluate"),
    ):
        monkeypatch.setattr(module, name, boom)
