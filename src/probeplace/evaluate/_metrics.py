"""The evaluation's metrics as typed records, and ``metrics.json``'s keys derived from them (issue 35).

:class:`EvalMetrics` is what :func:`evaluate.score` measures: the run's settings (:class:`RunSettings`), one
record per image component (:data:`EVAL_COMPONENTS`: :class:`DiffuseScores`, :class:`GlossyScores`,
:class:`ComponentScores` for the full image), the run-wide figures and the ``samples`` group
(:class:`SampleCounts`). :meth:`EvalMetrics.to_json` gives the ``metrics.json`` dict,
:meth:`EvalMetrics.from_json` reads one back (a key an older run lacks is None).

**Keys** (:func:`metric_key`, the one rule; docs/evaluate.md "metrics.json" lists them and
``tests/evaluate/test_metrics_keys.py`` holds the list to :data:`METRIC_KEYS`):

* a *family* figure (:data:`FAMILIES`: ``mse``, ``noise_floor``, ``mse_black``, ``relmse``,
  ``relmse_black``, ``ci95_mse``) or a :func:`measured` figure of a component record is
  ``<name>_<component>``: ``glossy_indirect.mse`` is ``mse_glossy_indirect``;
* a figure of one of the glossy error's parts (the perfect trace, the trace's share, ...) declares its
  family and image (:func:`_part`): ``GlossyScores.mse_perfect_trace`` is ``mse_glossy_perfect_trace``;
* every other figure is named by its field: ``DiffuseScores.light_leak_pixels`` is ``light_leak_pixels``.

Records (:class:`RunSettings`, the component records) are flattened into the top level of the dict; a
*group* (a field holding an object with ``to_json``: :class:`SampleCounts`) is one nested dict under its
field's name. :data:`_JSON_ORDER` keeps the order ``score`` wrote its keys in before these records existed,
so that a run's ``metrics.json`` stays byte-identical; a field it does not list follows the listed ones in
declaration order.

**Measured figures**: a field declared ``measured(<how>)`` is computed by :func:`measure_record` from the
component's :class:`ComponentImages` on every component that has it (``mse``, ``relmse``, ``ci95_mse``,
``mse_black``, ``relmse_black``); ``score`` gives the others. A new metric of a component's images is one
such field here and its row in docs/evaluate.md (docs/architecture.md, "Adding a metric").
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import field
from typing import Any

import numpy as np

from ._config import EvalConfig
from ._decompose import bootstrap_ci, mean_sq_error, relative_mse, tail_count, tail_index, top_share

#: The figures every component record may have, each ``<family>_<component>`` in metrics.json.
FAMILIES = ("mse", "noise_floor", "mse_black", "relmse", "relmse_black", "ci95_mse")


def metric_key(family: str, image: str) -> str:
    """The metrics.json key of ``family``'s figure of ``image`` (a component or a part of the glossy
    error): ``metric_key("mse", "glossy_indirect") == "mse_glossy_indirect"``."""
    return f"{family}_{image}"


def _part(family: str, image: str) -> dict:
    """A field's metadata: a figure of a part of the glossy error, its key ``metric_key(family, image)``."""
    return {"key": metric_key(family, image)}


Interval = tuple[float, float]


@dataclasses.dataclass(frozen=True)
class ComponentImages:
    """What a measured figure of one image component is computed from (:func:`measured`): the component's
    name, its probe image and reference ((h, w, 3) float64; the glossy image's reference is the CRN one),
    the per-pixel squared error (flat, mean over RGB; the glossy image's from its samples' errors,
    ``_decompose.glossy_terms``) and the evaluation's config."""

    component: str
    probe: np.ndarray
    reference: np.ndarray
    sq_px: np.ndarray
    config: EvalConfig


def measured(measure: Callable[[ComponentImages], Any]) -> Any:
    """A field of a component record whose value is ``measure(images)`` (:class:`ComponentImages`), set by
    :func:`measure_record` for every component that has the field; its key is ``<field>_<component>``
    (:func:`metric_key`), like a family's. A new metric of the images is this one field (docs/architecture.md,
    "Adding a metric")."""
    return field(default=None, metadata={"measure": measure})


def measure_record(cls: type, images: ComponentImages, **given) -> Any:
    """Component record ``cls``: its :func:`measured` fields measured on ``images``, the others ``given``."""
    values = {
        f.name: f.metadata["measure"](images) for f in dataclasses.fields(cls) if "measure" in f.metadata
    }
    return cls(**values, **given)


def interval95(config: EvalConfig, per_pixel: np.ndarray) -> tuple[float, float]:
    """The 95 % bootstrap interval of the mean of ``per_pixel`` (``bootstrap_ci``, seed 0): every
    ``ci95_mse`` figure's."""
    return tuple(bootstrap_ci(per_pixel, n_resamples=config.bootstrap_resamples, seed=0))


def _black(m: ComponentImages) -> np.ndarray:
    return np.zeros_like(m.reference)


def _top_pixel_share(m: ComponentImages) -> float | None:
    """The largest pixel's share of the summed per-pixel squared error (None for no error)."""
    return top_share(m.sq_px, 1)


def _one_percent(m: ComponentImages) -> int:
    """How many pixels the error's tail holds: 1 % of them, one at least (``tail_count``)."""
    return tail_count(np.size(m.sq_px))


def _top_percent_share(m: ComponentImages) -> float | None:
    """The share of the summed per-pixel squared error made by the 1 % of pixels with the largest (one
    pixel at least; None for no error)."""
    return top_share(m.sq_px, _one_percent(m))


def _tail_index(m: ComponentImages) -> float | None:
    """Hill's tail index of the per-pixel squared error from its 1 % of largest pixels (one at least)."""
    return tail_index(m.sq_px, _one_percent(m))


@dataclasses.dataclass(frozen=True)
class RunSettings:
    """What was evaluated and how: scene, view, image size, sample counts (the ones rendered, chosen
    ones included), shading and tracer settings, the seed, the probes."""

    scene: str | None = None
    view: str | None = None
    width: int | None = None
    height: int | None = None
    spp: int | None = None
    glossy_spp: int | None = None
    glossy_ref_spp: int | None = None
    max_depth: int | None = None
    shading: str | None = None
    trace_hierarchy: str | None = None
    glossy_filter: str | None = None
    glossy_lod_bias: float | None = None
    seed: int | None = None
    n_probes: int | None = None
    n_probes_usable: int | None = None
    probe_first_hit_lobes: str | None = None


@dataclasses.dataclass(frozen=True)
class ComponentScores:
    """One image component's probe image against its reference (the full image's record): MSE, its 95 %
    bootstrap interval over pixels, relative MSE and the reference's noise floor (docs/evaluate.md)."""

    mse: float | None = measured(lambda m: mean_sq_error(m.probe, m.reference))
    noise_floor: float | None = None  # the reference's own noise, measured per component by ``score``
    relmse: float | None = measured(lambda m: relative_mse(m.probe, m.reference, eps=m.config.relmse_eps))
    ci95_mse: tuple[float, float] | None = measured(lambda m: interval95(m.config, m.sq_px))
    # Near 1, the MSE is one pixel's: on Sponza one glossy ray reflecting a sun highlight, which no probe
    # holds, made 75 % of every method's glossy MSE on one seed (issue 33; experiments/README.md §2).
    top_pixel_share: float | None = measured(_top_pixel_share)
    # The error's tail apart from its bulk: on Sponza's 8×4×4 grid the top 1 % of pixels (mostly the probes'
    # own too-bright reads at small dark spots, and unresolved rays; a sun glint on some seeds:
    # experiments/tail_causes.py) make 32–48 % of the glossy MSE and all of its seed-to-seed spread; the
    # bulk, mse × (1 − this), repeats within 1.2 % (issue 33; experiments/README.md §2).
    top_percent_share: float | None = measured(_top_percent_share)
    # How heavy that tail is: below 2 the per-pixel squared error has no finite variance over the range
    # sampled, so ``ci95_mse`` (a bootstrap over pixels) understates the MSE's uncertainty and no count of
    # pixels or samples makes it repeat as 1/√n. Sponza's glossy error: 0.7–1.5 on every run measured
    # (issue 33).
    tail_index: float | None = measured(_tail_index)


@dataclasses.dataclass(frozen=True)
class IndirectScores(ComponentScores):
    """An indirect component: also a black image's MSE and relative MSE against the same reference."""

    # A black image (no indirect light at all) against the same reference: a method above it adds more
    # wrong light (leaks, self-hits) than it recovers.
    mse_black: float | None = measured(lambda m: mean_sq_error(_black(m), m.reference))
    relmse_black: float | None = measured(
        lambda m: relative_mse(_black(m), m.reference, eps=m.config.relmse_eps)
    )


@dataclasses.dataclass(frozen=True)
class DiffuseScores(IndirectScores):
    """The diffuse indirect image, and its light leak against the reference's own noise."""

    light_leak_energy: float | None = None
    light_leak_pixels: int | None = None
    light_leak_judged_pixels: int | None = None
    light_leak_share: float | None = None
    light_leak_sigmas: float | None = None


@dataclasses.dataclass(frozen=True)
class GlossyScores(IndirectScores):
    """The glossy indirect image (against the CRN reference) and its error taken apart
    (``_decompose.py``): the rays' statuses, the perfect trace, view dependence, the trace's share."""

    mse_no_crn: float | None = field(default=None, metadata=_part("mse", "glossy_indirect_no_crn"))
    glossy_rays: int | None = None
    unresolved_share: float | None = None
    origin_seen_share: float | None = None
    unresolved_seen_share: float | None = None
    mse_perfect_trace: float | None = field(default=None, metadata=_part("mse", "glossy_perfect_trace"))
    mse_view_dependence: float | None = field(default=None, metadata=_part("mse", "glossy_view_dependence"))
    mse_trace_share: float | None = field(default=None, metadata=_part("mse", "glossy_trace_share"))
    trace_excess: float | None = None
    mse_by_status: dict[str, float] | None = field(default=None, metadata=_part("mse", "glossy_by_status"))
    mse_resolved_only: float | None = field(default=None, metadata=_part("mse", "glossy_resolved_only"))
    # The image's MSE at infinitely many glossy rays and reference paths a pixel, estimated without bias
    # (``_decompose.converged_sq_error``): no sample's own squared error in it, so not the square of a sun
    # glint met by one ray of a pixel. Null at one glossy ray a pixel.
    mse_converged: float | None = field(default=None, metadata=_part("mse", "glossy_converged"))
    glossy_status_share: dict[str, float] | None = None
    glossy_hit_agreement: float | None = None
    glossy_hit_agreement_rays: int | None = None
    perfect_trace_fallbacks: int | None = None
    perfect_trace_fallback_share: float | None = None
    relmse_perfect_trace: float | None = field(default=None, metadata=_part("relmse", "glossy_perfect_trace"))
    ci95_mse_perfect_trace: Interval | None = field(
        default=None, metadata=_part("ci95_mse", "glossy_perfect_trace")
    )
    ci95_mse_trace_share: Interval | None = field(
        default=None, metadata=_part("ci95_mse", "glossy_trace_share")
    )
    ci95_mse_converged: Interval | None = field(default=None, metadata=_part("ci95_mse", "glossy_converged"))


@dataclasses.dataclass(frozen=True)
class SampleCounts:
    """metrics.json's ``samples`` group (``_samples.samples_metrics``; docs/evaluate.md "Sample counts
    from a noise target"): the counts, how each was chosen, the pilot's figures per scored component
    (None for a fixed count), the final pass's floor ÷ black MSE and whether every component meets the
    target. Keys are the field names."""

    noise_target: float | None = None
    pilot_spp: int | None = None
    max_spp: int | None = None
    reference_spp: int | None = None
    reference_chosen_by: str | None = None
    glossy_ref_spp: int | None = None
    glossy_ref_chosen_by: str | None = None
    pilot_floor: dict[str, float | None] | None = None
    pilot_floor_se: dict[str, float | None] | None = None
    pilot_black: dict[str, float | None] | None = None
    pilot_floor_over_black: dict[str, float | None] | None = None
    pilot_s: dict[str, float | None] | None = None
    predicted_floor_over_black: dict[str, float | None] | None = None
    floor_over_black: dict[str, float | None] | None = None
    target_met: bool | None = None

    def to_json(self) -> dict:
        """The group as metrics.json holds it."""
        return {f.name: _json_value(getattr(self, f.name)) for f in dataclasses.fields(self)}

    @classmethod
    def from_json(cls, d: Mapping) -> SampleCounts:
        """The group from its dict; a key it lacks is None."""
        _check_mapping(d, "samples")
        return cls(**{f.name: copy.deepcopy(d[f.name]) for f in dataclasses.fields(cls) if f.name in d})


@dataclasses.dataclass(frozen=True)
class EvalMetrics:
    """Every metric of one evaluation (module docstring; docs/evaluate.md "metrics.json")."""

    settings: RunSettings = field(default_factory=RunSettings)
    diffuse_indirect: DiffuseScores = field(default_factory=DiffuseScores)
    glossy_indirect: GlossyScores = field(default_factory=GlossyScores)
    full: ComponentScores = field(default_factory=ComponentScores)
    bootstrap_resamples: int | None = None
    relmse_eps: float | None = None
    shading_s_per_frame: float | None = None
    shading_compile_s: float | None = None
    reference_s: float | None = None
    memory_bytes: dict | None = None  # evaluate.memory_bytes's dict
    samples: SampleCounts | None = None

    def component(self, name: str) -> ComponentScores:
        """The record of the image component ``name`` (one of :data:`EVAL_COMPONENTS`).

        Raises:
            KeyError: not a component.
        """
        if name not in EVAL_COMPONENTS:
            raise KeyError(f"no image component {name!r}; components: {list(EVAL_COMPONENTS)}")
        return getattr(self, name)

    def to_json(self) -> dict:
        """The ``metrics.json`` dict (keys :data:`METRIC_KEYS`, in that order; fresh containers)."""
        out = {}
        for path, key in _LEAVES:
            v = self
            for name in path:
                v = getattr(v, name)
            out[key] = _json_value(v)
        return out

    @classmethod
    def from_json(cls, d: Mapping) -> EvalMetrics:
        """The metrics from a ``metrics.json`` dict: a key it lacks (an older run's) is None, a key that is
        not an evaluation metric (``error_png_vmax``, ``bake_samples``, the runner's ``backend``) ignored.

        Raises:
            TypeError: ``d`` is not a mapping.
        """
        _check_mapping(d, "metrics")
        return _build(cls, d, ())


def _check_mapping(d, what: str) -> None:
    if not isinstance(d, Mapping):
        raise TypeError(f"{what}: expected a dict (metrics.json), got {type(d).__name__}")


def _json_value(v):
    """A field's value as metrics.json holds it: a group's dict, an interval as a list, containers copied."""
    if hasattr(v, "to_json"):
        return v.to_json()
    if isinstance(v, tuple):
        return list(v)
    return copy.deepcopy(v) if isinstance(v, dict | list) else v


@functools.cache
def _hints(cls) -> dict:
    """The fields' types, without ``| None``."""
    out = {}
    for name, t in typing.get_type_hints(cls).items():
        if typing.get_origin(t) in (typing.Union, types.UnionType):
            args = [a for a in typing.get_args(t) if a is not type(None)]
            t = args[0] if len(args) == 1 else t
        out[name] = t
    return out


def _is_record(t) -> bool:
    """A record flattened into the top level (a dataclass without its own JSON form)."""
    return dataclasses.is_dataclass(t) and not hasattr(t, "to_json")


def _walk(cls, path: tuple = ()):
    """(path, key) of every leaf of ``cls``, in declaration order; a leaf's key (module docstring) is its
    declared key, a component record's family figure's ``metric_key``, else its name."""
    for f in dataclasses.fields(cls):
        t = _hints(cls)[f.name]
        if _is_record(t):
            yield from _walk(t, (*path, f.name))
        elif "key" in f.metadata:
            yield (*path, f.name), f.metadata["key"]
        elif issubclass(cls, ComponentScores) and (f.name in FAMILIES or "measure" in f.metadata):
            yield (*path, f.name), metric_key(f.name, path[-1])
        else:
            yield (*path, f.name), f.name


def _build(cls, d: Mapping, path: tuple):
    kw = {}
    for f in dataclasses.fields(cls):
        t, sub = _hints(cls)[f.name], (*path, f.name)
        if _is_record(t):
            kw[f.name] = _build(t, d, sub)
        elif (key := _KEY_OF[sub]) in d and d[key] is not None:
            v = d[key]
            if hasattr(t, "from_json"):
                v = t.from_json(v)
            elif t is tuple or typing.get_origin(t) is tuple:
                v = tuple(v) if isinstance(v, list | tuple) else v
            else:
                v = copy.deepcopy(v)
            kw[f.name] = v
    return cls(**kw)


#: The image components, in the order of :class:`EvalMetrics`' records.
EVAL_COMPONENTS = tuple(
    name for name, t in _hints(EvalMetrics).items() if isinstance(t, type) and issubclass(t, ComponentScores)
)

#: metrics.json's order (module docstring): paths into EvalMetrics, a record standing for all its leaves.
_JSON_ORDER = (
    "settings",
    "glossy_indirect.mse", "glossy_indirect.noise_floor", "glossy_indirect.mse_no_crn",
    "diffuse_indirect.mse", "glossy_indirect.mse_black", "diffuse_indirect.mse_black",
    "diffuse_indirect.noise_floor", "full.mse", "full.noise_floor",
    "diffuse_indirect.light_leak_energy", "diffuse_indirect.light_leak_pixels",
    "diffuse_indirect.light_leak_judged_pixels", "diffuse_indirect.light_leak_share",
    "diffuse_indirect.light_leak_sigmas",
    "glossy_indirect.glossy_rays", "glossy_indirect.unresolved_share", "glossy_indirect.origin_seen_share",
    "glossy_indirect.unresolved_seen_share", "glossy_indirect.mse_perfect_trace",
    "glossy_indirect.mse_view_dependence", "glossy_indirect.mse_trace_share", "glossy_indirect.trace_excess",
    "glossy_indirect.mse_by_status", "glossy_indirect.mse_resolved_only",
    "glossy_indirect.glossy_status_share", "glossy_indirect.glossy_hit_agreement",
    "glossy_indirect.glossy_hit_agreement_rays", "glossy_indirect.perfect_trace_fallbacks",
    "glossy_indirect.perfect_trace_fallback_share", "glossy_indirect.relmse",
    "glossy_indirect.relmse_perfect_trace", "glossy_indirect.relmse_black", "glossy_indirect.ci95_mse",
    "glossy_indirect.ci95_mse_perfect_trace", "glossy_indirect.ci95_mse_trace_share",
    "diffuse_indirect.relmse", "diffuse_indirect.relmse_black", "full.relmse",
    "diffuse_indirect.ci95_mse", "full.ci95_mse",
    "bootstrap_resamples", "relmse_eps", "shading_s_per_frame", "shading_compile_s", "reference_s",
    "memory_bytes", "samples",
)  # fmt: skip


def _ordered_leaves() -> tuple[tuple[tuple[str, ...], str], ...]:
    """Every leaf's (path, key) in metrics.json's order (:data:`_JSON_ORDER`, then the rest)."""
    leaves = dict(_walk(EvalMetrics))
    order: list[tuple[str, ...]] = []
    for entry in _JSON_ORDER:
        path = tuple(entry.split("."))
        under = [p for p in leaves if p[: len(path)] == path]
        if not under:
            raise AssertionError(f"_JSON_ORDER: {entry!r} is no field of EvalMetrics")
        if any(p in order for p in under):
            raise AssertionError(f"_JSON_ORDER: {entry!r} is listed twice")
        order += under
    order += [p for p in leaves if p not in order]
    keys = [leaves[p] for p in order]
    if len(set(keys)) != len(keys):
        raise AssertionError(f"two metrics share a key: {sorted({k for k in keys if keys.count(k) > 1})}")
    return tuple((p, leaves[p]) for p in order)


_LEAVES = _ordered_leaves()
_KEY_OF = dict(_LEAVES)
#: Every key of :meth:`EvalMetrics.to_json`, in order (docs/evaluate.md's "metrics.json" table).
METRIC_KEYS = tuple(key for _, key in _LEAVES)
