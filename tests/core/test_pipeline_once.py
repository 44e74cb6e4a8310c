"""One pipeline behind every front door (issue 35): the runner (``experiment``), the CLI and the stage tour
compose the stages through ``probeplace.pipeline``; none of them bakes, checks a backend, converts a memory
budget or writes a placement on its own. The runner and ``probeplace evaluate`` once baked each their own
way (turn 2's bake-depth drift)."""

from __future__ import annotations

import ast
from pathlib import Path

import probeplace

ROOT = Path(probeplace.__file__).parent

#: The steps the pipeline composes, and the stage that defines each (which may call its own).
STEPS = {
    "bake_probes": "probes",
    "choose_bake_spp": "probes",
    "path_traced_radiance": "probes",
    "pad_probes": "probes",
    "load_mitsuba": "render",
    "count_for_memory": "placement",
    "result_coverage_detail": "placement",
    "save_top_view": "placement",
    "save_probe_set": "_core",
}


def calls_of(path: Path) -> list[tuple[int, str]]:
    """(line, name) of every call of a :data:`STEPS` name in ``path`` (``f(...)`` or ``mod.f(...)``)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
            if name in STEPS:
                found.append((node.lineno, name))
    return found


def test_only_the_pipeline_composes_the_stages():
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        stage = rel.parts[0] if len(rel.parts) > 1 else rel.stem
        if stage in ("pipeline", "_vendor") or "_vendor" in rel.parts:
            continue
        bad += [f"{rel}:{line} calls {name}" for line, name in calls_of(path) if STEPS[name] != stage]
    assert not bad, "call probeplace.pipeline instead:\n" + "\n".join(bad)


def test_the_check_sees_both_call_spellings(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("from x import bake_probes\nimport y\nbake_probes(1)\ny.load_mitsuba()\nz = pad_probes\n")
    assert calls_of(f) == [(3, "bake_probes"), (4, "load_mitsuba")]


def test_run_folder_names_are_spelled_once():
    """The files of a run folder are named in ``_core.files.RunFiles`` only: no other module spells
    ``"metrics.json"``, ``"probes_baked.npz"``, ... as a string of its own."""
    from probeplace._core import RunFiles

    names = {v for k, v in vars(RunFiles).items() if not k.startswith("_") and isinstance(v, str)}
    names -= {RunFiles.eval_dir, RunFiles.export_dir}  # "eval", "export": words used otherwise too
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        if "_vendor" in path.parts or path.name == "_run_files.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Constant) and node.value in names:
                bad.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.value!r}")
    assert not bad, "use probeplace._core.RunFiles:\n" + "\n".join(bad)
