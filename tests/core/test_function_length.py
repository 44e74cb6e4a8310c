"""No function body in ``src/probeplace`` is longer than :data:`MAX_BODY_LINES` lines.

A body is counted from its first statement after the docstring to the function's last line, blank and
comment lines included; a nested function counts inside its parent and on its own. A longer function is
split into named steps (small helpers in the same module, each with a one-line docstring).
"""

from __future__ import annotations

import ast
from pathlib import Path

import probeplace

MAX_BODY_LINES = 80
ROOT = Path(probeplace.__file__).parent


def body_lines(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines from the first statement after the docstring to the function's last line (0: docstring only)."""
    body = fn.body
    first = body[0] if body else None
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        body = body[1:]
    if not body:
        return 0
    return fn.end_lineno - body[0].lineno + 1


def long_functions(source: str, max_lines: int = MAX_BODY_LINES) -> list[tuple[str, int, int]]:
    """(qualified name, ``def`` line, body lines) of every function whose body exceeds ``max_lines``."""
    found = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                name = prefix + child.name
                if (n := body_lines(child)) > max_lines:
                    found.append((name, child.lineno, n))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(source), "")
    return found


def _synthetic(n_body: int) -> str:
    """A function with a two-line docstring and exactly ``n_body`` body lines, one blank and one comment."""
    body = (
        ["    x = 0", "", "    # a comment line counts too"]
        + ["    x += 1"] * (n_body - 4)
        + ["    return x"]
    )
    assert len(body) == n_body
    return 'def f():\n    """Doc.\n\n    More doc."""\n' + "\n".join(body) + "\n"


def test_counter_counts_body_lines_exactly():
    # The counter must flag an 81-line body as 81 (so the check below cannot pass vacuously) and let an
    # 80-line body through; the docstring does not count, blank and comment lines do.
    assert long_functions(_synthetic(81)) == [("f", 1, 81)]
    assert long_functions(_synthetic(80)) == []
    fn = ast.parse(_synthetic(81)).body[0]
    assert body_lines(fn) == 81
    assert body_lines(ast.parse("def g():\n    'only a docstring'\n").body[0]) == 0


def test_counter_sees_nested_functions_and_methods():
    inner = "\n".join("        " + line if line else "" for line in _synthetic(81).splitlines())
    src = "class C:\n    def m(self):\n        y = 1\n" + inner + "\n        return y\n"
    # m: its own two statements + f's def line, 3-line docstring and 81-line body = 87.
    assert long_functions(src) == [("C.m", 2, 87), ("C.m.f", 4, 81)]


def test_no_function_body_is_too_long():
    paths = sorted(ROOT.rglob("*.py"))
    n_functions, bad = 0, []
    for path in paths:
        source = path.read_text(encoding="utf-8")
        tree = ast.parse(source)
        n_functions += sum(isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef) for n in ast.walk(tree))
        for name, line, n in long_functions(source):
            bad.append(f"{path.relative_to(ROOT.parent)}:{line} {name}: {n} lines")
    assert len(paths) > 50 and n_functions > 500, (len(paths), n_functions)  # the walk found the package
    assert not bad, (
        f"function bodies over {MAX_BODY_LINES} lines (split them into named steps):\n" + "\n".join(bad)
    )
