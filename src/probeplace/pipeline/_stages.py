"""The stages' shared steps, written once (issue 35: the runner and the CLI each baked, checked the
backend, the view and the memory budget, and wrote the placement their own way; turn 2's bake-depth drift
and the CLI's per-ray tracer came from that).

Each function takes the stages' library configs (``probes.BakeConfig``, ``evaluate.EvalConfig``) and plain
values; the front doors — ``experiment.run`` (the runner), ``probeplace place`` / ``evaluate`` (the CLI)
and ``probeplace demo`` (the stage tour) — translate their options into those and call these. ``key``
arguments name the option a refusal should quote (``"bake.backend"`` for the runner, ``"--backend"`` for
the CLI): the check is one, its wording follows the door.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._core import ConfigError

if TYPE_CHECKING:
    from .._core import LightFieldProbes, ProbeSet, Scene


def check_backend(backend: str, key: str) -> None:
    """Refuse a ``"mitsuba"`` path tracer whose module or LLVM variant cannot load, before any work
    (``render.load_mitsuba``'s message after ``key``); any other backend passes (its name is checked by
    the config that holds it)."""
    if backend != "mitsuba":
        return
    from ..render import load_mitsuba

    try:
        load_mitsuba()
    except ImportError as e:
        raise ConfigError(f"{key}: {e}") from None


def check_view(scene: Scene, view: str | None, key: str, label: str | None = None) -> str:
    """The evaluated view: ``view``, or the scene's first when ``None``; refused (naming ``key``, and the
    scene as ``label``, default its name) when the scene has no view or not this one."""
    label = scene.name if label is None else label
    views = [c.name for c in scene.views]
    if not views:
        raise ConfigError(f"scene {label!r} has no view to evaluate (add one in its sidecar config)")
    view = views[0] if view is None else view
    if view not in views:
        raise ConfigError(f"{key}: scene {label!r} has no view {view!r}; views: {views}")
    return view


def probe_budget(scene: Scene, budget: int | str, memory_budget: int | str | None, bake: Any) -> int | str:
    """The probe count to place: ``budget``, or — with ``memory_budget`` (bytes, or ``"512MB"``…) — the
    most probes whose baked maps at ``bake`` (``probes.BakeConfig``) fit in it
    (``placement.count_for_memory`` over ``probes.probe_bytes``)."""
    if memory_budget is None:
        return budget
    from ..placement import count_for_memory
    from ..probes import probe_bytes

    return count_for_memory(memory_budget, probe_bytes(scene, bake))


def write_placement(
    scene: Scene,
    placed: Any,
    out: Path,
    *,
    png: Path,
    title: str,
    metadata: dict,
    on_error: Callable[[Path], Any] | None = None,
) -> None:
    """A placement (``placement.PlaceResult``) on disk: its top view ``png``, each probe's part in the
    coverage beside the set (``<stem>.coverage.npz``, when the placement can give it) and the probe set
    ``out`` with ``metadata`` — last, so a probe set on disk means the rest was written; on any failure
    or interrupt the top view and the detail are removed. ``on_error`` wraps each write (a context
    manager factory naming the file; ``_core.files._io.naming_the_file`` for the CLI)."""
    from contextlib import nullcontext

    from .._core import save_probe_set
    from .._core.files import coverage_detail_path
    from ..placement import result_coverage_detail, save_top_view

    naming = on_error or (lambda _path: nullcontext())
    active = np.asarray(placed.probes.active)
    pos = np.asarray(placed.probes.pos_world)[active]
    detail_path = coverage_detail_path(out)
    detail = result_coverage_detail(placed)  # the placement's own visibility pass, else one more
    try:
        with naming(png):  # a full disk fails savefig's write() naming no file
            save_top_view(scene, pos, png, title=title)
        if detail is not None:
            with naming(detail_path):
                detail.save(detail_path)
        save_probe_set(out, placed.probes, units_m=scene.unit_m, metadata=metadata)
    except BaseException:
        png.unlink(missing_ok=True)
        detail_path.unlink(missing_ok=True)
        raise


@dataclasses.dataclass(frozen=True)
class Baked:
    """A bake's result: the light-field probes and how its paths per texel ray were chosen
    (``probes.BakeSamples``: ``metrics.json``'s ``bake_samples``)."""

    probes: LightFieldProbes
    samples: Any


def bake(
    scene: Scene,
    probes: ProbeSet,
    *,
    config: Any,
    spp: int | str,
    eval_max_depth: int,
    backend: str,
    caster: Any,
    key: Any,
    pad: bool = True,
    say: Callable[[str], None] | None = None,
) -> Baked:
    """The one bake of a placed set, with the reference path tracer: padded to a few compiled sizes
    (``pad``: ``probes.pad_probes``; the results do not change), its paths per texel ray fixed (``spp``)
    or chosen from ``config.noise_target`` by a pilot (``"auto"``, ``probes.choose_bake_spp``), path depth
    ``probes.bake_depth_for(eval_max_depth)`` (a texel replaces the rest of a camera path: one depth rule
    for bake, reference and evaluation), then ``probes.bake_probes``.

    Args:
        config: ``probes.BakeConfig``.
        backend: ``"jax"`` or ``"mitsuba"`` (``render.resolve_backend``'d by the caller); Mitsuba casts its
            own rays (Embree), the texel-centre geometry rays and the inside test use ``caster`` always.
        say: called with a line when the count is chosen (the CLI's stage messages).
    """
    from .._core import is_auto
    from ..probes import bake_depth_for, bake_probes, choose_bake_spp, pad_probes, path_traced_radiance

    radiance_fn = path_traced_radiance(
        scene,
        spp=config.pilot_spp if is_auto(spp) else spp,
        max_depth=bake_depth_for(eval_max_depth),
        caster=None if backend == "mitsuba" else caster,
        backend=backend,
    )
    probes = pad_probes(probes) if pad else probes
    samples = choose_bake_spp(scene, probes, radiance_fn=radiance_fn, key=key, config=config, spp=spp)
    if say is not None and samples.chosen_by == "target":
        say(f"bake: {samples.spp} paths per texel ray chosen (bake_samples in metrics.json)")
    lf = bake_probes(
        scene, probes, caster=caster, radiance_fn=samples.radiance_fn(radiance_fn), key=key, config=config
    )
    return Baked(lf, samples)


def export_baked(baked_npz: Path, formats: list[str] | tuple[str, ...], folder: Path) -> list[Path]:
    """The baked probes of ``baked_npz`` exported to each engine format into ``folder`` (created) as
    ``probes.<format>``; the written files (a format may write several)."""
    from ..export import export_probes, read_probes

    data = read_probes(baked_npz)
    folder.mkdir(parents=True, exist_ok=True)
    return [p for fmt in formats for p in export_probes(data, fmt, folder / f"probes.{fmt}")]
