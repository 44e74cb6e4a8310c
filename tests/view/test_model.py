"""The view model and what the viewer sends, against oracles: the run's own files and the closed-form
maps of ``_fixture`` (no browser here; ``test_browser.py`` looks at the page)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from probeplace.scene import srgb8
from probeplace.view import STATUS_RGB, load_view_model, pick_probe, resolve_input, start_viewer
from probeplace.view._maps import distance_image, normal_image, read_npz_row
from probeplace.view._server import STRIP_GAP

from . import _fixture as fx

# Statuses the fixture's flags give: probe 1 inside geometry (magenta), probe 3 inactive (grey).
EXPECTED_STATUS = np.array([0, 1, 0, 2])


def test_positions_and_status_colours_follow_the_run_files(model, run):
    doc = json.loads((run / "probes.json").read_text())
    np.testing.assert_array_equal(model.positions, np.asarray(doc["positions"], np.float32))
    np.testing.assert_array_equal(model.status, EXPECTED_STATUS)
    np.testing.assert_array_equal(model.colours("status"), STATUS_RGB[EXPECTED_STATUS])
    assert model.status_note.startswith("No probe was relocated or filled")


def test_the_viewer_sends_the_run_probes_and_their_maps(model, run):
    """What start_viewer puts on the wire (the batched probe markers, the selected probe's images) is the
    run's probes.json and the npz's maps."""
    viewer = start_viewer(model, port=0)
    try:
        probes = viewer._gui["probes"]
        np.testing.assert_array_equal(probes.batched_positions, model.positions)
        np.testing.assert_array_equal(probes.batched_colors, STATUS_RGB[EXPECTED_STATUS])
        viewer.select(2)
        strip = viewer._gui["maps"].image  # radiance | distance | normal, each enlarged to 256 px
        tiles = [strip[:, j * (256 + STRIP_GAP) :][:, :256] for j in range(3)]
        assert strip.shape == (256, 3 * 256 + 2 * STRIP_GAP, 3)
        with np.load(run / "probes_baked.npz") as z:
            d, n = z["distance"][2], z["normal16"][2]
        k = 256 // fx.GEOMETRY_RES  # texel by texel
        np.testing.assert_array_equal(tiles[1][::k, ::k], distance_image(d, fx.FAR))
        np.testing.assert_array_equal(tiles[2][::k, ::k], normal_image(n, d, fx.FAR))
        # usable probes 0 and 2 see constant radiance 0.1 and 0.3, so white = 0.3 and probe 2 is white
        assert (tiles[0] == 255).all()
        assert viewer._gui["probes"].batched_scales[2] == 0  # the irradiance ball stands in for it
    finally:
        viewer.stop()


def test_radiance_exposure_and_irradiance_ball(model):
    """Constant radiance L: the map shows L / white, and the irradiance E(n)/π of a constant L is L in every
    direction (SH L2 holds a constant exactly), shown on the same rule."""
    b = model.baked
    # rel 1e-3: the SH projection of a 16² map is a midpoint sum (export.project_radiance); E/π of a
    # constant 0.3 comes back within 4e-4 of it (2e-2 at 4²: why the fixture's maps are 16²)
    assert b.white == pytest.approx(0.3) and b.irradiance_white == pytest.approx(0.3, rel=1e-3)
    from probeplace.placement import fibonacci_directions
    from probeplace.view._maps import irradiance_colours, radiance_image

    img = radiance_image(b.radiance[0], b.white)
    assert img.shape == (fx.RADIANCE_RES, fx.RADIANCE_RES, 3)
    np.testing.assert_array_equal(img, srgb8(np.full(img.shape, 0.1 / 0.3)))
    ball = irradiance_colours(
        b.sh[0], fibonacci_directions(64).astype(np.float64), b.irradiance_white
    ).astype(int)
    # 1 level: the rounding of that 4e-4 relative error
    np.testing.assert_allclose(ball, srgb8(np.full(ball.shape, 0.1 / 0.3)), atol=1)


def test_maps_are_the_npz_maps(run):
    """Distance: near bright, farthest hit black, escaped blue; normals: all +z, (n + 1)/2, escaped black."""
    d = fx.distance_map(1)
    img = distance_image(d, fx.FAR)
    inner = d[1:-1, 1:-1]
    hit = inner < fx.FAR
    np.testing.assert_array_equal(img[~hit], np.broadcast_to([40, 90, 255], img[~hit].shape))
    np.testing.assert_array_equal(img[hit][:, 0], np.round(255 * (1 - inner[hit] / inner[hit].max())))
    normal = normal_image(read_npz_row(run / "probes_baked.npz", "normal16", 1), d, fx.FAR)
    np.testing.assert_array_equal(normal[hit], np.broadcast_to([128, 128, 255], normal[hit].shape))
    assert (normal[~hit] == 0).all()


def test_npz_rows_are_read_one_at_a_time_exactly(run):
    with np.load(run / "probes_baked.npz") as z:
        for key in ("distance", "normal16", "radiance"):
            for row in (0, 5, 7):
                np.testing.assert_array_equal(read_npz_row(run / "probes_baked.npz", key, row), z[key][row])


def test_reach_sizes_and_missing_figures(model):
    np.testing.assert_allclose(model.baked.reach, fx.REACH[:4])
    assert model.colour_options == ("status", "mean visible distance")
    r = model.radii("mean visible distance")
    np.testing.assert_allclose(
        r / model.radii("uniform"), np.clip(fx.REACH[:4] / np.median(fx.REACH[:4]), 0.5, 2)
    )
    # coverage / error contributions and uncovered samples are not in a run's files: listed, not faked
    assert set(model.unavailable) == {
        "coverage contribution",
        "error contribution",
        "uncovered surface samples",
    }
    assert all(reason.startswith("not recorded") for reason in model.unavailable.values())
    assert model.eval.view == "front" and set(model.eval.images) == {"full"}


def test_a_bare_baked_file_shows_its_active_rows(run):
    """An .npz alone: its scene is the one its bake recorded; its inactive (padding) rows are dropped."""
    m = load_view_model(resolve_input(run / "probes_baked.npz"))
    np.testing.assert_array_equal(m.positions, fx.POSITIONS[fx.ACTIVE])
    np.testing.assert_array_equal(m.baked.rows, np.flatnonzero(fx.ACTIVE))
    assert m.eval is None and "no error images" in m.eval_note


def test_a_run_without_bake_or_evaluation_says_so(tmp_path):
    m = load_view_model(resolve_input(fx.write_run(tmp_path / "r", bake=False, evaluation=False)))
    assert m.baked is None and m.colour_options == ("status",)
    assert "no baked maps" in m.baked_note and "no error images" in m.eval_note
    assert "Inside-geometry flags come with the bake: not recorded" in m.status_note


def test_relocated_and_filled_counts_are_reported_not_assigned(tmp_path):
    meta = {"valid_space": {"n_relocated": 2}, "budget_fit": {"n_filled": 3}, "scene": "cornell_box"}
    p = fx.write_probes_json(tmp_path / "p.json", metadata=meta)
    m = load_view_model(resolve_input(p))
    assert m.status_note.startswith("2 relocated, 3 filled") and "not recorded" in m.status_note
    m = load_view_model(resolve_input(fx.write_probes_json(tmp_path / "q.json", metadata={}), "cornell_box"))
    assert m.status_note.startswith("Relocated / filled: not recorded")


def test_pick_probe_takes_the_first_marker_on_the_ray():
    pos = np.array([[0.0, 0.0, 5.0], [0.0, 0.0, 2.0], [3.0, 0.0, 2.0]])
    radii = np.full(3, 0.5)
    assert pick_probe(pos, radii, (0, 0, 0), (0, 0, 1)) == 1
    assert pick_probe(pos, radii, (3, 0.4, 0), (0, 0, 1)) == 2
    assert pick_probe(pos, radii, (0, 0, 0), (0, 1, 0)) is None
    assert pick_probe(pos, radii, (0, 0, 10), (0, 0, 1)) is None  # markers behind the camera


# ---------------------------------------------------------------- the per-probe figures of this version
@pytest.fixture(scope="module")
def detail_model(tmp_path_factory):
    run = fx.write_run(tmp_path_factory.mktemp("view_detail") / "run", detail=True)
    return load_view_model(resolve_input(run))


def test_relocated_and_filled_probes_get_their_colours(detail_model):
    """probes.json names probe 2 relocated and probe 0 filled; probe 1 stays magenta (the bake's inside
    flag wins), probe 3 grey (inactive)."""
    from probeplace.view._model import FILLED, INACTIVE, INSIDE, RELOCATED

    want = np.array([FILLED, INSIDE, RELOCATED, INACTIVE])
    np.testing.assert_array_equal(detail_model.status, want)
    np.testing.assert_array_equal(detail_model.colours("status"), STATUS_RGB[want])
    assert detail_model.status_note.startswith("1 relocated out of geometry, 1 filled to the budget")
    assert detail_model.unavailable == {}


def test_coverage_and_error_layers_are_the_files(detail_model):
    from matplotlib import colormaps

    from probeplace.view._model import COVERAGE_SEEN, COVERAGE_UNIQUE, ERROR_DIFFUSE, ERROR_GLOSSY

    m = detail_model
    assert m.colour_options == (
        "status",
        "mean visible distance",
        COVERAGE_SEEN,
        COVERAGE_UNIQUE,
        ERROR_DIFFUSE,
        ERROR_GLOSSY,
    )
    viridis = lambda t: np.round(255 * colormaps["viridis"](t)[:, :3]).astype(np.uint8)
    np.testing.assert_array_equal(m.colours(COVERAGE_SEEN), viridis(fx.SEEN / fx.SEEN.max()))
    np.testing.assert_array_equal(m.colours(COVERAGE_UNIQUE), viridis(fx.UNIQUE / fx.UNIQUE.max()))
    # the error file holds the bake's 8 rows; the shown probes are rows 0-3
    np.testing.assert_array_equal(m.error.shares["diffuse_indirect"], fx.DIFFUSE_SHARE[:4])
    np.testing.assert_array_equal(
        m.colours(ERROR_GLOSSY), viridis(fx.GLOSSY_SHARE[:4] / fx.GLOSSY_SHARE.max())
    )
    assert m.error.mse == fx.MSE
    assert m.error.unattributed["diffuse_indirect"] == pytest.approx(0.002)
    np.testing.assert_array_equal(m.coverage.uncovered, fx.UNCOVERED)
    assert "3 seen by no probe" in m.coverage_note
    assert "of the diffuse_indirect MSE 0.01" in m.legend(ERROR_DIFFUSE)


def test_the_viewer_draws_the_uncovered_samples_and_recolours(detail_model):
    from probeplace.view._model import COVERAGE_SEEN, FILLED, RELOCATED

    viewer = start_viewer(detail_model, port=0)
    try:
        g = viewer._gui
        cloud = g["uncovered_points"]
        assert not cloud.visible
        g["show_uncovered"].value = True
        viewer.server.flush()
        assert cloud.visible
        np.testing.assert_array_equal(cloud.points, fx.UNCOVERED)
        np.testing.assert_array_equal(g["probes"].batched_colors[[0, 2]], STATUS_RGB[[FILLED, RELOCATED]])
        g["colour"].value = COVERAGE_SEEN
        viewer.restyle()
        np.testing.assert_array_equal(g["probes"].batched_colors, detail_model.colours(COVERAGE_SEEN))
        assert "of 20 coverable samples" in g["colour_legend"].content
        viewer.select(0)
        assert "sees 10 of 20 coverable surface samples, 4 of them alone" in g["selected"].content
        assert "diffuse_indirect 0.002 (20 %)" in g["selected"].content
    finally:
        viewer.stop()


def test_a_run_of_an_older_version_says_rerun(model):
    """The shared fixture run has none of the per-probe files: each figure says why and how to get it."""
    for name in ("coverage contribution", "uncovered surface samples", "error contribution"):
        assert "rerun with this version" in model.unavailable[name]
    assert model.coverage is None and model.error is None
