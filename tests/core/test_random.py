"""Named random streams: one key per consumer, derived from the run's seed (``_core.maths._random``)."""

from __future__ import annotations

import jax
import numpy as np

from probeplace._core import host_rng, stream


def _data(key):
    return np.asarray(jax.random.key_data(key))


def test_two_consumers_get_different_streams_and_a_rerun_the_same():
    a, b = stream(0, "coverage"), stream(0, "refine")
    assert not np.array_equal(_data(a), _data(b))
    assert not np.array_equal(jax.random.uniform(a, (8,)), jax.random.uniform(b, (8,)))
    np.testing.assert_array_equal(_data(stream(0, "coverage")), _data(a))  # a rerun: the same key
    assert not np.array_equal(_data(stream(1, "coverage")), _data(a))  # another seed: another key
    # the root key itself is no consumer's stream (re-creating it cannot collide with one)
    assert not np.array_equal(_data(jax.random.key(0)), _data(a))


def test_host_generators_follow_their_key():
    x = host_rng(stream(3, "search")).integers(1 << 30, size=4)
    np.testing.assert_array_equal(host_rng(stream(3, "search")).integers(1 << 30, size=4), x)
    assert not np.array_equal(host_rng(stream(3, "vardis-tet")).integers(1 << 30, size=4), x)
