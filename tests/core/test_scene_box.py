"""``scene_box``: the host (lo, hi) box of a scene's vertices, or a checked explicit box."""

from __future__ import annotations

import numpy as np
import pytest

from probeplace._core import ConfigError, scene_box
from probeplace.scene import build_scene, make_materials

# Two triangles: the box is read off the coordinates by hand.
_V = np.array([[0.5, -1.0, 2.0], [3.0, 0.25, 2.0], [0.5, 4.0, -0.75], [1.0, 1.0, 5.5]], np.float32)
_F = np.array([[0, 1, 2], [1, 3, 2]])


@pytest.fixture(scope="module")
def tiny():
    return build_scene("tiny", _V, _F, np.zeros(2, int), make_materials(["grey"], np.full(3, 0.5)))


def test_box_of_a_tiny_mesh(tiny):
    lo, hi = scene_box(tiny)
    assert lo.dtype == hi.dtype == np.float64 and lo.shape == hi.shape == (3,)
    np.testing.assert_array_equal(lo, [0.5, -1.0, -0.75])  # exact: corners are vertex coordinates
    np.testing.assert_array_equal(hi, [3.0, 4.0, 5.5])
    np.testing.assert_array_equal(np.stack(scene_box(tiny)), np.asarray(tiny.bounds, np.float64))


def test_dtype_none_keeps_the_scene_precision(tiny):
    lo, hi = scene_box(tiny, dtype=None)
    assert lo.dtype == hi.dtype == np.asarray(tiny.vertices).dtype


def test_explicit_bounds_win_and_are_checked(tiny):
    lo, hi = scene_box(tiny, ([0, 0, 0], np.array([[1.0], [2.0], [3.0]])))
    np.testing.assert_array_equal(lo, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(hi, [1.0, 2.0, 3.0])
    assert scene_box(None, ((0, 0, 0), (1, 1, 1)))[1].tolist() == [1.0, 1.0, 1.0]
    with pytest.raises(ConfigError, match="hi > lo"):
        scene_box(tiny, ((0, 0, 0), (1, 0, 1)))
    with pytest.raises(ConfigError, match="give a scene or explicit bounds"):
        scene_box(None)
