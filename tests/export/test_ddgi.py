"""DDGI atlases: layout, EXR contents against closed forms, previews and sidecar."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from probeplace.export import export_probes, read_exr
from probeplace.export._ddgi import unpack_atlas
from probeplace.export._octa import texel_directions

from ._fixture import asymmetric_probes, linear_radiance_params


@pytest.fixture
def ddgi(tmp_path):
    src = asymmetric_probes(with_maps=True)
    files = export_probes(src, "ddgi", tmp_path / "a.json", irradiance_res=6, distance_res=4)
    side = json.loads((tmp_path / "a.json").read_text())
    return src, files, side, tmp_path


def test_files_and_sidecar(ddgi):
    src, files, side, d = ddgi
    assert {f.name for f in files} == {
        "a.json", "a.irradiance.exr", "a.distance.exr", "a.irradiance.png", "a.distance.png"
    }  # fmt: skip
    act = src.active_only()
    assert side["probe_count"] == act.n == 5
    assert side["source_rows"] == [0, 1, 2, 3, 5]
    assert side["tiles_per_row"] == 3
    assert side["irradiance"]["tile_res"] == 8 and side["distance"]["tile_res"] == 6
    assert side["irradiance"]["size"] == [16, 24] and side["distance"]["size"] == [12, 18]
    np.testing.assert_array_equal(np.asarray(side["positions"], np.float32), act.positions)
    png = np.asarray(Image.open(d / "a.irradiance.png"))
    assert png.shape == (16, 24, 3) and png.dtype == np.uint8


def test_irradiance_atlas_matches_closed_form(ddgi):
    """Fixture radiance L = a + Bω (+ sky emission max(0, ω_y) in green): E(n) = πa + (2π/3)Bn for the
    reflected part; the green sky adds ∫ 0.5 max(0, ω_y) max(0, n·ω) dω, which for n = +Y is 0.5·2π/3."""
    _src, _, side, d = ddgi
    exr = read_exr(d / "a.irradiance.exr")
    atlas = np.stack([exr["R"], exr["G"], exr["B"]], axis=-1)
    tiles = unpack_atlas(atlas, 5, 8, side["tiles_per_row"])
    a, b = linear_radiance_params(6)
    rows = [0, 1, 2, 3, 5]
    n = texel_directions(6)
    want = np.pi * a[rows, None, None, :] + 2 * np.pi / 3 * np.einsum("pcx,ijx->pijc", b[rows], n)
    got = tiles[:, 1:-1, 1:-1]
    # red and blue carry no sky: the 8² bake quadrature of a linear integrand (≈1 % at this resolution)
    np.testing.assert_allclose(got[..., [0, 2]], want[..., [0, 2]], rtol=0.03)
    assert np.all(got[..., 1] >= want[..., 1] * 0.97)  # sky only adds light
    # border ring: copies of the interior across the octahedral fold (one example: corner ↔ corner)
    np.testing.assert_array_equal(tiles[:, 0, 0], tiles[:, -2, -2])


def test_distance_atlas_is_the_baked_moments(ddgi):
    src, _, side, d = ddgi
    exr = read_exr(d / "a.distance.exr")
    atlas = np.stack([exr["R"], exr["G"]], axis=-1)
    tiles = unpack_atlas(atlas, 5, 6, side["tiles_per_row"])
    np.testing.assert_array_equal(tiles, src.active_only().maps.moments)  # same res: copied exactly


def test_reflected_light_uses_the_baked_irradiance_map(tmp_path):
    src = asymmetric_probes(with_maps=True)
    export_probes(src, "ddgi", tmp_path / "r.json", irradiance_res=4, light="reflected")
    exr = read_exr(tmp_path / "r.irradiance.exr")
    tiles = unpack_atlas(np.stack([exr["R"], exr["G"], exr["B"]], -1), 5, 6, 3)
    np.testing.assert_array_equal(tiles, src.active_only().maps.irradiance)
