"""Regenerate the golden export files from the asymmetric fixture (tests/export/_fixture.py).

Run from the repository root after an *intended* format change, then review the diff::

    .venv/bin/python tests/data/export/regenerate.py

Every file here is written by the exporters themselves; tests/export/test_golden.py compares fresh
exports with these files (byte for byte for text/binary layouts, parsed-equal for EXR, PNG and USD).
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))  # the repository root, for `tests.export._fixture`

from tests.export._fixture import asymmetric_probes  # noqa: E402

from probeplace.export import export_probes  # noqa: E402

# (format, file name, options, fixture options)
GOLDEN = (
    ("json", "probes.export.json", {}, {}),
    ("gltf", "probes.gltf", {}, {}),
    ("gltf", "probes.glb", {"to_metres": True}, {}),
    ("unity", "probes.prefab", {}, {}),
    ("godot", "probes.tscn", {}, {}),
    ("threev8", "probes.lodprobes", {}, {"with_maps": True}),
    ("ddgi", "probes_ddgi.json", {"irradiance_res": 4, "distance_res": 4}, {"with_maps": True}),
    ("usd", "probes.usda", {}, {}),
)


def regenerate(out_dir: Path = HERE) -> list[Path]:
    written = []
    for fmt, name, opts, fix in GOLDEN:
        written += export_probes(asymmetric_probes(**fix), fmt, out_dir / name, **opts)
    return written


if __name__ == "__main__":
    for p in regenerate():
        print(p.relative_to(HERE.parents[2]))
