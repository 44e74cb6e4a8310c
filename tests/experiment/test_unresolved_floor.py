"""experiments/unresolved_floor.py's visibility with a margin (``--margin-texels``), against a closed form:
a probe at the origin behind a half-plane screen z = 1, x < 0 (its edge the y axis at z = 1)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from ._util import experiment_script


def _module():
    return experiment_script("unresolved_floor")


class _Screen:
    """A caster whose only surface is the half-plane z = 1, x < 0 (triangle 0)."""

    def closest_hit(self, o, d):
        o, d = np.asarray(o, np.float64), np.asarray(d, np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (1.0 - o[:, 2]) / d[:, 2]
        hit = (t > 0) & ((o[:, 0] + t * d[:, 0]) < 0)
        return SimpleNamespace(tri=np.where(hit, 0, -1), t=np.where(hit, t, np.inf))


@pytest.mark.parametrize("margin", [0.01, 0.05])
def test_ring_directions_lie_at_the_margin(margin):
    mod = _module()
    dv = np.random.default_rng(0).normal(size=(64, 3))
    dv /= np.linalg.norm(dv, axis=1, keepdims=True)
    for w in mod._ring(dv, margin):
        np.testing.assert_allclose(np.linalg.norm(w, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.arccos(np.clip(np.sum(w * dv, axis=1), -1, 1)), margin, atol=1e-9)


def test_a_point_beside_an_edge_is_seen_exactly_but_not_with_a_margin():
    """From the origin, the screen's edge lies in direction (0, 0, 1). A point at (δ, 0, 2) is seen past
    the edge at angle atan(δ / 2): with a margin beyond that angle a ring ray meets the screen, within it
    none does. A point behind the screen is seen by neither test."""
    mod = _module()
    probe = np.zeros((1, 1, 3))
    margin = 0.02
    beside = np.array([[2 * np.tan(margin / 2), 0.0, 2.0]])  # half a margin past the edge
    clear = np.array([[2 * np.tan(3 * margin), 0.0, 2.0]])  # three margins clear of the edge
    behind = np.array([[-0.2, 0.0, 2.0]])
    for x, exact, with_margin in ((beside, True, False), (clear, True, True), (behind, False, False)):
        assert mod._probes_see(_Screen(), probe, x)[0][0, 0] == exact
        assert mod._probes_see(_Screen(), probe, x, margin)[0][0, 0] == with_margin
