"""Named random streams: one key per consumer, every one derived from the run's seed.

A consumer (the coverage samples, the grid's jitter, a refiner, ...) asks for ``stream(seed, name)``:
the root key ``jax.random.key(seed)`` folded with a hash of the name. Two names give independent
streams, the same name the same stream on every run and in every method — so the coverage samples of
the uniform grid and of the skeleton search are the same for one seed, and their coverages compare like
for like — and no consumer can reuse another's key by accident (splitting a key and using a part twice,
or re-creating the root key later, were both easy to write). A consumer that needs several keys splits
its own stream.
"""

from __future__ import annotations

import zlib

import jax
import numpy as np


def stream(seed: int, name: str) -> jax.Array:
    """The PRNG key of consumer ``name`` in the run seeded with ``seed`` (module docstring)."""
    return jax.random.fold_in(jax.random.key(int(seed)), zlib.crc32(name.encode()) & 0x7FFFFFFF)


def host_rng(key: jax.Array) -> np.random.Generator:
    """A NumPy generator seeded from every word of ``key`` (for host-side consumers: subsets, shuffles)."""
    return np.random.default_rng(np.asarray(jax.random.key_data(key), np.uint32).ravel())
