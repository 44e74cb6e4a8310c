"""The exporters import no JAX (DESIGN.md: ``export/`` is NumPy only), and ``import probeplace`` is lazy.

Oracle: a fresh interpreter whose import system refuses JAX and the libraries built on it (a
``sys.meta_path`` finder, so nothing is stubbed: ``probeplace/__init__`` and ``_core/__init__`` run as
they are) reads a baked ``.npz`` written with NumPy, writes it in every format of ``FORMATS``, reads back
the formats that have importers, and ends with none of the refused packages in ``sys.modules``.
A static check also scans the export modules' import statements.
"""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
import textwrap
from pathlib import Path

import probeplace
import probeplace.export

from ._fixture import POSITIONS, write_baked_npz

EXPORT_DIR = Path(probeplace.export.__file__).parent
BLOCKED = ("jax", "jaxlib", "equinox", "optimistix", "jaxopt")
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
    "contextlib",
    "importlib",
    "types",
}


def test_export_modules_import_only_numpy_and_file_libraries():
    core = EXPORT_DIR.parent / "_core"
    numpy_only = ("_errors", "files._io", "maths._sh", "files._probe_files")
    for f in [*EXPORT_DIR.glob("*.py"), *(core / f"{m.replace('.', '/')}.py" for m in numpy_only)]:
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                roots = {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                if node.level:  # relative: inside export/, or the NumPy-only _core modules below
                    here = f.parent.relative_to(EXPORT_DIR.parent).parts  # ("export",), ("_core", "files")
                    target = ".".join([*here[: len(here) - node.level + 1], *filter(None, [node.module])])
                    assert target.split(".")[0] == "export" or target in {f"_core.{m}" for m in numpy_only}, (
                        f.name,
                        target,
                    )
                    continue
                roots = {node.module.split(".")[0]}
            else:
                continue
            assert roots <= ALLOWED_ROOTS, (f.name, roots - ALLOWED_ROOTS)


def _run_without_jax(body: str) -> subprocess.CompletedProcess:
    """Run ``body`` in a fresh interpreter in which importing any of :data:`BLOCKED` raises."""
    prelude = f"""
        import importlib.abc, sys
        BLOCKED = {BLOCKED!r}
        assert not [m for m in sys.modules if m.split(".")[0] in BLOCKED], "imported before the block"

        class RefuseJax(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in BLOCKED:
                    raise ModuleNotFoundError(f"{{name}} is blocked in this test", name=name)
                return None

        sys.meta_path.insert(0, RefuseJax())
        try:
            import jax  # noqa: F401
        except ModuleNotFoundError:
            pass
        else:
            raise AssertionError("the import block does not work")
    """
    code = textwrap.dedent(prelude) + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)


def test_exports_run_in_an_interpreter_without_jax(tmp_path):
    npz = tmp_path / "baked.npz"
    write_baked_npz(npz)
    out = tmp_path / "out"
    res = _run_without_jax(
        f"""
        from pathlib import Path
        import numpy as np
        import probeplace.export as ex
        from probeplace._core import ProbeplaceError

        assert issubclass(ex.ExportError, ProbeplaceError)
        probes = ex.read_probes({str(npz)!r})
        assert probes.maps is not None and probes.sh is not None
        out = Path({str(out)!r})
        for name, fmt in ex.FORMATS.items():
            path = out / name / ("probes" + fmt.extensions[0])
            written = ex.export_probes(probes, name, path)
            assert path in written and all(p.is_file() and p.stat().st_size > 0 for p in written), name
            if fmt.read is not None:  # Three.V8 holds the active probes only
                want = probes.active_only() if name == "threev8" else probes
                assert np.array_equal(ex.import_probes(path, name).positions, want.positions), name
        leaked = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
        assert not leaked, leaked
        print(",".join(sorted(ex.FORMATS)))
        """
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == ",".join(sorted(probeplace.export.FORMATS))
    for name in probeplace.export.FORMATS:
        assert any((out / name).iterdir()), name
    assert probeplace.export.read_probes(out / "json" / "probes.json").n == len(POSITIONS)


def test_import_probeplace_loads_no_jax_until_a_jax_name_is_used():
    res = _run_without_jax(
        """
        import probeplace
        assert "probeplace._core._types" not in sys.modules
        assert set(probeplace.__all__) <= set(dir(probeplace))
        try:
            probeplace.ProbeSet
        except ModuleNotFoundError as e:
            assert e.name.split(".")[0] in BLOCKED, e
        else:
            raise AssertionError("ProbeSet loaded without JAX")
        print("ok")
        """
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"


def test_every_public_name_imports_and_is_the_core_object():
    core = importlib.import_module("probeplace._core")
    assert probeplace.__all__, "probeplace.__all__ is empty"
    for name in probeplace.__all__:
        ns: dict = {}
        exec(f"from probeplace import {name}", ns)
        assert ns[name] is getattr(core, name), name
        assert name in dir(probeplace)
    for name in core.__all__:
        assert getattr(core, name) is not None, name
    assert probeplace.export.ExportError.__mro__[1] is core.ProbeplaceError  # one class, not a copy
    assert probeplace.export is sys.modules["probeplace.export"]


def test_the_cli_help_runs():
    res = subprocess.run(
        [sys.executable, "-m", "probeplace", "--help"], capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr
    assert "export" in res.stdout


def test_the_lazy_names_match_what_static_checkers_see():
    """``_core``'s ``TYPE_CHECKING`` imports name the same objects as its run-time ``_LAZY`` map."""
    core = importlib.import_module("probeplace._core")
    tree = ast.parse(Path(core.__file__).read_text())
    block = next(n for n in tree.body if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING")
    seen = {a.name: node.module for node in block.body for a in node.names}
    assert seen == core._LAZY
