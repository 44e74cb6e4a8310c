"""Shared test helpers."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# CI has ../shared beside the checkout; a user's clone may not. Tests that need an external scene
# ask for it through this fixture and are skipped with the reason when it is absent.
SHARED_SCENES = Path(
    os.environ.get("PROBEPLACE_SHARED_SCENES", Path(__file__).resolve().parents[2] / "shared" / "scenes")
)


def shared_scene_path(name: str) -> Path:
    """Path of an external scene from ../shared/scenes; skips the test with the reason if absent."""
    path = SHARED_SCENES / name
    if not path.exists():
        pytest.skip(f"external scene {name} not found in {SHARED_SCENES} (set PROBEPLACE_SHARED_SCENES)")
    return path
