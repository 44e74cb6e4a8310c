"""The exporters import no JAX (DESIGN.md: ``export/`` is NumPy only).

Oracle: a fresh interpreter in which ``import jax`` fails loads ``probeplace.export`` (with the parent
packages stubbed, since ``probeplace/__init__`` itself pulls in the JAX pytrees) and exports every
format that needs no baked maps. A static check also scans the export modules' import statements.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import probeplace.export

EXPORT_DIR = Path(probeplace.export.__file__).parent
ALLOWED_ROOTS = {"__future__", "numpy", "OpenEXR", "PIL", "pxr"} | {
    "json",
    "os",
    "io",
    "math",
    "struct",
    "zipfile",
    "tempfile",
    "pathlib",
    "typing",
    "dataclasses",
    "collections",
    "importlib",
    "types",
}


def test_export_modules_import_only_numpy_and_file_libraries():
    core = EXPORT_DIR.parent / "_core"
    for f in [*EXPORT_DIR.glob("*.py"), core / "_errors.py", core / "_sh.py"]:
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                roots = {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: inside export/, or the NumPy-only _core modules below
                    assert node.level == 1 or node.module in ("_core._errors", "_core._sh"), (
                        f.name,
                        node.module,
                    )
                    continue
                roots = {node.module.split(".")[0]}
            else:
                continue
            assert roots <= ALLOWED_ROOTS, (f.name, roots - ALLOWED_ROOTS)


def test_exports_run_in_an_interpreter_without_jax(tmp_path):
    src_root = EXPORT_DIR.parents[1]
    tests_root = Path(__file__).resolve().parents[2]
    code = textwrap.dedent(
        f"""
        import sys, types
        sys.modules["jax"] = None  # any `import jax` now raises ImportError
        for name, sub in (("probeplace", ""), ("probeplace._core", "/_core")):
            m = types.ModuleType(name)
            m.__path__ = [{str(src_root)!r} + "/probeplace" + sub]
            sys.modules[name] = m
        import importlib.util
        from probeplace.export import export_probes, import_probes
        spec = importlib.util.spec_from_file_location("fx", {str(tests_root / "tests/export/_fixture.py")!r})
        fx = importlib.util.module_from_spec(spec); spec.loader.exec_module(fx)
        p = fx.asymmetric_probes()
        out = {str(tmp_path)!r}
        for fmt, name in [("json", "a.json"), ("gltf", "a.glb"), ("unity", "a.prefab"), ("godot", "a.tscn"),
                          ("threev8", "a.lodprobes"), ("usd", "a.usda")]:
            export_probes(p, fmt, out + "/" + name)
        assert import_probes(out + "/a.glb").n == 6
        assert not any(k == "jax" or k.startswith("jax.") for k, v in sys.modules.items() if v is not None)
        print("ok")
        """
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"
