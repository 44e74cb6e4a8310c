"""The runner's compile/run split of stage times (``experiment._run._timed``): the union of JAX's compile
spans, each counted once, and nothing for code already compiled."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import pytest

from probeplace.experiment._run import _covered_s, _timed

# compile time and compile counts as a fresh process sees them: no persistent compilation cache (issue 32)
pytestmark = pytest.mark.usefixtures("no_persistent_cache")


def test_covered_s_counts_overlaps_once_and_clips():
    # nested (a jit traced inside its caller's trace), overlapping, disjoint, and outside the window
    spans = [(1.0, 4.0), (2.0, 3.0), (3.5, 5.0), (6.0, 7.0), (-2.0, -1.0), (9.0, 12.0)]
    assert _covered_s(spans, 0.0, 10.0) == pytest.approx(4.0 + 1.0 + 1.0)  # [1,5] + [6,7] + [9,10]
    assert _covered_s([], 0.0, 1.0) == 0.0
    assert _covered_s([(0.5, 0.7), (0.2, 0.9)], 0.0, 1.0) == pytest.approx(0.7)


def test_timed_splits_compile_from_run():
    """A function compiled in the block: compile > 0 and compile + run == wall; the same call again, now
    cached: (almost) no compile time."""
    k = jnp.float32(1.7)

    @jax.jit
    def f(x):  # a fresh function: nothing cached for it
        for _ in range(20):
            x = jnp.sin(x) * k + jnp.cos(x)
        return x

    x = jnp.linspace(0.0, 1.0, 4096, dtype=jnp.float32)
    first: dict[str, float] = {}
    with _timed(first, "bake"):
        jax.block_until_ready(f(x))
    assert set(first) == {"bake_s", "bake_compile_s", "bake_run_s"}
    assert 0.0 < first["bake_compile_s"] <= first["bake_s"]
    assert first["bake_run_s"] >= 0.0
    assert first["bake_compile_s"] + first["bake_run_s"] == pytest.approx(first["bake_s"], rel=1e-12)
    again: dict[str, float] = {}
    with _timed(again, "bake"):
        jax.block_until_ready(f(x))
    assert again["bake_compile_s"] == 0.0  # no compile event at all for a cached executable


def test_timed_leaves_no_listener_behind_on_error():
    from jax._src import monitoring

    before = len(monitoring.get_event_time_span_listeners())
    timings: dict[str, float] = {}
    with pytest.raises(RuntimeError), _timed(timings, "place"):
        raise RuntimeError("stage failed")
    assert len(monitoring.get_event_time_span_listeners()) == before
    assert timings == {}  # a failed stage records nothing
