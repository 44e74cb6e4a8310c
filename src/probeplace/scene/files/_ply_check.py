"""PLY structure checks before trimesh reads the file (issue 31).

trimesh fails on a truncated or malformed PLY deep inside (``IndexError: list index out of range``,
``KeyError: 'y'``), naming neither the line nor the problem. A file cut off at any byte breaks its header,
its row count or its last row, so these are checked here: the header line by line, an ASCII body row
by row (how many values each row holds) and a binary body by its length. What passes is left to trimesh,
whose remaining failures ``trimesh_errors`` still turns into a SceneError naming the file.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..._core import SceneError

#: Bytes per value of each PLY scalar type (both spellings).
_SIZES = {"char": 1, "uchar": 1, "short": 2, "ushort": 2, "int": 4, "uint": 4, "float": 4, "double": 8,
          "int8": 1, "uint8": 1, "int16": 2, "uint16": 2, "int32": 4, "uint32": 4, "float32": 4,
          "float64": 8}  # fmt: skip
_KINDS = {1: "u1", 2: "u2", 4: "u4"}  # list counts are read as unsigned of their size
_FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")


@dataclasses.dataclass
class _Element:
    name: str
    count: int
    line: int  # header line declaring it
    #: (value type, list count type or None, name) per property
    props: list[tuple[str, str | None, str]] = dataclasses.field(default_factory=list)


def check_ply(path: Path) -> None:
    """Refuse a PLY whose header is malformed or whose body is shorter than the header says.

    Raises:
        SceneError: ``file:line`` for a header fault or a short/garbled ASCII row; ``file`` and the byte
            counts for a short binary body.
    """
    data = path.read_bytes()
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        what = "no 'ply' first line" if not data.startswith(b"ply") else "its header has no end_header line"
        raise SceneError(f"{path}: not a PLY file, or a corrupt or truncated one: {what}")
    body_start = data.find(b"\n", end)
    body_start = len(data) if body_start < 0 else body_start + 1
    fmt, elements = _header(path, data[:end].decode("latin-1").split("\n"))
    if fmt == "ascii":
        first_line = data[:body_start].count(b"\n") + 1
        _check_ascii(path, data[body_start:].decode("latin-1"), first_line, elements)
    else:
        _check_binary(path, memoryview(data)[body_start:], fmt, elements)


def _header(path: Path, lines: list[str]) -> tuple[str, list[_Element]]:
    fmt = ""
    elements: list[_Element] = []
    for line_no, line in enumerate(lines, 1):
        words = line.split()
        bad = f"{path}:{line_no}: bad PLY header line {line.strip()!r}"
        if not words or words[0] in ("ply", "comment", "obj_info"):
            continue
        if words[0] == "format":
            if len(words) != 3 or words[1] not in _FORMATS:
                raise SceneError(f"{bad}: expected 'format <{'|'.join(_FORMATS)}> 1.0'")
            fmt = words[1]
        elif words[0] == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise SceneError(f"{bad}: expected 'element <name> <count>'")
            elements.append(_Element(words[1], int(words[2]), line_no))
        elif words[0] == "property":
            if not elements:
                raise SceneError(f"{bad}: a property before any element")
            elements[-1].props.append(_property(words, bad))
    if not fmt:
        raise SceneError(f"{path}: bad PLY header: no 'format' line")
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None or not {"x", "y", "z"} <= {p[2] for p in vertex.props}:
        raise SceneError(f"{path}: bad PLY header: no 'element vertex' with properties x, y and z")
    return fmt, elements


def _property(words: list[str], bad: str) -> tuple[str, str | None, str]:
    if len(words) == 3 and words[1] in _SIZES:
        return words[1], None, words[2]
    if len(words) == 5 and words[1] == "list" and words[2] in _SIZES and words[3] in _SIZES:
        if _SIZES[words[2]] in _KINDS and "float" not in words[2] and "double" not in words[2]:
            return words[3], words[2], words[4]
    raise SceneError(f"{bad}: expected 'property <type> <name>' or 'property list <int type> <type> <name>'")


def _check_ascii(path: Path, body: str, first_line: int, elements: list[_Element]) -> None:
    """Every declared row is present and holds the values its properties need; the last row's values
    must be numbers (where a cut lands; earlier garbage is left to trimesh's own message)."""
    rows = ((first_line + i, line.split()) for i, line in enumerate(body.split("\n")))
    rows = (r for r in rows if r[1])
    line_no, words = first_line, []
    for e in elements:
        for k in range(e.count):
            line_no, words = next(rows, (None, None))
            if words is None:
                raise SceneError(
                    f"{path}: truncated PLY: line {e.line} declares {e.count} {e.name} rows, the file ends "
                    f"after {k}"
                )
            _check_row(path, line_no, words, e)
    try:
        [float(w) for w in words]
    except ValueError:
        raise SceneError(f"{path}:{line_no}: bad number in {' '.join(words)!r}: corrupt PLY") from None


def _check_row(path: Path, line_no: int, words: list[str], e: _Element) -> None:
    at = 0
    for _, count_type, _ in e.props:
        if count_type is None:
            at += 1
            continue
        n = words[at] if at < len(words) else ""
        if not n.isdigit():
            break  # a malformed count: the length check below fails
        at += 1 + int(n)
    if at != len(words) or at == 0:
        raise SceneError(
            f"{path}:{line_no}: {e.name} row {' '.join(words)!r} does not match the header's properties "
            f"(line {e.line}): truncated or corrupt PLY"
        )


def _check_binary(path: Path, body: memoryview, fmt: str, elements: list[_Element]) -> None:
    """The body is at least as long as the header says: exactly computable when list rows all have the
    length of the first (triangle meshes); otherwise only the rows before the first list element."""
    order = "<" if fmt == "binary_little_endian" else ">"
    need = 0
    for e in elements:
        size = _row_size(body, need, e, order)
        if size is None:
            return
        need += e.count * size
        if need > len(body):
            raise SceneError(
                f"{path}: truncated PLY: the header declares "
                f"{', '.join(f'{x.count} {x.name}' for x in elements)} rows ({fmt}), which need at least "
                f"{need} bytes after end_header; the file holds {len(body)}"
            )


def _row_size(body: memoryview, offset: int, e: _Element, order: str) -> int | None:
    """Bytes per row of element ``e`` starting at ``offset``, or None when rows differ in length."""
    if e.count == 0:
        return 0
    lists = [i for i, p in enumerate(e.props) if p[1] is not None]
    fixed = sum(_SIZES[t] for t, c, _ in e.props if c is None)
    if not lists:
        return fixed
    if len(lists) > 1:
        return None
    t, c, _ = e.props[lists[0]]
    head = offset + sum(_SIZES[p[0]] for p in e.props[: lists[0]])
    if head + _SIZES[c] > len(body):
        return fixed + _SIZES[c]  # not even the first count is there: the length check fails
    kind = np.dtype(order + _KINDS[_SIZES[c]])
    n = int(np.frombuffer(body, kind, 1, head)[0])
    size = fixed + _SIZES[c] + n * _SIZES[t]
    rows = min(e.count, (len(body) - head - _SIZES[c]) // size + 1)  # rows whose count is in the file
    counts = np.ndarray((rows,), kind, body, head, (size,)) if rows > 1 else np.array([n])
    return size if bool((counts == n).all()) else None
