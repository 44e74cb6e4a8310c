"""Fresh exports of the asymmetric fixture equal the golden files in tests/data/export/.

Text and binary layouts are compared byte for byte; EXR and PNG by their decoded pixels (their
encoders may legally change bytes); USD by its parsed content. After an intended format change run
``.venv/bin/python tests/data/export/regenerate.py`` and review the diff.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from probeplace.export import import_probes, read_exr

GOLDEN_DIR = Path(__file__).resolve().parents[1] / "data" / "export"
_spec = importlib.util.spec_from_file_location("export_regenerate", GOLDEN_DIR / "regenerate.py")
_regen = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_regen)
GOLDEN, regenerate = _regen.GOLDEN, _regen.regenerate
BYTE_EXACT = (".json", ".gltf", ".glb", ".prefab", ".tscn", ".lodprobes")


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    out = tmp_path_factory.mktemp("golden")
    return {p.name: p for p in regenerate(out)}


def test_every_format_has_a_golden_file(fresh):
    assert {fmt for fmt, *_ in GOLDEN} == {"json", "gltf", "unity", "godot", "threev8", "ddgi", "usd"}
    for name in fresh:
        assert (GOLDEN_DIR / name).is_file(), f"golden file {name} missing: run regenerate.py"


@pytest.mark.parametrize(
    "name", [*sorted(n for _, n, *_ in GOLDEN if n.endswith(BYTE_EXACT)), "probes.lodprobes.json"]
)
def test_text_and_binary_layouts_are_byte_identical(fresh, name):
    assert fresh[name].read_bytes() == (GOLDEN_DIR / name).read_bytes(), f"{name} differs from its golden"


@pytest.mark.parametrize("stem", ["irradiance", "distance"])
def test_ddgi_images_match_golden_pixels(fresh, stem):
    new, old = read_exr(fresh[f"probes_ddgi.{stem}.exr"]), read_exr(GOLDEN_DIR / f"probes_ddgi.{stem}.exr")
    assert new.keys() == old.keys()
    for k in new:
        # float32 sums of the same terms; allow a few ulp for a different BLAS summation order
        np.testing.assert_allclose(new[k], old[k], rtol=1e-6, atol=1e-6)
    a = np.asarray(Image.open(fresh[f"probes_ddgi.{stem}.png"]))
    b = np.asarray(Image.open(GOLDEN_DIR / f"probes_ddgi.{stem}.png"))
    assert a.shape == b.shape and np.abs(a.astype(int) - b.astype(int)).max() <= 1  # 8-bit rounding


def test_usd_matches_golden_content(fresh):
    a, b = import_probes(fresh["probes.usda"]), import_probes(GOLDEN_DIR / "probes.usda")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.sh, b.sh)
    np.testing.assert_array_equal(a.active, b.active)
    assert (a.method, a.units_m, a.metadata) == (b.method, b.units_m, b.metadata)
