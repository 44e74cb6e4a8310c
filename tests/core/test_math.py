"""``next_pow2``: the bucket sizes host code pads batches to (closed forms and the lo/hi clamps)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from probeplace._core import next_pow2


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
