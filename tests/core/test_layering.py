"""The stage order of docs/architecture.md: a subpackage imports only stages below it (and ``_core``)."""

from __future__ import annotations

import ast
from pathlib import Path

import probeplace

# Lowest first. ``pipeline`` holds the stages' shared steps, which the runner and the CLI call. ``export``
# sits beside the stages: it reads probe files and may import ``_core`` only.
ORDER = (
    "_core",
    "scene",
    "geometry",
    "render",
    "placement",
    "probes",
    "evaluate",
    "pipeline",
    "experiment",
    "view",
)
ALLOWED = {stage: set(ORDER[:i]) for i, stage in enumerate(ORDER)}
ALLOWED["pipeline"] |= {"export"}
ALLOWED["experiment"] |= {"export"}
ALLOWED["view"] |= {"export"}
ALLOWED["export"] = {"_core"}

ROOT = Path(probeplace.__file__).parent


def imported_stages(path: Path, stage: str) -> set[str]:
    """Stages that ``path`` (a module of ``stage``) imports, at module level or inside functions."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level >= 2 and node.module:  # from ..geometry import x
            found.add(node.module.split(".")[0])
        elif node.level >= 2:  # from .. import geometry
            found.update(a.name for a in node.names)
        elif node.level == 0 and (node.module or "").startswith("probeplace."):
            found.add(node.module.split(".")[1])
    return found - {stage}


def test_stages_import_only_lower_stages():
    bad = []
    for stage in ALLOWED:
        for path in sorted((ROOT / stage).rglob("*.py")):
            up = {s for s in imported_stages(path, stage) if s in ALLOWED} - ALLOWED[stage]
            bad += [f"{path.relative_to(ROOT)} imports {s}" for s in sorted(up)]
    assert not bad, "upward imports (docs/architecture.md stage order):\n" + "\n".join(bad)


def test_the_check_sees_an_upward_import(tmp_path):
    """The parser finds the three spellings of a cross-stage import (so the test above can fail)."""
    f = tmp_path / "m.py"
    f.write_text("from ..probes import x\nfrom .. import evaluate\nfrom probeplace.experiment import y\n")
    assert imported_stages(f, "placement") == {"probes", "evaluate", "experiment"}
