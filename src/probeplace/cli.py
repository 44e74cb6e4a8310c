"""The ``probeplace`` command. Subcommands grow with the pipeline stages."""

from __future__ import annotations

import argparse
import logging
import sys

from ._core import ProbeplaceError


def _cmd_scenes(args: argparse.Namespace) -> int:
    from .scene import list_scenes

    for entry in list_scenes():
        print(f"{entry.name:<24} {entry.kind:<9} {entry.source}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .demo import load_demo_config, run_demo

    config = load_demo_config(args.config) if args.config else None
    return run_demo(out_dir=args.out, config=config)


# --- export (issue 8) ---
def _cmd_export(args: argparse.Namespace) -> int:
    import dataclasses

    from .export import export_probes, read_probes

    probes = read_probes(args.probes, sh_source=args.sh_source)
    if args.probe_set:  # method, units and config of the placement, for a baked .npz
        placed = read_probes(args.probe_set)
        if placed.n != probes.n:
            raise ProbeplaceError(f"--probe-set has {placed.n} probes, {args.probes} has {probes.n}")
        probes = dataclasses.replace(
            probes, method=placed.method, units_m=placed.units_m, metadata=placed.metadata
        )
    opts: dict = {}
    if args.format in ("gltf", "unity", "godot") and args.to_metres:
        opts["to_metres"] = True
    if args.format == "threev8":
        opts["base_cells"] = args.base_cells
    if args.format == "ddgi":
        opts.update(irradiance_res=args.irradiance_res, distance_res=args.distance_res, light=args.sh_source)
    for path in export_probes(probes, args.format, args.out, **opts):
        print(path)
    return 0


def _add_export_parser(sub) -> None:
    from .export._registry import FORMATS  # NumPy only: keeps `probeplace --help` light

    e = sub.add_parser(
        "export",
        help="write a probe set to an engine format (docs/export.md)",
        description="Export probes: " + "; ".join(f"{k}: {f.summary}" for k, f in FORMATS.items()),
    )
    e.add_argument("probes", help="ProbeSet .json (probeplace place), baked .npz, or an exported file")
    e.add_argument("--format", required=True, choices=sorted(FORMATS), help="output format")
    e.add_argument("--out", required=True, help="output file (ddgi: the .json sidecar)")
    e.add_argument("--probe-set", help="ProbeSet .json giving method/units/config when PROBES is a .npz")
    e.add_argument(
        "--sh-source",
        choices=("total", "reflected"),
        default="total",
        help="light in SH / DDGI irradiance from a .npz: reflected+emitted (total) or reflected only",
    )
    e.add_argument("--to-metres", action="store_true", help="gltf/unity/godot: root scale = units_m")
    e.add_argument("--base-cells", type=int, default=2, help="threev8: base cells on the longest axis")
    e.add_argument("--irradiance-res", type=int, default=6, help="ddgi: interior irradiance tile size")
    e.add_argument("--distance-res", type=int, default=14, help="ddgi: interior distance tile size")
    e.set_defaults(func=_cmd_export)


# --- place (placement helper) ---
def _cmd_place(args: argparse.Namespace) -> int:
    """Place probes (``placement.place``), write the probe set with its record and the top view."""
    from pathlib import Path

    from ._core import save_probe_set
    from .placement import place, save_top_view
    from .scene import load_scene, scene_overrides_from_args

    scene = load_scene(args.scene, overrides=scene_overrides_from_args(args))
    budget = "auto" if args.budget == "auto" else _positive_int(args.budget)
    if args.memory_budget is not None:
        from .placement import count_for_memory
        from .probes import BakeConfig, probe_bytes

        if budget != "auto":
            raise ProbeplaceError("give --budget or --memory-budget, not both")
        bake = BakeConfig(radiance_res=args.radiance_res, geometry_res=args.geometry_res)
        budget = count_for_memory(args.memory_budget, probe_bytes(scene, bake))
    refiner = None if args.refiner == "none" else args.refiner
    region = (
        None if args.height_band is None else {"height": _number_list(args.height_band, 2, "--height-band")}
    )
    res = place(
        scene,
        method=args.method,
        budget=budget,
        refiner=refiner,
        objective=args.objective,
        seed=args.seed,
        target=args.target,
        options=_place_options(args.option),
        clearance=args.clearance,
        region=region,
    )
    out = Path(args.out)
    save_probe_set(out, res.probes, units_m=scene.unit_m, metadata={**res.metadata, "scene": args.scene})
    png = Path(args.png) if args.png else out.with_suffix(".png")
    summary = f"{res.n_probes} probes, coverage {res.coverage:.4f}"
    save_top_view(scene, res.probes.pos_world, png, title=f"{args.scene}: {summary}")
    print(f"{summary}, {res.timings['total_s']:.1f} s -> {out}, {png}")
    return 0


def _place_options(items: list[str]) -> dict:
    """``KEY=VALUE`` pairs of ``place --option``; values are Python literals (``3,3,3``: a tuple) or text."""
    import ast

    out = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ProbeplaceError(f"--option must be KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = ast.literal_eval(text.strip())
        except (ValueError, SyntaxError):
            out[key.strip()] = text.strip()
    return out


def _number_list(text: str, n: int, flag: str) -> list[float]:
    """``n`` comma-separated numbers of ``flag``."""
    try:
        values = [float(x) for x in text.split(",")]
    except ValueError:
        values = []
    if len(values) != n:
        raise ProbeplaceError(f"{flag} must be {n} comma-separated numbers, got {text!r}")
    return values


def _positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise ProbeplaceError(f"--budget must be 'auto' or a positive integer, got {text!r}")
    return n


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = argparse.ArgumentParser(prog="probeplace", description=__doc__)
    p.add_argument("--version", action="version", version=f"probeplace {__version__}")
    p.add_argument("-v", "--verbose", action="store_true", help="log at INFO level")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("scenes", help="list built-in scenes and scenes found on the search path")
    s.set_defaults(func=_cmd_scenes)
    d = sub.add_parser("demo", help="run the default experiment on the built-in Cornell box")
    d.add_argument("--out", default="results/demo", help="output folder (default: results/demo)")
    d.add_argument("--config", help="YAML config (default: built-in values, as in configs/demo.yaml)")
    d.set_defaults(func=_cmd_demo)
    _add_place_parser(sub)
    _add_export_parser(sub)
    from .evaluate._cli import add_parser as _add_evaluate  # --- evaluate (issue 4) ---

    _add_evaluate(sub)
    return p


def _add_place_parser(sub) -> None:
    """``probeplace place``: methods and refiners from their registries."""
    from .placement import OBJECTIVES, REFINERS, get_method, method_names
    from .scene import add_scene_options

    pl = sub.add_parser("place", help="place probes in a scene and write a ProbeSet JSON file + top view")
    pl.add_argument("scene", help="scene name or file (see `probeplace scenes`)")
    add_scene_options(pl)
    pl.add_argument(
        "--method",
        default="skeleton+medial",
        choices=method_names(),
        help="; ".join(f"{m}: {get_method(m).label}" for m in method_names()),
    )
    pl.add_argument(
        "-o",
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="baseline option, repeatable (e.g. -o dims=8,8,8 -o inside=relocate; -o levels=2; "
        "-o dense_probes=512 -o tolerance=0.05); see docs/baselines.md",
    )
    pl.add_argument(
        "--budget", default="auto", help="'auto' (fewest probes to the target) or the exact probe count"
    )
    pl.add_argument(
        "--memory-budget",
        default=None,
        metavar="SIZE",
        help="instead of --budget: the most probes whose baked maps fit in SIZE (e.g. 64MiB) at "
        "--radiance-res / --geometry-res",
    )
    pl.add_argument("--radiance-res", type=int, default=None, help="bake radiance resolution (memory budget)")
    pl.add_argument("--geometry-res", type=int, default=None, help="bake geometry resolution (memory budget)")
    pl.add_argument(
        "--clearance",
        type=float,
        default=None,
        help="smallest probe-to-geometry distance, scene units (default: from the scene's size); nearer "
        "probes are relocated",
    )
    pl.add_argument(
        "--height-band", default=None, metavar="MIN,MAX", help="keep probes this high above the floor"
    )
    pl.add_argument("--refiner", default="none", help=", ".join(("none", *REFINERS)))
    pl.add_argument("--objective", default="coverage", choices=OBJECTIVES)
    pl.add_argument("--target", type=float, default=1.0, help="coverage target (default 1.0)")
    pl.add_argument("--seed", type=int, default=0)
    pl.add_argument("--out", default="probes.json", help="ProbeSet file (default probes.json)")
    pl.add_argument("--png", default=None, help="top view PNG (default: --out with .png)")
    pl.set_defaults(func=_cmd_place)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(message)s"
    )
    try:
        return int(args.func(args) or 0)
    except ProbeplaceError as e:  # user-facing errors: one clear line, no traceback
        print(f"probeplace: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
