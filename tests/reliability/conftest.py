"""Reliability fixtures: hypothesis profiles and one small baked probe set shared by the module tests.

Hypothesis profiles: ``default`` (20 examples, used in the default run) and ``slow`` (200 examples, used
by the ``@pytest.mark.slow`` variants); ``HYPOTHESIS_PROFILE=slow`` raises the default tests too.
"""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

_COMMON = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
               derandomize=True)  # fmt: skip  # derandomized: a failing example fails every run
settings.register_profile("default", max_examples=20, **_COMMON)
settings.register_profile("slow", max_examples=200, **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

SLOW = settings(max_examples=200, **_COMMON)
# for properties whose every example compiles anew (a new BVH layout, a rebaked probe set): fewer examples
SLOW_COMPILING = settings(max_examples=25, **_COMMON)

from .catalogue import cornell_probes as cornell_probes  # noqa: E402


@pytest.fixture(scope="session")
def cornell_baked():
    """The catalogue's Cornell probes baked at 16² (one compile, shared with the catalogue), with a tracer."""
    from probeplace.probes import make_tracer

    from .catalogue import _baked, cornell

    lf = _baked()
    return lf, make_tracer(lf, cornell().bounds)
