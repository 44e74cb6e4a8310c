"""A real browser for the tests of pages a person opens (report.html, ``probeplace view``; issue 36).

Debian's ``chromium`` (``make test`` installs it the way it installs libllvm19) runs headless, driven by
Playwright (dev extra) through ``executable_path``: Playwright's own browser download is never used, and
nothing is fetched at run time. WebGL comes from SwiftShader (software), so a 3D view draws on a machine
with no GPU. Where the browser or Playwright is missing, ``browser_page`` skips the test with the reason.
"""

from __future__ import annotations

import io
import shutil
from contextlib import contextmanager

import numpy as np
import pytest

# SwiftShader's WebGL: a headless machine has no GPU, and Chromium otherwise refuses WebGL there.
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
]


def chromium_path() -> str:
    """The system Chromium's path; skips the test with the reason when there is none."""
    for name in ("chromium", "chromium-browser"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("no system Chromium (apt-get install chromium; `make test` installs it where it can)")


@contextmanager
def browser_page(width: int = 1024, height: int = 768):
    """A fresh headless Chromium page of ``width`` × ``height`` CSS pixels; closed on exit.

    Console errors and uncaught page errors are collected in ``page.errors`` (a list of strings) so a test
    can assert the page ran cleanly."""
    exe = chromium_path()
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("Playwright is not installed (dev extra: pip install -e '.[dev]')")
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS, headless=True)
        try:
            page = browser.new_page(viewport={"width": width, "height": height})
            page.errors = []
            page.on("pageerror", lambda e: page.errors.append(f"pageerror: {e}"))
            page.on("console", lambda m: m.type == "error" and page.errors.append(f"console: {m.text}"))
            yield page
        finally:
            browser.close()


def screenshot_rgb(page, **kwargs) -> np.ndarray:
    """The page (or ``clip=...``) as an (H, W, 3) uint8 array."""
    from PIL import Image

    png = page.screenshot(type="png", **kwargs)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))
