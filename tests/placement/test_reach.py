"""Reachable free space (``placement.space._reach``) and its use by the valid space and the budgets.

Oracles: a closed-form SDF of a hollow shell (a sealed cavity inside solid walls), with and without a slot
through one wall, where which points a viewer can get to is known by construction; and the ``rooms``
scene, whose room D is sealed by construction (``scene.builtin._rooms`` docstring).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from probeplace.geometry import SDFGrid
from probeplace.placement import make_problem, make_valid, place
from probeplace.placement.space._reach import reachable_space
from probeplace.placement.space._valid import valid_candidates

H = 0.025
C = 2 * H
OUTER = (np.array([0.2, 0.2, 0.2]), np.array([0.8, 0.8, 0.8]))
INNER = (np.array([0.3, 0.3, 0.3]), np.array([0.7, 0.7, 0.7]))  # the cavity (walls 0.1 thick)
SLOT = (np.array([0.425, 0.4, -0.1]), np.array([0.575, 0.6, 0.6]))  # through the −z wall, 0.15 × 0.2
IN_CAVITY = np.array([[0.5, 0.5, 0.5], [0.4, 0.6, 0.45]])
OUTSIDE = np.array([[0.05, 0.5, 0.5], [0.95, 0.9, 0.1]])


def box_sdf(p, lo, hi):
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    q = np.abs(p - c) - half
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)


def shell_grid(slot: bool) -> SDFGrid:
    """Solid walls between OUTER and INNER (CSG: outer ∖ inner, ∖ the slot when ``slot``) on [0, 1]³."""
    ax = H * np.arange(round(1 / H) + 1)
    p = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), axis=-1)
    solid = np.maximum(box_sdf(p, *OUTER), -box_sdf(p, *INNER))
    if slot:
        solid = np.maximum(solid, -box_sdf(p, *SLOT))
    return SDFGrid(
        values=jnp.asarray(solid, jnp.float32),
        origin=jnp.zeros(3, jnp.float32),
        voxel_size=jnp.asarray(H, jnp.float32),
    )


def viewer(*positions) -> np.ndarray:
    """Camera positions, (c, 3)."""
    return np.asarray(positions, np.float64).reshape(-1, 3)


@pytest.fixture(scope="module")
def sealed():
    return shell_grid(slot=False)


def test_sealed_cavity_is_not_reachable_from_outside(sealed):
    reach = reachable_space(sealed, C, viewer([0.05, 0.05, 0.05]))
    assert not reach.contains(IN_CAVITY).any()
    assert reach.contains(OUTSIDE).all()
    # every reachable lattice point is free and outside OUTER grown by the clearance
    pts = reach.points()
    assert (box_sdf(pts, *OUTER) >= C - 1e-6).all()


def test_a_view_inside_reaches_only_the_cavity(sealed):
    reach = reachable_space(sealed, C, viewer([0.5, 0.5, 0.5]))
    assert reach.contains(IN_CAVITY).all()
    assert not reach.contains(OUTSIDE).any()
    both = reachable_space(sealed, C, viewer([0.5, 0.5, 0.5], [0.05, 0.05, 0.05]))
    assert both.contains(np.concatenate([IN_CAVITY, OUTSIDE])).all()


def test_an_opening_wider_than_twice_the_clearance_joins_the_cavity():
    reach = reachable_space(shell_grid(slot=True), C, viewer([0.05, 0.05, 0.05]))
    assert reach.contains(IN_CAVITY).all()
    # a slot narrower than 2 × clearance does not: at 0.08 no point of the 0.15-wide slot is free
    narrow = reachable_space(shell_grid(slot=True), 0.08, viewer([0.05, 0.05, 0.05]))
    assert not narrow.contains(IN_CAVITY).any()


def test_a_camera_nearer_a_wall_than_the_clearance_seeds_its_side(sealed):
    # 0.01 outside the outer wall: its nearest free lattice point is outside, not in the cavity
    reach = reachable_space(sealed, C, viewer([0.19, 0.5, 0.5]))
    assert reach.contains(OUTSIDE).all() and not reach.contains(IN_CAVITY).any()


def test_no_views_no_constraint(sealed):
    assert reachable_space(sealed, C, viewer()) is None


def test_make_valid_drops_unreachable_probes_and_keeps_the_rest_bit_identical(sealed):
    reach = reachable_space(sealed, C, viewer([0.05, 0.05, 0.05]))
    pos = np.concatenate([OUTSIDE, IN_CAVITY]).astype(np.float32)
    v = make_valid(sealed, pos, clearance=C, lo=np.zeros(3), hi=np.ones(3), reach=reach)
    assert v.unreachable.tolist() == [False, False, True, True]
    assert v.dropped.tolist() == [False, False, True, True]
    np.testing.assert_array_equal(v.pos, pos)
    assert v.record()["n_unreachable"] == 2
    free = make_valid(sealed, pos, clearance=C, lo=np.zeros(3), hi=np.ones(3))
    assert not free.dropped.any() and not free.unreachable.any()
    cand = valid_candidates(sealed, np.zeros(3), np.ones(3), C, None, 0.1, reach)
    assert len(cand) and reach.contains(cand).all() and (box_sdf(cand, *INNER) > 0).all()


def test_rooms_without_a_view_in_the_sealed_room_get_no_probe_there():
    from probeplace.scene import rooms
    from probeplace.scene.builtin._rooms import ROOMS_DARK_ROOM_BOUNDS

    scene = rooms()
    lo, hi = (np.asarray(b) for b in ROOMS_DARK_ROOM_BOUNDS)
    in_dark = lambda p: np.all((p > lo) & (p < hi), axis=-1)
    no_dark_view = dataclasses.replace(scene, views=tuple(v for v in scene.views if v.name != "dark_room"))
    res = place(no_dark_view, method="grid", budget=12, seed=0)
    pos = np.asarray(res.probes.pos_world)
    assert len(pos) == 12 and not in_dark(pos).any()
    assert res.metadata["valid_space"]["n_unreachable"] > 0  # the 4x?x? lattice has probes in D
    with_dark_view = place(scene, method="grid", budget=12, seed=0)
    assert in_dark(np.asarray(with_dark_view.probes.pos_world)).any()
    # D's walls are coverable only when a view can reach D (a probe there is usable)
    for sc, expect in ((no_dark_view, False), (scene, True)):
        problem = make_problem(sc, key=jax.random.key(0), n_samples=3000)
        in_d = in_dark(np.asarray(problem.position))
        assert in_d.sum() > 50
        assert np.asarray(problem.coverable)[in_d].any() == expect


def test_coverable_samples_follow_the_requested_clearance():
    """The coverage problem's reach uses the request's clearance, as the valid space does: with only the
    lit room's view and a clearance above half the doorways' 1 m width, rooms B and C are sealed off, so
    their walls are no longer coverable; at the default clearance they are."""
    from probeplace.geometry import build_sdf
    from probeplace.placement._finish import coverage_context
    from probeplace.placement._registry import PlaceRequest
    from probeplace.scene import rooms

    scene = rooms()
    lit_only = dataclasses.replace(scene, views=tuple(v for v in scene.views if v.name == "lit_room"))
    sdf = build_sdf(lit_only)
    behind_doors = lambda p: (p[:, 0] > 9.3) | ((p[:, 2] > 5.3) & (p[:, 0] > 4.3))
    covered = {}
    for clearance in (None, 0.6):
        request = PlaceRequest(budget=8, seed=0, clearance=clearance)
        problem = coverage_context(lit_only, request, sdf).problem
        far = behind_doors(np.asarray(problem.position))
        assert far.sum() > 50
        covered[clearance] = np.asarray(problem.coverable)[far].mean()
    # (outer faces are never coverable; a few samples at the doorways have witnesses in room A)
    assert covered[None] > 0.3 and covered[0.6] < 0.01, covered
