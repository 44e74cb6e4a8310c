"""Exported glTF/GLB files pass the Khronos glTF-Validator with zero errors (and zero warnings).

The validator is the npm package ``gltf-validator`` pinned in package.json / package-lock.json at the
repository root; install it with ``npm ci``. Without node or the package the test is skipped with the
reason (CI installs it).
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from probeplace.export import export_probes

from ._fixture import asymmetric_probes

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = Path(__file__).with_name("gltf_validate.mjs")


def _validate(*files: Path) -> list[dict]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed: the Khronos glTF-Validator (npm gltf-validator) needs it")
    if not (ROOT / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("npm package gltf-validator not installed: run `npm ci` in the repository root")
    res = subprocess.run(
        [node, str(SCRIPT), *map(str, files)], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert res.returncode == 0, res.stderr
    return [json.loads(line) for line in res.stdout.splitlines()]


def test_validator_catches_a_broken_file(tmp_path):
    """Guard against a validator that says yes to everything: a node pointing at a missing child."""
    bad = tmp_path / "bad.gltf"
    bad.write_text(json.dumps({"asset": {"version": "2.0"}, "nodes": [{"children": [5]}]}))
    (report,) = _validate(bad)
    assert report["issues"]["numErrors"] > 0


def test_exports_have_no_validator_errors(tmp_path):
    files = []
    for with_sh in (True, False):
        for name, opts in (("p.gltf", {}), ("p.glb", {}), ("m.glb", {"to_metres": True})):
            out = tmp_path / f"{'sh' if with_sh else 'plain'}_{name}"
            export_probes(asymmetric_probes(with_sh=with_sh), "gltf", out, **opts)
            files.append(out)
    reports = _validate(*files)
    assert len(reports) == len(files)
    for report in reports:
        issues = report["issues"]
        assert issues["numErrors"] == 0, (report["file"], issues["messages"])
        assert issues["numWarnings"] == 0, (report["file"], issues["messages"])
