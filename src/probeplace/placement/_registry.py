"""The placement method registry and the types every method shares.

A method registers once, beside its function (:func:`register_method`): its name, its options dataclass,
its function and a display label. ``place``, the ``probeplace place`` command, the experiment schema and
the report read the registry; nothing else lists the methods. The config file of a method is
``configs/placer/<config_name>.yaml`` (``lod-grid`` → ``lod_grid``: Hydra option names are file names).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .._core import ConfigError, ProbeSet
from ..geometry import AbstractRayCaster

#: The ``help`` of a :class:`PlaceRequest` field no front door sets (a Python object, not a value).
LIBRARY_ONLY = "(library only)"


def _help(text: str) -> dict:
    """A :class:`PlaceRequest` field's metadata: the one-line help of its flag and config key."""
    return {"help": text}


@dataclass(frozen=True)
class PlaceRequest:
    """What ``place`` asks of every method (all but the method's own options): the placement stage's one
    schema of settings. Every field is a keyword of :func:`place`; the runner's ``placer`` config group
    (``experiment.PlacerConfig``) and ``probeplace place``'s flags are derived from the fields, their help
    from each field's ``help`` metadata, their checks from :meth:`__post_init__`: a new setting is a field
    here with its check (docs/architecture.md, "Adding a placer setting"). The front doors set a few
    themselves: ``refiner`` (the runner's ``refiner.name``), ``seed`` (the run's), ``region`` (the CLI's
    ``--height-band``); ``config`` and ``caster`` are the library's only (their ``help`` says so).

    Attributes:
        budget: ``"auto"`` (fewest probes reaching ``target`` coverage) or the exact number of usable
            probes: the method's own set is trimmed (least unique coverage first) or filled (farthest
            valid point first) to it (``space._budget``).
        refiner: registry name (``refine.REFINERS``) or ``None``; refines on the soft ``objective`` with
            ``n_opt_samples`` surface samples and is kept only if that objective improved
            (``RefineResult.improved``) and every probe stays usable.
        objective: the refiner's soft objective, ``coverage``, ``wang`` or ``shading``.
        seed: PRNG seed (samples, refinement).
        target: coverage target of the automatic budget, in (0, 1].
        n_opt_samples: surface samples of the refiner's problem.
        config: fitness parameters (``FitnessConfig``) or ``None`` for the defaults.
        caster: binary visibility of the coverage: ``"auto"`` (exact Embree occlusion rays when embreex
            imports, else the SDF tracer), ``"embree"``, ``None``/``"sdf"`` (SDF sphere tracer), or a caster
            object (any ``geometry.AbstractRayCaster``: its ``occluded_host`` decides).
        clearance: smallest free distance from a probe to geometry, scene units; ``None``: derived from
            the scene (``space.default_clearance``). Probes nearer are relocated along the SDF gradient,
            else dropped.
        region: where probes may go (``space.Region.from_config``: ``{"boxes": [[lo, hi], ...],
            "height": [a, b]}``); ``None``: the whole scene box.
    """

    budget: int | str = field(
        default="auto", metadata=_help("'auto' (fewest probes reaching --target) or the exact probe count")
    )
    refiner: str | None = field(
        default=None, metadata=_help("refine the placement: a placement.REFINERS name, or none")
    )
    objective: str = field(
        default="coverage", metadata=_help("the refiner's objective: coverage, wang or shading")
    )
    seed: int = field(default=0, metadata=_help("random seed (samples, refinement)"))
    target: float = field(default=1.0, metadata=_help("coverage target of the automatic budget, in (0, 1]"))
    n_opt_samples: int = field(default=1500, metadata=_help("surface samples of the refiner's problem"))
    config: Any = field(default=None, metadata=_help(LIBRARY_ONLY))
    caster: str | AbstractRayCaster | None = field(default="auto", metadata=_help(LIBRARY_ONLY))
    clearance: float | None = field(
        default=None,
        metadata=_help(
            "smallest probe-to-geometry distance, scene units (default: from the scene's size); nearer "
            "probes are relocated"
        ),
    )
    region: Any = field(
        default=None,
        metadata=_help("where probes may go: {boxes: [[lo, hi], ...], height: [a, b]}; none: anywhere"),
    )

    @classmethod
    def settings(cls, *, scalar: bool = False) -> dict[str, tuple[Any, Any, str]]:
        """name → (type, default, help) of the fields a front door may set (not the library-only ones);
        ``scalar``: only those a flag or a config value of one scalar can hold (not ``region``)."""
        import typing

        hints = typing.get_type_hints(cls)
        return {
            f.name: (hints[f.name], f.default, f.metadata["help"])
            for f in dataclasses.fields(cls)
            if f.metadata["help"] != LIBRARY_ONLY and not (scalar and hints[f.name] is Any)
        }

    def __post_init__(self):
        """The checks of ``place``'s arguments (the experiment runner builds a request to run them too)."""
        from .refine import OBJECTIVES, REFINERS

        b = self.budget
        if b != "auto" and (isinstance(b, bool) or not isinstance(b, int) or b < 1):
            raise ConfigError(f"budget must be 'auto' or a positive integer, got {b!r}")
        if self.refiner is not None and self.refiner not in REFINERS:
            raise ConfigError(f"refiner must be one of {REFINERS} or None, got {self.refiner!r}")
        if self.objective not in OBJECTIVES:
            raise ConfigError(f"objective must be one of {OBJECTIVES}, got {self.objective!r}")
        if not 0.0 < float(self.target) <= 1.0:
            raise ConfigError(f"target must be in (0, 1], got {self.target!r}")
        n = self.n_opt_samples
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            raise ConfigError(f"n_opt_samples must be a positive integer, got {n!r}")
        c = self.clearance
        if c is not None and (isinstance(c, bool) or not isinstance(c, (int, float)) or not c >= 0):
            raise ConfigError(f"clearance must be a non-negative distance (scene units) or None, got {c!r}")
        from .space import Region

        Region.from_config(self.region)  # its errors name the bad key, before any work


@dataclass(frozen=True)
class PlaceResult:
    """What ``place`` returns (host side: a frozen dataclass, docs/architecture.md).

    Attributes:
        probes: the placed probes (all active).
        method: the method's registry name.
        request: what was asked.
        coverage: binary surface coverage of ``probes`` (share of coverable area seen by ≥ 1 probe).
        visibility: who decided the binary visibility: ``"sdf"`` or the exact caster's class name.
        timings: seconds per step of the method (``total_s``: all of it).
        refine_status: the refiner's status (``"ok"``, ...) or ``None`` when no refiner ran.
        refined: whether the refined positions were kept (they are only when coverage does not drop).
        target_reached: whether the automatic search reached ``request.target`` (``None``: no search).
        min_probe_clearance: smallest distance from a probe to a surface (``None``: not measured).
        info: the method's own record (JSON-able): its resolved options or fitness config under
            ``config``, and its statistics; ``relocated_probes``, ``projected_probes`` and
            ``filled_probes`` name which probes (indices into ``probes``) the common end moved or added.
        coverage_detail: each probe's part in ``coverage`` (``_binary.CoverageDetail``) when the method
            measured it from the final set's visibility, else None (``coverage_detail`` measures it from
            ``coverage_context`` then).
        coverage_context: how ``coverage`` was measured (``_finish.CoverageContext``), or None. Neither of
            the last two is part of :attr:`metadata`.
    """

    probes: ProbeSet
    method: str
    request: PlaceRequest
    coverage: float
    visibility: str
    timings: dict[str, float]
    refine_status: str | None = None
    refined: bool = False
    target_reached: bool | None = None
    min_probe_clearance: float | None = None
    info: dict[str, Any] = field(default_factory=dict)
    coverage_detail: Any = field(default=None, repr=False, compare=False)
    coverage_context: Any = field(default=None, repr=False, compare=False)

    @property
    def n_probes(self) -> int:
        return int(self.probes.pos_world.shape[0])

    @property
    def refine_converged(self) -> bool | None:
        """Whether the refiner converged (stopped on its tolerance; the fixed-sweep refiners when they
        finish finite); ``None`` when no refiner ran."""
        return None if self.refine_status is None else self.refine_status == "ok"

    @property
    def metadata(self) -> dict[str, Any]:
        """The JSON record stored with the probe set (``save_probe_set(metadata=...)``)."""
        r = self.request
        # the automatic search reports both (clearance None without probes); the lattice methods neither
        search = (
            {}
            if self.target_reached is None
            else {"target_reached": self.target_reached, "min_probe_clearance": self.min_probe_clearance}
        )
        return {
            "method": self.method,
            "budget": r.budget,
            "refiner": r.refiner,
            "objective": r.objective,
            "seed": r.seed,
            **refine_record(self.refine_status, self.refined),
            "n_probes": self.n_probes,
            "coverage": self.coverage,
            "visibility": self.visibility,
            **search,
            **self.info,
            "timings": self.timings,
        }


def refine_record(status: str | None, refined: bool) -> dict[str, Any]:
    """The refinement step's record: its status, whether it converged (the solver stopped on its
    tolerance, not on ``max_steps`` or a non-finite objective; the fixed-sweep Gibbs and ascent refiners
    count as converged when they finish finite) and whether its positions were kept."""
    if status is None:
        return {"refined": False}
    return {"refine_status": status, "refine_converged": status == "ok", "refined": bool(refined)}


PlaceFn = Callable[[Any, PlaceRequest, Any], PlaceResult]


@dataclass(frozen=True)
class PlacementMethod:
    """A registered placement method.

    Attributes:
        name: registry key: ``place(method=...)``, ``placer.method``, run folder names, metrics.
        place_fn: ``place_fn(scene, request, options) -> PlaceResult``.
        options: frozen dataclass of the method's options with their defaults; ``None``: it takes none.
        label: display label (CLI help, report legends).
        lattice: the method lays a lattice anchored to the scene's bounding box; its ``shift`` option (a
            3-vector, scene units) moves that lattice (the stability study keeps it fixed in the world).
        reference: a reference baseline: reports list it first, and compare every method with the first
            registered one (the uniform grid).
    """

    name: str
    place_fn: PlaceFn
    options: type | None = None
    label: str = ""
    lattice: bool = False
    reference: bool = False

    @property
    def config_name(self) -> str:
        """The file stem of its ``configs/placer/`` config (Hydra option names are file names)."""
        return self.name.replace("-", "_").replace("+", "_")

    def parse_options(self, given: dict | None) -> Any:
        """The options dataclass with ``given`` applied; unknown keys raise ConfigError."""
        given = dict(given or {})
        if self.options is None:
            if given:
                raise ConfigError(
                    f"options apply to the methods {methods_with_options()} only, got {sorted(given)}"
                )
            return None
        known = [f.name for f in dataclasses.fields(self.options)]
        unknown = set(given) - set(known)
        if unknown:
            raise ConfigError(f"unknown {self.name} options {sorted(unknown)}; known: {sorted(known)}")
        return self.options(**given)


_METHODS: dict[str, PlacementMethod] = {}


def register_method(method: PlacementMethod) -> PlacementMethod:
    """Add ``method`` to the registry (its name must be new); returns it."""
    if method.name in _METHODS:
        raise ValueError(f"placement method {method.name!r} is already registered")
    _METHODS[method.name] = method
    return method


def get_method(name: str) -> PlacementMethod:
    """The registered method ``name``; ConfigError naming the known ones otherwise."""
    if name not in _METHODS:
        raise ConfigError(f"method must be one of {method_names()}, got {name!r}")
    return _METHODS[name]


def method_names() -> tuple[str, ...]:
    """Every registered method, in registration order."""
    return tuple(_METHODS)


def reference_methods() -> tuple[str, ...]:
    """The reference baselines, in registration order (the first is what reports compare against)."""
    return tuple(m.name for m in _METHODS.values() if m.reference)


def methods_with_options() -> tuple[str, ...]:
    return tuple(m.name for m in _METHODS.values() if m.options is not None)


def method_options(name: str) -> dict[str, Any]:
    """The options of method ``name`` with their defaults (empty for a method without options)."""
    opts = get_method(name).options
    return {} if opts is None else {f.name: f.default for f in dataclasses.fields(opts)}
