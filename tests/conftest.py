"""Test configuration: float64 available, strict promotion (STYLE §4), shared fixtures."""

from __future__ import annotations

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")


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
