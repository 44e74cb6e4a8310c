"""The shared wavefront lane scheduler (``_core.maths._lanes``) against a slow loop that hands out a queue by
hand: free lanes take the next rays in lane order, a finished lane's result lands in its ray's row."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from probeplace._core import take_queued, write_finished


def _slow_take(free, head, n):
    ray, take = np.full(len(free), -1), np.zeros(len(free), bool)
    for lane, f in enumerate(free):
        if f and head < n:
            ray[lane], take[lane], head = head, True, head + 1
    return ray, take, head


@pytest.mark.parametrize("seed", range(6))
def test_free_lanes_take_the_queue_in_lane_order(seed):
    rng = np.random.default_rng(seed)
    w, n = int(rng.integers(1, 40)), int(rng.integers(0, 60))
    free, head = rng.random(w) < 0.5, int(rng.integers(0, n + 2))
    ray, take, new_head = take_queued(jnp.asarray(free), jnp.asarray(head, jnp.int32), n)
    want = _slow_take(free, head, n)
    np.testing.assert_array_equal(np.asarray(ray), want[0])
    np.testing.assert_array_equal(np.asarray(take), want[1])
    assert int(new_head) == want[2]


def test_a_drained_queue_leaves_free_lanes_idle_and_the_head_at_n():
    ray, take, head = take_queued(jnp.ones(8, bool), jnp.asarray(5, jnp.int32), 7)
    assert np.asarray(ray).tolist() == [5, 6, -1, -1, -1, -1, -1, -1]
    assert np.asarray(take).sum() == 2 and int(head) == 7


@pytest.mark.parametrize("rows", ["n", "n + 1"])
def test_finished_lanes_write_their_ray_s_row_and_the_rest_nothing(rows):
    n = 6
    m = n if rows == "n" else n + 1
    out = (jnp.full(m, -1.0), jnp.zeros(m, jnp.int32))
    done = jnp.asarray([True, False, True, True])
    ray = jnp.asarray([4, 1, 0, -1])  # the last lane is idle (done, no ray: its row is the sink)
    t, k = write_finished(out, done & (ray >= 0), ray, (jnp.asarray([0.5, 9.0, 1.5, 7.0]), jnp.arange(4)), n)
    want_t, want_k = np.full(m, -1.0), np.zeros(m, int)
    want_t[[4, 0]], want_k[[4, 0]] = [0.5, 1.5], [0, 2]
    # rows 0 … n − 1 only: an (n + 1)-th row is the sink, written by every lane not done (in any order)
    np.testing.assert_array_equal(np.asarray(t)[:n], want_t[:n])
    np.testing.assert_array_equal(np.asarray(k)[:n], want_k[:n])
