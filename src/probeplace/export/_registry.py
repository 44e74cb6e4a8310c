"""Format registry: one name per exporter (the ``--format`` values of ``probeplace export``)."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from pathlib import Path

from .._core._errors import ProbeplaceError
from .._core.files._probe_files import PROBE_SET_FORMAT, read_json_doc
from ._data import ExportError, ExportProbes, _probe_set_doc, read_light_field_npz
from ._ddgi import write_ddgi
from ._engines import write_godot, write_unity
from ._gltf import read_gltf, write_gltf
from ._json import JSON_FORMAT, from_json_doc, read_json, write_json
from ._threev8 import read_threev8, write_threev8
from ._usd import read_usd, write_usd


@dataclasses.dataclass(frozen=True)
class ExportFormat:
    name: str
    write: Callable[..., list[Path]]
    read: Callable[[str | os.PathLike], ExportProbes] | None
    extensions: tuple[str, ...]
    summary: str


FORMATS: dict[str, ExportFormat] = {
    f.name: f
    for f in (
        ExportFormat("json", write_json, read_json, (".json",), "probeplace.ProbeExport/1 JSON + Schema"),
        ExportFormat("gltf", write_gltf, read_gltf, (".gltf", ".glb"), "glTF 2.0 nodes with extras"),
        ExportFormat("unity", write_unity, None, (".prefab",), "Unity prefab with a LightProbeGroup"),
        ExportFormat("godot", write_godot, None, (".tscn",), "Godot 4: LightmapGI + LightmapProbe nodes"),
        ExportFormat("threev8", write_threev8, read_threev8, (".lodprobes",), "Three.V8 mixed-res grid"),
        ExportFormat("ddgi", write_ddgi, None, (".json",), "DDGI atlases (EXR + PNG + JSON sidecar)"),
        ExportFormat("usd", write_usd, read_usd, (".usda", ".usdc", ".usd"), "USD UsdGeomPoints + primvars"),
    )
}


#: The file suffixes :func:`read_probes` reads: those of every format with a reader (``.json`` is also a
#: ProbeSet's; the file's own tag tells them apart).
READABLE_SUFFIXES = tuple(dict.fromkeys(ext for f in FORMATS.values() if f.read for ext in f.extensions))


def export_probes(probes: ExportProbes, fmt: str, out: str | os.PathLike, **options) -> list[Path]:
    """Write ``probes`` in format ``fmt`` (a key of :data:`FORMATS`) to ``out``; returns the files written.

    ``options`` are the format writer's keyword arguments (e.g. ``to_metres`` for gltf/unity/godot,
    ``base_cells`` for threev8, ``irradiance_res``/``distance_res``/``light`` for ddgi).

    Raises:
        ExportError: unknown format, unsupported option, or data the format cannot hold.
    """
    if fmt not in FORMATS:
        raise ExportError(f"unknown export format {fmt!r}; choose one of {sorted(FORMATS)}")
    try:
        return FORMATS[fmt].write(probes, out, **options)
    except TypeError as e:
        if "unexpected keyword" in str(e):
            raise ExportError(f"format {fmt!r}: {e}") from None
        raise


def import_probes(path: str | os.PathLike, fmt: str | None = None) -> ExportProbes:
    """Read probes back from an exported file (json, gltf, threev8, usd); ``fmt`` is guessed from the
    file when omitted."""
    path = Path(path)
    if not path.is_file():
        raise ExportError(f"file not found: {path}")
    if fmt is None:
        suffix = path.suffix.lower()
        if suffix == ".json":
            return _from_json(path, _json_doc(path))
        fmt = next((f.name for f in FORMATS.values() if f.read and suffix in f.extensions), None)
        if fmt is None:
            raise ExportError(f"{path}: cannot tell the format from the extension {suffix!r}")
    if fmt not in FORMATS or FORMATS[fmt].read is None:
        readable = sorted(k for k, f in FORMATS.items() if f.read)
        raise ExportError(f"format {fmt!r} has no importer; importers exist for {readable}")
    return FORMATS[fmt].read(path)


def read_probes(path: str | os.PathLike, *, sh_source: str = "total") -> ExportProbes:
    """Read a probe set from any file probeplace understands.

    * ``*.npz`` baked light-field probes (``probeplace.probes.save_probes``): positions, activity,
      inside flags, SH L2 projected from the radiance maps and the maps for texture exports;
    * a ProbeSet JSON file (``probeplace place``; format ``probeplace.ProbeSet/1``);
    * any file an importer of this package reads (JSON export, glTF/GLB, Three.V8, USD).

    Args:
        path: the file.
        sh_source: for ``.npz`` input, which light the SH hold: ``"total"`` (reflected + emitted/sky:
            what a dynamic object at the probe receives; the default) or ``"reflected"``.

    Raises:
        ExportError: missing or unreadable file, unknown content.
    """
    path = Path(path)
    if not path.is_file():
        raise ExportError(f"probe file not found: {path}")
    if path.suffix == ".npz":
        return read_light_field_npz(path, sh_source=sh_source)
    if path.suffix.lower() == ".json":  # read once, told apart by the format tag
        doc = _json_doc(path)
        return _probe_set_doc(path, doc) if doc.get("format") == PROBE_SET_FORMAT else _from_json(path, doc)
    return import_probes(path)


def _json_doc(path: Path) -> dict:
    try:
        return read_json_doc(path)
    except ProbeplaceError as e:
        raise ExportError(str(e)) from None


def _from_json(path: Path, doc: dict) -> ExportProbes:
    """A JSON export (``probeplace.ProbeExport/1``) from its loaded document."""
    tag = doc.get("format")
    if tag != JSON_FORMAT:
        raise ExportError(f"{path}: JSON file of unknown format {tag!r} (expected {JSON_FORMAT!r})")
    return from_json_doc(doc, str(path))
