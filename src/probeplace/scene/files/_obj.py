"""Wavefront OBJ + MTL loading: geometry through trimesh, materials from the MTL file(s) directly.

* Geometry: ``trimesh.load(path, force='scene', process=False)``, which splits the file into one mesh
  per material (``usemtl``); each becomes a part named after its material. (``o``/``g`` groups are not
  kept: trimesh 5.2's per-object split mislabels objects.) ``process=False`` keeps degenerate triangles
  so :func:`~probeplace.scene.build_scene` drops and counts them.
* Materials, from every ``mtllib`` the OBJ names (paths relative to the OBJ):

  - ``Kd`` → base colour (taken as linear RGB reflectance, the usual reading of MTL values);
  - ``Ke`` → emitted radiance;
  - ``Pr`` (PBR extension) → roughness if present, else ``Ns`` (Phong exponent) → roughness
    ``(2 / (Ns + 2))^(1/4)``: Walter et al. 2007 ("Microfacet models for refraction", §5.2) match a
    Phong exponent to a Beckmann / GGX slope α = sqrt(2 / (Ns + 2)), and our roughness is perceptual
    (α = roughness², see :class:`~probeplace._core.Materials`). No ``Pr`` and no ``Ns``: roughness 1;
  - ``Pm`` → metallic (default 0). ``Ks``, ``Ka``, ``d`` and texture maps are ignored.

  A material the MTL does not define (or no MTL at all) gets :data:`~probeplace.scene._raw.DEFAULT_GREY`.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np
import trimesh

from ..._core import SceneError
from .._raw import DEFAULT_GREY, PartCollector, RawScene, material_arrays, trimesh_errors

log = logging.getLogger(__name__)


def ns_to_roughness(ns: float) -> float:
    """Perceptual GGX roughness for a Phong exponent ``ns`` (Walter et al. 2007, §5.2)."""
    return float((2.0 / (max(float(ns), 0.0) + 2.0)) ** 0.25)


def _floats(tokens: list[str], n: int, path: Path, line_no: int) -> np.ndarray:
    try:
        vals = [float(t) for t in tokens[:n]]
    except ValueError as e:
        raise SceneError(f"{path}:{line_no}: bad number in {' '.join(tokens)!r}") from e
    if len(vals) == 1 and n == 3:
        vals = vals * 3  # "Kd 0.5" means grey
    if len(vals) != n:
        raise SceneError(f"{path}:{line_no}: expected {n} numbers, got {tokens!r}")
    return np.asarray(vals, np.float64)


def parse_mtl(path: Path) -> dict[str, dict]:
    """Material name → {base_color, roughness, metallic, emission} from one MTL file."""
    out: dict[str, dict] = {}
    cur: dict | None = None
    for line_no, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
        tok = line.split("#", 1)[0].split()
        if not tok:
            continue
        key, args = tok[0], tok[1:]
        if key == "newmtl":
            cur = {"base_color": np.asarray(DEFAULT_GREY), "emission": np.zeros(3), "metallic": 0.0}
            out[" ".join(args)] = cur
        elif cur is None:
            continue
        elif key == "Kd":
            cur["base_color"] = _floats(args, 3, path, line_no)
        elif key == "Ke":
            cur["emission"] = _floats(args, 3, path, line_no)
        elif key == "Ns":
            cur["ns"] = float(_floats(args, 1, path, line_no)[0])
        elif key == "Pr":
            cur["pr"] = float(_floats(args, 1, path, line_no)[0])
        elif key == "Pm":
            cur["metallic"] = float(_floats(args, 1, path, line_no)[0])
    for m in out.values():  # Pr wins over Ns; neither: fully rough
        pr, ns = m.pop("pr", None), m.pop("ns", None)
        m["roughness"] = pr if pr is not None else (ns_to_roughness(ns) if ns is not None else 1.0)
    return out


def _read_text(path: Path) -> str:
    data = path.read_bytes()
    if b"\x00" in data:
        raise SceneError(f"{path}: corrupt OBJ: binary data (NUL bytes) in a text format")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")  # old exporters write Latin-1 comments and names


# Numbers each vertex statement needs (``v x y z [w | r g b [a]]``, ``vt u [v [w]]``, ``vn x y z``).
_ARITY = {"v": (3, 7), "vt": (1, 3), "vn": (3, 3)}
_NAMES = {"v": "vertex", "vt": "texture coordinate", "vn": "normal"}


def check_obj_lines(path: Path, lines: list[str]) -> list[str]:
    """Check every statement trimesh reads and return the ``mtllib`` file names.

    trimesh drops some malformed lines silently and fails on others deep inside (a vertex cut to two
    numbers breaks its array shapes: issue 31), naming no line; a file cut off at any byte makes one of
    these, so each is refused here as ``file:line``.

    Raises:
        SceneError: a vertex statement with too few numbers or a bad one, a face with fewer than 3
            corners, a malformed corner, or a vertex index that is 0 or beyond the file's vertices.
    """
    libs: list[str] = []
    n_vertices = 0
    worst = (0, 0)  # (largest |vertex index| of any face, its line)
    for line_no, line in enumerate(lines, 1):
        words = (line if "#" not in line else line[: line.index("#")]).split()
        if not words:
            continue
        key = words[0]
        if key in _ARITY:
            _check_numbers(path, line_no, words, *_ARITY[key])
            n_vertices += key == "v"
        elif key == "f":
            worst = max(worst, (_check_face(path, line_no, words), line_no))
        elif key == "mtllib" and len(words) > 1:
            libs.append(line.split("#", 1)[0].split(maxsplit=1)[1].strip())
    if worst[0] > n_vertices:
        raise SceneError(
            f"{path}:{worst[1]}: face uses vertex {worst[0]} but the file defines {n_vertices} vertices: "
            "truncated or corrupt OBJ"
        )
    return libs


def _check_numbers(path: Path, line_no: int, words: list[str], lo: int, hi: int) -> None:
    if not lo <= len(words) - 1 <= hi:
        need = f"{lo}–{hi}" if lo < hi else str(lo)
        raise SceneError(
            f"{path}:{line_no}: {_NAMES[words[0]]} {' '.join(words)!r} has {len(words) - 1} numbers, "
            f"needs {need}: truncated or corrupt OBJ"
        )
    try:
        [float(w) for w in words[1:]]
    except ValueError:
        raise SceneError(f"{path}:{line_no}: bad number in {' '.join(words)!r}: corrupt OBJ") from None


def _check_face(path: Path, line_no: int, words: list[str]) -> int:
    """The largest |vertex index| of one face statement, after checking its corners."""
    if len(words) < 4:
        # trimesh silently drops a face with < 3 corners: the mark of a file cut off mid-line (issue 9).
        raise SceneError(
            f"{path}:{line_no}: face with {len(words) - 1} vertices (need ≥ 3): truncated or corrupt OBJ"
        )
    index = [_vertex_index(corner) for corner in words[1:]]
    if 0 in index:  # OBJ counts from 1 (negative: back from the last vertex); 0 or text is corrupt
        raise SceneError(
            f"{path}:{line_no}: bad face corner {words[1 + index.index(0)]!r} in {' '.join(words)!r} "
            "(vertex indices count from 1): corrupt OBJ"
        )
    return max(map(abs, index))


def _vertex_index(corner: str) -> int:
    """The vertex index of a face corner (``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``), 0 if it is not a
    number (a malformed texture or normal index is left to trimesh's own error)."""
    try:
        return int(corner.split("/", 1)[0])
    except ValueError:
        return 0


def load_obj(path: Path) -> RawScene:
    """Read an ``.obj`` file and its MTL library (see the module docstring for the mapping).

    Raises:
        SceneError: binary garbage, a malformed statement (``file:line``: :func:`check_obj_lines`), a
            malformed MTL value, anything else trimesh cannot parse, or no triangles.
    """
    text = _read_text(path)
    mtl: dict[str, dict] = {}
    for lib_name in check_obj_lines(path, text.splitlines()):
        lib = path.parent / lib_name
        if lib.is_file():
            mtl.update(parse_mtl(lib))
        else:
            log.warning("%s: material library %s not found; its materials become grey", path, lib)
    with trimesh_errors(path, "OBJ"):
        tscene = trimesh.load(
            io.BytesIO(text.encode("utf-8")),
            file_type="obj",
            force="scene",
            process=False,
            resolver=trimesh.resolvers.FilePathResolver(path),
        )
    with trimesh_errors(path, "OBJ"):  # a backstop: the line check should leave trimesh nothing to trip on
        return _raw_scene(path, tscene, mtl)


def _raw_scene(path: Path, tscene, mtl: dict[str, dict]) -> RawScene:
    parts = PartCollector()
    mat_names: list[str] = []
    props: list[dict] = []
    for frame in sorted(tscene.graph.nodes_geometry, key=str):
        transform, geom_name = tscene.graph[frame]
        geom = tscene.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        name = getattr(getattr(geom.visual, "material", None), "name", None) or "default"
        if name not in mat_names:
            if name not in mtl:
                log.info("%s: material %r is not defined in the MTL; using grey", path, name)
            mat_names.append(name)
            props.append(
                mtl.get(
                    name,
                    {
                        "base_color": np.asarray(DEFAULT_GREY),
                        "roughness": 1.0,
                        "metallic": 0.0,
                        "emission": np.zeros(3),
                    },
                )
            )
        v = trimesh.transform_points(np.asarray(geom.vertices, np.float64), transform)
        parts.add(str(geom_name), v, np.asarray(geom.faces), mat_names.index(name))
    vertices, faces, tri_mat, tri_part = parts.arrays(str(path))
    return RawScene(
        vertices=vertices,
        faces=faces,
        tri_material=tri_mat,
        tri_part=tri_part,
        part_names=parts.part_names,
        material_names=mat_names,
        **material_arrays(props),
    )
