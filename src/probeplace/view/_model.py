"""The view model: everything ``probeplace view`` shows, as NumPy arrays and paths, read from the files a
run (or a probes file) left. Nothing is recomputed: a figure the files do not hold is listed in
:attr:`ViewModel.unavailable` with the reason, never estimated.

Loading the scene imports JAX (a ``Scene`` is an Equinox module); nothing is compiled.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._core.files import PROBE_ERROR_FILE, RunFiles, coverage_detail_path
from ..export import read_light_field_npz, sh_irradiance, texel_solid_angles
from ._input import ViewInput
from ._maps import exposure_white

#: Probe status codes, their legend and colours (saturated cyan / magenta / grey / gold / blue / violet:
#: hues no scene material of the built-ins has, so a probe stands out against the walls; the browser test
#: looks for them). Relocated, filled and projected come from the placement record (``relocated_probes``,
#: ``filled_probes``, ``projected_probes`` in probes.json's metadata); the bake's inside flag and an
#: inactive probe take precedence.
USABLE, INSIDE, INACTIVE, RELOCATED, FILLED, PROJECTED = 0, 1, 2, 3, 4, 5
STATUS_LABELS = (
    "usable",
    "inside geometry at bake (unusable for shading)",
    "inactive",
    "relocated out of geometry",
    "filled to the budget",
    "moved into the placement region",
)
STATUS_RGB = np.array(
    [[0, 200, 255], [255, 0, 200], [150, 150, 150], [255, 190, 0], [40, 70, 255], [150, 80, 255]], np.uint8
)

COLOUR_STATUS = "status"
REACH = "mean visible distance"
COVERAGE_SEEN = "coverage: samples it sees"
COVERAGE_UNIQUE = "coverage: samples only it sees"
ERROR_DIFFUSE = "error: share of diffuse indirect MSE"
ERROR_GLOSSY = "error: share of glossy indirect MSE"
SIZE_UNIFORM = "uniform"
#: uncovered surface samples are drawn in this colour (red: the probes' colours are cyan and magenta)
UNCOVERED_RGB = (255, 30, 30)
#: why a run folder lacks the per-probe figures of this version
RERUN = "rerun with this version"


@dataclass(frozen=True)
class ViewCamera:
    """One of the scene's views (``Scene.views``): a pinhole camera in look-at form, scene units."""

    name: str
    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov_y_deg: float


@dataclass(frozen=True)
class EvalImages:
    """The evaluation's error images (``eval/error_<component>_false.png``: viridis, colour bar right).

    Attributes:
        view: the camera they were rendered from.
        width, height: the rendered image's size (the PNG adds the colour bar on the right).
        images: component → PNG path.
        vmax: component → error shown at the top of the colour bar (``eval/metrics.json``).
    """

    view: str
    width: int
    height: int
    images: dict[str, Path]
    vmax: dict[str, float]


@dataclass(frozen=True)
class Baked:
    """The baked maps behind the shown probes.

    Attributes:
        path: the ``.npz``.
        rows: (n,) the archive row of each shown probe.
        radiance: (n, R+2, R+2, 3) light each probe sees (reflected + emitted), bordered.
        sh: (n, 9, 3) SH L2 of that light (``export.read_light_field_npz``, ``sh_source="total"``).
        inside: (n,) the bake's inside-geometry flags of the shown probes, or None (not recorded).
        reach: (n,) mean visible distance: the moments map's E[r] averaged over the sphere (solid-angle
            weighted), escaping directions counted at the scene's diagonal.
        far: the distance the bake stores for escaping rays.
        white: radiance shown as white: :func:`_maps.exposure_white` of the usable probes' *reflected*
            radiance, so the walls are exposed and an emitter seen directly clips.
        irradiance_white: E/π shown as white on the irradiance spheres (the same rule over the usable
            probes' SH irradiance: the spheres of one set share one scale).
    """

    path: Path
    rows: np.ndarray
    radiance: np.ndarray
    sh: np.ndarray
    inside: np.ndarray | None
    reach: np.ndarray
    far: float
    white: float
    irradiance_white: float


@dataclass(frozen=True)
class CoverageLayer:
    """Each shown probe's part in the placement's coverage (``<probe set>.coverage.npz``, counted over the
    coverage problem's coverable surface samples: ``placement.coverage_detail``).

    Attributes:
        path: the ``.npz``.
        seen: (n,) samples each probe sees.
        unique: (n,) samples only that probe sees.
        uncovered: (m, 3) the samples no probe sees, world frame.
        n_coverable: coverable samples of the problem.
        coverage: the coverage (share of coverable area seen).
    """

    path: Path
    seen: np.ndarray
    unique: np.ndarray
    uncovered: np.ndarray
    n_coverable: int
    coverage: float


@dataclass(frozen=True)
class ErrorLayer:
    """Each shown probe's share of the evaluation's MSE (``eval/probe_error.npz``: ``evaluate._attribute``).

    Attributes:
        path: the ``.npz``.
        shares: component (``diffuse_indirect``, ``glossy_indirect``) → (n,) the probe's share of the MSE.
        mse: component → the MSE.
        unattributed: component → the part charged to no probe (diffuse: pixels without a hit; glossy:
            misses, and unresolved rays, whose fallback read no probe resolved).
    """

    path: Path
    shares: dict[str, np.ndarray]
    mse: dict[str, float]
    unattributed: dict[str, float]


@dataclass(frozen=True)
class ViewModel:
    """What the viewer draws. ``positions``, ``status`` and the baked rows are in the probe file's order."""

    title: str
    mesh: object  # scene.PreviewMesh
    lo: np.ndarray
    hi: np.ndarray
    cameras: tuple[ViewCamera, ...]
    positions: np.ndarray
    status: np.ndarray
    status_note: str
    baked: Baked | None
    baked_note: str
    eval: EvalImages | None
    eval_note: str
    unavailable: dict[str, str] = field(default_factory=dict)
    coverage: CoverageLayer | None = None
    coverage_note: str = ""
    error: ErrorLayer | None = None
    error_note: str = ""

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.hi - self.lo))

    @property
    def colour_options(self) -> tuple[str, ...]:
        out = [COLOUR_STATUS]
        if self.baked is not None:
            out.append(REACH)
        if self.coverage is not None:
            out += [COVERAGE_SEEN, COVERAGE_UNIQUE]
        if self.error is not None:
            out += [ERROR_DIFFUSE, ERROR_GLOSSY]
        return tuple(out)

    def values(self, by: str) -> np.ndarray | None:
        """(n,) the per-probe figure a colour option shows, or None for the status colours."""
        cov, err = self.coverage, self.error
        table = {
            REACH: (lambda: self.baked.reach) if self.baked is not None else None,
            COVERAGE_SEEN: (lambda: cov.seen) if cov is not None else None,
            COVERAGE_UNIQUE: (lambda: cov.unique) if cov is not None else None,
            ERROR_DIFFUSE: (lambda: err.shares["diffuse_indirect"]) if err is not None else None,
            ERROR_GLOSSY: (lambda: err.shares["glossy_indirect"]) if err is not None else None,
        }
        get = table.get(by)
        if by == COLOUR_STATUS or get is None:
            return None
        return np.asarray(get(), np.float64)

    @property
    def size_options(self) -> tuple[str, ...]:
        return (SIZE_UNIFORM, REACH) if self.baked is not None else (SIZE_UNIFORM,)

    def colours(self, by: str) -> np.ndarray:
        """(n, 3) uint8 probe colours: by status (:data:`STATUS_RGB`), or a per-probe figure in viridis:
        reach from its smallest to its largest value, a count or an error share from 0 to its largest
        value (a probe that sees nothing or is charged nothing is the colour of 0)."""
        if by == COLOUR_STATUS:
            return STATUS_RGB[self.status]
        v = self.values(by)
        if v is None or by not in self.colour_options:
            raise ValueError(f"colour by {by!r}: options are {self.colour_options}")
        from matplotlib import colormaps

        lo = float(v.min()) if by == REACH and len(v) else 0.0
        t = (v - lo) / max(float(v.max()) - lo if len(v) else 0.0, 1e-300)
        return np.round(255 * colormaps["viridis"](np.clip(t, 0.0, 1.0))[:, :3]).astype(np.uint8)

    def legend(self, by: str) -> str:
        """What the colours of ``by`` mean, one line (the scale's ends)."""
        if by == COLOUR_STATUS:
            return "status (the legend above)"
        v = self.values(by)
        top = float(v.max()) if v is not None and len(v) else 0.0
        if by == REACH:
            return f"viridis: shortest {float(v.min()):.4g} … longest {top:.4g} (scene units)"
        if by in (COVERAGE_SEEN, COVERAGE_UNIQUE):
            return f"viridis: 0 … {top:.0f} of {self.coverage.n_coverable} coverable samples"
        comp = "diffuse_indirect" if by == ERROR_DIFFUSE else "glossy_indirect"
        e = self.error
        mse = e.mse.get(comp, float("nan"))
        return f"viridis: 0 … {top:.4g} of the {comp} MSE {mse:.4g} (unattributed {e.unattributed[comp]:.4g})"

    def radii(self, by: str) -> np.ndarray:
        """(n,) marker radii, scene units: 1.2 % of the scene's diagonal, or that times the probe's reach
        over the median reach (clipped to [0.5, 2]: sizes stay readable)."""
        base = np.full(len(self.positions), 0.012 * self.diagonal)
        if by == SIZE_UNIFORM:
            return base
        if by == REACH and self.baked is not None:
            r = self.baked.reach
            return base * np.clip(r / max(float(np.median(r)), 1e-30), 0.5, 2.0)
        raise ValueError(f"size by {by!r}: options are {self.size_options}")


def load_view_model(inp: ViewInput) -> ViewModel:
    """Load the scene and read every file the viewer shows (module docstring)."""
    from ..scene import preview_mesh

    scene = _load_scene(inp)
    lo = np.asarray(scene.vertices, np.float64).min(axis=0)
    hi = np.asarray(scene.vertices, np.float64).max(axis=0)
    probes = inp.probes
    rows = np.arange(probes.n)
    if inp.path.suffix == ".npz":  # the bake pads its set to a power of two with inactive copies
        rows = rows[probes.active]
    positions = probes.positions[rows]
    baked, baked_note = _baked(inp, positions, rows, float(np.linalg.norm(hi - lo)))
    status = np.where(probes.active[rows], USABLE, INACTIVE).astype(np.int8)
    meta = inp.metadata
    if inp.path.suffix != ".npz":  # the placement record's indices are probes.json's rows
        for key, code in (
            ("projected_probes", PROJECTED),
            ("relocated_probes", RELOCATED),
            ("filled_probes", FILLED),
        ):
            idx = _indices(meta.get(key), len(rows))
            status[idx[status[idx] == USABLE]] = code
    if baked is not None and baked.inside is not None:
        status[(status != INACTIVE) & baked.inside] = INSIDE
    ev, eval_note = _eval_images(inp)
    coverage, coverage_note = _coverage(inp, len(positions))
    error, error_note = _error(inp, positions, baked, float(np.linalg.norm(hi - lo)))
    return ViewModel(
        title=inp.path.name,
        mesh=preview_mesh(scene),
        lo=lo,
        hi=hi,
        cameras=tuple(_camera(c) for c in scene.views),
        positions=positions,
        status=status,
        status_note=status_note(meta, inside_known=baked is not None),
        baked=baked,
        baked_note=baked_note,
        eval=ev,
        eval_note=eval_note,
        unavailable=_unavailable(
            meta, coverage_note if coverage is None else None, error_note if error is None else None
        ),
        coverage=coverage,
        coverage_note=coverage_note,
        error=error,
        error_note=error_note,
    )


def _indices(value, n: int) -> np.ndarray:
    """A recorded index list as int64 indices below ``n`` (anything else: none)."""
    if not isinstance(value, list) or not all(isinstance(i, int) and 0 <= i < n for i in value):
        return np.zeros(0, np.int64)
    return np.asarray(value, np.int64)


def _npz(path: Path) -> dict | None:
    """Every array of an ``.npz`` (None when it cannot be read)."""
    import zipfile

    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError):
        return None


def _coverage(inp: ViewInput, n: int) -> tuple[CoverageLayer | None, str]:
    """(the coverage layer or None, a line saying what it is or why it is missing)."""
    if inp.coverage_path is None:
        want = coverage_detail_path(inp.probes_path).name
        if inp.run_config is None and inp.probes_path.suffix != ".json":
            return None, f"not recorded: {want} comes with a probe set of probeplace place or a run folder"
        return None, f"not recorded: no {want} beside {inp.probes_path.name} (an older version); {RERUN}"
    z = _npz(inp.coverage_path)
    keys = {"seen", "unique", "uncovered_pos", "n_coverable", "coverage"}
    if z is None or not keys <= set(z):
        return None, f"not shown: {inp.coverage_path.name} cannot be read; {RERUN}"
    if z["seen"].shape != (n,):
        return None, f"not shown: {inp.coverage_path.name} holds {len(z['seen'])} probes, probes.json {n}"
    layer = CoverageLayer(
        path=inp.coverage_path,
        seen=np.asarray(z["seen"], np.int64),
        unique=np.asarray(z["unique"], np.int64),
        uncovered=np.asarray(z["uncovered_pos"], np.float32).reshape(-1, 3),
        n_coverable=int(z["n_coverable"]),
        coverage=float(z["coverage"]),
    )
    note = (
        f"{layer.n_coverable} coverable surface samples of the placement's coverage problem; "
        f"{len(layer.uncovered)} seen by no probe (coverage {layer.coverage:.4g} by area)"
    )
    return layer, note


def _error(inp: ViewInput, positions: np.ndarray, baked, diagonal: float) -> tuple[ErrorLayer | None, str]:
    """(the error layer or None, a line saying what it is or why it is missing)."""
    if inp.eval_dir is None:
        where = "a run folder" if inp.run_config is None else "this run's eval/ (eval.enabled was off?)"
        return None, f"not recorded: each probe's share of the error comes with {where}"
    path = inp.eval_dir / PROBE_ERROR_FILE
    if not path.is_file():
        return None, f"not recorded: this run's eval/ has no {PROBE_ERROR_FILE} (an older version); {RERUN}"
    z = _npz(path)
    comps = ("diffuse_indirect", "glossy_indirect")
    if z is None or not {"pos_world", *comps} <= set(z):
        return None, f"not shown: {path.name} cannot be read; {RERUN}"
    rows = baked.rows if baked is not None else np.arange(len(positions))
    pos = np.asarray(z["pos_world"], np.float64)
    if len(pos) <= (rows.max() if len(rows) else -1) or not np.allclose(
        pos[rows], positions, rtol=0, atol=1e-5 * diagonal
    ):
        return None, f"not shown: {path.name} holds other probes than {inp.probes_path.name}"
    scalar = lambda k: float(z[k]) if k in z else float("nan")
    unres = scalar("unattributed_glossy_indirect_unresolved")
    layer = ErrorLayer(
        path=path,
        shares={c: np.asarray(z[c], np.float64)[rows] for c in comps},
        mse={c: scalar(f"mse_{c}") for c in comps},
        unattributed={
            "diffuse_indirect": scalar("unattributed_diffuse_indirect"),
            "glossy_indirect": unres
            + scalar("unattributed_glossy_indirect_miss")
            + scalar("unattributed_glossy_indirect_other"),
        },
    )
    note = (
        "each pixel's squared error handed to the probes that shaded it (diffuse: by their irradiance "
        "weights; glossy: the probe that resolved the ray). Unattributed: diffuse "
        f"{layer.unattributed['diffuse_indirect']:.4g}, glossy {layer.unattributed['glossy_indirect']:.4g} "
        f"(of which unresolved rays {unres:.4g})"
    )
    return layer, note


def _load_scene(inp: ViewInput):
    if inp.scene is not None:
        from ..scene import load_scene

        return load_scene(inp.scene)
    from ..experiment import load_experiment_scene, to_config

    return load_experiment_scene(to_config(inp.run_config).scene)


def _camera(c) -> ViewCamera:
    vec = lambda a: np.asarray(a, np.float64).reshape(3)
    return ViewCamera(c.name, vec(c.position), vec(c.look_at), vec(c.up), float(c.fov_y_deg))


def _baked(inp: ViewInput, positions: np.ndarray, rows: np.ndarray, diagonal: float):
    """(Baked or None, a line saying what the maps are or why there are none)."""
    if inp.baked_path is None:
        where = "a run folder that baked" if inp.run_config is None else "this run (bake.enabled was off?)"
        return None, f"no baked maps: probes_baked.npz comes with {where}"
    # A bare .npz was read whole by resolve_input already; a baked file is mostly maps: read it once.
    lf = inp.probes if inp.baked_path == inp.probes_path else read_light_field_npz(inp.baked_path)
    if inp.path.suffix != ".npz":  # a run: probes.json and the bake must hold the same probes, in order
        n = len(positions)
        same = lf.n >= n and np.allclose(lf.positions[:n], positions, rtol=0, atol=1e-5 * diagonal)
        if not same:
            return (
                None,
                f"{inp.baked_path.name} holds other probes than {inp.probes_path.name}: maps not shown",
            )
    maps = lf.maps
    usable = lf.active[rows] & (~lf.inside[rows] if lf.inside is not None else True)
    white = exposure_white(interior_all(maps.radiance[rows][usable]))
    sh = lf.sh[rows]
    from ..placement import fibonacci_directions  # imports JAX, as the scene already has

    irradiance = sh_irradiance(sh[usable], fibonacci_directions(256).astype(np.float64)) / np.pi
    irr_white = exposure_white(irradiance)
    baked = Baked(
        path=inp.baked_path,
        rows=rows,
        radiance=maps.radiance[rows] + maps.emission[rows],
        sh=sh,
        inside=None if lf.inside is None else np.asarray(lf.inside[rows], bool),
        reach=_reach(maps.moments[rows], maps.far, diagonal),
        far=maps.far,
        white=white,
        irradiance_white=irr_white,
    )
    note = (
        f"maps of {inp.baked_path.name}. White: radiance {white:.4g}, irradiance sphere E/π {irr_white:.4g} "
        "(99th percentiles over the usable probes)"
    )
    return baked, note


def interior_all(bordered: np.ndarray) -> np.ndarray:
    """Bordered maps (n, R+2, R+2, c) without their border."""
    return bordered[:, 1:-1, 1:-1]


def _reach(moments: np.ndarray, far: float, diagonal: float) -> np.ndarray:
    """(n,) solid-angle mean of the filtered distance E[r] (moments channel 0), escapes counted at
    ``diagonal`` (``far`` is a sentinel, not a distance)."""
    m = interior_all(np.asarray(moments, np.float64))[..., 0]
    m = np.where(m >= far * (1 - 1e-6), diagonal, np.minimum(m, diagonal))
    w = texel_solid_angles(m.shape[-1])
    return (m * w).sum(axis=(1, 2)) / w.sum()


def status_note(meta: dict, *, inside_known: bool) -> str:
    """What the probe file says about relocated and filled probes: which ones (``relocated_probes``,
    ``filled_probes``: coloured) or, in a record of an older version, the counts only."""
    inside = "" if inside_known else " Inside-geometry flags come with the bake: not recorded here."
    if isinstance(meta.get("relocated_probes"), list) and isinstance(meta.get("filled_probes"), list):
        n_rel, n_fill = len(meta["relocated_probes"]), len(meta["filled_probes"])
        n_proj = len(meta["projected_probes"]) if isinstance(meta.get("projected_probes"), list) else 0
        if not n_rel and not n_fill and not n_proj:
            return "No probe was relocated or filled: every probe is where the method put it." + inside
        proj = f", {n_proj} moved into the placement region" if n_proj else ""
        return (
            f"{n_rel} relocated out of geometry, {n_fill} filled to the budget{proj}: coloured in the "
            "status colours (before any refinement moved them)." + inside
        )
    valid = meta.get("valid_space") if isinstance(meta.get("valid_space"), dict) else {}
    fit = meta.get("budget_fit") if isinstance(meta.get("budget_fit"), dict) else {}
    relocated = valid.get("n_relocated", meta.get("n_relocated"))
    filled = fit.get("n_filled")
    if relocated is None and filled is None:
        return "Relocated / filled: not recorded in this probe file." + inside
    if not relocated and not filled:
        return "No probe was relocated or filled: every probe is where the method put it." + inside
    return (
        f"{relocated or 0} relocated, {filled or 0} filled to the budget; which probes is not recorded "
        f"(this placement record keeps the counts only: {RERUN})." + inside
    )


def _unavailable(meta: dict, coverage_why: str | None, error_why: str | None) -> dict[str, str]:
    """Per-probe figures the saved files do not hold, each with why (``None``: that figure is there)."""
    out = {}
    if coverage_why is not None:
        cov = meta.get("coverage")
        total = f" (the set's coverage {cov:.4g} is in probes.json)" if isinstance(cov, int | float) else ""
        out["coverage contribution"] = coverage_why + total
        out["uncovered surface samples"] = coverage_why
    if error_why is not None:
        out["error contribution"] = error_why
    return out


def _eval_images(inp: ViewInput) -> tuple[EvalImages | None, str]:
    d = inp.eval_dir
    if d is None:
        where = "a run folder" if inp.run_config is None else "this run's eval/ (eval.enabled was off?)"
        return None, f"no error images: they come with {where}"
    images = {p.name[len("error_") : -len("_false.png")]: p for p in sorted(d.glob("error_*_false.png"))}
    try:
        metrics = json.loads((d / RunFiles.metrics).read_text())
    except (OSError, ValueError):
        metrics = {}
    if not images or not isinstance(metrics, dict) or "width" not in metrics:
        return None, f"no error images: {d} holds no finished evaluation"
    vmax = metrics.get("error_png_vmax") or {}
    ev = EvalImages(
        view=str(metrics.get("view", "")),
        width=int(metrics["width"]),
        height=int(metrics["height"]),
        images=images,
        vmax={k: float(v) for k, v in vmax.items()},
    )
    return ev, f"view {ev.view!r}, {ev.width}×{ev.height}; colour bar top = error_png_vmax"
