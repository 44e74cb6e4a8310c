"""scene.preview_mesh: the colours a 3D view draws, against the sRGB formula and the Cornell materials."""

from __future__ import annotations

import numpy as np

from probeplace.scene import preview_mesh


def test_cornell_box_preview_colours(cornell):
    mesh = preview_mesh(cornell)
    assert mesh.vertices.shape == np.asarray(cornell.vertices).shape and mesh.vertices.dtype == np.float32
    assert mesh.faces.shape == np.asarray(cornell.faces).shape and mesh.faces.dtype == np.int32
    assert mesh.face_rgb.shape == (len(mesh.faces), 3) and mesh.face_rgb.dtype == np.uint8
    mats = cornell.materials
    tri_mat = np.asarray(cornell.tri_material)
    for m in np.unique(tri_mat):
        emission = np.asarray(mats.emission[m], np.float64)
        lin = emission / emission.max() if emission.max() > 0 else np.asarray(mats.base_color[m], np.float64)
        # sRGB (IEC 61966-2-1) by its textbook branches, one channel at a time
        want = [round(255 * (12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055)) for c in lin]
        assert (mesh.face_rgb[tri_mat == m] == want).all(), mats.names[m]
    emitters = np.asarray(cornell.emissive_tris)
    assert len(emitters) and (mesh.face_rgb[emitters].max(axis=1) == 255).all()


def test_tonemap_is_exposure_then_srgb8():
    """``render.tonemap`` = 2^exposure scaling, NaN/negative → 0, then the one sRGB curve (``scene.srgb8``),
    against the textbook branches per value."""
    from probeplace.render import tonemap

    lin = np.array([[[0.0, 0.001, 0.0031308], [0.2, 0.5, 1.0], [2.0, -1.0, np.nan]]])
    got = tonemap(lin, exposure=1.0)
    scaled = np.clip(np.nan_to_num(lin, nan=0.0) * 2.0, 0.0, 1.0)
    want = [
        [
            [round(255 * (12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055)) for c in px]
            for px in row
        ]
        for row in scaled
    ]
    np.testing.assert_array_equal(got, np.array(want, np.uint8))
