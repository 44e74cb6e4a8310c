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

from ..export import read_light_field_npz, sh_irradiance, texel_solid_angles
from ._input import ViewInput
from ._maps import exposure_white

#: Probe status codes, their legend and colours (saturated cyan / magenta / grey: hues no scene material
#: of the built-ins has, so a probe stands out against the walls; the browser test looks for them).
USABLE, INSIDE, INACTIVE = 0, 1, 2
STATUS_LABELS = ("usable", "inside geometry at bake (unusable for shading)", "inactive")
STATUS_RGB = np.array([[0, 200, 255], [255, 0, 200], [150, 150, 150]], np.uint8)

COLOUR_STATUS = "status"
REACH = "mean visible distance"
SIZE_UNIFORM = "uniform"


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

    @property
    def diagonal(self) -> float:
        return float(np.linalg.norm(self.hi - self.lo))

    @property
    def colour_options(self) -> tuple[str, ...]:
        return (COLOUR_STATUS, REACH) if self.baked is not None else (COLOUR_STATUS,)

    @property
    def size_options(self) -> tuple[str, ...]:
        return (SIZE_UNIFORM, REACH) if self.baked is not None else (SIZE_UNIFORM,)

    def colours(self, by: str) -> np.ndarray:
        """(n, 3) uint8 probe colours: by status (:data:`STATUS_RGB`) or by reach (viridis, low to high)."""
        if by == COLOUR_STATUS:
            return STATUS_RGB[self.status]
        if by == REACH and self.baked is not None:
            from matplotlib import colormaps

            r = self.baked.reach
            t = (r - r.min()) / max(float(np.ptp(r)), 1e-30)
            return np.round(255 * colormaps["viridis"](t)[:, :3]).astype(np.uint8)
        raise ValueError(f"colour by {by!r}: options are {self.colour_options}")

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
    if baked is not None and baked.inside is not None:
        status[(status == USABLE) & baked.inside] = INSIDE
    ev, eval_note = _eval_images(inp)
    meta = inp.metadata
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
        unavailable=_unavailable(meta),
    )


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
    """What the probe file says about relocated and filled probes (counts only: which ones is not saved)."""
    valid = meta.get("valid_space") if isinstance(meta.get("valid_space"), dict) else {}
    fit = meta.get("budget_fit") if isinstance(meta.get("budget_fit"), dict) else {}
    relocated = valid.get("n_relocated", meta.get("n_relocated"))
    filled = fit.get("n_filled")
    inside = "" if inside_known else " Inside-geometry flags come with the bake: not recorded here."
    if relocated is None and filled is None:
        return "Relocated / filled: not recorded in this probe file." + inside
    if not relocated and not filled:
        return "No probe was relocated or filled: every probe is where the method put it." + inside
    return (
        f"{relocated or 0} relocated, {filled or 0} filled to the budget; which probes is not recorded "
        "(the placement record keeps the counts only)." + inside
    )


def _unavailable(meta: dict) -> dict[str, str]:
    """Per-probe figures the saved files do not hold, each with why."""
    cov = meta.get("coverage")
    total = f" ({cov:.4g})" if isinstance(cov, int | float) else ""
    return {
        "coverage contribution": f"not recorded: probes.json keeps the set's coverage{total}, not each "
        "probe's share",
        "error contribution": "not recorded: eval/ keeps per-pixel errors, not which probe shaded a pixel",
        "uncovered surface samples": "not recorded: the run keeps the coverage figure, not its samples",
    }


def _eval_images(inp: ViewInput) -> tuple[EvalImages | None, str]:
    d = inp.eval_dir
    if d is None:
        where = "a run folder" if inp.run_config is None else "this run's eval/ (eval.enabled was off?)"
        return None, f"no error images: they come with {where}"
    images = {p.name[len("error_") : -len("_false.png")]: p for p in sorted(d.glob("error_*_false.png"))}
    try:
        metrics = json.loads((d / "metrics.json").read_text())
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
