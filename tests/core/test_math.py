"""``next_pow2`` and ``padded_count``: the sizes host code pads batches to (closed forms and the clamps)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probeplace._core import next_pow2, padded_count


@pytest.mark.parametrize("n", [*range(0, 70), 127, 128, 129, 1000, 2**20, 2**20 + 1])
def test_smallest_power_of_two_not_below_n(n):
    want = 1 if n <= 1 else 2 ** math.ceil(math.log2(n))  # exact: log2 of a power of two is an integer
    assert next_pow2(n) == want
    assert next_pow2(np.int64(n)) == want  # NumPy counts work too


def test_lo_raises_and_hi_caps():
    assert [next_pow2(n, lo=8) for n in (0, 1, 5, 8, 9, 33)] == [8, 8, 8, 8, 16, 64]
    assert [next_pow2(n, lo=64, hi=100) for n in (0, 3, 64, 65, 10_000)] == [64, 64, 64, 100, 100]
    assert [next_pow2(n, hi=6) for n in (0, 3, 5, 6, 7)] == [1, 4, 6, 6, 6]  # hi need not be a power of 2
    assert next_pow2(3, lo=64, hi=16) == 16  # hi wins over lo (a chunk smaller than the minimum)


@pytest.mark.parametrize("n", [*range(0, 200), 4095, 4096, 4097, 10_000, 2**20 + 1])
def test_padded_count_doubles_up_to_step_then_adds_steps(n):
    lo, step = 8, 64
    got = padded_count(n, lo=lo, step=step)
    # the obvious rule: the first power of two >= max(n, lo) while that is at most step, else the first
    # multiple of step >= n
    pow2 = lo
    while pow2 < n:
        pow2 *= 2
    want = pow2 if pow2 <= step else step * math.ceil(n / step)
    assert got == want and got >= n
    assert got <= max(2 * n, lo) if n <= step else got < n + step  # what the padding can cost
    assert padded_count(np.int64(n), lo=lo, step=step) == got
