"""Convergence of the probe error with probe density and map resolution, and what the error is made of.

    .venv/bin/python benchmarks/convergence.py [--plan papers|sweep|quick] [--quick]
        [--scenes cornell sponza] [--bake-spp N | scene:N ...] [--n-sub N] [--texel-rays surfel|jittered]
        [--res 16 32 64] [--grids 4x4x4 8x4x4] [--seeds N] [--fresh] [--geometry-res N]
        [--backend jax|mitsuba] [--no-auto] [--no-costs]

What a run measures, where its options do not say, is its plan (``PLANS``). The default, ``papers``, is
issue 33's instrument at the papers' resolution: Cornell 4×4×4 at 128² radiance and Sponza 8×4×4 and
16×8×8 at 64², all with 512² geometry maps, 32 bake paths a Cornell texel and 128 a Sponza texel, 512 glossy
rays a Sponza pixel and fifteen seeds of the 8×4×4 grid; about 2 h 15 min on 2 cores from an empty cache,
and a rerun reuses every cell already done.
``--plan sweep`` is issue 16's grids × radiance resolutions (16–128) with geometry maps twice as fine;
``--quick`` (``--plan quick``) a few minutes of small cells.

For each scene (Cornell box "front", Crytek Sponza "CameraMain"), uniform grids (cell centres of the scene
box; by density in the sweep) × radiance-map resolutions, baked with the path tracer
(``probes.path_traced_radiance``, ``--bake-spp`` paths × ``--n-sub``² rays per texel along its surfel's
direction, or jittered over it (``--texel-rays``, ``probes.BakeConfig.texel_rays``; the surfel's ray by
default: one ray a texel reads better there than one jittered ray, experiments/README.md §2), path depth
= the evaluation's ``max_depth`` − 1) and evaluated (``probeplace.evaluate``: light-field shading,
``glossy_filter`` of the evaluation's default). Per cell: the glossy and diffuse MSE, the glossy MSE's
parts (perfect trace, trace share and ``trace_excess``, split by ray status, resolved only), noise floors,
black images, agreement of resolved hits with the exact distance, unresolved share, 95 % intervals, bake
time (compile apart: a one-batch warm-up first), ``make_tracer`` time (``make_tracer_s``, with
``usable_probes``: the tracer's set-up, issue 33) and shading time (compile apart; ``--trace-engine``,
default the runner's ``wavefront``), and the unresolved share among the glossy rays whose origin one of
the K nearest usable probes sees (``unresolved_seen``: the evaluation's ``unresolved_seen_share``; the
share of such rays is ``origin_seen``).

Besides the grids, Sponza has one cell for the automatic skeleton set (``--no-auto`` skips it): the probes
``placement.place(scene, method="skeleton", budget="auto", seed=0)`` places (Wang 2019's skeleton seeds,
the fewest that reach full coverage; the runner's ``method=skeleton placer.budget=auto``, and
``probeplace place crytek_sponza --method skeleton``), baked and evaluated exactly as a grid cell (same
bake settings, geometry resolution and shared steps) at the run's finest Sponza radiance resolution. It
is not a grid, so the tracer indexes it with ``voxel_index``. Its figures, ``sponza_auto_r{R}_…`` and
``sponza_auto_g{G}_…`` (``unresolved``, ``unresolved_seen``, ``agreement``, ``glossy_over_black``,
``n_probes``, ``n_probes_usable``, …), stand beside the grids'. The placement is cached in
``convergence_cells/`` as well (its name and the cell's settings carry the method, budget and placement
seed); the cell records its time (``place_s``) and coverage.

The reference, the primary samples and the CRN glossy reference depend only on (scene, evaluation
settings, seed): they are computed once per scene and seed with the evaluation's public steps
(``evaluate.render_reference`` …) and shared by every cell; only shading, the perfect trace and scoring
run per cell. Each cell's JSON is cached atomically in ``benchmarks/results/convergence_cells/`` (the
name carries a hash of the settings, not of the code) and skipped when present; ``--fresh`` recomputes
each once (do so after changing the code).

Targets (issue 16), each reported as ``targets: {key: {value, target, met}}`` (the seeds' spread also with
``upper95``, its one-sided 95 % bound; an estimate under its target whose bound is not is undecided: ``met``
null, with ``why``):
``cornell_4x4x4_r64_mse_over_floor`` ≤ 1.3 (glossy MSE ÷ CRN noise floor); on Sponza at 16×8×8 × 64²
``_agreement`` ≥ 0.95, ``_unresolved`` ≤ 0.03, ``_trace_excess`` ≤ 0.2, ``_glossy_over_black`` and
``_diffuse_over_black`` < 1; ``sponza_grid128_glossy_over_black`` < 1 (8×4×4, 128 probes) and
``sponza_grid128_seed_cv`` ≤ 0.10 (coefficient of variation, population σ / mean, of the glossy MSE over
``--seeds`` bake + evaluation seeds, ``--first-seed`` … on; only the first seed's shading is timed, the
others run it once untimed, ``evaluate.EvalConfig.timing_repeats`` 0). Keys of cells not run (left out by
the plan or the options, or Sponza absent) are null with a reason in ``skipped``. Last stdout line: the
JSON, also written to benchmarks/results/convergence_geometry<N>.json when the geometry maps are at least
N² (the papers plan: ``convergence_geometry512.json``), else to ``convergence.json`` (the sweep and quick
plans).
Issue 33 (the instrument at the papers' resolution, the default plan): every cell's figures
also under ``{scene}_{grid}_g{G}_…`` (G the geometry maps' resolution); targets
``cornell_4x4x4_g512_mse_over_floor`` ≤ 1.3, ``sponza_16x8x8_g512_agreement`` ≥ 0.95, ``_unresolved_seen``
≤ 0.03 (null with the reason when the cell did not run), ``_trace_excess`` ≤ 0.2, ``_glossy_over_black`` < 1,
``sponza_grid_seed_spread`` ≤ 0.05 (the 8×4×4 grid's seed_cv) with, beside it,
``sponza_grid_seed_spread_over_black`` (the same spread of the glossy MSE ÷ each seed's black-image MSE:
a seed draws new glossy rays, and the reference energy of those rays — the black image's MSE — itself
moves 4–8 % between seeds, which no number of bake or reference paths removes; paired comparisons at one
seed divide it out), ``sponza_grid_seed_spread_ci95`` (its 95 % interval, :func:`cv_interval`),
``sponza_grid_seed_spread_upper95`` (its one-sided 95 % upper bound, :func:`cv_upper95`: under 0.05, the
target is met at 95 % confidence) and, with
``--spread-fixed-rays``, ``sponza_grid_seed_spread_fixed_rays`` (the seeds' spread on the first seed's
evaluation rays: the bake's and the reference's noise alone, what the sample counts control) with its
interval,
``sponza_grid_seed_spread_bulk`` (the spread of the glossy MSE less each run's 1 % of pixels with the
largest error, ``top_percent_share``, which makes the raw spread: mostly too-bright reads at small dark
spots and unresolved rays, ``experiments/tail_causes.py``) with its interval,
``sponza_grid_seed_spread_converged`` (the spread of each seed's ``mse_glossy_converged``, the unbiased
estimate of the glossy image's MSE at infinitely many glossy rays and reference paths a pixel,
``evaluate.converged_sq_error``: no sample's own squared error is in it, so neither the reference's noise
floor nor the square of one ray meeting a sun glint alone in its pixel) with its interval,
``sponza_grid_seed_spread_tail_index`` (each seed's Hill index of its per-pixel glossy error,
``evaluate.tail_index``: below 2 the raw spread does not fall as 1/√n with more pixels or samples); and
the set-up costs of 128 usable probes
on a line through Sponza's atrium, ``make_tracer_128_g512_s`` ≤ 10 and ``geometry_bake_128_g512_s`` ≤ 10
(the median of ``COST_REPEATS`` warm runs, compile apart; ``--no-costs`` skips them), with
``tracer_mb_per_probe_g512``.
Geometry maps are ``--geometry-factor`` (default 2) times finer than the radiance maps: the light-field
trace resolves depth edges at the geometry resolution, while the radiance texels' footprint sets the
representation floor (``BakeConfig.geometry_res``).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import re
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from probeplace._core import TEXEL_RAYS, ConfigError, ResourceError, SceneError, scene_box, write_text_atomic

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, atrium_line, env_info, setup_scene_path, write_result

CELLS = RESULTS / "convergence_cells"
SCENES = {
    "cornell": {"name": "cornell_box", "view": "front"},
    "sponza": {"name": "crytek_sponza", "view": "CameraMain"},
}
#: What a run measures where its options do not say (``--plan``; ``--quick`` is ``--plan quick``): per scene
#: the grids, radiance resolutions, evaluation image (width, height) and sample counts (bake paths a texel
#: ray, glossy rays a pixel, CRN reference paths a glossy ray); for the run the geometry maps' resolution
#: (None: ``--geometry-factor`` × the radiance's), the 8×4×4 grid's seeds and radiance resolution, and the
#: reference's paths a pixel. A per-scene option (``--grids sponza:16x8x8``) replaces that scene's value only.
PLANS = {
    # Issue 33, the default: the instrument at the papers' resolution, 512² geometry maps (Wang 2019 §5),
    # with the counts that decide its targets: Cornell's 32 bake paths (its floor ratio at 128² radiance);
    # Sponza's 512 glossy rays a pixel (the rays' sample no longer adds to the seed spread) and 128 bake
    # paths, the count that decides the spread: at 32 the bake made 4.1 % of a 4.5-4.8 % spread, which no
    # affordable seed count decides against 5 % (experiments/README.md §2, "A fresh sample"); at 128 fifteen
    # seeds read 1.9 %, one-sided bound 2.8 % ("The bake's paths raised to decide the spread").
    # About 2 h 15 min on 2 cores from an empty cache: the fifteen seeds ~1.5 h (the first, timed, ~9.5 min,
    # each other ~6 min: its shading runs once, untimed; its bake ~140 s), the 16×8×8 cell ~30 min (its bake
    # ~20 min), the other cells ~15 min; every cell is cached as it finishes, so a stopped run resumes where
    # it stopped (experiments/README.md §2, "The bare command at the plan's 128 bake paths").
    "papers": {
        "cornell": {
            "grids": ["4x4x4"], "res": [128], "eval": (32, 32),
            "bake_spp": 32, "glossy_spp": 16, "glossy_ref_spp": 4,
        },
        "sponza": {
            "grids": ["8x4x4", "16x8x8"], "res": [64], "eval": (64, 48),
            "bake_spp": 128, "glossy_spp": 512, "glossy_ref_spp": 4,
        },
        "geometry_res": 512, "seeds": 15, "grid128_res": 64, "eval_spp": 32,
    },
    # Issue 16: the error against probe density × radiance resolution, geometry maps twice the radiance's.
    # Its counts are also the cells' of the experiments that rerun one (sponza_cell_bench, paper_check.py).
    "sweep": {
        "cornell": {
            "grids": ["2x2x2", "3x3x3", "4x4x4", "6x6x6"], "res": [16, 32, 64, 128], "eval": (32, 32),
            "bake_spp": 8, "glossy_spp": 16, "glossy_ref_spp": 4,
        },
        "sponza": {
            "grids": ["4x2x2", "8x4x4", "16x8x8"], "res": [16, 32, 64], "eval": (64, 48),
            "bake_spp": 8, "glossy_spp": 16, "glossy_ref_spp": 4,
        },
        "geometry_res": None, "seeds": 3, "grid128_res": 64, "eval_spp": 32,
    },
    # A few minutes: small grids, resolutions, images and counts.
    "quick": {
        "cornell": {
            "grids": ["2x2x2", "4x4x4"], "res": [16, 64], "eval": (24, 24),
            "bake_spp": 4, "glossy_spp": 16, "glossy_ref_spp": 4,
        },
        "sponza": {
            "grids": ["8x4x4"], "res": [16], "eval": (48, 36),
            "bake_spp": 4, "glossy_spp": 16, "glossy_ref_spp": 4,
        },
        "geometry_res": None, "seeds": 3, "grid128_res": 16, "eval_spp": 16,
    },
}  # fmt: skip
#: The options a plan fills in for the whole run (each None on the command line unless given).
RUN_PLANNED = ("geometry_res", "seeds", "grid128_res", "eval_spp")
#: (key suffix, target, comparison) of the issue's targets.
TARGETS = {
    "cornell_4x4x4_r64_mse_over_floor": (1.3, "<="),
    "sponza_16x8x8_r64_agreement": (0.95, ">="),
    "sponza_16x8x8_r64_unresolved": (0.03, "<="),
    "sponza_16x8x8_r64_trace_excess": (0.2, "<="),
    "sponza_16x8x8_r64_glossy_over_black": (1.0, "<"),
    "sponza_16x8x8_r64_diffuse_over_black": (1.0, "<"),
    "sponza_grid128_glossy_over_black": (1.0, "<"),
    "sponza_grid128_seed_cv": (0.10, "<="),
    # issue 33: the instrument at the papers' resolution (--geometry-res 512)
    "cornell_4x4x4_g512_mse_over_floor": (1.3, "<="),
    "sponza_16x8x8_g512_agreement": (0.95, ">="),
    "sponza_16x8x8_g512_unresolved_seen": (0.03, "<="),
    "sponza_16x8x8_g512_trace_excess": (0.2, "<="),
    "sponza_16x8x8_g512_glossy_over_black": (1.0, "<"),
    "sponza_grid_seed_spread": (0.05, "<="),
    "make_tracer_128_g512_s": (10.0, "<="),
    "geometry_bake_128_g512_s": (10.0, "<="),
}
#: The automatic skeleton set's cell (Sponza; module docstring): its name among the grids and how it is
#: placed (``placement.place``'s arguments; the placement seed is the cell's seed).
AUTO = "auto"
AUTO_PLACEMENT = {"method": "skeleton", "budget": "auto"}
#: Figures of every cell reported at the top level as ``{scene}_{grid}_r{R}_…`` and ``…_g{G}_…``.
CELL_FIGURES = (
    "mse_over_floor", "agreement", "unresolved", "unresolved_seen", "origin_seen", "trace_excess",
    "glossy_over_black", "diffuse_over_black", "bake_s", "make_tracer_s", "usable_probes",
    "shading_s_per_frame", "n_probes", "n_probes_usable", "mse_glossy_perfect_trace",
    "view_dependence_over_black",
)  # fmt: skip
#: The automatic skeleton set's figures reported beside the grid's (``sponza_auto_g{G}_…``).
AUTO_FIGURES = (
    "unresolved",
    "unresolved_seen",
    "agreement",
    "glossy_over_black",
    "n_probes",
    "n_probes_usable",
)
#: issue 33's figures without a target, reported beside the grid's.
REPORTED = (
    "sponza_8x4x4_g512_agreement",
    "sponza_grid_seed_spread_over_black",
    "sponza_grid_seed_spread_ci95",
    "sponza_grid_seed_spread_upper95",
    "sponza_grid_seed_spread_fixed_rays",
    "sponza_grid_seed_spread_fixed_rays_ci95",
    "sponza_grid_seed_spread_bulk",
    "sponza_grid_seed_spread_bulk_ci95",
    "sponza_grid_seed_spread_converged",
    "sponza_grid_seed_spread_converged_ci95",
    *(f"sponza_{AUTO}_g512_{f}" for f in AUTO_FIGURES),
)
#: Warm runs of each set-up cost (:func:`instrument_costs`); the figure is their median.
COST_REPEATS = 3
#: figures not measured yet, with why (reported null, the reason in ``skipped``); none at present.
NOT_MEASURED: dict[str, str] = {}


def log(msg: str) -> None:
    print(f"[convergence {time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def is_grid(text: str) -> bool:
    """Whether ``text`` names a uniform grid NxMxK of positive counts written without leading zeros (the
    ``--grid`` of the experiments that rerun a cell: experiments/tail_causes.py, spread_parts.py,
    ray_allocation.py)."""
    return re.fullmatch(r"[1-9]\d*x[1-9]\d*x[1-9]\d*", text) is not None


def dims_of(grid: str) -> tuple[int, int, int]:
    d = tuple(int(v) for v in grid.split("x"))
    if len(d) != 3 or min(d) < 1:
        raise SystemExit(f"bad grid {grid!r}: want NxMxK")
    return d  # type: ignore[return-value]


def grid_positions(scene, dims) -> np.ndarray:
    """Cell centres of a dims grid over the scene's bounding box."""
    lo, hi = scene_box(scene)
    axes = [(np.arange(n) + 0.5) / n for n in dims]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * (hi - lo) + lo


def sponza_cell_bench(
    grid: str,
    res: int,
    bake_spp: int,
    geometry_res: int,
    texel_rays: str,
    glossy_ref_spp: int | None = None,
    glossy_spp: int | None = None,
) -> Bench:
    """The Sponza :class:`Bench` of this benchmark's ``grid`` × ``res`` cell at these settings, the rest its
    defaults and the counts not given the ``sweep`` plan's (for the experiments that rerun a cell:
    experiments/tail_causes.py, spread_parts.py, ray_allocation.py). Raises what ``load_scene`` raises
    when the scene is not on the scene path."""
    setup_scene_path()
    argv = ["--plan", "sweep", "--scenes", "sponza", "--grids", f"sponza:{grid}", "--res", f"sponza:{res}"]
    argv += ["--bake-spp", f"sponza:{bake_spp}", "--geometry-res", str(geometry_res)]
    argv += ["--texel-rays", texel_rays]
    if glossy_ref_spp is not None:
        argv += ["--glossy-ref-spp", f"sponza:{glossy_ref_spp}"]
    if glossy_spp is not None:
        argv += ["--glossy-spp", f"sponza:{glossy_spp}"]
    return Bench("sponza", parse_args(argv))


def add_cell_arguments(ap: argparse.ArgumentParser, *, seeds: int, bake_spp: int, glossy_spp: int) -> None:
    """The arguments of an experiment that reruns one Sponza cell over seeds 0 … N − 1 (spread_parts.py,
    ray_allocation.py): the cell (grid, radiance and geometry resolution, texel rays) and its counts, as
    :func:`sponza_cell_bench` takes them; the defaults that differ between the experiments are given."""
    ap.add_argument("--grid", default="8x4x4", help="uniform grid NxMxK (a convergence cell's)")
    ap.add_argument("--seeds", type=int, default=seeds, help="bake and reference seeds, 0 … N − 1 (N >= 2)")
    ap.add_argument("--res", type=int, default=64, help="radiance map resolution")
    ap.add_argument("--bake-spp", type=int, default=bake_spp)
    ap.add_argument("--glossy-ref-spp", type=int, default=4, help="CRN reference paths a glossy ray")
    ap.add_argument("--glossy-spp", type=int, default=glossy_spp, help="glossy rays a pixel")
    ap.add_argument("--geometry-res", type=int, default=512)
    ap.add_argument(
        "--texel-rays",
        default="surfel",
        choices=TEXEL_RAYS,
        help="where a radiance texel's rays leave (default as this benchmark's)",
    )


def cell_bench_of(ap: argparse.ArgumentParser, args: argparse.Namespace) -> tuple[Bench, np.ndarray]:
    """The bench of :func:`add_cell_arguments`' cell and its grid's probe positions; exits with status 2
    through ``ap.error`` for a grid that is not NxMxK or a Sponza that is not on the scene path."""
    if not is_grid(args.grid):
        ap.error(f"--grid {args.grid!r}: want NxMxK, e.g. 8x4x4")
    b = sponza_cell_bench_or_exit(
        ap,
        args.grid,
        args.res,
        args.bake_spp,
        args.geometry_res,
        args.texel_rays,
        args.glossy_ref_spp,
        args.glossy_spp,
    )
    return b, grid_positions(b.scene, dims_of(args.grid))


def sponza_cell_bench_or_exit(ap: argparse.ArgumentParser, *bench_args) -> Bench:
    """:func:`sponza_cell_bench` of ``bench_args``, or exit with status 2 through ``ap.error`` when Sponza
    is not on the scene path (it lives outside the repository: PROBEPLACE_SCENE_PATH) or does not load; one
    line (``load_scene``'s message lists the searched folders on further lines)."""
    try:
        return sponza_cell_bench(*bench_args)
    except SceneError as e:
        ap.error(
            f"Crytek Sponza not loaded ({str(e).splitlines()[0].rstrip(':')}); set PROBEPLACE_SCENE_PATH"
        )


class Bench:
    """One scene's shared state: scene, caster, evaluation config and the per-seed shared steps."""

    def __init__(self, key: str, args):
        from probeplace.evaluate import EvalConfig
        from probeplace.probes import TraceConfig
        from probeplace.render import default_caster
        from probeplace.scene import load_scene

        self.key, self.args = key, args
        self.plan = scene_plan(args, key)
        self.bake_spp = self.plan["bake_spp"]
        self.scene = load_scene(SCENES[key]["name"])
        self.view = SCENES[key]["view"]
        self.caster = default_caster(self.scene)
        # tracer settings from the command line: given to the tracer and recorded in every cell's settings
        self.trace_options = (
            {"fallback_radius": args.fallback_radius} if args.fallback_radius is not None else {}
        )
        self.config = EvalConfig(
            width=self.plan["eval"][0],
            height=self.plan["eval"][1],
            spp=args.eval_spp,
            glossy_spp=self.plan["glossy_spp"],
            glossy_ref_spp=self.plan["glossy_ref_spp"],
            max_depth=args.max_depth,
            timing_repeats=args.timing_repeats,
            backend=args.backend,
            trace=TraceConfig(subdivide=args.subdivide, engine=args.trace_engine, **self.trace_options),
        )
        self.shared: dict = {}
        self.warm: set = set()
        self.written: set = set()  # cache files this run wrote: --fresh recomputes each once

    def cached(self, path: Path) -> bool:
        """Whether ``path`` (a cell's or a placement's JSON) is read instead of computed: present, and not
        under ``--fresh`` unless this run wrote it."""
        return path.exists() and (not self.args.fresh or path in self.written)

    def settings(self) -> dict:
        c = self.config
        return (
            {
                "scene": self.scene.name,
                "view": self.view,
                "width": c.width,
                "height": c.height,
                "spp": c.spp,
                "glossy_spp": c.glossy_spp,
                "glossy_ref_spp": c.glossy_ref_spp,
                "max_depth": c.max_depth,
                "glossy_filter": c.glossy_filter,
                "bake_spp": self.bake_spp,
                "n_sub": self.args.n_sub,
                "texel_rays": self.args.texel_rays,
                "bake_depth": c.max_depth - 1,
                "first_hit_lobes": "diffuse",  # what texels store (probes.path_traced_radiance's default)
            }
            | (
                {"geometry_res": self.args.geometry_res}
                if self.args.geometry_res
                else {"geometry_factor": self.args.geometry_factor}
            )
            | ({"backend": self.args.backend} if self.args.backend != "jax" else {})
            | ({"subdivide": self.args.subdivide} if self.args.subdivide != 2 else {})
            | self.trace_options
            | {"trace_engine": self.args.trace_engine}
        )

    def steps(self, seed: int, ray_seed: int | None = None):
        """Reference, primary samples and CRN reference of one seed (computed once, shared by cells); with
        ``ray_seed`` the primary samples (camera jitter, glossy directions) are that seed's, the reference's
        paths still ``seed``'s."""
        key = seed if ray_seed is None else (seed, ray_seed)
        if key not in self.shared:
            from probeplace.evaluate import crn_reference, render_reference, sample_primary

            cam = self.scene.view(self.view)
            t0 = time.perf_counter()
            ref = render_reference(self.scene, cam, self.config, seed=seed, caster=self.caster)
            rays = seed if ray_seed is None else ray_seed
            prim = sample_primary(self.scene, cam, self.config, seed=rays, caster=self.caster)
            crn = crn_reference(self.scene, prim, self.config, seed=seed, caster=self.caster)
            log(f"{self.key}: reference + CRN reference for seed {key}: {time.perf_counter() - t0:.1f} s")
            self.shared[key] = (ref, prim, crn, time.perf_counter() - t0)
        return self.shared[key]

    def bake(self, pos: np.ndarray, res: int, seed: int):
        """Bake the probes at ``pos`` as every cell is baked: (probes, bake times)."""
        from probeplace._core import ProbeSet
        from probeplace.probes import BakeConfig, bake_probes, path_traced_radiance

        a = self.args
        geo = cell_geometry_res(a, res)
        # ~2^18 radiance rays and ~2^21 geometry rays a batch (at 512² geometry: 8 probes)
        per_batch = int(max(1, min(len(pos), (1 << 18) // (res * res * a.n_sub**2), (1 << 21) // geo**2)))
        cfg = BakeConfig(
            radiance_res=res,
            geometry_res=geo,
            n_sub=a.n_sub,
            texel_rays=a.texel_rays,
            probes_per_batch=per_batch,
            progress=False,
        )
        fn = path_traced_radiance(
            self.scene,
            spp=self.bake_spp,
            max_depth=self.config.max_depth - 1,
            caster=self.caster if a.backend == "jax" else None,
            backend=a.backend,
        )
        warm_s = 0.0
        if (res, per_batch) not in self.warm:  # compile with one batch of the same shapes, timed apart
            sub = ProbeSet(
                pos_world=jnp.asarray(pos[:per_batch], jnp.float32), active=jnp.ones(per_batch, bool)
            )
            t0 = time.perf_counter()
            # The inside test is left out of the warm-up: on a handful of probes it may find none that
            # escapes and warn about a closed scene, which says nothing about the real bake.
            warm_cfg = dataclasses.replace(cfg, inside_test="none")
            bake_probes(
                self.scene, sub, caster=self.caster, radiance_fn=fn, key=jax.random.key(seed), config=warm_cfg
            )
            warm_s = time.perf_counter() - t0
            self.warm.add((res, per_batch))
        probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(len(pos), bool))
        t0 = time.perf_counter()
        lf = bake_probes(
            self.scene, probes, caster=self.caster, radiance_fn=fn, key=jax.random.key(seed), config=cfg
        )
        bake_s = time.perf_counter() - t0
        n_batches = -(-len(pos) // per_batch)
        return lf, {
            "bake_s": bake_s,
            "bake_compile_s": max(warm_s - bake_s / n_batches, 0.0) if warm_s else 0.0,
        }

    def auto_positions(self, seed: int) -> tuple[np.ndarray, dict]:
        """The automatic skeleton set (``AUTO_PLACEMENT``, placement seed ``seed``): positions and the
        placement's record (time, coverage), cached in ``CELLS`` like a cell."""
        key = {"scene": self.scene.name, **AUTO_PLACEMENT, "seed": seed}
        digest = hashlib.sha1(json.dumps(key, sort_keys=True).encode()).hexdigest()[:10]
        method, budget = AUTO_PLACEMENT["method"], AUTO_PLACEMENT["budget"]
        path = CELLS / f"{self.key}_place_{method}_{budget}_s{seed}_{digest}.json"
        if self.cached(path):
            log(f"{path.name}: cached")
            rec = json.loads(path.read_text())
            return np.asarray(rec.pop("positions"), np.float64), rec
        from probeplace.placement import place

        log(f"{self.key}: placing the automatic skeleton set ({AUTO_PLACEMENT}, seed {seed})")
        t0 = time.perf_counter()
        placed = place(self.scene, **AUTO_PLACEMENT, seed=seed)
        place_s = time.perf_counter() - t0
        pos = np.asarray(placed.probes.pos_world, np.float64)[np.asarray(placed.probes.active)]
        rec = key | {
            "place_s": place_s,
            "coverage": placed.coverage,
            "target_reached": placed.target_reached,
            "n_placed": len(pos),
        }
        write_text_atomic(path, json.dumps(rec | {"positions": pos.tolist()}, indent=1, sort_keys=True))
        self.written.add(path)
        log(f"{self.key}: placed {len(pos)} probes in {place_s:.1f} s, coverage {placed.coverage:.4f}")
        return pos, rec

    def cell(
        self,
        grid: str,
        res: int,
        seed: int,
        positions: np.ndarray | None = None,
        ray_seed: int | None = None,
        timed: bool = True,
    ) -> dict:
        """One cell's figures, from the cache when present: a grid (``NxMxK``), the automatic skeleton
        set (``AUTO``; its placement seed is ``seed``) or, named ``grid``, the probes at ``positions``;
        ``ray_seed``: the evaluation's rays from that seed (:meth:`steps`), the bake and reference paths
        from ``seed``; ``timed`` False: the shading runs once, untimed (``shading_s_per_frame`` null; its
        timed repeat is 145 s of a 6.4 min Sponza seed), every other figure the same."""
        settings = self.settings() | {"grid": grid, "res": res, "seed": seed}
        if ray_seed is not None:
            settings["ray_seed"] = ray_seed
        if grid == AUTO:
            settings["placement"] = AUTO_PLACEMENT | {"seed": seed}
        if positions is not None:
            positions = np.asarray(positions, np.float64)
            settings["positions_sha1"] = hashlib.sha1(positions.tobytes()).hexdigest()
        digest = hashlib.sha1(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:10]
        path = CELLS / f"{self.key}_{grid}_r{res}_s{seed}_{digest}.json"
        if self.cached(path):
            log(f"{path.name}: cached")
            return json.loads(path.read_text())
        from probeplace.evaluate import perfect_trace, score, shade_probes
        from probeplace.probes import check_bake_settings, glossy_maps, make_tracer

        placement = {}
        if positions is not None:
            pos = positions
        elif grid == AUTO:
            pos, placement = self.auto_positions(seed)
        else:
            pos = grid_positions(self.scene, dims_of(grid))
        log(f"{self.key} {grid} r{res} seed {seed}: baking {len(pos)} probes")
        lf, times = self.bake(pos, res, seed)
        log(f"{self.key} {grid} r{res} seed {seed}: baked in {times['bake_s']:.1f} s; evaluating")
        ref, prim, crn, _ = self.steps(seed, ray_seed)
        check_bake_settings(lf, scene_name=self.scene.name, eval_max_depth=self.config.max_depth)
        t0 = time.perf_counter()
        tracer = make_tracer(lf, self.scene.bounds, config=self.config.trace)  # timed alone (issue 33)
        tracer_s = time.perf_counter() - t0
        index_kind = type(tracer.index).__name__  # a grid's GridIndex, any other set's VoxelIndex
        del tracer  # shade_probes builds its own: not two at once
        t0 = time.perf_counter()
        maps = glossy_maps(lf, self.config.glossy_filter, include_emission=False)
        config = self.config if timed else dataclasses.replace(self.config, timing_repeats=0)
        shading = shade_probes(self.scene, lf, prim, config, maps=maps)
        perfect = perfect_trace(lf, prim, self.config, caster=self.caster, maps=maps)
        m = score(self.scene, lf, self.view, self.config, seed, ref, prim, crn, shading, perfect).metrics
        out = summarise(m) | times | {"eval_s": time.perf_counter() - t0, "settings": settings}
        out |= {
            "make_tracer_s": tracer_s,
            "usable_probes": int((np.asarray(lf.active) & ~np.asarray(lf.inside)).sum()),
            "tracer_index": index_kind,
        }
        if placement:
            out |= {"place_s": placement["place_s"], "placement": placement}
        write_text_atomic(path, json.dumps(out, indent=1, sort_keys=True))
        self.written.add(path)
        log(
            f"{self.key} {grid} r{res} seed {seed}: glossy {out['mse_glossy']:.3g} (floor "
            f"{out['noise_floor_glossy']:.3g}, perfect {out['mse_glossy_perfect_trace']:.3g}), unresolved "
            f"{out['unresolved']:.3f} (origin seen: {out['unresolved_seen']}), agreement {out['agreement']}"
        )
        return out


def seed_cv(values) -> float | None:
    """Coefficient of variation (population σ / mean) of ``values``; None below two values or for a mean
    that is not positive."""
    v = np.asarray(values, np.float64)
    return float(v.std() / v.mean()) if len(v) > 1 and v.mean() > 0 else None


def cv_interval(values: np.ndarray) -> list[float] | None:
    """95 % interval of the coefficient of variation (population σ / mean) of ``values``: σ's χ² interval
    (n σ̂² / σ² ~ χ²(n − 1) for normal values, σ̂ the population estimate) over the mean (its own error
    ignored). From three seeds it spans about 0.5–4.4× the estimate, from five 0.6–2.9×: a spread of 6 %
    from five seeds cannot tell 5 % from 15 %. None below two values."""
    return _cv_bounds(values, (0.975, 0.025))


def cv_upper95(values: np.ndarray) -> float | None:
    """One-sided 95 % upper bound of the coefficient of variation of ``values`` (σ's χ² bound over the mean,
    as :func:`cv_interval`). A target "spread ≤ x" asks a one-sided question: a bound under x decides it at
    95 % (the upper end of :func:`cv_interval` is the 97.5 % bound). None below two values."""
    bounds = _cv_bounds(values, (0.05,))
    return None if bounds is None else bounds[0]


def _cv_bounds(values: np.ndarray, quantiles: tuple[float, ...]) -> list[float] | None:
    """√(n σ̂² / χ²_q(n − 1)) / mean for each q in ``quantiles``; None below two values or for a mean that is
    not positive."""
    from scipy.stats import chi2

    v = np.asarray(values, np.float64)
    n = len(v)
    if n < 2 or not v.mean() > 0:
        return None
    s2 = n * v.var()
    return [float(np.sqrt(s2 / chi2.ppf(q, n - 1)) / v.mean()) for q in quantiles]


def summarise(m: dict) -> dict:
    """The cell's figures from an evaluation's metrics."""
    ratio = lambda a, b: a / b if b else None
    return {
        "n_probes": m["n_probes"],
        "n_probes_usable": m["n_probes_usable"],
        "mse_glossy": m["mse_glossy_indirect"],
        "noise_floor_glossy": m["noise_floor_glossy_indirect"],
        "mse_over_floor": ratio(m["mse_glossy_indirect"], m["noise_floor_glossy_indirect"]),
        "mse_glossy_perfect_trace": m["mse_glossy_perfect_trace"],
        "perfect_trace_over_floor": ratio(m["mse_glossy_perfect_trace"], m["noise_floor_glossy_indirect"]),
        "perfect_trace_over_black": ratio(m["mse_glossy_perfect_trace"], m["mse_black_glossy_indirect"]),
        "mse_glossy_view_dependence": m["mse_glossy_view_dependence"],
        "view_dependence_over_black": ratio(m["mse_glossy_view_dependence"], m["mse_black_glossy_indirect"]),
        "trace_share": m["mse_glossy_trace_share"],
        "trace_excess": m["trace_excess"],
        "by_status": m["mse_glossy_by_status"],
        "resolved_only": m["mse_glossy_resolved_only"],
        "mse_glossy_converged": m["mse_glossy_converged"],
        "status_share": m["glossy_status_share"],
        "agreement": m["glossy_hit_agreement"],
        "unresolved": m["unresolved_share"],
        "origin_seen": m["origin_seen_share"],
        "unresolved_seen": m["unresolved_seen_share"],
        "perfect_trace_fallback_share": m["perfect_trace_fallback_share"],
        "mse_black_glossy": m["mse_black_glossy_indirect"],
        "glossy_over_black": ratio(m["mse_glossy_indirect"], m["mse_black_glossy_indirect"]),
        "mse_diffuse": m["mse_diffuse_indirect"],
        "noise_floor_diffuse": m["noise_floor_diffuse_indirect"],
        "mse_black_diffuse": m["mse_black_diffuse_indirect"],
        "diffuse_over_black": ratio(m["mse_diffuse_indirect"], m["mse_black_diffuse_indirect"]),
        "relmse_glossy": m["relmse_glossy_indirect"],
        "relmse_diffuse": m["relmse_diffuse_indirect"],
        "ci95_mse_glossy": m["ci95_mse_glossy_indirect"],
        "top_pixel_share_glossy": m["top_pixel_share_glossy_indirect"],
        "top_percent_share_glossy": m["top_percent_share_glossy_indirect"],
        "tail_index_glossy": m["tail_index_glossy_indirect"],
        "ci95_mse_glossy_perfect_trace": m["ci95_mse_glossy_perfect_trace"],
        "ci95_mse_diffuse": m["ci95_mse_diffuse_indirect"],
        "shading_s_per_frame": m["shading_s_per_frame"],
        "shading_compile_s": m["shading_compile_s"],
    }


def report_cell(
    result: dict,
    name: str,
    res: int,
    geo: int,
    c: dict,
    missing: str = "the cell was cached before this figure was recorded: rerun with --fresh",
) -> dict:
    """Put a cell's figures at the top level of ``result`` as ``{name}_r{res}_…`` and, by geometry
    resolution (issue 33's keys: the tracer's resolution is the geometry maps'), ``{name}_g{geo}_…`` (the
    last cell run at that geometry: the finest radiance). A figure the cell lacks is null, with the reason
    ``missing`` in ``skipped`` (a cell not run at all: ``c`` empty). Returns ``c``."""
    for f in CELL_FIGURES:
        for k in (f"{name}_r{res}_{f}", f"{name}_g{geo}_{f}"):
            result[k] = c.get(f)
            if f not in c:
                result["skipped"][k] = missing
            else:
                result["skipped"].pop(k, None)
    return c


def run_scene(key: str, args, result: dict) -> None:
    try:
        b = Bench(key, args)
    except SceneError as e:  # not on the scene path (it lives outside the repository) or unreadable
        result["skipped"][key] = f"{SCENES[key]['name']} not loaded: {type(e).__name__}: {e}"
        log(result["skipped"][key])
        return
    plan = b.plan
    cells = {}
    for grid in plan["grids"]:
        for res in plan["res"]:
            geo = cell_geometry_res(args, res)
            try:
                c = b.cell(grid, res, 0)
            except ResourceError as e:  # e.g. 1,024 probes at 1024² on a small machine: the other cells run
                log(f"{key} {grid} r{res}: not run: {e}")
                report_cell(result, f"{key}_{grid}", res, geo, {}, missing=f"not run: {e}")
                continue
            cells[f"{grid}_r{res}"] = report_cell(result, f"{key}_{grid}", res, geo, c)
    if key == "sponza" and args.no_auto:
        for f in AUTO_FIGURES:
            k = f"sponza_{AUTO}_g{cell_geometry_res(args, max(plan['res']))}_{f}"
            result[k], result["skipped"][k] = None, "--no-auto"
    elif key == "sponza":  # the automatic skeleton set, at the finest radiance resolution of the run
        res = max(plan["res"])
        cells[f"{AUTO}_r{res}"] = report_cell(
            result, f"{key}_{AUTO}", res, cell_geometry_res(args, res), b.cell(AUTO, res, 0)
        )
    result["cells"][key] = cells
    result["shared_steps_s"][key] = {str(s): v[3] for s, v in b.shared.items()}
    if key == "sponza":  # the 128-probe grid over seeds
        res = args.grid128_res
        seeds = range(args.first_seed, args.first_seed + args.seeds)
        runs = [b.cell("8x4x4", res, s, timed=s == seeds[0]) for s in seeds]
        g = np.array([r["mse_glossy"] for r in runs])
        result["sponza_grid128"] = {
            "res": res,
            "seeds": args.seeds,
            "first_seed": args.first_seed,
            "runs": runs,
        }
        result["sponza_grid128_glossy_over_black"] = runs[0]["glossy_over_black"]
        result["sponza_grid128_diffuse_over_black"] = runs[0]["diffuse_over_black"]
        result["sponza_grid128_mse_glossy_perfect_trace"] = runs[0]["mse_glossy_perfect_trace"]
        result["sponza_grid128_perfect_trace_over_black"] = runs[0]["perfect_trace_over_black"]
        result["sponza_grid128_perfect_trace_over_floor"] = runs[0]["perfect_trace_over_floor"]
        result["sponza_grid128_seed_cv"] = seed_cv(g)
        result["sponza_grid_seed_spread"] = result["sponza_grid128_seed_cv"]  # issue 33's name, same figure
        result["sponza_grid_seed_spread_over_black"] = seed_cv([x["glossy_over_black"] for x in runs])
        result["sponza_grid_seed_spread_ci95"] = cv_interval(g)
        result["sponza_grid_seed_spread_upper95"] = cv_upper95(g)  # decides "≤ 0.05" at 95 %
        # The bulk: the glossy MSE without its 1 % of pixels with the largest error (which make the raw
        # spread, experiments/README.md §2, "What the tail is made of"); and how heavy that tail is, each
        # seed's Hill index (``evaluate.tail_index``: below 2, no count of pixels or samples makes the raw
        # spread fall as 1/√n). Null for cells cached before the figure existed.
        # And the converged image's MSE (``evaluate.converged_sq_error``): no sample's own square in it, so
        # neither the reference's noise floor nor the square of a lone ray's sun glint (README §2).
        cached = "a cell was cached before this figure existed: rerun with --fresh"
        tail = [x.get("top_percent_share_glossy") for x in runs]
        conv = [x.get("mse_glossy_converged") for x in runs]
        for name, values in (
            ("bulk", None if None in tail else g * (1.0 - np.array(tail))),
            ("converged", None if None in conv else np.array(conv)),
        ):
            k = f"sponza_grid_seed_spread_{name}"
            if values is None:
                for figure in (k, f"{k}_ci95"):
                    result[figure], result["skipped"][figure] = None, cached
            else:
                result[k], result[f"{k}_ci95"] = seed_cv(values), cv_interval(values)
        hill, k = [x.get("tail_index_glossy") for x in runs], "sponza_grid_seed_spread_tail_index"
        result[k] = None if None in hill else hill
        if None in hill:
            result["skipped"][k] = cached
        if args.spread_fixed_rays:  # the same seeds, every one evaluated on the first seed's rays
            # the first seed on its own rays is the raw spread's first cell, not a second one
            first = seeds[0]
            on_first_rays = [runs[0]] + [
                b.cell("8x4x4", res, s, ray_seed=first, timed=False) for s in seeds[1:]
            ]
            fixed = np.array([c["mse_glossy"] for c in on_first_rays])
            result["sponza_grid_seed_spread_fixed_rays"] = seed_cv(fixed)
            result["sponza_grid_seed_spread_fixed_rays_ci95"] = cv_interval(fixed)
        else:
            for k in ("sponza_grid_seed_spread_fixed_rays", "sponza_grid_seed_spread_fixed_rays_ci95"):
                result[k], result["skipped"][k] = None, "--spread-fixed-rays not given"
    settings = b.settings()
    result["settings"][key] = settings | {"grids": plan["grids"], "res": plan["res"]}


def instrument_costs(args, result: dict, n: int = 128) -> None:
    """Issue 33's set-up costs at the geometry resolution G (``--geometry-res``, default 512): the geometry
    bake (one exact ray per texel; the radiance maps 4² of a constant, so that nothing else is timed) and
    ``make_tracer`` of ``n`` probes that are all usable — on a line through Sponza's atrium at a third of
    its height (the 8×4×4 grid has only 42 usable probes). Each is run 1 + ``COST_REPEATS`` times: the
    median of the warm runs is the figure (each warm run is listed beside it), the first minus it the
    compile time."""
    from probeplace._core import ProbeSet
    from probeplace.probes import BakeConfig, TraceConfig, bake_probes, make_tracer, tracer_bytes
    from probeplace.render import default_caster
    from probeplace.scene import load_scene

    geo = args.geometry_res or 512
    try:
        scene = load_scene(SCENES["sponza"]["name"])
    except SceneError as e:  # not on the scene path (it lives outside the repository) or unreadable
        result["skipped"]["instrument_costs"] = f"crytek_sponza not loaded: {type(e).__name__}: {e}"
        return
    caster = default_caster(scene)
    pos = atrium_line(scene, n)
    probes = ProbeSet(pos_world=jnp.asarray(pos, jnp.float32), active=jnp.ones(n, bool))
    const = lambda o, d, k: (np.full((o.shape[0], 3), 0.5, np.float32), np.zeros((o.shape[0], 3), np.float32))
    cfg = BakeConfig(
        radiance_res=4, geometry_res=geo, irradiance_res=4, moments_res=4, n_sub=1, progress=False
    )
    times = {"bake": [], "tracer": []}
    for _ in range(1 + COST_REPEATS):
        t0 = time.perf_counter()
        lf = jax.block_until_ready(
            bake_probes(scene, probes, caster=caster, radiance_fn=const, key=jax.random.key(0), config=cfg)
        )
        times["bake"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        tc = TraceConfig(subdivide=args.subdivide)
        tr = jax.block_until_ready(make_tracer(lf, scene.bounds, config=tc))
        times["tracer"].append(time.perf_counter() - t0)
        del tr
    usable = int((np.asarray(lf.active) & ~np.asarray(lf.inside)).sum())
    for name, key in (("bake", f"geometry_bake_{n}_g{geo}"), ("tracer", f"make_tracer_{n}_g{geo}")):
        warm = float(np.median(times[name][1:]))  # the machines are shared: the median of the warm runs
        result[f"{key}_s"] = warm
        result[f"{key}_warm_runs_s"] = times[name][1:]
        result[f"{key}_compile_s"] = max(times[name][0] - warm, 0.0)
    result[f"make_tracer_{n}_g{geo}_usable"] = usable
    result[f"tracer_mb_per_probe_g{geo}"] = tracer_bytes(1, geo, args.subdivide) / 1e6
    mb = result[f"tracer_mb_per_probe_g{geo}"]
    bake_s, tracer_s = result[f"geometry_bake_{n}_g{geo}_s"], result[f"make_tracer_{n}_g{geo}_s"]
    log(
        f"instrument costs at {geo}²: geometry bake {bake_s:.1f} s, make_tracer {tracer_s:.1f} s (medians of "
        f"{COST_REPEATS} warm runs; {usable} of {n} usable), {mb:.1f} MB a probe"
    )


#: Targets "at most" whose estimate comes from few samples, with the key of its one-sided 95 % upper bound:
#: an estimate under the target counts as met only when the bound is too.
UPPER_BOUNDS = dict.fromkeys(
    ("sponza_grid_seed_spread", "sponza_grid128_seed_cv"), "sponza_grid_seed_spread_upper95"
)


def targets(result: dict) -> dict:
    """Each target's value and whether it is met: null when the value is, or when an estimate meets an
    "at most" target that its one-sided 95 % bound (``UPPER_BOUNDS``) does not (undecided: ``why``)."""
    out = {}
    for k, (t, op) in TARGETS.items():
        v = result.get(k)
        met = None if v is None else {"<=": v <= t, ">=": v >= t, "<": v < t}[op]
        out[k] = {"value": v, "target": f"{op} {t}", "met": met}
        bound = result.get(UPPER_BOUNDS[k]) if k in UPPER_BOUNDS else None
        if met and bound is not None:
            out[k]["upper95"] = bound
            if bound > t:
                out[k]["met"] = None
                out[k]["why"] = (
                    f"undecided: the one-sided 95 % bound {bound:.3g} is above {t}; run more seeds"
                )
    return out


def scene_values(values: list[str] | None, key: str, kind) -> list | None:
    """``--grids`` / ``--res`` / ``--bake-spp`` / ``--glossy-spp`` / ``--glossy-ref-spp`` values for scene
    ``key``: plain values apply to every scene, ``scene:value`` to that scene only (e.g. ``--res cornell:64
    sponza:16``)."""
    if not values:
        return None
    out = [kind(v.split(":", 1)[1]) for v in values if v.startswith(f"{key}:")]
    out += [kind(v) for v in values if ":" not in v]
    return out or None


def cell_geometry_res(args, res: int) -> int:
    """The geometry maps' resolution of a cell with radiance maps at ``res``."""
    return max(res, args.geometry_res) if args.geometry_res else args.geometry_factor * res


def scene_plan(args, key: str) -> dict:
    """Scene ``key``'s grids, radiance resolutions, evaluation image and sample counts: the run's plan
    (:data:`PLANS`) with the per-scene options given on the command line put over it."""
    plan = dict(PLANS[args.plan][key])
    for name, kind in (("grids", str), ("res", int)):
        plan[name] = scene_values(getattr(args, name), key, kind) or plan[name]
    for name in ("bake_spp", "glossy_spp", "glossy_ref_spp"):
        plan[name] = (scene_values(getattr(args, name), key, int) or [plan[name]])[0]
    size = scene_values(args.eval_size, key, str)
    if size:  # e.g. sponza:128x96: the evaluation image's pixels (the seed spread's sample, issue 33)
        w, _, h = size[0].partition("x")
        plan["eval"] = (int(w), int(h))
    return plan


def plan_defaults(name: str) -> str:
    """Each plan's value of ``name`` for the options' help, read from :data:`PLANS` (e.g. ``papers 32,
    sweep 8, quick 4``; per scene where the scenes differ; a geometry resolution of None is the factor's)."""

    def shown(v) -> str:
        if v is None:
            return "--geometry-factor × radiance"
        return "x".join(map(str, v)) if isinstance(v, tuple) else str(v)

    def value(plan: dict) -> str:
        if name in plan:
            return shown(plan[name])
        per = {scene: shown(plan[scene][name]) for scene in SCENES}
        return (
            per.popitem()[1]
            if len(set(per.values())) == 1
            else " / ".join(f"{k} {v}" for k, v in per.items())
        )

    return ", ".join(f"{p} {value(plan)}" for p, plan in PLANS.items())


def parse_args(argv=None) -> argparse.Namespace:
    """The benchmark's options, the run-wide ones its plan's where not given (also what ``paper_check.py``
    builds its cells with)."""
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--plan",
        choices=list(PLANS),
        default=None,
        help="what to measure where the options below do not say (PLANS): papers (default; issue 33's "
        "cells at 512² geometry and the counts that decide its targets, about 2 h 15 min on 2 cores from an "
        "empty cache, resumable), sweep (issue 16's grids × radiance resolutions) or quick",
    )
    ap.add_argument("--quick", action="store_true", help="--plan quick: small grids, resolutions and images")
    ap.add_argument("--scenes", nargs="+", default=["cornell", "sponza"], choices=list(SCENES))
    ap.add_argument(
        "--grids", nargs="+", default=None, help="grids, e.g. 4x4x4 (all scenes) or sponza:16x8x8"
    )
    ap.add_argument(
        "--res", nargs="+", default=None, help="map resolutions, e.g. 64 (all scenes) or cornell:64"
    )
    ap.add_argument(
        "--bake-spp",
        nargs="+",
        default=None,
        help=f"paths per texel ray, e.g. 8 (all scenes) or cornell:32 (default the plan's: "
        f"{plan_defaults('bake_spp')})",
    )
    ap.add_argument("--n-sub", type=int, default=1, help="n_sub² rays per radiance texel")
    ap.add_argument(
        "--texel-rays",
        default="surfel",
        choices=TEXEL_RAYS,
        help="where a radiance texel's rays leave (probes.BakeConfig.texel_rays): along its surfel's "
        "direction (default here: with one ray a texel, this benchmark's --n-sub 1, it read better on every "
        "Sponza grid cell and seed, issue 33) or jittered over the texel (the library's default)",
    )
    ap.add_argument("--max-depth", type=int, default=4, help="evaluation path depth (bake: − 1)")
    ap.add_argument(
        "--eval-spp",
        type=int,
        default=None,
        help=f"reference paths/pixel (default the plan's: {plan_defaults('eval_spp')})",
    )
    ap.add_argument(
        "--glossy-spp",
        nargs="+",
        default=None,
        help="glossy rays per pixel, e.g. 16 (all scenes) or sponza:512 (default the plan's: "
        f"{plan_defaults('glossy_spp')}; the seeds' raw spread falls as the rays grow: on Sponza 8x4x4 at "
        "512² geometry, 512 rays at 4 reference paths a ray read 3.7 %% and 4.8 %% on two samples of thirty "
        "seeds at 32 bake paths a texel, for 156-200 s of shading a frame on 2 cores; "
        "experiments/README.md §2)",
    )
    ap.add_argument(
        "--glossy-ref-spp",
        nargs="+",
        default=None,
        help="CRN reference paths per glossy ray, e.g. 4 (all scenes) or sponza:16 (default the plan's: "
        f"{plan_defaults('glossy_ref_spp')}; Cornell's target divides by this reference's noise floor)",
    )
    ap.add_argument(
        "--eval-size",
        nargs="+",
        default=None,
        help=f"evaluation image size, e.g. sponza:128x96 (default the plan's: {plan_defaults('eval')})",
    )
    ap.add_argument("--timing-repeats", type=int, default=1)
    ap.add_argument(
        "--seeds",
        type=int,
        default=None,
        help=f"bake + evaluation seeds of the 128-probe grid (default the plan's: {plan_defaults('seeds')})",
    )
    ap.add_argument(
        "--first-seed",
        type=int,
        default=0,
        help="the 128-probe grid's seeds start here (default 0): a fresh sample, fixed before it is looked "
        "at, for a spread that seeds 0 … N − 1 left undecided (experiments/README.md §2)",
    )
    ap.add_argument(
        "--spread-fixed-rays",
        action="store_true",
        help="also run the 128-probe grid's seeds on the first seed's evaluation rays (the bake and "
        "reference paths still each seed's): sponza_grid_seed_spread_fixed_rays, the spread the sample "
        "counts control",
    )
    ap.add_argument(
        "--grid128-res",
        type=int,
        default=None,
        help=f"its map resolution (default the plan's: {plan_defaults('grid128_res')})",
    )
    ap.add_argument("--fresh", action="store_true", help="recompute cached cells")
    ap.add_argument(
        "--no-auto",
        action="store_true",
        help="skip Sponza's cell of the automatic skeleton set (placement.place(method='skeleton', "
        "budget='auto'); minutes to place)",
    )
    ap.add_argument(
        "--no-costs",
        action="store_true",
        help="skip the set-up costs of 128 usable probes (geometry bake, make_tracer; issue 33)",
    )
    ap.add_argument(
        "--backend",
        default="jax",
        choices=["jax", "mitsuba"],
        help="path tracer of the bakes and the references (render.RenderConfig.backend)",
    )
    ap.add_argument(
        "--geometry-res",
        type=int,
        default=None,
        help="geometry maps at least this fine (BakeConfig.geometry_res; default the plan's: "
        f"{plan_defaults('geometry_res')})",
    )
    ap.add_argument(
        "--trace-engine",
        default="wavefront",
        choices=["wavefront", "per_ray"],
        help="light-field tracer engine of the shading (the runner's eval.trace_engine; per_ray: the simple "
        "reference, much slower at high resolution)",
    )
    ap.add_argument(
        "--subdivide",
        type=int,
        default=2,
        choices=[1, 2],
        help="light-field tracer march cells per geometry texel and axis (probes.TraceConfig.subdivide)",
    )
    ap.add_argument(
        "--fallback-radius",
        type=float,
        default=None,
        help="probe spacings within which the tracer's fallback takes a probe (probes.TraceConfig."
        "fallback_radius; default the tracer's own, 2.5)",
    )
    ap.add_argument(
        "--geometry-factor",
        type=int,
        default=2,
        choices=[1, 2, 4],
        help="geometry maps this many times finer than the radiance maps (default 2: on Sponza 16x8x8 at "
        "64², 128² geometry cut the glossy MSE from 1.79 to 1.05x black and the trace excess from 1.18 to "
        "0.34; 1 = McGuire's single resolution)",
    )
    args = ap.parse_args(argv)
    if args.fallback_radius is not None:  # the tracer's own declared bound, refused before any work
        from probeplace.probes import TraceConfig

        try:
            TraceConfig(fallback_radius=args.fallback_radius)
        except ConfigError as e:
            ap.error(f"--fallback-radius: {e}")
    if args.quick and args.plan not in (None, "quick"):
        ap.error(f"--quick is --plan quick: give one of --quick and --plan {args.plan}")
    args.plan = "quick" if args.quick else args.plan or "papers"
    for name in RUN_PLANNED:
        if getattr(args, name) is None:
            setattr(args, name, PLANS[args.plan][name])
    if args.seeds < 1:  # the 8×4×4 grid's figures are its first seed's
        ap.error(f"--seeds {args.seeds}: want at least 1 (2 or more for the seeds' spread)")
    if args.first_seed < 0:
        ap.error(f"--first-seed {args.first_seed}: want 0 or more")
    return args


def main(argv=None) -> dict:
    args = parse_args(argv)
    setup_scene_path()
    t_all = time.perf_counter()
    result: dict = {
        "env": env_info(),
        "plan": args.plan,
        "cells": {},
        "settings": {},
        "skipped": {},
        "shared_steps_s": {},
    }
    for key in args.scenes:
        run_scene(key, args, result)
    if "sponza" in args.scenes and not args.no_costs:
        instrument_costs(args, result)
    for k, why in NOT_MEASURED.items():
        result[k] = None
        result["skipped"][k] = why
    for k in (*TARGETS, *REPORTED):
        if k not in result:
            result[k] = None
            result["skipped"].setdefault(
                k, "cell not run (--plan, --grids/--res/--geometry-res or the scene is absent)"
            )
    result["targets"] = targets(result)
    result["total_s"] = time.perf_counter() - t_all
    # A run with finer geometry maps is a variant: written beside the main figures, not over them.
    write_result(f"convergence_geometry{args.geometry_res}" if args.geometry_res else "convergence", result)
    return result


if __name__ == "__main__":
    main()
