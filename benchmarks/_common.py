"""Shared benchmark helpers: timing medians, atomic JSON results, scene search path, environment info."""

from __future__ import annotations

import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path

from probeplace._core.runtime import enable_compilation_cache

# JAX's compilation cache (issue 32), like the command's: set up before JAX is imported. Benchmarks time
# compilation apart from run time: a warm cache makes their compile figures cache-load times
# (PROBEPLACE_JAX_CACHE=off for cold-compile figures).
enable_compilation_cache()

import jax  # noqa: E402

from probeplace._core import write_text_atomic  # noqa: E402

ROOT = Path(__file__).resolve().parent
RESULTS = ROOT / "results"


def setup_scene_path() -> None:
    """Put ../shared/scenes (beside the checkout) on PROBEPLACE_SCENE_PATH when it exists."""
    shared = ROOT.parent.parent / "shared" / "scenes"
    if shared.is_dir():
        cur = os.environ.get("PROBEPLACE_SCENE_PATH", "")
        if str(shared) not in cur.split(os.pathsep):
            os.environ["PROBEPLACE_SCENE_PATH"] = os.pathsep.join(p for p in (cur, str(shared)) if p)


def timed(fn: Callable[[], object]) -> tuple[float, object]:
    """(seconds, result) of one call, blocking on JAX results."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    return time.perf_counter() - t0, out


def median_time(fn: Callable[[], object], repeats: int = 5) -> float:
    """Median wall time of ``repeats`` calls (after none: warm up yourself)."""
    return statistics.median(timed(fn)[0] for _ in range(repeats))


def env_info() -> dict:
    """Device kind, versions and CPU count, written beside every figure."""
    dev = jax.devices()[0]
    return {
        "device": getattr(dev, "device_kind", str(dev)),
        "platform": dev.platform,
        "jax": jax.__version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }


def write_result(name: str, result: dict) -> Path:
    """Write ``results/<name>.json`` atomically (``probeplace._core.write_text_atomic``) and print it as the
    last line."""
    path = write_text_atomic(RESULTS / f"{name}.json", json.dumps(result, indent=2, sort_keys=True))
    print(json.dumps(result, sort_keys=True), flush=True)
    return path


def atrium_line(scene, n: int):
    """``n`` points on a line through Sponza's atrium (x from 20 % to 80 % of the scene box, at a third of
    its height, mid-depth): probes that all see the open atrium, for the bake's set-up costs (issue 33)."""
    import numpy as np

    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    t = np.linspace(0.2, 0.8, n)
    return np.stack(
        [
            lo[0] + t * (hi[0] - lo[0]),
            np.full(n, lo[1] + 0.3 * (hi[1] - lo[1])),
            np.full(n, 0.5 * (lo[2] + hi[2])),
        ],
        axis=1,
    )
