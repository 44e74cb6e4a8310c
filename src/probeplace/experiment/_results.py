"""Results folders written atomically: a hidden partial folder, a ``DONE`` marker last, one rename.

A run writes ``<results_dir>/<experiment>/<run>/`` by filling ``.<run>.partial-<pid>`` next to it, writing
``DONE`` as the last file and renaming the folder into place with ``os.replace``. A folder without
``DONE`` (or a hidden ``.partial`` one) is never complete: readers skip it and a resumed sweep redoes it.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

from .._core import write_text_atomic

DONE = "DONE"


def is_complete(run_dir: str | os.PathLike) -> bool:
    """True when ``run_dir`` is a finished run (its ``DONE`` marker exists)."""
    return (Path(run_dir) / DONE).is_file()


def iter_runs(exp_dir: str | os.PathLike) -> Iterator[Path]:
    """Finished run folders under ``exp_dir`` (sorted); partial and hidden folders are skipped."""
    exp = Path(exp_dir)
    if not exp.is_dir():
        return
    for d in sorted(exp.iterdir()):
        if d.is_dir() and not d.name.startswith(".") and is_complete(d):
            yield d


def begin(final: Path) -> Path:
    """A fresh partial folder for ``final``; stale partial (and replaced ``.old``) folders of the same run
    are removed."""
    final.parent.mkdir(parents=True, exist_ok=True)
    for stale in [*final.parent.glob(f".{final.name}.partial-*"), *final.parent.glob(f".{final.name}.old-*")]:
        shutil.rmtree(stale, ignore_errors=True)
    partial = final.parent / f".{final.name}.partial-{os.getpid()}"
    partial.mkdir()
    return partial


def commit(partial: Path, final: Path) -> Path:
    """Write ``DONE`` into ``partial`` (fsynced) and rename it to ``final``, replacing an unfinished folder
    or a finished one being redone (``redo``): that one is first renamed to a hidden ``.<run>.old-<pid>``,
    so readers see the old run or the new one, never a half-removed folder."""
    with open(partial / DONE, "w") as f:
        f.write("ok\n")
        f.flush()
        os.fsync(f.fileno())
    old = None
    if final.exists():
        old = final.parent / f".{final.name}.old-{os.getpid()}"
        shutil.rmtree(old, ignore_errors=True)
        os.replace(final, old)
    os.replace(partial, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return final


def write_json(path: Path, data) -> None:
    """``data`` as JSON (indent 2, NumPy values and paths converted), written atomically."""
    write_text_atomic(path, json.dumps(data, indent=2, default=_json_default))


def _json_default(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)


def environment() -> dict:
    """Versions, git revision and device of this process (``env.json``)."""
    import jax
    import numpy as np

    from .. import __version__ as pp_version

    try:
        root = Path(__file__).resolve().parents[3]
        rev = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10, check=False
        )
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=10,
            check=False,
        )
        git = {"revision": rev.stdout.strip() or None, "dirty": bool(dirty.stdout.strip())}
    except (OSError, subprocess.SubprocessError):
        git = {"revision": None, "dirty": None}
    from ..geometry import embree_packets_available

    dev = jax.devices()[0]
    return {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "probeplace": pp_version,
        "jax": jax.__version__,
        "numpy": np.__version__,
        "git": git,
        "device": {"platform": dev.platform, "kind": getattr(dev, "device_kind", str(dev))},
        "cpu_count": os.cpu_count(),
        # the geometry bake's coherent rays go in Embree's packets where the compiled loop exists
        "embree_packets": embree_packets_available(),
    }
