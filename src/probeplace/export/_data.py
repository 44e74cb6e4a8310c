"""The exporters' input: a probe set as plain NumPy arrays, read from the files the pipeline writes.

Exporters import no JAX (DESIGN.md: ``export/`` is NumPy only), so they take :class:`ExportProbes`
rather than the ``ProbeSet`` / ``LightFieldProbes`` pytrees. Build one with
:meth:`ExportProbes.from_probe_set` (duck-typed: anything with ``pos_world``/``active``/``method``),
or read a file with ``_registry.read_probes`` (a ProbeSet JSON file, a baked ``.npz``, or any file an
importer of this package understands).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from .._core._errors import ProbeplaceError
from .._core.files._probe_files import parse_probe_set, read_light_field_arrays
from ._sh import project_radiance


class ExportError(ProbeplaceError, ValueError):
    """An export or import failed: bad input file, unknown format, or data the format cannot hold."""


@dataclasses.dataclass(frozen=True, eq=False)
class LightFieldMaps:
    """The pre-filtered maps of baked probes that texture exports need (the LightFieldProbes layout).

    Attributes:
        irradiance: (n, I+2, I+2, 3) bordered octahedral irradiance maps (reflected light, as baked).
        moments: (n, M+2, M+2, 2) bordered maps of filtered (E[r], E[r²]) distance moments.
        radiance: (n, R+2, R+2, 3) reflected radiance (used for SH and total irradiance), or None.
        emission: (n, R+2, R+2, 3) emitted / sky radiance (same layout), or None.
        far: distance stored for escaping rays.
    """

    irradiance: np.ndarray
    moments: np.ndarray
    radiance: np.ndarray | None
    emission: np.ndarray | None
    far: float

    def select(self, rows: np.ndarray) -> LightFieldMaps:
        pick = lambda a: None if a is None else a[rows]
        return LightFieldMaps(
            self.irradiance[rows], self.moments[rows], pick(self.radiance), pick(self.emission), self.far
        )


@dataclasses.dataclass(frozen=True, eq=False)
class ExportProbes:
    """A probe set ready to export (NumPy arrays, world frame: right-handed, +Y up, scene units).

    Attributes:
        positions: (n, 3) float32 probe centres.
        active: (n,) bool, which rows are real probes (engine formats write only these).
        method: name of the placer that made the set.
        units_m: metres per scene unit.
        metadata: free-form JSON-serialisable dict (config, seed, timings, …).
        sh: optional (n, 9, 3) float32 SH L2 radiance coefficients (``_sh`` module: three.js convention).
        inside: optional (n,) bool, probes found inside geometry at bake time (invalid for shading).
        maps: optional baked maps (DDGI textures, Three.V8 visibility).
    """

    # Array-likes on input (lists, JAX arrays); __post_init__ stores them as NumPy arrays.
    positions: Any
    active: Any
    method: str = "manual"
    units_m: float = 1.0
    metadata: dict = dataclasses.field(default_factory=dict)
    sh: Any = None
    inside: Any = None
    maps: LightFieldMaps | None = None

    def __post_init__(self):
        pos = np.asarray(self.positions, np.float32)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ExportError(f"positions must have shape (n, 3), got {pos.shape}")
        if not np.isfinite(pos).all():
            raise ExportError("probe positions must be finite (NaN or inf found)")
        active = np.asarray(self.active, bool).reshape(-1)
        if active.shape != (len(pos),):
            raise ExportError(f"active must have shape ({len(pos)},), got {active.shape}")
        if not (isinstance(self.units_m, int | float) and math.isfinite(self.units_m) and self.units_m > 0):
            raise ExportError(f"units_m must be a positive finite number, got {self.units_m!r}")
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "active", active)
        object.__setattr__(self, "units_m", float(self.units_m))
        if self.sh is not None:
            sh = np.asarray(self.sh, np.float32)
            if sh.shape != (len(pos), 9, 3):
                raise ExportError(f"sh must have shape ({len(pos)}, 9, 3), got {sh.shape}")
            if not np.isfinite(sh).all():
                raise ExportError("SH coefficients must be finite")
            object.__setattr__(self, "sh", sh)
        if self.inside is not None:
            inside = np.asarray(self.inside, bool).reshape(-1)
            if inside.shape != (len(pos),):
                raise ExportError(f"inside must have shape ({len(pos)},), got {inside.shape}")
            object.__setattr__(self, "inside", inside)
        if self.maps is not None and len(self.maps.irradiance) != len(pos):
            raise ExportError(f"maps hold {len(self.maps.irradiance)} probes, positions {len(pos)}")
        try:
            json.dumps(self.metadata, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise ExportError(f"metadata must be JSON-serialisable ({e})") from None

    @property
    def n(self) -> int:
        return len(self.positions)

    def active_only(self) -> ExportProbes:
        """The active rows only (what engine formats hold), in their original order."""
        rows = np.flatnonzero(self.active)
        return dataclasses.replace(
            self,
            positions=self.positions[rows],
            active=np.ones(len(rows), bool),
            sh=None if self.sh is None else self.sh[rows],
            inside=None if self.inside is None else self.inside[rows],
            maps=None if self.maps is None else self.maps.select(rows),
        )

    @classmethod
    def from_probe_set(cls, probes: Any, **kw) -> ExportProbes:
        """From a ``ProbeSet`` or ``LightFieldProbes`` (any object with ``pos_world`` and ``active``).

        Arrays are converted with ``np.asarray``, so JAX arrays work without this module importing JAX.
        """
        return cls(
            positions=np.asarray(probes.pos_world),
            active=np.asarray(probes.active),
            method=str(getattr(probes, "method", kw.pop("method", "manual"))),
            **kw,
        )


def _probe_set_doc(path: Path, doc: dict) -> ExportProbes:
    try:
        ps = parse_probe_set(doc, path)
    except ProbeplaceError as e:
        raise ExportError(str(e)) from None
    return ExportProbes(ps.positions, ps.active, ps.method, ps.units_m, dict(doc.get("metadata") or {}))


def read_light_field_npz(path: str | os.PathLike, *, sh_source: str = "total") -> ExportProbes:
    """Read baked probes (``.npz`` of ``probeplace.probes.save_probes``) with NumPy alone."""
    path = Path(path)
    if sh_source not in ("total", "reflected"):
        raise ExportError(f"sh_source must be 'total' or 'reflected', got {sh_source!r}")
    needed = ("pos_world", "active", "radiance", "emission", "irradiance", "moments", "far")
    try:  # the geometry maps (gigabytes at 512²) stay on disk
        data = read_light_field_arrays(path, (*needed, "inside"))
    except ProbeplaceError as e:
        raise ExportError(str(e)) from None
    missing = [k for k in needed if k not in data]
    if missing:
        raise ExportError(f"{path}: probe file lacks {missing}")
    maps = LightFieldMaps(
        irradiance=np.asarray(data["irradiance"], np.float32),
        moments=np.asarray(data["moments"], np.float32),
        radiance=np.asarray(data["radiance"], np.float32),
        emission=np.asarray(data["emission"], np.float32),
        far=float(data["far"]),
    )
    light = maps.radiance + maps.emission if sh_source == "total" else maps.radiance
    return ExportProbes(
        positions=data["pos_world"],
        active=data["active"],
        method="baked",
        metadata={"source": path.name, "sh_source": sh_source},
        sh=project_radiance(light),
        inside=data.get("inside"),
        maps=maps,
    )
