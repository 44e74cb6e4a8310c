"""Placement fixtures: one small Cornell problem shared by the fitness, seed and refiner tests."""

import jax
import pytest

from probeplace.placement import FitnessConfig, make_problem


@pytest.fixture(scope="session")
def small(cornell):
    """~400 samples and 12 soft-visibility steps: one coverable-mask compile, shared jit caches."""
    return make_problem(cornell, key=jax.random.key(1), n_samples=400, config=FitnessConfig(n_steps=12))
