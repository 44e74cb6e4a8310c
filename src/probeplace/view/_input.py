"""What ``probeplace view`` is asked to show, checked before anything slow (no JAX, no scene, no server).

A run folder (``experiments/run.py``'s ``<results>/<experiment>/<run>/``) holds ``probes.json``, its
``config.yaml`` (the scene), and, when the run baked and evaluated, ``probes_baked.npz`` and ``eval/``.
A bare probes file (a ProbeSet ``.json``, a baked ``.npz``, an exported ``.glb``/``.usda``/...) names its
scene with ``--scene``, or records it (``probeplace place`` writes ``metadata.scene``; a bake writes
``bake_settings.scene``). Every refusal is a :class:`ProbeplaceError` of one line naming the fix.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from .._core import ProbeplaceError
from .._core.files import RunFiles, coverage_detail_path, read_light_field_arrays
from ..export import ExportError, ExportProbes, read_probes

_WHAT = "give a run folder (it holds probes.json) or a probes file (.json, .npz, .glb, .usda, ...)"


@dataclass(frozen=True)
class ViewInput:
    """A checked request: the probes (parsed, NumPy), where the rest lies, which scene to load.

    Attributes:
        path: what was given.
        probes: the probe set (``export.read_probes``), in file order.
        probes_path: the file the probes came from.
        baked_path: the baked ``.npz`` whose maps the viewer shows, or None.
        eval_dir: the run's ``eval/`` folder, or None.
        scene: the scene name or file to load (``--scene`` or recorded), or None for a run folder whose
            ``config.yaml`` (``run_config``) says it.
        run_config: a run folder's ``config.yaml`` as a dict, or None.
        metadata: the probe file's metadata (placement record: which probes were relocated / filled).
        coverage_path: the probe set's ``<stem>.coverage.npz``
            (``_core.files._probe_files.coverage_detail_path``: ``probeplace place`` and the runner write
            it), or None (an older version's, an engine file).
    """

    path: Path
    probes: ExportProbes
    probes_path: Path
    baked_path: Path | None
    eval_dir: Path | None
    scene: str | None
    run_config: dict | None
    metadata: dict
    coverage_path: Path | None = None


def resolve_input(path: str | os.PathLike, scene: str | None = None) -> ViewInput:
    """Check ``path`` (and ``--scene``) and read the probes; no scene is loaded yet.

    Raises:
        ProbeplaceError: a missing path, a folder that is not a finished run (no ``probes.json``), a
            corrupt probes file, a scene that is neither given, recorded nor found.
    """
    p = Path(path)
    if not p.exists():
        raise ProbeplaceError(f"{p}: no such file or folder; {_WHAT}")
    if p.is_dir():
        return _run_folder(p, scene)
    probes = _read(p)
    baked = p if p.suffix == ".npz" else None
    recorded = _recorded_scene(p, probes)
    name = scene or recorded
    if not name:
        raise ProbeplaceError(
            f"{p}: the probes file records no scene; give it with --scene NAME_OR_PATH "
            "(see probeplace scenes)"
        )
    check_scene_found(name, "--scene" if scene else f"{p} (the scene it records)")
    coverage = coverage_detail_path(p)  # beside a probe set of `probeplace place`
    meta = dict(probes.metadata)
    return ViewInput(p, probes, p, baked, None, name, None, meta, coverage if coverage.is_file() else None)


def _run_folder(d: Path, scene: str | None) -> ViewInput:
    probes_path = d / RunFiles.probes
    if not probes_path.is_file():
        raise ProbeplaceError(
            f"{d}: not a finished run (no {RunFiles.probes}); give a run folder of experiments/run.py whose "
            "placement finished, or a probes file with --scene"
        )
    probes = _read(probes_path)
    config = None
    cfg_path = d / RunFiles.config
    if cfg_path.is_file():
        import yaml

        try:
            config = yaml.safe_load(cfg_path.read_text())
        except (yaml.YAMLError, UnicodeDecodeError) as e:
            raise ProbeplaceError(f"{cfg_path}: not valid YAML ({' '.join(str(e).split())})") from None
        if not isinstance(config, dict):
            raise ProbeplaceError(f"{cfg_path}: not a run config (a YAML mapping); give --scene NAME_OR_PATH")
    if scene:
        check_scene_found(scene, "--scene")
    elif config is None:
        raise ProbeplaceError(
            f"{d}: the run folder has no {RunFiles.config} naming its scene; give --scene NAME_OR_PATH"
        )
    else:
        name = (config.get("scene") or {}).get("name") if isinstance(config.get("scene"), dict) else None
        if not isinstance(name, str) or not name:
            raise ProbeplaceError(f"{cfg_path}: no scene.name; give --scene NAME_OR_PATH")
        check_scene_found(name, f"{cfg_path} (scene.name)")
    baked = d / RunFiles.baked
    eval_dir = d / RunFiles.eval_dir
    coverage = coverage_detail_path(probes_path)
    return ViewInput(
        d,
        probes,
        probes_path,
        baked if baked.is_file() else None,
        eval_dir if eval_dir.is_dir() else None,
        scene,
        config,
        dict(probes.metadata),
        coverage if coverage.is_file() else None,
    )


def _read(path: Path) -> ExportProbes:
    try:
        return read_probes(path)
    except ExportError as e:
        raise ProbeplaceError(
            f"{e}; the probes file is damaged or not a probe set: re-run the placement"
        ) from None


def _recorded_scene(path: Path, probes: ExportProbes) -> str | None:
    """The scene a probes file records: ``metadata.scene`` (``probeplace place``), or a baked file's
    ``bake_settings.scene``."""
    name = probes.metadata.get("scene")
    if isinstance(name, str) and name:
        return name
    if path.suffix != ".npz":
        return None
    try:
        z = read_light_field_arrays(path, ("bake_settings",))
        settings = json.loads(str(z["bake_settings"])) if "bake_settings" in z else {}
    except (ProbeplaceError, ValueError):
        return None  # read_probes read this file already; a bake without settings records no scene
    name = settings.get("scene") if isinstance(settings, dict) else None
    return name if isinstance(name, str) and name else None


def check_scene_found(name: str, where: str) -> None:
    """Refuse a scene that cannot load because it is not there: a file that does not exist, or a name that
    is neither built-in nor on the search path. Cheap: reads no geometry, imports no JAX."""
    from ..scene import BUILTIN_SCENES, SCENE_PATH_ENV, find_scene_file, looks_like_path

    if looks_like_path(name):
        if not Path(name).is_file():
            raise ProbeplaceError(f"{where}: scene file {name} not found; give --scene NAME_OR_PATH")
    elif name not in BUILTIN_SCENES and find_scene_file(name) is None:
        raise ProbeplaceError(
            f"{where}: scene {name!r} is neither built-in nor on the scene search path (${SCENE_PATH_ENV}); "
            "give --scene NAME_OR_PATH (see probeplace scenes)"
        )
