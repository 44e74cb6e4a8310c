"""glTF 2.0 / GLB loading through trimesh, plus the few things trimesh does not read.

* Geometry: ``trimesh.load(path, force='scene')``; one part per scene-graph node that holds a mesh
  primitive, with the node's world transform applied (instanced meshes become one part per node).
* Materials (glTF 2.0 spec §3.9, "Materials"): ``baseColorFactor`` (linear RGB), ``roughnessFactor``,
  ``metallicFactor``, emission = ``emissiveFactor`` × ``KHR_materials_emissive_strength.emissiveStrength``.
  trimesh quantises ``baseColorFactor`` to uint8 and ignores the strength extension, so the factors are
  read from the file's JSON (for a GLB, the JSON chunk after the 12-byte header) and matched to trimesh's
  materials by name. A material that cannot be matched (unnamed or duplicate name) falls back to trimesh's
  values with strength 1. Textures are ignored (constant colour per material); a primitive without a
  material gets :data:`~probeplace.scene._raw.DEFAULT_GREY`, rough and dielectric.
* Cameras: every node with a ``perspective`` camera, in world space (glTF cameras look along −Z of the
  node frame with +Y up; spec §3.10). ``yfov`` is in radians in the file. trimesh 5.2 keeps only the
  first camera and ignores ``KHR_lights_punctual``, so both are read from the JSON here.
* Sun: the first ``KHR_lights_punctual`` directional light (:func:`gltf_sun`).
"""

from __future__ import annotations

import json
import logging
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import trimesh

from ..._core import Camera, SceneError, Sun
from .._build import make_camera
from .._raw import DEFAULT_GREY, PartCollector, RawScene, material_arrays, trimesh_errors
from ..light import sun_from_irradiance

log = logging.getLogger(__name__)

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A  # "JSON" little-endian


def read_gltf_json(path: Path) -> dict:
    """The glTF JSON document of a ``.gltf`` or ``.glb`` file, with the GLB container checked.

    Raises:
        SceneError: not a GLB (bad magic / version), truncated, or the JSON does not parse.
    """
    data = path.read_bytes()
    if path.suffix.lower() == ".glb":
        if len(data) < 20:
            raise SceneError(f"{path}: truncated GLB: {len(data)} bytes, shorter than the 20-byte header")
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        if magic != _GLB_MAGIC:
            raise SceneError(f"{path}: not a GLB file (magic {magic!r}, expected {_GLB_MAGIC!r})")
        if version != 2:
            raise SceneError(f"{path}: GLB container version {version} is not supported (only glTF 2.0)")
        if length > len(data):
            raise SceneError(
                f"{path}: truncated GLB: the header declares {length} bytes but the file has {len(data)}"
            )
        chunk_len, chunk_type = struct.unpack_from("<II", data, 12)
        if chunk_type != _CHUNK_JSON:
            raise SceneError(f"{path}: corrupt GLB: the first chunk is not JSON (type 0x{chunk_type:08x})")
        if 20 + chunk_len > length:
            raise SceneError(f"{path}: truncated GLB: the JSON chunk runs past the end of the file")
        raw = data[20 : 20 + chunk_len]
    else:
        raw = data
    try:
        doc = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise SceneError(f"{path}: corrupt glTF: the JSON does not parse ({e})") from e
    if not isinstance(doc, dict) or not str(doc.get("asset", {}).get("version", "")).startswith("2"):
        raise SceneError(f"{path}: not a glTF 2.0 document (asset.version missing or not 2.x)")
    return doc


def _json_materials(doc: dict) -> list[dict]:
    """Per glTF material: name, base colour, roughness, metallic and emitted radiance (spec defaults)."""
    out = []
    for i, m in enumerate(doc.get("materials", [])):
        pbr = m.get("pbrMetallicRoughness", {})
        strength = (
            m.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
        )
        out.append(
            {
                "name": m.get("name", f"material_{i}"),
                "base_color": np.asarray(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), np.float64)[:3],
                "roughness": float(pbr.get("roughnessFactor", 1.0)),
                "metallic": float(pbr.get("metallicFactor", 1.0)),
                "emission": np.asarray(m.get("emissiveFactor", [0.0, 0.0, 0.0]), np.float64)
                * float(strength),
            }
        )
    return out


def _trimesh_material(mat) -> dict:
    """Fallback: the factors trimesh kept (base colour is uint8 of the linear value, no strength)."""
    bc = getattr(mat, "baseColorFactor", None)
    ef = getattr(mat, "emissiveFactor", None)
    rough, metal = getattr(mat, "roughnessFactor", None), getattr(mat, "metallicFactor", None)
    return {
        "name": str(getattr(mat, "name", None) or "unnamed"),
        "base_color": np.asarray(DEFAULT_GREY) if bc is None else np.asarray(bc, np.float64)[:3] / 255.0,
        "roughness": 1.0 if rough is None else float(rough),
        "metallic": 1.0 if metal is None else float(metal),
        "emission": np.zeros(3) if ef is None else np.asarray(ef, np.float64)[:3],
    }


def _node_local(node: dict) -> np.ndarray:
    """A node's local 4×4 matrix: ``matrix`` (column-major) or T·R·S (spec §3.5.3)."""
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T
    t = np.eye(4)
    t[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    r = trimesh.transformations.quaternion_matrix(np.roll(node.get("rotation", [0.0, 0.0, 0.0, 1.0]), 1))
    s = np.diag([*node.get("scale", [1.0, 1.0, 1.0]), 1.0])
    return t @ r @ s


def _world_nodes(doc: dict) -> Iterator[tuple[int, dict, np.ndarray]]:
    """(index, node, world 4×4) for every node of the default scene, parents before children."""
    nodes = doc.get("nodes", [])
    scenes = doc.get("scenes", [])
    roots = scenes[doc.get("scene", 0)].get("nodes", []) if scenes else range(len(nodes))
    stack = [(int(i), np.eye(4)) for i in roots]
    seen: set[int] = set()
    while stack:
        i, parent = stack.pop(0)
        if i in seen or not 0 <= i < len(nodes):
            continue  # a malformed cyclic or dangling graph: ignore, do not loop
        seen.add(i)
        node = nodes[i]
        world = parent @ _node_local(node)
        yield i, node, world
        stack.extend((int(c), world) for c in node.get("children", []))


def gltf_cameras(doc: dict) -> list[Camera]:
    """World-space perspective cameras of the default scene's nodes (orthographic ones are skipped)."""
    cams = doc.get("cameras", [])
    out: list[Camera] = []
    for i, node, world in _world_nodes(doc):
        if "camera" in node and 0 <= node["camera"] < len(cams):
            cam = cams[node["camera"]]
            if cam.get("type") == "perspective" and "perspective" in cam:
                pos = world[:3, 3]
                fwd = -world[:3, 2] / np.linalg.norm(world[:3, 2])
                up = world[:3, 1] / np.linalg.norm(world[:3, 1])
                name = node.get("name") or cam.get("name") or f"camera_{len(out)}"
                fov = float(np.degrees(cam["perspective"]["yfov"]))
                out.append(make_camera(pos, pos + fwd, fov, name, up=up))
            else:
                log.info("skipping non-perspective camera on node %d", i)
    return out


def gltf_sun(doc: dict, path: Path | str = "<glTF>") -> Sun | None:
    """The first ``KHR_lights_punctual`` directional light of the default scene, as the sun.

    The light shines along its node's −Z (extension spec), so the sun lies along the node's world +Z.
    ``color × intensity`` (lux in the spec) is taken as the sun's irradiance in the scene's relative
    radiance units; the disk has the real sun's size (the extension gives directional lights none).
    Point and spot lights are skipped with a warning: probeplace has no point lights (use emitters).
    """
    lights = doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    if not lights:
        return None
    suns: list[Sun] = []
    for _, node, world in _world_nodes(doc):
        ref = node.get("extensions", {}).get("KHR_lights_punctual", {}).get("light")
        if not isinstance(ref, int) or not 0 <= ref < len(lights):
            continue
        light = lights[ref]
        if light.get("type") != "directional":
            log.warning(
                "%s: KHR_lights_punctual %s light %r skipped: only directional lights (as the sun) are read",
                path,
                light.get("type"),
                light.get("name", ref),
            )
            continue
        irradiance = np.asarray(light.get("color", [1.0, 1.0, 1.0]), np.float64) * float(
            light.get("intensity", 1.0)
        )
        suns.append(sun_from_irradiance(world[:3, 2], irradiance))
    if len(suns) > 1:
        log.warning(
            "%s: %d directional lights; the first is the sun, the others are skipped", path, len(suns)
        )
    return suns[0] if suns else None


def _node_order(doc: dict) -> dict[str, int]:
    order: dict[str, int] = {}
    for i, n in enumerate(doc.get("nodes", [])):
        if "name" in n:
            order.setdefault(n["name"], i)
    return order


def load_gltf(path: Path) -> RawScene:
    """Read a ``.glb`` / ``.gltf`` file (see the module docstring for what is read).

    Raises:
        SceneError: unreadable container or JSON, trimesh cannot parse it, or it holds no triangles.
    """
    doc = read_gltf_json(path)
    with trimesh_errors(path, "glTF"):
        tscene = trimesh.load(path, force="scene", process=False)
    json_mats = _json_materials(doc)
    names = [m["name"] for m in json_mats]
    by_name = {n: i for i, n in enumerate(names) if names.count(n) == 1}

    mats: list[dict] = []  # the table we build, in first-use order
    mat_row: dict[object, int] = {}
    order = _node_order(doc)
    parts = PartCollector()

    # Part names and a deterministic order: a frame that is a named glTF node keeps its name and index;
    # trimesh names the frames of a multi-primitive mesh with random suffixes, so those parts take the
    # (deterministic) geometry name and sort after the named nodes.
    def part_key(frame) -> tuple[int, str]:
        return (order[frame], frame) if frame in order else (len(order), str(tscene.graph[frame][1]))

    for frame in sorted(tscene.graph.nodes_geometry, key=part_key):
        transform, geom_name = tscene.graph[frame]
        geom = tscene.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue  # points and lines carry no surface
        tm = getattr(geom.visual, "material", None)
        tm_name = getattr(tm, "name", None)
        if tm is None:
            key, props = (
                "__default__",
                {
                    "name": "default",
                    "base_color": np.asarray(DEFAULT_GREY),
                    "roughness": 1.0,
                    "metallic": 0.0,
                    "emission": np.zeros(3),
                },
            )
        elif tm_name in by_name:
            key, props = by_name[tm_name], json_mats[by_name[tm_name]]
        else:
            props = _trimesh_material(tm)
            key = ("trimesh", id(tm))
            log.warning(
                "%s: material %r not matched in the glTF JSON; using trimesh's factors", path, tm_name
            )
        if key not in mat_row:
            mat_row[key] = len(mats)
            mats.append(props)
        v = trimesh.transform_points(np.asarray(geom.vertices, np.float64), transform)
        parts.add(part_key(frame)[1], v, np.asarray(geom.faces), mat_row[key])
    vertices, faces, tri_mat, tri_part = parts.arrays(str(path))
    mat_names, k = [], 0
    for m in mats:  # unique material names (a name may repeat through the fallback path)
        n = m["name"]
        while n in mat_names:
            n, k = f"{m['name']}_{k}", k + 1
        mat_names.append(n)
    return RawScene(
        vertices=vertices,
        faces=faces,
        tri_material=tri_mat,
        tri_part=tri_part,
        part_names=parts.part_names,
        material_names=mat_names,
        **material_arrays(mats),
        views=gltf_cameras(doc),
        sun=gltf_sun(doc, path),
        unit_m=1.0,  # glTF 2.0: "the units for all linear distances are meters" (spec §3.4)
    )
