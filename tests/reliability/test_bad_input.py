"""Bad-input catalogue (issue 9): each entry of ``catalogue.CATALOGUE`` is refused with a specific
ProbeplaceError whose message names the problem, raised by probeplace itself (never from deep inside
JAX), or — for the repairs — succeeds and logs what it did."""

from __future__ import annotations

import logging
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from jaxtyping import TypeCheckError

from probeplace._core import ProbeplaceError

from .catalogue import CATALOGUE, Ctx, Entry

# Frames from these packages must not be where a catalogued error is raised.
_FOREIGN = ("/jax/", "/jaxlib/", "/equinox/", "/numpy/", "/trimesh/")


def _params():
    for e in CATALOGUE:
        marks = [pytest.mark.xfail(reason=e.xfail, run=False, strict=True)] if e.xfail else []
        yield pytest.param(e, id=e.id, marks=marks)


@pytest.mark.parametrize("entry", list(_params()))
def test_catalogue_entry(entry: Entry, tmp_path: Path, caplog):
    ctx = Ctx(tmp_path)
    if entry.error is None:
        with caplog.at_level(logging.WARNING, logger="probeplace"):
            out = entry.run(ctx)
        assert out is not None
        assert any(__import__("re").search(entry.match, r.getMessage()) for r in caplog.records), caplog.text
        return
    if entry.wrong_type:  # the test-time type checker answers first; it must name the parameter
        with pytest.raises(TypeCheckError, match=entry.what.split("(")[1].split("=")[0]):
            entry.run(ctx)
        return
    with pytest.raises(entry.error, match=entry.match) as info:
        entry.run(ctx)
    assert isinstance(info.value, ProbeplaceError)
    raise_site = str(info.traceback[-1].path)
    assert "/probeplace/" in raise_site and not any(f in raise_site for f in _FOREIGN), raise_site


@pytest.mark.isa
def test_inverted_cornell_probe_inside_test_ignores_winding(tmp_path):
    """Inverted normals: the default ``reach`` inside test never reads winding, so a probe in a box modelled
    inside-out is usable exactly as in the correctly wound box; the winding-based ``backface`` test (kept as
    an option) flags it, since every first hit is a back face."""
    from .catalogue import INSIDE_OUT_PROBE, bake, cornell

    pos = [INSIDE_OUT_PROBE]
    lf = bake(cornell(inverted=True), pos)
    lf_ok = bake(cornell(), pos)
    assert not bool(lf.inside[0]) and not bool(lf_ok.inside[0])
    assert bool(bake(cornell(inverted=True), pos, inside_test="backface").inside[0])
    assert not bool(bake(cornell(), pos, inside_test="backface").inside[0])
    # Same geometry either way, so the same distance maps up to rounding: a reversed triangle lists its
    # corners in another order, and the ray–triangle test (edge vectors, two cross and three dot products,
    # a division: ~20 float32 operations) rounds differently — bit for bit equal on AVX-512, 1 ulp apart
    # at one texel under SSE4.2. 16 ulps of t bounds it; a probe flagged or moved differently would change
    # whole texels by far more.
    np.testing.assert_allclose(
        np.asarray(lf.distance), np.asarray(lf_ok.distance), rtol=16 * float(np.finfo(np.float32).eps), atol=0
    )


def test_duplicate_triangles_keep_opposite_windings(tmp_path):
    """Only same-winding duplicates are dropped: a back-to-back pair is a legitimate two-sided sheet."""
    from probeplace.scene import load_scene

    from .catalogue import tet_obj

    p = tmp_path / "sheet.obj"
    p.write_text(tet_obj() + "f 1 2 3\n")  # the first face (1 3 2) reversed
    assert load_scene(p).n_triangles == 5


def test_placement_needs_no_light():
    """A scene with no light cannot be rendered or path-baked, but placement (geometry only) works: its SDF
    builds and is negative nowhere inside the empty room."""
    import jax.numpy as jnp

    from probeplace.geometry import build_sdf, sdf_value

    grid = build_sdf(Ctx.room(), cache_dir=False)
    assert float(sdf_value(grid, jnp.asarray([2.0, 1.5, 2.5], jnp.float32))) > 1.0


def test_default_radiance_res_is_bounded_for_any_scale():
    """The derived bake resolution is clipped to [16, 128], so no scene size can make it overflow."""
    from probeplace.probes import default_radiance_res
    from probeplace.scene import build_scene, make_materials
    from probeplace.scene._primitives import box

    mats = make_materials(["wall"], np.array([[0.5, 0.5, 0.5]]))
    for size in (1e-6, 1.0, 1e6):
        v, f = box(np.zeros(3), np.array([4.0, 3.0, 5.0]) * size)
        s = build_scene("b", v, f, np.zeros(len(f), int), mats)
        assert 16 <= default_radiance_res(s) <= 128


def test_wrong_types_are_config_errors_without_the_type_checker():
    """Users run without the jaxtyping hook: there a wrong-typed value must still be a ConfigError."""
    ids = [e.id for e in CATALOGUE if e.wrong_type]
    code = (
        "import sys, re, tempfile, pathlib\n"
        "from tests.reliability.catalogue import CATALOGUE, Ctx\n"
        f"ids = {ids!r}\n"
        "for e in CATALOGUE:\n"
        "    if e.id in ids:\n"
        "        try:\n"
        "            e.run(Ctx(pathlib.Path(tempfile.mkdtemp())))\n"
        "        except e.error as err:\n"
        "            assert re.search(e.match, str(err)), (e.id, str(err))\n"
        "        else:\n"
        "            sys.exit(f'{e.id}: no error')\n"
        "print('ok', len(ids))\n"
    )
    root = Path(__file__).resolve().parents[2]
    r = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == f"ok {len(ids)}", r.stderr[-2000:]


def test_errors_doc_is_current():
    """docs/errors.md is generated from the catalogue (make_errors_doc.py): every entry must be listed."""
    doc = (Path(__file__).resolve().parents[2] / "docs" / "errors.md").read_text()
    missing = [e.id for e in CATALOGUE if f"| `{e.id}` | {e.what} |" not in doc]
    assert not missing, f"regenerate docs/errors.md (python -m tests.reliability.make_errors_doc): {missing}"
