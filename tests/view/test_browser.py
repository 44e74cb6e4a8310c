"""``probeplace view`` in a real browser (headless Chromium, SwiftShader WebGL; ``tests/browser.py``): the
page loads from the viser wheel's static client with no network, the 3D canvas draws, and the probes appear
in their status colours where the evaluation camera projects them."""

from __future__ import annotations

import time
from urllib.parse import urlparse

import numpy as np

from probeplace.view import start_viewer
from tests.browser import browser_page, screenshot_rgb

W, H = 800, 500
#: viser's control panel floats over the right of the canvas: probes are looked for left of this column
PANEL_LEFT = W - 340
#: the orientation gizmo in the bottom-left corner (its blue and green axes read as "cyan") is drawn
#: before the scene arrives: the corner is left out of the search
GIZMO_PX = 100
DRAW_TIMEOUT_S = 60


def cyan(img: np.ndarray) -> np.ndarray:
    """Pixels of the usable-probe colour (0, 200, 255) under any shading: blue and green high, red low."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return (b > 120) & (g > 80) & (r < 0.5 * g) & (b > r + 80)


def magenta(img: np.ndarray) -> np.ndarray:
    """Pixels of the inside-geometry colour (255, 0, 200): red and blue high, green low."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return (r > 120) & (b > 90) & (g < 0.5 * b)


def project(points: np.ndarray, cam) -> np.ndarray:
    """(n, 2) pixel positions (column, row) of ``points`` through the look-at camera ``cam`` on the W × H
    canvas: three.js's perspective camera, vertical field of view, aspect W / H."""
    f = cam.look_at - cam.position
    f /= np.linalg.norm(f)
    right = np.cross(f, cam.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    rel = points - cam.position
    depth = rel @ f
    t = np.tan(np.radians(cam.fov_y_deg) / 2)
    x = (rel @ right) / depth / (t * W / H)
    y = (rel @ up) / depth / t
    return np.stack([(x + 1) * W / 2, (1 - y) * H / 2], axis=1)


def canvas(img: np.ndarray) -> np.ndarray:
    """The part of a screenshot where probes are looked for: left of the panel, the gizmo blanked."""
    out = img[:, :PANEL_LEFT].copy()
    out[-GIZMO_PX:, :GIZMO_PX] = 255
    return out


def wait_for_probes(page) -> np.ndarray:
    """Screenshots until the canvas shows probe-coloured pixels (SwiftShader takes seconds to draw)."""
    t0 = time.monotonic()
    while True:
        img = screenshot_rgb(page)
        if cyan(canvas(img)).sum() > 20:
            return img
        assert time.monotonic() - t0 < DRAW_TIMEOUT_S, f"nothing drawn in {DRAW_TIMEOUT_S} s; {page.errors}"
        time.sleep(0.2)


def test_viewer_page_draws_the_probes_offline(model):
    viewer = start_viewer(model, port=0)
    origin = urlparse(viewer.url)
    try:
        with browser_page(W, H) as page:
            requests, failed = [], []
            page.on("request", lambda r: requests.append(r.url))
            page.on("requestfailed", lambda r: failed.append(f"{r.url}: {r.failure}"))
            page.goto(viewer.url)
            img = wait_for_probes(page)
            assert img.std() > 20  # scene, walls and probes: not a blank canvas
            # every probe in front of the evaluation camera and left of the panel shows its status colour
            cam = next(c for c in model.cameras if c.name == model.eval.view)
            uv = np.round(project(model.positions.astype(np.float64), cam)).astype(int)
            shown = {0: cyan, 1: magenta, 2: cyan}  # probe 3 is inactive: grey, like the walls
            for i, is_colour in shown.items():
                u, v = uv[i]
                if u >= PANEL_LEFT:
                    continue
                window = img[max(v - 6, 0) : v + 7, max(u - 6, 0) : u + 7]
                assert is_colour(window).sum() >= 10, (i, (u, v))
            # the same view with the probes hidden has no probe colour left
            viewer._gui["show_probes"].value = False
            t0 = time.monotonic()
            while cyan(hidden := canvas(screenshot_rgb(page))).sum() > 0:
                assert time.monotonic() - t0 < 20, "probes still drawn after hiding them"
            assert magenta(hidden).sum() == 0
            assert not page.errors, page.errors
            assert not failed, failed
            hosts = {
                urlparse(u).netloc for u in requests if urlparse(u).scheme in ("http", "https", "ws", "wss")
            }
            assert hosts == {origin.netloc}, hosts  # the viser client is served by the viewer alone
    finally:
        viewer.stop()
