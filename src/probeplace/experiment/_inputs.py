"""What a run's results depend on besides its config (issue 31), recorded in the run folder's
``inputs.json`` and compared, with ``config.yaml``, whenever a finished run is met again (``run``).

``inputs.json``:

* ``code``: ``results_version`` (:data:`RESULTS_VERSION`) and ``probeplace`` (the package version).
* ``scene``: what the scene was made from, read without loading the geometry (cheap: a sweep checks it
  for every finished run):

  - a built-in: ``kind: builtin``, its ``name``, the generator's ``parameters`` (the factory's keyword
    defaults; the factories take none today, so a generator change must bump :data:`RESULTS_VERSION`) and
    ``config``, the resolved ``scene.overrides``;
  - a file: ``kind: file``, ``sha256`` of the file, ``references`` (the sha256 of each file its loader
    reads beside it: an OBJ's ``mtllib`` files, a glTF's external buffers; ``null`` for a missing one) and
    ``config``, the *resolved* sidecar: the layers ``KNOWN_SCENES`` < ``<stem>.probeplace.yaml`` <
    ``scene.overrides`` merged and parsed (sun, sky, emitters, materials, cameras, units, up axis as
    values: ``daylight`` is its radiance, ``mm`` is 0.001), so a reformatted sidecar is the same run and
    a changed sun is not. ``path`` (where it was found) is recorded but not compared: moving the scenes
    folder changes no result.

* ``scene_loaded`` (written once the scene has loaded; not compared): what the run actually saw, the
  scene's own summary (``probeplace scenes -v``): world-frame sun, sky, emitters, cameras, bounds,
  triangles.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import json
import os
from pathlib import Path
from typing import Any
from urllib.parse import unquote

#: The version of the numbers a run writes. Bump it in the commit that changes them (placement, bake,
#: evaluation, a built-in scene's generator, a default that ``config.yaml`` does not record): every run
#: finished under another version is then refused as stale (``redo=stale`` redoes it). Not the git
#: revision: a docs or test commit must not invalidate results (the revision stays in ``env.json``).
#: 2 (2026-12-04): the light-field tracer's edge-on rule covers every candidate surfel an ambiguous cell's
#: ray meets, which moves glossy estimates (issue 33).
#: 3 (2026-12-04): a ray starts on a surfel's surface only within ``TraceConfig.start_tol`` in front of
#: its plane (was the thickness): rays leaving a surface next to another hit it (issue 33).
#: 4 (2026-12-05): the tracer's fallback takes up rays stalled on a surface (``TraceConfig.surface_lookback``)
#: and its surface shell is half as thick (``TraceConfig.thickness`` 1.5 %): glossy estimates move (issue 33).
#: 5 (2026-12-05): a concave-crease partner is a neighbour whose normal differs from the surfel's by more
#: than the shell allows (``_march._partners``): rays near one flat surface's texels resolve (issue 33).
#: 6 (2026-12-05): the geometry bake casts its texel rays in Embree's 16-ray packets where the compiled
#: loop exists (``geometry/_embree_packets.py``): distances move by a few ulps, a few texels' hits on
#: edges and ties (issue 33).
#: 7 (2026-12-06): the depth-aware read takes each radiance texel's surfel from the geometry texel holding
#: its centre by integer arithmetic (``_core.surfel_texels``; a float round trip had picked either side of
#: a texel boundary), and a bake may send a texel's rays along its surfel (``BakeConfig.texel_rays``,
#: default still "jittered") (issue 33).
#: 8 (2026-12-06): the glossy read's default filter is ``"depth_normal"``: the depth-aware read's texels must
#: also face as the hit's surface does (``probes._glossy.NORMAL_COS``), every glossy figure moves (issue 33).
RESULTS_VERSION = 8

#: Input keys recorded but not compared (flattened, as the refusal names them).
NOT_COMPARED = ("scene.path",)
#: Top-level parts of ``inputs.json`` that are records only.
RECORD_ONLY = ("scene_loaded",)


def code_version() -> dict:
    """``results_version`` and the ``probeplace`` version. The package version is compared too: it moves
    only at a release, which may gather numeric changes whose :data:`RESULTS_VERSION` bump was forgotten.
    Third-party versions (JAX, NumPy, Mitsuba) are in ``env.json`` and not compared: an upgrade moves last
    bits, not what a result means, and refusing every result after ``pip install -U`` would only teach
    ``redo=all``."""
    from .. import __version__

    return {"results_version": RESULTS_VERSION, "probeplace": __version__}


def json_digest(data: Any) -> str:
    """SHA-1 of ``data`` as sorted JSON (also what names a run's ``scene.overrides``: ``run_name``)."""
    return hashlib.sha1(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


_DIGESTS: dict[tuple, str] = {}  # (resolved path, size, mtime) -> sha256: a sweep hashes each file once


def file_sha256(path: Path) -> str | None:
    """SHA-256 of a file's bytes (None when it is missing), cached per process by size and mtime."""
    try:
        st = path.stat()
    except OSError:
        return None
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _DIGESTS:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
        _DIGESTS[key] = h.hexdigest()
    return _DIGESTS[key]


def _references(path: Path) -> list[Path]:
    """The files the loader reads beside ``path``: an OBJ's ``mtllib`` files (as ``load_obj`` names
    them), a glTF's / GLB's external buffers. Textures are not read by the loaders, so not listed."""
    ext = path.suffix.lower()
    if ext == ".obj":
        out = []
        for line in path.read_bytes().decode("utf-8", errors="replace").splitlines():
            tok = line.split("#", 1)[0].split(maxsplit=1)
            if len(tok) == 2 and tok[0] == "mtllib":
                out.append(path.parent / tok[1].strip())
        return out
    if ext in (".gltf", ".glb"):
        from ..scene import read_gltf_json

        uris = [b.get("uri") for b in read_gltf_json(path).get("buffers", []) if isinstance(b, dict)]
        return [path.parent / unquote(u) for u in uris if isinstance(u, str) and not u.startswith("data:")]
    return []


def _plain(data: Any) -> Any:
    """JSON's view of ``data`` (tuples as lists), so a fresh record equals one read back from disk."""
    return json.loads(json.dumps(data, default=str))


def _resolved(cfg) -> dict:
    """A merged sidecar ``SceneConfig`` as plain data, without ``source`` (a label for messages)."""
    d = dataclasses.asdict(cfg)
    d.pop("source", None)
    return _plain(d)


def _scene_file(name: str, overrides) -> Path | None:
    """The scene file ``load_scene`` would read for ``name``, or None for a built-in. A name or path that
    does not resolve is refused with ``load_scene``'s own message (it fails before reading anything)."""
    from ..scene import BUILTIN_SCENES, SCENE_EXTENSIONS, find_scene_file, load_scene, looks_like_path

    if looks_like_path(name):
        path: Path | None = Path(name)
    elif name in BUILTIN_SCENES:
        return None
    else:
        path = find_scene_file(name)
    if path is None or not path.is_file() or path.suffix.lower() not in SCENE_EXTENSIONS:
        load_scene(name, overrides=overrides)  # raises: unknown name, missing file, unsupported extension
        raise AssertionError(f"load_scene accepted {name!r}")  # pragma: no cover
    return path


def scene_inputs(scene_cfg) -> dict:
    """The ``scene`` part of ``inputs.json`` for a run's ``scene`` group (module docstring).

    Raises:
        SceneError: an unknown scene name, a missing file, an unsupported extension, a corrupt glTF header.
        ConfigError: an invalid sidecar or ``scene.overrides``.
    """
    from ..scene import BUILTIN_SCENES, merge_scene_configs, parse_scene_config, scene_config_layers

    name = str(scene_cfg.name)
    overrides = dict(getattr(scene_cfg, "overrides", None) or {}) or None
    path = _scene_file(name, overrides)
    if path is None:
        params = {
            k: p.default
            for k, p in inspect.signature(BUILTIN_SCENES[name]).parameters.items()
            if p.default is not inspect.Parameter.empty
        }
        return _plain(
            {
                "kind": "builtin",
                "name": name,
                "parameters": params,
                "config": _resolved(parse_scene_config(overrides, "overrides")),
            }
        )
    config = merge_scene_configs(*scene_config_layers(path, overrides))
    refs = {os.path.relpath(r, path.parent): file_sha256(r) for r in _references(path)}
    return _plain(
        {
            "kind": "file",
            "path": str(path),
            "sha256": file_sha256(path),
            "references": refs,
            "config": _resolved(config),
        }
    )


def run_inputs(scene_cfg) -> dict:
    """``inputs.json`` of a run before its scene loads: ``code`` and ``scene``."""
    return {"code": code_version(), "scene": scene_inputs(scene_cfg)}
