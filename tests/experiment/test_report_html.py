"""report.html (issue 36): one self-contained page with the report's charts and tables, each method's
evaluation images at one scale, and a 3D view of its placements drawn by the inlined three.js.

Synthetic runs (``test_report._fake_run``: the Cornell box, random probes) with evaluation images of
known values. The page itself is checked in the system Chromium (``tests/browser.py``): the 3D view draws
something, the probes are where its ``project()`` says in their colour, the images are shown at least
256 CSS px wide, and nothing goes to the console."""

from __future__ import annotations

import base64
import io
import re

import numpy as np
import pytest

from probeplace.experiment import load_runs, make_report
from probeplace.experiment._report_html import MIN_CSS_PX, TARGET_LEVEL, representative_runs
from probeplace.render import save_exr, tonemap

from ..browser import browser_page, screenshot_rgb
from .test_report import _fake_run

LABELS = ("grid", "skeleton")
REF = 0.01  # the glossy reference's constant radiance: the block's exposure follows from it
H, W = 12, 16  # evaluation images; upscaled ×16 to 256 CSS px


def _with_images(d, k: float) -> None:
    """Replace the run's ``eval/images.exr`` by every glossy, diffuse and full image (constant values; the
    probe image is the reference × ``k``, so its error is |k − 1| × the reference)."""
    layers = {}
    for c, ref in (("glossy_indirect", REF), ("diffuse_indirect", 4 * REF), ("full", 8 * REF)):
        layers[f"ref_{c}"] = np.full((H, W, 3), ref, np.float32)
        layers[f"probe_{c}"] = np.full((H, W, 3), k * ref, np.float32)
        layers[f"error_{c}"] = np.full((H, W, 3), abs(k - 1) * ref, np.float32)
    layers["perfect_trace_glossy_indirect"] = layers["ref_glossy_indirect"]
    (d / "eval").mkdir(exist_ok=True)
    save_exr(d / "eval" / "images.exr", layers, main="probe_full")  # as write_evaluation does


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """Two methods at 8 probes on seed 0, with images, and the grid on seed 1 (not shown) → report.html."""
    exp = tmp_path_factory.mktemp("html") / "synth"
    for label, k in zip(LABELS, (1.5, 1.25), strict=True):
        _with_images(_fake_run(exp, label, 8), k)
    _fake_run(exp, "grid", 8, seed=1)
    make_report(exp)
    return exp, (exp / "report" / "report.html").read_text(encoding="utf-8")


def test_representative_runs_are_one_per_method_at_the_grids_count(tmp_path):
    """The grid's comparison count (8, the median of 4, 8, 16), seed 0, the unperturbed pose; a method
    never run at 8 is shown at its count nearest in log (vardis: 4 rather than 32, ties go down)."""
    exp = tmp_path / "reps"
    for n in (4, 8, 16):
        for seed in (1, 0):
            _fake_run(exp, "grid", n, seed=seed)
    _fake_run(exp, "skeleton", 8, seed=0, translate=(0.01, 0.0, 0.0))  # a perturbed pose: not shown
    _fake_run(exp, "skeleton", 8, seed=2)
    for n in (4, 16):
        _fake_run(exp, "vardis", n)
    reps = representative_runs(load_runs(exp), "cornell_box", ["grid", "skeleton", "vardis"])
    assert [(r["label"], r["n_probes"], r["seed"], r["translate_frac"]) for r in reps] == [
        ("grid", 8, 0, [0.0, 0.0, 0.0]),
        ("skeleton", 8, 2, [0.0, 0.0, 0.0]),
        ("vardis", 4, 0, [0.0, 0.0, 0.0]),
    ]


def test_report_html_is_self_contained(report):
    """No URL the page would fetch (the one http:// string is three.js's XHTML namespace name, an
    identifier for createElementNS); every chart inlined byte for byte; report.md's tables, row for row."""
    exp, page = report
    urls = set(re.findall(r"https?://[^\s\"'<>)]+", page))
    assert urls <= {"http://www.w3.org/1999/xhtml"}, urls
    assert not re.search(r"""(?:src|href)\s*=\s*["'](?!data:|#)""", page)
    assert "<link" not in page and "url(" not in page
    out = exp / "report"
    for stem in ("mse_vs_count", "mse_vs_time", "memory_vs_mse"):
        data = base64.b64encode((out / f"{stem}.png").read_bytes()).decode()
        assert f'src="data:image/png;base64,{data}"' in page, stem
    md = (out / "report.md").read_text().splitlines()
    rows = [ln for ln in md if ln.startswith("|") and not ln.startswith("|---")]
    assert page.count("<tr>") == len(rows)
    for run in load_runs(exp):
        assert f"<td>{run['run']}</td>" in page


def test_images_share_one_exposure_and_one_error_scale(report):
    """Each block's images are tone-mapped at one exposure (the references' 99th percentile shown near
    80 %: REF = 0.01 → +6 stops) and the page states it and the image size and sample counts."""
    from PIL import Image

    _, page = report
    glossy = page.split("<summary>glossy indirect</summary>")[1].split("</details>")[0]
    stops = float(np.floor(np.log2(TARGET_LEVEL / REF)))
    assert f"Exposure {stops:+.0f} stops for every image of this block" in glossy
    assert f"{W} × {H} px" in glossy
    assert glossy.count("<figure") == 2 * 4  # two methods × reference, probe-lit, perfect trace, error

    def shown(alt: str) -> list[np.ndarray]:
        uris = re.findall(rf'<img src="data:image/png;base64,([^"]+)"[^>]*alt="{alt}"', glossy)
        return [np.asarray(Image.open(io.BytesIO(base64.b64decode(u))).convert("RGB")) for u in uris]

    want_ref = tonemap(np.full((1, 1, 3), REF), stops)[0, 0]
    for img in shown("reference") + shown("perfect trace"):
        assert img.shape == (H, W, 3) and (img == want_ref).all()
    probe = [img[0, 0] for img in shown("probe-lit")]  # grid 1.5 × the reference, skeleton 1.25 ×
    assert (probe[0] == tonemap(np.full((1, 1, 3), 1.5 * REF), stops)[0, 0]).all()
    assert (probe[1] == tonemap(np.full((1, 1, 3), 1.25 * REF), stops)[0, 0]).all()
    grid_err, skel_err = shown("error")
    assert (grid_err != skel_err).any()  # one scale: errors of 0.5 and 0.25 × REF differ in colour


def test_a_scene_that_cannot_load_is_named_in_one_line(tmp_path):
    """A run whose scene is not on the search path: the report is still written, and the 3D view and the
    top views say why in one line each."""
    exp = tmp_path / "lost"
    d = _fake_run(exp, "grid", 4)
    cfg = d / "config.yaml"
    cfg.write_text(cfg.read_text().replace("  name: cornell_box", "  name: no_such_scene_xyz"))
    report = make_report(exp)
    page = (report.parent / "report.html").read_text(encoding="utf-8")
    why = re.findall(r'<p class="why">3D view unavailable: ([^<]*)</p>', page)
    assert len(why) == 1 and "no_such_scene_xyz" in why[0] and "\n" not in why[0]
    assert "no_such_scene_xyz" in report.read_text()
    assert 'id="three-js"' not in page  # nothing to draw: the library is left out


def test_report_html_draws_in_a_browser(report):
    """In headless Chromium (SwiftShader WebGL): the 3D view's first frame is not one flat colour, each
    probe in view shows its set's colour at the position ``project()`` gives (for both sets), every
    evaluation image is at least 256 CSS px wide, and the page logs no error."""
    exp, _ = report
    with browser_page(1100, 800) as page:
        page.goto((exp / "report" / "report.html").as_uri())
        page.wait_for_function(
            "window.probeplaceViews?.length === 1 && window.probeplaceViews[0].ready",
            timeout=30_000,
        )
        canvas = page.locator("section.view3d canvas")
        canvas.scroll_into_view_if_needed()
        for i in range(len(LABELS)):
            if i:
                page.locator("section.view3d .toolbar button").nth(i).click()
                page.wait_for_timeout(100)  # the click redraws on the next animation frame
            box = canvas.bounding_box()
            shot = screenshot_rgb(page, clip=box).astype(int)
            assert len(np.unique(shot.reshape(-1, 3), axis=0)) > 50  # walls, boxes, light, probes
            colour = np.array(page.evaluate("window.probeplaceViews[0].colour()"))
            pts = [p for p in page.evaluate("window.probeplaceViews[0].project()") if p["inside"]]
            assert len(pts) >= 4  # random probes inside the box: most are in the evaluation's view
            for p in pts:
                y, x = round(p["y"]), round(p["x"])
                patch = shot[y - 1 : y + 2, x - 1 : x + 2].reshape(-1, 3)
                assert np.abs(patch - colour).max(axis=1).min() <= 3, (p, patch)
            share = (np.abs(shot - colour).max(axis=-1) <= 3).mean()
            assert 0 < share < 0.05  # the colour marks the probes, not the scene
        page.evaluate("document.querySelectorAll('details').forEach(d => d.open = true)")
        widths = page.evaluate(
            "[...document.querySelectorAll('figure.shot img')].map(i => i.getBoundingClientRect().width)"
        )
        assert len(widths) == len(LABELS) * (4 + 3 + 3) and min(widths) >= MIN_CSS_PX
        assert page.errors == []
