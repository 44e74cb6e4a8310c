"""The viewer tests' shared run folder and its view model (loading the Cornell box once: ~2 s with JAX)."""

from __future__ import annotations

import pytest

from probeplace.view import load_view_model, resolve_input

from . import _fixture as fx


@pytest.fixture(scope="session")
def run(tmp_path_factory):
    return fx.write_run(tmp_path_factory.mktemp("view") / "run")


@pytest.fixture(scope="session")
def model(run):
    return load_view_model(resolve_input(run))
