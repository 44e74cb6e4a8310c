"""The bad-input catalogue (issue 9): every input probeplace refuses or repairs, with the expected outcome.

One :class:`Entry` per input. ``test_bad_input.py`` runs each one; ``make_errors_doc.py`` runs them again
to write the table of ``docs/errors.md`` with the exact messages, so the document cannot drift from the
code. Entries already covered by ``tests/scene/test_bad_input.py`` and the stage tests (missing .glb,
random bytes per format, truncated GLB, NaN vertices, degenerate triangles, bad MTL values, …) are not
repeated here; the document lists them from those tests' messages under "Also refused".
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import json
import os
import struct
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from probeplace._core import ConfigError, ProbeSet, ResourceError, SceneError
from probeplace._core import ProbeplaceError as ProbeplaceError
from probeplace.scene import build_scene, make_materials
from probeplace.scene._primitives import box

# A closed tetrahedron, outward winding: the smallest valid mesh in every format.
TET_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float64)
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
ROOM_HI = np.array([4.0, 3.0, 5.0])


def tet_obj(v=TET_V, f=TET_F) -> str:
    return "".join(f"v {a} {b} {c}\n" for a, b, c in v) + "".join(
        f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f
    )


def tet_ply(v=TET_V, f=TET_F) -> str:
    head = (
        f"ply\nformat ascii 1.0\nelement vertex {len(v)}\nproperty float x\nproperty float y\n"
        f"property float z\nelement face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    return head + "".join(f"{a} {b} {c}\n" for a, b, c in v) + "".join(f"3 {a} {b} {c}\n" for a, b, c in f)


def tet_gltf() -> str:
    """A self-contained .gltf (buffer as a data URI)."""
    import base64

    vb = TET_V.astype(np.float32).tobytes()
    ib = TET_F.astype(np.uint32).tobytes()
    blob = vb + ib
    doc = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {
                "bufferView": 0,
                "componentType": 5126,
                "count": 4,
                "type": "VEC3",
                "min": [0, 0, 0],
                "max": [1, 1, 1],
            },
            {"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": len(vb)},
            {"buffer": 0, "byteOffset": len(vb), "byteLength": len(ib)},
        ],
        "buffers": [
            {
                "byteLength": len(blob),
                "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode(),
            }
        ],
    }
    return json.dumps(doc)


def tet_glb() -> bytes:
    """The same tetrahedron as a GLB container (JSON chunk + BIN chunk)."""
    vb = TET_V.astype(np.float32).tobytes()
    ib = TET_F.astype(np.uint32).tobytes()
    blob = vb + ib
    doc = json.loads(tet_gltf())
    doc["buffers"] = [{"byteLength": len(blob)}]
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


VALID = {".obj": lambda: tet_obj().encode(), ".ply": lambda: tet_ply().encode(),
         ".gltf": lambda: tet_gltf().encode(), ".glb": tet_glb}  # fmt: skip

# The 8-byte PNG signature and a 1×1 IHDR: a real image file given a mesh extension.
PNG = (
    b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0)
    + b"\0" * 4 + b"\0\0\0\0IEND\xaeB`\x82"
)  # fmt: skip


# ------------------------------------------------------------------------------------------ context
class Ctx:
    """What an entry may use: a temporary folder and small scenes / baked probes built once per process."""

    def __init__(self, tmp: Path):
        self.tmp = tmp

    def write(self, name: str, data: bytes | str) -> Path:
        p = self.tmp / name
        p.write_bytes(data if isinstance(data, bytes) else data.encode())
        return p

    @staticmethod
    def room(inverted: bool = False, lit: bool = False):
        return _room(inverted, lit)

    @staticmethod
    def baked():
        return _baked()

    @staticmethod
    def cornell(inverted: bool = False):
        return cornell(inverted)


def const_radiance(o, d, k):
    """A constant-radiance stand-in for the path tracer (geometry maps are what the tracer reads)."""
    n = o.shape[0]
    return jnp.full((n, 3), 0.5, o.dtype), jnp.zeros((n, 3), o.dtype)


@functools.cache
def _room(inverted: bool, lit: bool):
    """A 4×3×5 box room; faces point inward (seen from inside as front faces) unless ``inverted``."""
    v, f = box(np.zeros(3), ROOM_HI)
    mats = make_materials(["wall"], np.array([[0.5, 0.5, 0.5]]))
    return build_scene(
        "inverted_room" if inverted else "room",
        v,
        f if inverted else f[:, ::-1],
        np.zeros(len(f), int),
        mats,
        sky_radiance=(1.0, 1.0, 1.0) if lit else (0.0, 0.0, 0.0),
    )


# probes_per_batch=1 and 16² maps everywhere: every bake batch of the Cornell box has the same shape, so
# one compile serves all reliability bakes (catalogue, fixtures, determinism).
TINY_BAKE = dict(
    radiance_res=16, irradiance_res=4, moments_res=4, n_sub=1, probes_per_batch=1, progress=False
)

# Cornell box (556 × 548.8 × 559.2 mm, y up), as fractions of its size: probes in free space, one pair
# coincident, one exactly on the floor (y = 0, clear of both blocks).
CORNELL_PROBE_FRACTIONS = np.array(
    [
        [0.25, 0.3, 0.25],
        [0.75, 0.3, 0.25],
        [0.25, 0.7, 0.75],
        [0.75, 0.7, 0.75],
        [0.5, 0.5, 0.5],
        [0.5, 0.5, 0.5],  # coincident with the previous
        [0.5, 0.0, 0.1],  # on the floor
        [0.15, 0.45, 0.6],
    ]
)


# Near the back wall, above the tall block: from here the open front of the box subtends little, so an
# inside-out box shows back faces in most directions.
INSIDE_OUT_PROBE = np.array([278.0, 411.6, 475.3], np.float32)


def cornell_probes(scene) -> np.ndarray:
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds)
    return (lo + CORNELL_PROBE_FRACTIONS * (hi - lo)).astype(np.float32)


@functools.cache
def cornell(inverted: bool = False):
    """The Cornell box, or the same triangles with every winding reversed (normals pointing out of it)."""
    from probeplace.scene import cornell_box

    c = cornell_box()
    if not inverted:
        return c
    return build_scene(
        "inverted_cornell",
        np.asarray(c.vertices),
        np.asarray(c.faces)[:, ::-1],
        np.asarray(c.tri_material),
        c.materials,
    )


def bake(scene, pos, *, radiance_fn=const_radiance, key=None, **cfg):
    """Bake ``pos`` with the brute-force caster, ``TINY_BAKE`` settings updated by ``cfg``."""
    from probeplace.geometry import BruteForceCaster
    from probeplace.probes import BakeConfig, bake_probes

    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
    return bake_probes(
        scene,
        probes,
        caster=BruteForceCaster(scene),
        radiance_fn=radiance_fn,
        key=jax.random.key(0) if key is None else key,
        config=BakeConfig(**{**TINY_BAKE, **cfg}),
    )


@functools.cache
def _baked():
    """The Cornell probes baked at 16²: enough for make_tracer checks (shared with the test fixtures)."""
    c = cornell()
    return bake(c, cornell_probes(c))


def probe_set(pos) -> ProbeSet:
    pos = np.asarray(pos, np.float32)
    return ProbeSet(pos_world=jnp.asarray(pos), active=jnp.ones(len(pos), bool))


# ------------------------------------------------------------------------------------------ entries
@dataclasses.dataclass(frozen=True)
class Entry:
    """One catalogue row.

    Attributes:
        id: short stable name (test id and document anchor).
        stage: ``scene file``, ``scene data``, ``memory``, ``probes``, ``config``.
        what: the bad input, in words.
        run: the call, given a :class:`Ctx`.
        error: the exception type expected, or ``None`` for a logged repair (the call succeeds).
        match: regex the message (or, for repairs, the log) must match: it names the problem.
        xfail: why the entry is expected to fail for now (a check still to be added by a file's owner).
        wrong_type: a value of the wrong Python type; under the test suite's jaxtyping/beartype hook the
            constructor's type check (a ``TypeCheckError`` naming the parameter) fires first, so the
            ConfigError is checked in a subprocess without the hook.
    """

    id: str
    stage: str
    what: str
    run: Callable[[Ctx], object]
    error: type[ProbeplaceError] | None
    match: str
    xfail: str | None = None
    wrong_type: bool = False


def _load(name):
    from probeplace.scene import load_scene

    return lambda c: load_scene(c.tmp / name)


def _load_bytes(name, data):
    from probeplace.scene import load_scene

    return lambda c: load_scene(c.write(name, data() if callable(data) else data))


def _gltf_with_uri(uri: str) -> bytes:
    doc = json.loads(tet_gltf())
    doc["buffers"][0]["uri"] = uri
    return json.dumps(doc).encode()


def _cut(ext, frac=0.5):
    return lambda: VALID[ext]()[: int(len(VALID[ext]()) * frac)]


def _render_huge(c):
    from probeplace.render import RenderConfig, render
    from probeplace.scene import make_camera

    cam = make_camera([2.0, 1.5, 4.5], [2.0, 1.5, 0.0], 60.0, "front")
    return render(c.room(lit=True), cam, RenderConfig(width=10**6, height=10**6, spp=4), key=0)


def _sdf_tiny_voxels(c):
    from probeplace.geometry import build_sdf

    return build_sdf(c.room(), voxel_size=1e-4, cache_dir=False)


def _save_nan(c):
    from probeplace._core import save_probe_set

    return save_probe_set(c.tmp / "p.json", probe_set([[1.0, 1.0, 1.0], [np.nan, 0.0, 0.0]]))


def _probe_json(doc):
    def run(c):
        from probeplace._core import load_probe_set

        p = c.tmp / "p.json"
        p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
        return load_probe_set(p)

    return run


_PS = "probeplace.ProbeSet/1"


def _tracer_over_limit(c):
    """make_tracer of the baked Cornell probes with the memory limit at 20 kB (restored afterwards)."""
    from probeplace.probes import make_tracer

    lf = c.baked()
    with _limit("20KB"):  # 7 usable probes' 16² maps are 2 × 28 kB
        return make_tracer(lf, c.cornell().bounds)


@contextlib.contextmanager
def _limit(value: str):
    """``$PROBEPLACE_MAX_BYTES=value`` inside the block (the variable restored afterwards)."""
    from probeplace._core import MAX_BYTES_ENV

    old = os.environ.get(MAX_BYTES_ENV)
    os.environ[MAX_BYTES_ENV] = value
    try:
        yield
    finally:
        os.environ.pop(MAX_BYTES_ENV) if old is None else os.environ.__setitem__(MAX_BYTES_ENV, old)


def _tracer_with(pos_fn, bounds=None):
    def run(c):
        import equinox as eqx

        from probeplace.probes import make_tracer

        lf = c.baked()
        lf = eqx.tree_at(
            lambda x: x.pos_world, lf, jnp.asarray(pos_fn(np.asarray(lf.pos_world)), jnp.float32)
        )
        return make_tracer(lf, c.cornell().bounds if bounds is None else jnp.asarray(bounds, jnp.float32))

    return run


def _with(value, row=0):
    def f(p):
        p = p.copy()
        p[row] = value
        return p

    return f


def _cfg(cls_path, **kw):
    def run(c):
        import importlib

        mod, name = cls_path.rsplit(".", 1)
        return getattr(importlib.import_module(mod), name)(**kw)

    return run


def _place(**kw):
    def run(c):
        from probeplace.placement import place

        return place(c.room(), **kw)

    return run


def _bake_dark(c):
    from probeplace.probes import path_traced_radiance

    return path_traced_radiance(c.room(), spp=1)


def _dark_sdf_ok(c):
    """Placement needs geometry only: the SDF of an unlit scene builds (compared in the test)."""
    from probeplace.geometry import build_sdf

    return build_sdf(c.room(), cache_dir=False)


# ------------------------------------------------------------------ command line and runner (issue 19)
def _cli(check: str, *argv: str, files: dict | None = None):
    """Parse ``probeplace argv`` with the real parser (``<dir>`` is the entry's folder, ``files`` are
    written there first) and run the command's up-front check ``check`` (``module.function``) on it."""

    def run(c):
        import importlib

        from probeplace.cli import build_parser

        for name, data in (files or {}).items():
            c.write(name, data)
        args = build_parser().parse_args([a.replace("<dir>", str(c.tmp)) for a in argv])
        mod, name = check.rsplit(".", 1)
        return getattr(importlib.import_module(mod), name)(args)

    return run


def _runner(cfg: dict):
    def run(c):
        from probeplace.experiment import to_config

        return to_config(cfg)

    return run


def _runner_scenes(cfg: Callable[[Ctx], dict]):
    """The runner's scene checks before any run (``experiments/run.py``'s precheck): ``check_scenes``."""

    def run(c):
        from probeplace.experiment import check_scenes, to_config

        return check_scenes([to_config(cfg(c))])

    return run


def _sidecar(text: str, **load):
    """``load_scene`` of a tetrahedron file (no light, no cameras) with ``text`` as its sidecar."""

    def run(c):
        from probeplace.scene import load_scene

        c.write("t.obj", tet_obj())
        if text:
            c.write("t.probeplace.yaml", text)
        return load_scene(c.tmp / "t.obj", **load)

    return run


def _probe_doc(pos, active=None) -> str:
    return json.dumps({"format": "probeplace.ProbeSet/1", "positions": pos,
                       "active": [True] * len(pos) if active is None else active})  # fmt: skip


_EVAL = ("probeplace.cli._evaluate._checked_inputs", "evaluate", "--scene", "cornell_box")
_ONE_PROBE = {"p.json": _probe_doc([[200.0, 250.0, 200.0]])}


CATALOGUE: list[Entry] = [
    # --- scene files ------------------------------------------------------------------------------
    *[
        Entry(f"missing{e}", "scene file", f"missing {e} file", _load(f"nope{e}"), SceneError, "not found")
        for e in (".gltf", ".obj", ".ply")
    ],
    Entry(
        "truncated.obj",
        "scene file",
        "OBJ cut off mid-line (face with < 3 corners)",
        _load_bytes("cut.obj", lambda: tet_obj()[:-4].encode()),
        SceneError,
        r"face with \d vertices \(need ≥ 3\): truncated or corrupt OBJ",
    ),
    Entry(
        "truncated.ply",
        "scene file",
        "PLY cut off inside the header",
        _load_bytes("cut.ply", _cut(".ply", 0.3)),
        SceneError,
        r"cut\.ply: not a PLY file, or a corrupt or truncated one: its header has no end_header line",
    ),
    Entry(
        "truncated-body.ply",
        "scene file",
        "PLY cut off before its faces",
        _load_bytes("cut2.ply", lambda: tet_ply().split("3 0 2 1")[0].encode()),
        SceneError,
        r"cut2\.ply: truncated PLY: line 7 declares 4 face rows, the file ends after 0",
    ),
    Entry(
        "truncated.gltf",
        "scene file",
        "glTF JSON cut in half",
        _load_bytes("cut.gltf", _cut(".gltf")),
        SceneError,
        r"corrupt glTF: the JSON does not parse",
    ),
    Entry(
        "truncated-bin.glb",
        "scene file",
        "GLB cut inside its binary chunk",
        _load_bytes("cut.glb", _cut(".glb", 0.9)),
        SceneError,
        r"truncated GLB",
    ),
    *[
        Entry(
            f"png-as{e}",
            "scene file",
            f"a PNG image renamed to {e}",
            _load_bytes(f"img{e}", PNG),
            SceneError,
            {
                ".obj": "corrupt OBJ: binary data",
                ".ply": r"not a PLY file, or a corrupt or truncated one: no 'ply' first line",
                ".glb": r"not a GLB file \(magic b'\\x89PNG'",
                ".gltf": "corrupt glTF: the JSON does not parse",
            }[e],
        )
        for e in (".obj", ".ply", ".glb", ".gltf")
    ],
    *[
        Entry(
            f"empty-file{e}",
            "scene file",
            f"zero-byte {e} file",
            _load_bytes(f"empty{e}", b""),
            SceneError,
            r"no triangles|truncated GLB: 0 bytes|corrupt glTF|could not read|not a PLY file",
        )
        for e in (".obj", ".ply", ".glb", ".gltf")
    ],
    Entry(
        "gltf-missing-buffer",
        "scene file",
        ".gltf whose external .bin buffer is missing",
        _load_bytes("ext.gltf", lambda: _gltf_with_uri("missing.bin")),
        SceneError,
        r"could not read the glTF file \(FileNotFoundError: .*missing\.bin",
    ),
    Entry(
        "obj-index-out-of-range",
        "scene file",
        "OBJ face referencing a vertex that does not exist",
        _load_bytes("idx.obj", tet_obj() + "f 1 2 9\n"),
        SceneError,
        r"idx\.obj:9: face uses vertex 9 but the file defines 4 vertices",
    ),
    Entry(
        "directory-as-scene",
        "scene file",
        "a directory named like a scene file",
        lambda c: (c.tmp / "d.obj").mkdir() or _load("d.obj")(c),
        SceneError,
        "not found",
    ),
    # --- scene data -------------------------------------------------------------------------------
    Entry(
        "coordinates-too-large",
        "scene data",
        "vertex coordinates beyond ±1e18 (float32 overflow)",
        _load_bytes("huge.obj", tet_obj(TET_V * 1e30)),
        SceneError,
        r"coordinates reach 1e\+30, beyond ±1e\+18: squared distances would overflow float32",
    ),
    Entry(
        "extent-too-small",
        "scene data",
        "scene extent below 1e-15 (float32 underflow)",
        _load_bytes("tiny.obj", tet_obj(TET_V * 1e-30)),
        SceneError,
        r"extent 1e-30 is below 1e-15: squared distances would underflow float32",
    ),
    Entry(
        "duplicate-triangles",
        "scene data",
        "the same triangle twice (same winding)",
        _load_bytes("dup.obj", tet_obj() + "f 1 3 2\nf 3 2 1\n"),
        None,
        r"dropped 2 duplicate triangles of 6",
    ),
    Entry(
        "inverted-normals",
        "scene data",
        "a Cornell box modelled inside-out, baked with the winding-based inside_test='backface' (the "
        "default 'reach' test ignores winding and keeps the probe)",
        lambda c: bake(c.cornell(inverted=True), [INSIDE_OUT_PROBE], inside_test="backface"),
        None,
        r"1 of 1 probes are inside geometry \(inside_test=backface\)",
    ),
    Entry(
        "no-light-bake",
        "scene data",
        "path-traced bake of a scene with no emitter, sun or sky",
        _bake_dark,
        SceneError,
        r"scene 'room' has no light \(no emissive material, sun or sky\)",
    ),
    Entry(
        "no-light-render",
        "scene data",
        "render of a scene with no emitter, sun or sky",
        lambda c: __import__("probeplace.render", fromlist=["render"]).render(
            c.room(),
            __import__("probeplace.scene", fromlist=["x"]).make_camera([2, 1.5, 4.5], [2, 1.5, 0], 60.0, "f"),
            __import__("probeplace.render", fromlist=["x"]).RenderConfig(
                width=2, height=2, spp=1, progress=False
            ),
            key=0,
        ),
        SceneError,
        "no light",
    ),
    # --- memory -----------------------------------------------------------------------------------
    Entry(
        "bake-resolution-too-large",
        "memory",
        "bake at radiance_res=65536 (2³² texels per probe)",
        lambda c: bake(c.cornell(), cornell_probes(c.cornell())[:1], radiance_res=65536),
        ResourceError,
        r"bake of 1 probes at radiance_res=65536.* needs ~\d+ bytes \(\d+\.\d GiB\), over the limit",
    ),
    Entry(
        "sdf-lattice-too-large",
        "memory",
        "SDF with voxel_size 1e-4 in a 5 m room",
        _sdf_tiny_voxels,
        ResourceError,
        r"lattice .*GiB to build, limit \d+ GiB\); use a larger voxel_size",
    ),
    Entry(
        "tracer-too-large",
        "memory",
        "light-field tracer over the memory limit ($PROBEPLACE_MAX_BYTES=20KB; 16² maps of 8 probes)",
        _tracer_over_limit,
        ResourceError,
        r"light-field tracer of \d+ usable probes, \d+ map rows, at geometry_res=16, subdivide=2 needs ~\d+ "
        r"bytes .* over the limit .*lower the geometry maps' resolution",
    ),
    Entry(
        "render-image-too-large",
        "memory",
        "render of a 10⁶×10⁶ image",
        _render_huge,
        ResourceError,
        r"\d+ bytes",
    ),
    # --- probe sets -------------------------------------------------------------------------------
    Entry(
        "bake-empty",
        "probes",
        "bake of an empty probe set",
        lambda c: bake(c.cornell(), np.zeros((0, 3))),
        ConfigError,
        "cannot bake an empty probe set",
    ),
    Entry(
        "bake-inf",
        "probes",
        "bake with an infinite probe position",
        lambda c: bake(c.cornell(), [[1.0, 1.0, np.inf]]),
        ConfigError,
        r"probe positions must be finite; 1 are not",
    ),
    Entry(
        "bake-duplicates",
        "probes",
        "bake with two probes at the same position",
        lambda c: bake(c.cornell(), cornell_probes(c.cornell())[4:6]),
        None,
        r"bake: 1 of 2 probe positions are duplicates",
    ),
    Entry(
        "bake-outside",
        "probes",
        "bake with a probe outside the scene bounds",
        lambda c: bake(c.cornell(), [cornell_probes(c.cornell())[0], [-100.0, 200.0, 200.0]]),
        None,
        r"bake: 1 of 2 probes lie outside the scene bounds",
    ),
    Entry(
        "save-nan",
        "probes",
        "save_probe_set with a NaN position",
        _save_nan,
        ProbeplaceError,
        "cannot save a probe set with NaN or infinite positions",
    ),
    Entry(
        "load-nan",
        "probes",
        "ProbeSet file with NaN in positions",
        _probe_json(f'{{"format": "{_PS}", "positions": [[1, 2, NaN]], "active": [true]}}'),
        ProbeplaceError,
        "non-finite probe positions",
    ),
    Entry(
        "load-count-mismatch",
        "probes",
        "ProbeSet file with more active flags than positions",
        _probe_json({"format": _PS, "positions": [[1, 2, 3]], "active": [True, False]}),
        ProbeplaceError,
        r"1 positions but 2 active flags",
    ),
    Entry(
        "load-bad-shape",
        "probes",
        "ProbeSet file whose positions are not triples",
        _probe_json({"format": _PS, "positions": [[1, 2]]}),
        ProbeplaceError,
        r"bad positions/active arrays",
    ),
    Entry(
        "load-wrong-format",
        "probes",
        "JSON file that is not a ProbeSet file",
        _probe_json({"format": "something/else", "positions": []}),
        ProbeplaceError,
        "not a probe set file",
    ),
    Entry(
        "load-not-json",
        "probes",
        "ProbeSet file that is not JSON",
        _probe_json("positions: [1, 2, 3]"),
        ProbeplaceError,
        "not valid JSON",
    ),
    Entry(
        "load-missing",
        "probes",
        "ProbeSet file that does not exist",
        lambda c: __import__("probeplace._core", fromlist=["x"]).load_probe_set(c.tmp / "none.json"),
        ProbeplaceError,
        "probe set file not found",
    ),
    Entry(
        "tracer-nan",
        "probes",
        "make_tracer on probes with a NaN position",
        _tracer_with(_with(np.nan)),
        ConfigError,
        r"probe positions must be finite; 1 are not",
    ),
    Entry(
        "tracer-bad-bounds",
        "probes",
        "make_tracer with inverted bounds",
        _tracer_with(lambda p: p, bounds=[[556.0, 548.8, 559.2], [0.0, 0.0, 0.0]]),
        ConfigError,
        r"bounds must be finite \(min, max\) corners",
    ),
    Entry(
        "tracer-duplicates",
        "probes",
        "make_tracer on probes with duplicate positions",
        _tracer_with(lambda p: np.concatenate([p[1:2], p[1:]])),
        None,
        r"make_tracer: 2 of 8 probe positions are duplicates",
    ),
    Entry(
        "tracer-outside",
        "probes",
        "make_tracer on probes outside the bounds",
        _tracer_with(_with([-100.0, 200.0, 200.0])),
        None,
        r"make_tracer: 1 of 8 probes lie outside",
    ),
    # --- configuration ----------------------------------------------------------------------------
    Entry(
        "render-width-zero",
        "config",
        "RenderConfig(width=0)",
        _cfg("probeplace.render.RenderConfig", width=0, height=4, spp=1),
        ConfigError,
        r"RenderConfig.width must be a positive int, got 0",
    ),
    Entry(
        "render-width-float",
        "config",
        "RenderConfig(width=4.5)",
        _cfg("probeplace.render.RenderConfig", width=4.5, height=4, spp=1),
        ConfigError,
        r"RenderConfig.width must be a positive int, got 4.5",
        wrong_type=True,
    ),
    Entry(
        "render-specular-nan",
        "config",
        "RenderConfig(specular=nan)",
        _cfg("probeplace.render.RenderConfig", width=4, height=4, spp=1, specular=float("nan")),
        ConfigError,
        r"RenderConfig.specular must be in \[0, 1\], got nan",
    ),
    Entry(
        "eval-spp-autox",
        "config",
        "EvalConfig(spp='autox')",
        _cfg("probeplace.evaluate.EvalConfig", spp="autox"),
        ConfigError,
        r"EvalConfig.spp must be a positive int or 'auto', got 'autox'",
    ),
    Entry(
        "eval-pilot-spp-one",
        "config",
        "EvalConfig(spp='auto', pilot_spp=1) (the floor is a sample variance: 2 paths at least)",
        _cfg("probeplace.evaluate.EvalConfig", spp="auto", pilot_spp=1),
        ConfigError,
        r"EvalConfig.pilot_spp must be ≥ 2, got 1",
    ),
    Entry(
        "bake-noise-target-negative",
        "config",
        "BakeConfig(noise_target=-0.1)",
        _cfg("probeplace.probes.BakeConfig", noise_target=-0.1),
        ConfigError,
        r"BakeConfig.noise_target must be in \(0, 1\), got -0.1",
    ),
    Entry(
        "bake-res-not-pow2",
        "config",
        "BakeConfig(radiance_res=24)",
        _cfg("probeplace.probes.BakeConfig", radiance_res=24),
        ConfigError,
        r"BakeConfig.radiance_res must be a power of two ≥ 2, got 24",
    ),
    Entry(
        "bake-nsub-zero",
        "config",
        "BakeConfig(n_sub=0)",
        _cfg("probeplace.probes.BakeConfig", n_sub=0),
        ConfigError,
        r"BakeConfig.n_sub must be ≥ 1, got 0",
    ),
    Entry(
        "bake-quality-nan",
        "config",
        "BakeConfig(quality=nan)",
        _cfg("probeplace.probes.BakeConfig", quality=float("nan")),
        ConfigError,
        r"BakeConfig.quality must be a finite number, got nan",
    ),
    Entry(
        "trace-hierarchy",
        "config",
        "TraceConfig(hierarchy='octree')",
        _cfg("probeplace.probes.TraceConfig", hierarchy="octree"),
        ConfigError,
        r"TraceConfig.hierarchy must be one of \('hiz', 'two_level', 'flat'\), got 'octree'",
    ),
    Entry(
        "trace-max-probes-str",
        "config",
        "TraceConfig(max_probes='8')",
        _cfg("probeplace.probes.TraceConfig", max_probes="8"),
        ConfigError,
        r"TraceConfig.max_probes must be an int, got '8'",
        wrong_type=True,
    ),
    Entry(
        "trace-margin-inf",
        "config",
        "TraceConfig(bounds_margin=inf)",
        _cfg("probeplace.probes.TraceConfig", bounds_margin=float("inf")),
        ConfigError,
        r"TraceConfig.bounds_margin must be a finite number, got inf",
    ),
    Entry(
        "fitness-w1-nan",
        "config",
        "FitnessConfig(w1=nan)",
        _cfg("probeplace.placement.FitnessConfig", w1=float("nan")),
        ConfigError,
        r"FitnessConfig.w1 must be a non-negative number, got nan",
    ),
    Entry(
        "fitness-clearance-zero",
        "config",
        "FitnessConfig(clearance_voxels=0)",
        _cfg("probeplace.placement.FitnessConfig", clearance_voxels=0.0),
        ConfigError,
        r"FitnessConfig.clearance_voxels must be a positive number, got 0.0",
    ),
    Entry(
        "fitness-map-res-zero",
        "config",
        "FitnessConfig(map_res=0)",
        _cfg("probeplace.placement.FitnessConfig", map_res=0),
        ConfigError,
        r"map_res ≥ 1",
    ),
    Entry(
        "demo-unknown-key",
        "config",
        "demo config with an unknown top-level key",
        lambda c: __import__("probeplace.demo", fromlist=["x"])._merge_config({"bakee": {}}),
        ConfigError,
        r"demo config: unknown key 'bakee'; known: \[",
    ),
    Entry(
        "demo-unknown-nested-key",
        "config",
        "demo config with an unknown key inside a section",
        lambda c: __import__("probeplace.demo", fromlist=["x"])._merge_config(
            {"bake": {"spp": 4, "sppp": 8}}
        ),
        ConfigError,
        r"demo config: unknown keys \['sppp'\] in 'bake'",
    ),
    Entry(
        "demo-bad-yaml",
        "config",
        "demo YAML file that does not parse",
        lambda c: __import__("probeplace.demo", fromlist=["x"]).load_demo_config(
            c.write("d.yaml", "bake: [1, 2\n")
        ),
        ConfigError,
        r"d\.yaml: not valid YAML",
    ),
    Entry(
        "place-method",
        "config",
        "place(method='voronoi')",
        _place(method="voronoi"),
        ConfigError,
        r"method must be one of .*, got 'voronoi'",
    ),
    Entry(
        "place-budget",
        "config",
        "place(budget=0)",
        _place(budget=0),
        ConfigError,
        r"budget must be 'auto' or a positive integer, got 0",
    ),
    Entry(
        "place-refiner",
        "config",
        "place(refiner='annealing')",
        _place(refiner="annealing"),
        ConfigError,
        r"refiner must be one of .* or None, got 'annealing'",
    ),
    Entry(
        "cli-out-under-a-file",
        "cli",
        "`place --out` under a path whose parent is a file",
        _cli(
            "probeplace.cli._checked_place_args",
            "place",
            "cornell_box",
            "--out",
            "<dir>/f/p.json",
            files={"f": "x"},
        ),
        ConfigError,
        r"--out: cannot create .*/f/p\.json: .*/f is a file, not a folder",
    ),
    Entry(
        "cli-out-is-a-folder",
        "cli",
        "`place --out` naming a folder",
        _cli("probeplace.cli._checked_place_args", "place", "cornell_box", "--out", "<dir>"),
        ConfigError,
        r"--out: .* is a folder, not a file",
    ),
    Entry(
        "cli-place-unknown-option",
        "cli",
        "`place --option` the method does not have",
        _cli(
            "probeplace.cli._checked_place_args", "place", "cornell_box", "--method", "grid", "-o", "bogus=1"
        ),
        ConfigError,
        r"unknown grid options \['bogus'\]",
    ),
    Entry(
        "cli-eval-width-zero",
        "cli",
        "`evaluate --width 0`",
        _cli(*_EVAL, "--probes", "<dir>/p.json", "--out", "<dir>/ev", "--width", "0", files=_ONE_PROBE),
        ConfigError,
        r"--width: EvalConfig.width must be ≥ 1, got 0",
    ),
    Entry(
        "cli-eval-spp-zero",
        "cli",
        "`evaluate --spp 0`",
        _cli(*_EVAL, "--probes", "<dir>/p.json", "--out", "<dir>/ev", "--spp", "0", files=_ONE_PROBE),
        ConfigError,
        r"--spp: EvalConfig.spp must be a positive int or 'auto', got 0",
    ),
    Entry(
        "cli-eval-spp-autox",
        "cli",
        "`evaluate --spp autox` (a count is an int or `auto`, issue 33)",
        _cli(*_EVAL, "--probes", "<dir>/p.json", "--out", "<dir>/ev", "--spp", "autox", files=_ONE_PROBE),
        ConfigError,
        r"--spp: EvalConfig.spp must be a positive int or 'auto', got 'autox'",
    ),
    Entry(
        "cli-eval-noise-target-one",
        "cli",
        "`evaluate --noise-target 1` (the reference noise floor as a share of the black image's MSE)",
        _cli(
            *_EVAL, "--probes", "<dir>/p.json", "--out", "<dir>/ev", "--noise-target", "1", files=_ONE_PROBE
        ),
        ConfigError,
        r"--noise-target: EvalConfig.noise_target must be in \(0, 1\), got 1\.0",
    ),
    Entry(
        "cli-eval-bake-spp-autox",
        "cli",
        "`evaluate --bake-spp autox`",
        _cli(
            *_EVAL, "--probes", "<dir>/p.json", "--out", "<dir>/ev", "--bake-spp", "autox", files=_ONE_PROBE
        ),
        ConfigError,
        r"--bake-spp must be a positive int or 'auto', got 'autox'",
    ),
    Entry(
        "cli-eval-out-under-a-file",
        "cli",
        "`evaluate --out` under a path whose parent is a file",
        _cli(*_EVAL, "--probes", "<dir>/p.json", "--out", "<dir>/f/ev", files={**_ONE_PROBE, "f": "x"}),
        ConfigError,
        r"--out: cannot create .*/f/ev: .*/f is a file, not a folder",
    ),
    Entry(
        "cli-eval-empty-set",
        "cli",
        "`evaluate` of a probe set with no active probes",
        _cli(
            *_EVAL,
            "--probes",
            "<dir>/p.json",
            "--out",
            "<dir>/ev",
            files={"p.json": _probe_doc([[1.0, 1.0, 1.0]], [False])},
        ),
        ConfigError,
        r"--probes: .*p\.json holds no active probes",
    ),
    Entry(
        "cli-text-npz",
        "cli",
        "a text file named .npz given as baked probes",
        _cli(*_EVAL, "--probes", "<dir>/t.npz", "--out", "<dir>/ev", files={"t.npz": "hello\n"}),
        ConfigError,
        r"--probes: .*t\.npz is not a probeplace \.npz: not a NumPy archive",
    ),
    Entry(
        "cli-eval-cut-glb",
        "cli",
        "a cut .glb given as an exported probe set",
        _cli(*_EVAL, "--probes", "<dir>/p.glb", "--out", "<dir>/ev", files={"p.glb": "glTF\x02\x00\x00\x00"}),
        ConfigError,
        r"--probes: .*p\.glb: truncated GLB header",
    ),
    Entry(
        "cli-export-empty-set",
        "cli",
        "`export` of a probe set with no probes",
        _cli(
            "probeplace.cli._export_input",
            "export",
            "<dir>/p.json",
            "--format",
            "json",
            "--out",
            "<dir>/o.json",
            files={"p.json": _probe_doc([])},
        ),
        ProbeplaceError,
        r"p\.json: the probe set has no active probes; nothing to export",
    ),
    Entry(
        "runner-unknown-key",
        "cli",
        "runner override `+colour=red` (a key the schema lacks)",
        _runner({"colour": "red"}),
        ConfigError,
        r"^colour: not a key of the config; known: \[",
    ),
    Entry(
        "runner-tracer-spp-autox",
        "cli",
        "runner `tracer.spp=autox` (a count is an int or `auto`, issue 33)",
        _runner({"tracer": {"spp": "autox"}}),
        ConfigError,
        r"^tracer\.spp: must be a positive int or 'auto', got 'autox'",
    ),
    Entry(
        "runner-max-spp-below-pilot",
        "cli",
        "runner `tracer.spp=auto tracer.max_spp=4` (a cap below the pilot's 8 paths)",
        _runner({"tracer": {"spp": "auto", "max_spp": 4}}),
        ConfigError,
        r"^tracer\.max_spp: must be >= pilot_spp \(8\): the chosen count lies between them, got 4",
    ),
    Entry(
        "runner-bake-noise-target-zero",
        "cli",
        "runner `bake.spp=auto bake.noise_target=0`",
        _runner({"bake": {"spp": "auto", "noise_target": 0.0}}),
        ConfigError,
        r"^bake\.noise_target: must be in \(0, 1\), got 0\.0",
    ),
    Entry(
        "runner-bake-spp-autox",
        "cli",
        "runner `bake.spp=autox`",
        _runner({"bake": {"spp": "autox"}}),
        ConfigError,
        r"^bake\.spp: must be a positive int or 'auto', got 'autox'",
    ),
    Entry(
        "runner-eval-view-unknown",
        "cli",
        "runner `eval.view=CameraMain` on a scene without that camera (checked after loading the scene, "
        "before any run)",
        _runner_scenes(lambda c: {"eval": {"view": "CameraMain"}}),
        ConfigError,
        r"^eval\.view: scene 'cornell_box' has no view 'CameraMain'; views: \['front', 'interior'\]",
    ),
    Entry(
        "runner-scene-no-light",
        "cli",
        "runner `scene.name=<file>` with no emitter, sun or sky (no sidecar) for a run that bakes",
        _runner_scenes(lambda c: {"scene": {"name": str(c.write("t.obj", tet_obj()))}}),
        SceneError,
        r"t\.obj: the scene has no light .*add one with a sidecar t\.probeplace\.yaml beside the scene file "
        r"\(keys: sun, sky, emitters",
    ),
    Entry(
        "runner-scene-overrides-bad",
        "cli",
        "runner `'+scene.overrides.sun={azimuth:0,elevation:120}'` (sidecar keys for the runner)",
        _runner({"scene": {"overrides": {"sun": {"azimuth": 0, "elevation": 120}}}}),
        ConfigError,
        r"^scene\.overrides: sun\.elevation: must be in \[-90, 90\], got 120",
    ),
    Entry(
        "run-results-dir-under-a-file",
        "cli",
        "`probeplace.experiment.run(cfg)` from Python with `results_dir` under a file (checked before "
        "the scene is loaded)",
        lambda c: __import__("probeplace.experiment", fromlist=["x"]).run(
            {"results_dir": str(c.write("f", "x") / "results"), "eval": {"enabled": False}}
        ),
        ConfigError,
        r"^results_dir: cannot create .*/f/results/default: .*/f is a file, not a folder",
    ),
    Entry(
        "sidecar-unknown-key",
        "config",
        "a scene sidecar `t.probeplace.yaml` with a misspelt key (`sunn:`)",
        _sidecar("sunn: {azimuth: 90, elevation: 35}\n"),
        ConfigError,
        r"t\.probeplace\.yaml: sunn: unknown key; known keys: cameras, emitters",
    ),
    Entry(
        "sidecar-invalid-yaml",
        "config",
        "a scene sidecar that is not valid YAML",
        _sidecar("sun: {azimuth: 90\nsky: daylight\n"),
        ConfigError,
        r"t\.probeplace\.yaml: .*line",
    ),
    Entry(
        "sidecar-emitter-unknown-material",
        "config",
        "a scene sidecar naming an emitter material the scene lacks",
        _sidecar("emitters:\n  lamp_shade: 20\n"),
        ConfigError,
        r"t\.probeplace\.yaml: emitters\.lamp_shade: .*material",
    ),
    Entry(
        "scene-no-light-needs-sidecar",
        "scene data",
        "a scene file with no emitter, sun or sky where light is required (`evaluate`, the runner's bake)",
        _sidecar("", require_light=True),
        SceneError,
        r"t\.obj: the scene has no light .*sidecar t\.probeplace\.yaml .*keys: sun, sky, emitters",
    ),
    Entry(
        "cli-sun-bad-elevation",
        "cli",
        "`place --sun az=120,el=120`",
        _cli(
            "probeplace.cli._scene_options.scene_overrides_from_args",
            "place",
            "cornell_box",
            "--sun",
            "az=120,el=120",
        ),
        ConfigError,
        r"^--sun: .*el.*must be in \[-90, 90\], got 120",
    ),
    Entry(
        "cli-camera-looks-at-itself",
        "cli",
        "`evaluate --camera name=c,pos=1,1,1,look_at=1,1,1`",
        _cli(
            "probeplace.cli._scene_options.scene_overrides_from_args",
            "evaluate",
            "--scene",
            "cornell_box",
            "--probes",
            "p.json",
            "--camera",
            "name=c,pos=1,1,1,look_at=1,1,1",
        ),
        ConfigError,
        r"^--camera c: .*look_at.*equals the position",
    ),
    Entry(
        "runner-results-dir-under-a-file",
        "cli",
        "runner `results_dir` under a path whose parent is a file",
        lambda c: __import__("probeplace._core.runtime._checks", fromlist=["x"]).check_writable_folder(
            c.write("f", "x") / "results" / "default", "results_dir"
        ),
        ConfigError,
        r"results_dir: cannot create .*/f/results/default: .*/f is a file, not a folder",
    ),
    Entry(
        "cli-eval-image-too-large",
        "memory",
        "`evaluate --width 100000000 --height 100000000`",
        _cli(
            *_EVAL,
            "--probes",
            "<dir>/p.json",
            "--out",
            "<dir>/ev",
            "--width",
            "100000000",
            "--height",
            "100000000",
            files=_ONE_PROBE,
        ),
        ResourceError,
        r"--width × --height: the reference render of 100000000×100000000 pixels × 16 spp needs",
    ),
    Entry(
        "runner-image-too-large",
        "memory",
        "runner `eval.width=100000000 eval.height=100000000`",
        _runner({"eval": {"width": 10**8, "height": 10**8}}),
        ResourceError,
        r"eval\.width × eval\.height: the reference render of 100000000×100000000 pixels",
    ),
    Entry(
        "runner-bake-too-large",
        "memory",
        "runner `bake.radiance_res=65536`",
        _runner({"bake": {"radiance_res": 65536}}),
        ResourceError,
        r"bake\.radiance_res=65536, .*one probe's bake needs",
    ),
]


# ------------------------------------------- parse errors at any byte, sizes, disk space (issue 31)
def _place_budget(n: int):
    """``place --method grid --budget n`` up to the memory check made once the scene is loaded."""

    def run(c):
        from probeplace.cli import _budget_that_fits, build_parser

        args = build_parser().parse_args(["place", "cornell_box", "--method", "grid", "--budget", str(n)])
        return _budget_that_fits(args, cornell(), n)

    return run


def _disk_full(c):
    """``--out`` on a file system with no free bytes (``shutil.disk_usage`` stands in for a full disk)."""
    import shutil
    from unittest import mock

    from probeplace._core.runtime._checks import check_writable_file

    full = shutil._ntuple_diskusage(10**9, 10**9, 0)
    with mock.patch("shutil.disk_usage", return_value=full):
        return check_writable_file(c.tmp / "p.json", "--out")


def tet_ply_binary(order: str = "<") -> bytes:
    """The tetrahedron as a binary PLY, little-endian (``"<"``) or big-endian (``">"``)."""
    fmt = {"<": "binary_little_endian", ">": "binary_big_endian"}[order]
    head = (
        f"ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
        "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    faces = b"".join(b"\x03" + row.astype(order + "i4").tobytes() for row in TET_F)
    return head + TET_V.astype(order + "f4").tobytes() + faces


CATALOGUE += [
    Entry(
        "cut-vertex.obj",
        "scene file",
        "OBJ whose last line is cut mid-vertex (`v 1.0 2.`)",
        _load_bytes("cut3.obj", lambda: (tet_obj() + "v 1.0 2.").encode()),
        SceneError,
        r"cut3\.obj:9: vertex 'v 1\.0 2\.' has 2 numbers, needs 3–7: truncated or corrupt OBJ",
    ),
    Entry(
        "face-past-vertices.obj",
        "scene file",
        "OBJ face using a vertex the file does not define (cut before its last vertex)",
        _load_bytes("few.obj", lambda: tet_obj().replace("v 0.0 0.0 1.0\n", "").encode()),
        SceneError,
        r"few\.obj:\d+: face uses vertex 4 but the file defines 3 vertices",
    ),
    Entry(
        "cut-row.ply",
        "scene file",
        "ASCII PLY whose last face row is cut",
        _load_bytes("cut3.ply", lambda: tet_ply()[:-4].encode()),
        SceneError,
        r"cut3\.ply:17: face row '3 1' does not match the header's properties \(line 7\)",
    ),
    Entry(
        "cut-binary.ply",
        "scene file",
        "binary PLY one byte short",
        _load_bytes("cut4.ply", lambda: tet_ply_binary()[:-1]),
        SceneError,
        r"cut4\.ply: truncated PLY: .* need at least 100 bytes after end_header; the file holds 99",
    ),
    Entry(
        "cli-budget-too-many-probes",
        "memory",
        "`place --method grid --budget 1000000000` (maps that cannot fit in memory)",
        _place_budget(10**9),
        ResourceError,
        r"^--budget 1000000000: baking 1000000000 probes \(\d+ bytes each at radiance_res=\d+, .*needs ~\d+ "
        r"bytes .*over the limit of \d+ bytes.*lower --budget, or give --memory-budget",
    ),
    Entry(
        "cli-memory-budget-too-large",
        "memory",
        "`place --memory-budget 1PB`",
        _cli("probeplace.cli._checked_place_args", "place", "cornell_box", "--memory-budget", "1PB"),
        ResourceError,
        r"^--memory-budget 1PB: baking the probes that fill it needs ~1000000000000000 bytes",
    ),
    Entry(
        "memory-budget-in-bits",
        "config",
        "memory budget `64Mb` (megabits)",
        lambda c: __import__("probeplace.placement", fromlist=["x"]).parse_bytes("64Mb"),
        ConfigError,
        r"memory budget '64Mb' reads as bits \(Mb\); write MB for bytes",
    ),
    Entry(
        "memory-budget-bare-prefix",
        "config",
        "memory budget `1G` (10⁹ or 2³⁰?)",
        lambda c: __import__("probeplace.placement", fromlist=["x"]).parse_bytes("1G"),
        ConfigError,
        r"'G' alone is ambiguous: write GB or GiB",
    ),
    Entry(
        "cli-out-disk-full",
        "cli",
        "`--out` on a full disk",
        _disk_full,
        ConfigError,
        r"^--out: cannot write .*p\.json: it needs at least 4096 bytes, 0 bytes are free",
    ),
]


# ------------------------------------------ probes, cameras and lights that do not fit the scene (issue 31)
def _eval_recorded(c):
    """``evaluate --scene rooms`` of a ProbeSet that ``probeplace place cornell_box`` wrote."""
    doc = json.loads(_probe_doc([[200.0, 250.0, 200.0]]))
    c.write("p.json", json.dumps({**doc, "metadata": {"scene": "cornell_box"}}))
    return _cli(*_EVAL[:3], "rooms", "--probes", "<dir>/p.json", "--out", "<dir>/ev")(c)


def _scene_check(sidecar: str, *, warn: bool = False):
    """The evaluate command's view and light checks on the sidecar tests' room with ``sidecar``."""

    def run(c):
        from probeplace.evaluate._scene_checks import check_views_and_lights as check
        from probeplace.evaluate._scene_checks import host_caster, warn_unreached_lights
        from probeplace.scene import load_scene
        from tests.scene.sidecar_util import write_room_obj

        path = write_room_obj(c.tmp)
        c.write("room.probeplace.yaml", sidecar)
        scene = load_scene(path)
        if warn:
            return warn_unreached_lights(scene, host_caster(scene), path)
        return check(scene, path)

    return run


_DOOR = "  door: {position: [2, 1.5, 0.5], look_at: [2, 1.2, 4]}\n"
_LAMP = "  lamp: {position: [2, 0.2, 2], look_at: [2, 0.2, 4]}\n"  # inside the lamp box on the floor

CATALOGUE += [
    Entry(
        "eval-probes-placed-elsewhere",
        "probes",
        "`evaluate --scene rooms` of a ProbeSet whose metadata records `cornell_box`",
        _eval_recorded,
        ConfigError,
        r"^--probes: .*p\.json: the probes were placed in scene 'cornell_box' but are evaluated in 'rooms'; "
        r"evaluate them with --scene cornell_box",
    ),
    Entry(
        "bake-probes-of-another-scene",
        "probes",
        "bake of a probe set lying farther outside the scene than its size (another scene's, other units)",
        lambda c: bake(c.room(lit=True), cornell_probes(c.cornell())[:4]),
        ConfigError,
        r"^bake: 4 of 4 probes lie outside room's bounds \[0, 0, 0\]–\[4, 3, 5\] by more than its size",
    ),
    Entry(
        "tracer-probes-of-another-scene",
        "probes",
        "make_tracer on probes all moved 10 m outside the bounds",
        _tracer_with(lambda p: p + 10000.0),
        ConfigError,
        r"^make_tracer: 8 of 8 probes lie outside the scene's bounds",
    ),
    Entry(
        "sidecar-camera-in-solid",
        "scene data",
        "a sidecar camera inside a solid (the room's lamp box), checked before rendering",
        _scene_check(f"sky: daylight\ncameras:\n{_DOOR}{_LAMP}"),
        ConfigError,
        r"^room\.probeplace\.yaml: cameras\.lamp: position \[2, 0\.2, 2\] is inside solid geometry",
    ),
    Entry(
        "sun-below-horizon",
        "scene data",
        "a sidecar sun below the horizon of a closed room (warned: it reaches no point the views see)",
        _scene_check(f"sun: {{azimuth: 90, elevation: -20}}\ncameras:\n{_DOOR}", warn=True),
        None,
        r"room: the sun \(elevation -20°, below the horizon\) reaches 0 of the \d+ surface points the views",
    ),
    Entry(
        "vardis-no-light",
        "scene data",
        "`place(method='vardis')` on a scene with no light (Vardis path-traces its probe values)",
        _place(method="vardis", budget=4),
        SceneError,
        r"^vardis placement ranks probes by the light they see, and scene 'room' has no light .*"
        r"room\.probeplace\.yaml .*keys: sun, sky, emitters",
    ),
]


def _max_bytes_env(value: str):
    """``$PROBEPLACE_MAX_BYTES=value`` read by the memory check (the variable restored afterwards)."""

    def run(c):
        from probeplace._core import memory_limit_bytes

        with _limit(value):
            return memory_limit_bytes()

    return run


CATALOGUE += [
    Entry(
        "max-bytes-env-not-a-size",
        "memory",
        "`$PROBEPLACE_MAX_BYTES` set to something that is not a size (sizes such as `8GiB` are read)",
        _max_bytes_env("lots"),
        ConfigError,
        r"^\$PROBEPLACE_MAX_BYTES='lots': memory budget must be a size in bytes .*unset it or give a size",
    ),
    Entry(
        "runner-redo-bad",
        "config",
        "runner `redo=sometimes` (never, stale or all)",
        _runner({"redo": "sometimes"}),
        ConfigError,
        r"redo: must be one of never, stale, all, got 'sometimes'",
    ),
]


# ------------------------------------------------------------------------- probeplace view (issue 36)
_VIEW = "probeplace.cli._view.checked_input"
CATALOGUE += [
    Entry(
        "view-missing-path",
        "cli",
        "`view` of a path that does not exist",
        _cli(_VIEW, "view", "<dir>/nowhere"),
        ProbeplaceError,
        r"nowhere: no such file or folder; give a run folder \(it holds probes\.json\) or a probes file",
    ),
    Entry(
        "view-not-a-run",
        "cli",
        "`view` of a folder that is not a finished run (no `probes.json`)",
        _cli(_VIEW, "view", "<dir>"),
        ProbeplaceError,
        r"not a finished run \(no probes\.json\); give a run folder .* or a probes file with --scene",
    ),
    Entry(
        "view-corrupt-probes",
        "cli",
        "`view` of a probes file that is not valid JSON",
        _cli(_VIEW, "view", "<dir>/p.json", files={"p.json": "{oops"}),
        ProbeplaceError,
        r"p\.json: not valid JSON .*the probes file is damaged or not a probe set",
    ),
    Entry(
        "view-no-scene",
        "cli",
        "`view` of a probes file that records no scene, without `--scene`",
        _cli(_VIEW, "view", "<dir>/p.json", files=_ONE_PROBE),
        ProbeplaceError,
        r"p\.json: the probes file records no scene; give it with --scene NAME_OR_PATH",
    ),
    Entry(
        "view-unknown-scene",
        "cli",
        "`view --scene` naming a scene that is neither built-in nor on the search path",
        _cli(_VIEW, "view", "<dir>/p.json", "--scene", "no_such_scene", files=_ONE_PROBE),
        ProbeplaceError,
        r"--scene: scene 'no_such_scene' is neither built-in nor on the scene search path",
    ),
]

assert len({e.id for e in CATALOGUE}) == len(CATALOGUE), "catalogue ids must be unique"
