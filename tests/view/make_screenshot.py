"""Write docs/images/viewer_cornell.png: ``probeplace view`` on the demo's grid run of the Cornell box, seen
from beside the evaluation camera (its error image on the frustum), one probe selected with its maps.

Run after ``make demo``: ``.venv/bin/python -m tests.view.make_screenshot [RUN_FOLDER]`` (about 30 s: the
page draws with software WebGL). Needs the system Chromium, as the browser tests do.
"""

from __future__ import annotations

import io
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

from probeplace.view import load_view_model, resolve_input, start_viewer

from .test_browser import cyan

ROOT = Path(__file__).resolve().parents[2]
RUN = ROOT / "results" / "cornell_comparison" / "cornell_box__grid__b27__s0"
OUT = ROOT / "docs" / "images" / "viewer_cornell.png"
W, H = 1400, 860
PROBE = 22  # top row, middle: its ball is lit from the ceiling light just above it
#: a view from above and left of the front camera, so its frustum and error image show beside the box
EYE, TARGET = (-700.0, 1000.0, -1700.0), (230.0, 200.0, 0.0)


def main(run: Path = RUN) -> Path:
    from tests.browser import browser_page

    model = load_view_model(resolve_input(run))
    viewer = start_viewer(model, port=0)
    try:
        with browser_page(W, H) as page:
            page.goto(viewer.url)
            t0 = time.monotonic()
            while cyan(np.asarray(_shot(page).convert("RGB"))).sum() < 50 and time.monotonic() - t0 < 120:
                time.sleep(0.5)
            for client in viewer.server.get_clients().values():
                client.camera.position, client.camera.look_at = EYE, TARGET
            viewer._gui["error_on_camera"].value = True
            viewer.select(PROBE)
            for close in page.locator("button.mantine-Notification-closeButton").all():
                close.click()  # the "software WebGL" notice a headless browser gets
            time.sleep(8)  # the new camera pose and the maps: a few software-rendered frames
            img = _shot(page)
    finally:
        viewer.stop()
    # 256 colours: the picture is flat-shaded walls, markers and GUI text (a full-colour PNG is ~3× larger)
    img.convert("RGB").quantize(256, dither=Image.Dither.NONE).save(OUT, optimize=True)
    return OUT


def _shot(page) -> Image.Image:
    return Image.open(io.BytesIO(page.screenshot(type="png")))


if __name__ == "__main__":
    out = main(Path(sys.argv[1]) if len(sys.argv) > 1 else RUN)
    print(f"wrote {out} ({out.stat().st_size // 1024} kB)")
