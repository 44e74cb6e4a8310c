"""The ``probeplace`` command. Subcommands grow with the pipeline stages."""

from __future__ import annotations

import argparse
import logging
import os
import sys

from .._core import ProbeplaceError, RunFiles
from . import _options


def _cmd_scenes(args: argparse.Namespace) -> int:
    """One line per scene; a file named like a built-in is marked: the name loads the built-in. With a
    scene name or file: what it resolved to (:func:`_show_scene`)."""
    if args.name is not None:
        return _show_scene(args)
    if args.sun is not None or args.sky is not None or args.camera:
        raise ProbeplaceError("--sun, --sky and --camera need a scene: probeplace scenes NAME --sun ...")
    from ..scene import list_scenes

    entries = list_scenes()
    builtin = {e.name for e in entries if e.kind == "builtin"}
    for entry in entries:
        note = ""
        if entry.kind == "file" and entry.name in builtin:
            note = "  (shadowed: the name loads the built-in; load this file by its path)"
        print(f"{entry.name:<24} {entry.kind:<9} {entry.source}{note}")
    return 0


def _show_scene(args: argparse.Namespace) -> int:
    """Load one scene (its sidecar, KNOWN_SCENES and --sun/--sky/--camera applied) and print what it
    resolved to: where it came from, units, bounds, triangles, sun, sky, emitters, cameras. Loading a scene
    imports JAX (a Scene is an Equinox module); nothing is compiled."""
    from pathlib import Path

    from ..scene import (
        BUILTIN_SCENES,
        find_scene_file,
        load_scene,
        looks_like_path,
        scene_config_layers,
        scene_summary,
    )
    from ._scene_options import scene_overrides_from_args

    overrides = scene_overrides_from_args(args)  # checked before the scene is read
    scene = load_scene(args.name, overrides=overrides or None)
    s = scene_summary(scene)
    path = Path(args.name) if looks_like_path(args.name) else None
    if path is None and args.name not in BUILTIN_SCENES:
        path = find_scene_file(args.name)

    def vec(v) -> str:  # float32 noise below 1e-9 of the vector's size printed as 0
        big = max((abs(x) for x in v), default=0.0)
        return "(" + ", ".join(f"{x if abs(x) > 1e-9 * big else 0.0:.6g}" for x in v) + ")"

    lines = [("scene", f"{s['name']} ({'built-in' if path is None else path})")]
    if path is not None:
        layers = [layer.source for layer in scene_config_layers(path, overrides or None)]
        lines.append(("config", " < ".join(layers) if layers else "none (the file alone)"))
    elif overrides:
        lines.append(("config", "overrides"))
    lo, hi = s["bounds"]
    lines += [
        ("units", f"{s['unit_m']:g} m per unit"),
        ("bounds", f"{vec(lo)} .. {vec(hi)}, size {vec([b - a for a, b in zip(lo, hi, strict=True)])}"),
        ("triangles", str(s["triangles"])),
    ]
    sun = s["sun"]
    if sun is None:
        lines.append(("sun", "none"))
    else:
        lines.append(
            (
                "sun",
                f"direction {vec(sun['direction'])} (azimuth {sun['azimuth_deg']:.6g}°, elevation "
                f"{sun['elevation_deg']:.6g}°), irradiance {vec(sun['irradiance'])}, radiance "
                f"{vec(sun['radiance'])}, angular diameter {sun['angular_diameter_deg']:.6g}°",
            )
        )
    lines.append(("sky", "none" if s["sky"] is None else f"radiance {vec(s['sky'])}"))
    if not s["emitters"]:
        lines.append(("emitters", "none"))
    for name, e in s["emitters"].items():
        lines.append(("emitter", f"{name}: radiance {vec(e['radiance'])}, {e['triangles']} triangles"))
    for name, c in s["cameras"].items():
        lines.append(
            (
                "camera",
                f"{name}: position {vec(c['position'])}, look_at {vec(c['look_at'])}, up {vec(c['up'])}, "
                f"fov {c['fov_deg']:.6g}°",
            )
        )
    for key, text in lines:
        print(f"{key:<10} {text}")
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .._core.runtime import check_writable_folder
    from ..demo import load_demo_config, run_demo

    config = load_demo_config(args.config) if args.config else None
    check_writable_folder(args.out, "--out")
    return run_demo(out_dir=args.out, config=config)


# --- export (issue 8) ---
def _cmd_export(args: argparse.Namespace) -> int:
    from ..export import export_probes

    probes = _export_input(args)
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


def _export_input(args: argparse.Namespace):
    """The probes ``export`` writes, every input and the output checked first: the output can be
    written, a ``.npz`` is a NumPy archive, the set has active probes."""
    import dataclasses

    from .._core.runtime import check_npz_archive, check_writable_file
    from ..export import read_probes

    check_writable_file(args.out, "--out")
    for flag, path in (("PROBES", args.probes), ("--probe-set", args.probe_set)):
        if path and str(path).endswith(".npz"):
            check_npz_archive(path, flag)
    probes = read_probes(args.probes, sh_source=args.sh_source)
    if probes.n == 0 or not bool(probes.active.any()):
        raise ProbeplaceError(f"{args.probes}: the probe set has no active probes; nothing to export")
    if args.probe_set:  # method, units and config of the placement, for a baked .npz
        placed = read_probes(args.probe_set)
        if placed.n != probes.n:
            raise ProbeplaceError(f"--probe-set has {placed.n} probes, {args.probes} has {probes.n}")
        probes = dataclasses.replace(
            probes, method=placed.method, units_m=placed.units_m, metadata=placed.metadata
        )
    return probes


def _fill_export_parser(e: argparse.ArgumentParser) -> None:
    from ..export import FORMATS  # NumPy only

    e.description = "Export probes: " + "; ".join(f"{k}: {f.summary}" for k, f in FORMATS.items())
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
    """Place probes (``placement.place``), write the top view, each probe's part in the coverage
    (``<out stem>.coverage.npz``, for ``probeplace view``) and then the probe set (last: a probe set on
    disk means the command finished)."""
    from .._core.files import naming_the_file
    from .._core.runtime import check_writable_file
    from ..pipeline import write_placement
    from ..placement import FitnessConfig, place
    from ..scene import load_scene
    from ._scene_options import scene_overrides_from_args

    out, png, settings = _checked_place_args(args)
    # vardis path-traces its dense probes: a scene without light is refused by the load, naming the method
    needs_light = "--method vardis" if args.method == "vardis" else False
    scene = load_scene(args.scene, overrides=scene_overrides_from_args(args), require_light=needs_light)
    budget = _budget_that_fits(args, scene, settings["budget"])
    if budget != "auto":  # room for the probe set: ≥ ~32 bytes a probe (3 numbers, a flag, a line each)
        check_writable_file(out, "--out", size=32 * budget)
    res = place(
        scene,
        method=args.method,
        options=_place_options(args.option),
        config=FitnessConfig(coverage=args.coverage),
        **(settings | {"budget": budget}),
    )
    summary = f"{res.n_probes} probes, coverage {res.coverage:.4f}"
    write_placement(  # the probe set last; interrupted or failed: no top view or detail without it
        scene,
        res,
        out,
        png=png,
        title=f"{args.scene}: {summary}",
        metadata={**res.metadata, "scene": args.scene},
        on_error=naming_the_file,
    )
    print(f"{summary}, {res.timings['total_s']:.1f} s -> {out}, {png}")
    return 0


def _budget_that_fits(args: argparse.Namespace, scene, budget):
    """The probe count of ``--memory-budget``, or ``--budget`` checked against memory (issue 31: a count
    whose baked maps cannot fit ran for minutes first), both at the bake settings of ``--radiance-res``
    and ``--geometry-res`` (else the scene's default); ``auto`` unchanged. Before any placement."""
    if budget == "auto" and args.memory_budget is None:
        return budget
    from ..pipeline import probe_budget
    from ..placement import check_probe_count
    from ..probes import BakeConfig, default_radiance_res, probe_bytes

    res = args.radiance_res or default_radiance_res(scene)
    bake = BakeConfig(radiance_res=res, geometry_res=args.geometry_res or res)
    if args.memory_budget is not None:
        return probe_budget(scene, budget, args.memory_budget, bake)
    settings = f"radiance_res={bake.radiance_res}, geometry_res={bake.geometry_res}"
    fix = "lower --budget, or give --memory-budget SIZE for the most probes that fit"
    check_probe_count(budget, probe_bytes(scene, bake), f"--budget {budget}", settings, fix)
    return budget


def _checked_place_args(args: argparse.Namespace):
    """Every ``place`` option checked before the scene is loaded: (out, png, settings), the settings the
    ``placement.PlaceRequest`` fields of the flags and ``--height-band``'s region, checked by it."""
    from pathlib import Path

    from .._core.runtime import check_writable_file, rekeyed
    from ..placement import PlaceRequest, get_method, parse_bytes

    region = (
        None if args.height_band is None else {"height": _number_list(args.height_band, 2, "--height-band")}
    )
    settings = {name: getattr(args, name) for name in PlaceRequest.settings(scalar=True)} | {"region": region}
    rekeyed(PlaceRequest, settings, {k: _options.flag(k) for k in settings})  # "--budget: must be ..."
    if args.memory_budget is not None:
        if settings["budget"] != "auto":
            raise ProbeplaceError("give --budget or --memory-budget, not both")
        from .._core import check_memory

        # the maps of the probes filling it must fit in memory themselves (issue 31: "1TB")
        check_memory(
            parse_bytes(args.memory_budget),
            f"--memory-budget {args.memory_budget}: baking the probes that fill it",
            "give a SIZE under the limit",
        )
        from ..probes import BakeConfig

        BakeConfig(radiance_res=args.radiance_res, geometry_res=args.geometry_res)
    get_method(args.method).parse_options(_place_options(args.option))  # unknown or bad options
    out = check_writable_file(args.out, "--out")
    png = check_writable_file(args.png or out.with_suffix(".png"), "--png")
    return Path(out), Path(png), settings


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


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Each option's help ends with its default, unless the default is ``None``, ``False`` or empty (the
    help says what happens then) or the help already names it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        d = action.default
        if d is None or d is False or d is argparse.SUPPRESS or d == [] or "default" in text:
            return text
        return super()._get_help_string(action)


def _add_log_options(parser: argparse.ArgumentParser, default) -> None:
    """``-v``/``--verbose`` and ``-q``/``--quiet``, before the subcommand (``default`` False) or after it
    (``default`` SUPPRESS: a subcommand's parser then never overwrites what was given before it)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", action="store_true", default=default, help="log at INFO level")
    group.add_argument(
        "-q", "--quiet", action="store_true", default=default, help="log warnings only; no progress bars"
    )


class _Subcommand(argparse.ArgumentParser):
    """A subcommand's parser whose options are added on first use (parsing it, its help), so that building
    the whole parser imports no stage: ``--help``, ``--version``, ``export``, ``scenes`` and ``cache`` load
    no JAX (issue 32). ``_fill(parser)`` adds the options; ``_choice`` is its line in the top-level help."""

    _fill = None
    _choice = None

    def filled(self) -> _Subcommand:
        """This parser with its options added (once) and the conventions every subcommand follows."""
        fill, self._fill = self._fill, None
        if fill is not None:
            fill(self)
            self.formatter_class = _HelpFormatter  # defaults in its help, -v/-q after its name
            if self.description is None:
                self.description = self._choice.help
            _add_log_options(self, argparse.SUPPRESS)
        return self

    def parse_known_args(self, args=None, namespace=None):
        return super(_Subcommand, self.filled()).parse_known_args(args, namespace)

    def format_help(self) -> str:
        return super(_Subcommand, self.filled()).format_help()

    def format_usage(self) -> str:
        return super(_Subcommand, self.filled()).format_usage()


class _Into:
    """The ``sub`` a stage's ``add_parser(sub)`` registers on when its subcommand is filled lazily: its
    ``sub.add_parser(name, help=..., **kwargs)`` returns the parser already listed under ``name``."""

    def __init__(self, parser: _Subcommand):
        self.parser = parser

    def add_parser(self, name: str, help: str | None = None, **kwargs) -> _Subcommand:
        assert name == self.parser.prog.split()[-1], (name, self.parser.prog)
        if help is not None:
            self.parser._choice.help = help
        for key, value in kwargs.items():  # description, epilog, formatter_class
            setattr(self.parser, key, value)
        return self.parser


class _Main(argparse.ArgumentParser):
    """The top-level parser: its help first fills the subcommands whose line it cannot know without
    loading them (none today: each line is given to ``_lazy``, so ``probeplace --help`` imports no stage;
    filling ``evaluate`` imports ``probes`` for its tracer options)."""

    def format_help(self) -> str:
        for parser in self._subparsers._group_actions[0].choices.values():
            if parser._choice.help is None:
                parser.filled()
        return super().format_help()


def _lazy(sub, name: str, help: str | None, fill) -> None:
    """List subcommand ``name`` (``help``: its line; None: ``fill`` sets it) whose options ``fill(parser)``
    adds on first use."""
    parser = sub.add_parser(name, help=help)
    parser._fill, parser._choice = fill, sub._choices_actions[-1]


def build_parser(lazy: bool = True) -> argparse.ArgumentParser:
    """The ``probeplace`` parser; each subcommand's options load on first use (``lazy=False``: all now,
    for code that inspects them)."""
    from .. import __version__

    p = _Main(prog="probeplace", description=__doc__, formatter_class=_HelpFormatter)
    p.add_argument("--version", action="version", version=f"probeplace {__version__}")
    _add_log_options(p, False)
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Subcommand)
    _lazy(
        sub,
        "scenes",
        "list built-in scenes and scenes found on the search path; with NAME, what that scene's sidecar "
        "resolved to (lights, cameras, units, bounds, triangles)",
        _fill_scenes_parser,
    )
    _lazy(
        sub,
        "demo",
        "the stage tour on the built-in Cornell box: scene, SDF, surface samples, G-buffer, reference "
        "render, automatic placement, bake and export, into one folder (`make demo` instead runs the "
        "cornell_comparison experiment)",
        _fill_demo_parser,
    )
    _lazy(sub, "place", _PLACE_HELP, _fill_place_parser)
    _lazy(sub, "export", _EXPORT_HELP, _fill_export_parser)
    _lazy(sub, "evaluate", _EVALUATE_HELP, _fill_evaluate_parser)  # --- evaluate (issue 4) ---
    _lazy(sub, "view", _VIEW_HELP, _fill_view_parser)  # --- view (issue 36) ---
    from ._cache import add_parser as _add_cache  # --- cache (issue 32); imports no JAX ---

    _add_cache(p, sub)
    cache = sub.choices["cache"]
    cache._fill, cache._choice = (lambda parser: None), sub._choices_actions[-1]
    if not lazy:
        for parser in sub.choices.values():
            parser.filled()
    return p


def _fill_scenes_parser(s: argparse.ArgumentParser) -> None:
    s.add_argument(
        "name",
        nargs="?",
        default=None,
        metavar="NAME",
        help="a scene name or file: load it (sidecar, KNOWN_SCENES and --sun/--sky/--camera applied) and "
        "print its lights, cameras, units, bounds and triangle count",
    )
    from ._scene_options import add_scene_options

    add_scene_options(s)
    s.set_defaults(func=_cmd_scenes)


def _fill_demo_parser(d: argparse.ArgumentParser) -> None:
    d.add_argument("--out", default="results/demo", help="output folder")
    d.add_argument("--config", help="YAML config (default: built-in values, as in configs/demo.yaml)")
    d.set_defaults(func=_cmd_demo)


def _fill_evaluate_parser(e: _Subcommand) -> None:
    from ._evaluate import add_parser

    add_parser(_Into(e))


_PLACE_HELP = "place probes in a scene and write a ProbeSet JSON file + top view"
_EVALUATE_HELP = (
    "evaluate a probe set on a scene view: MSE per component vs the path tracer (docs/evaluate.md)"
)
_VIEW_HELP = (
    "a web viewer of a run folder or a probes file: scene, probes, cameras, error image, a probe's maps "
    "(docs/view.md)"
)


def _fill_view_parser(v: argparse.ArgumentParser) -> None:
    from ._view import add_parser

    add_parser(v)


_EXPORT_HELP = "write a probe set to an engine format (docs/export.md)"


def _fill_place_parser(pl: argparse.ArgumentParser) -> None:
    """``probeplace place``: methods and refiners from their registries (imports the placement stage)."""
    from ..placement import COVERAGE_RULES, PlaceRequest, get_method, method_names
    from ._scene_options import add_scene_options

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
    for name, (tp, default, text) in PlaceRequest.settings(scalar=True).items():  # the stage's schema
        pl.add_argument(
            _options.flag(name),
            type=_options.value_parser(tp),
            default=default,
            metavar=name.upper(),
            help=text,
        )
    pl.add_argument(
        "--memory-budget",
        default=None,
        metavar="SIZE",
        help="instead of --budget: the most probes whose baked maps fit in SIZE (e.g. 64MiB) at "
        "--radiance-res / --geometry-res",
    )
    pl.add_argument(
        "--radiance-res",
        type=int,
        default=None,
        help="bake radiance resolution of --memory-budget (default: derived from the scene)",
    )
    pl.add_argument(
        "--geometry-res",
        type=int,
        default=None,
        help="bake geometry resolution of --memory-budget (default: --radiance-res)",
    )
    pl.add_argument(
        "--height-band",
        default=None,
        metavar="MIN,MAX",
        help="keep probes this high above the floor, scene units (default: anywhere)",
    )
    pl.add_argument(
        "--coverage",
        default="reachable",
        choices=COVERAGE_RULES,
        help="surface that counts toward coverage: every surface a probe in the views' reachable space "
        "sees head-on (reachable), or only what the view cameras' positions see (views: Wang 2019's "
        "playable space)",
    )
    pl.add_argument("--out", default=RunFiles.probes, help="ProbeSet JSON file to write")
    pl.add_argument("--png", default=None, help="top view PNG (default: --out with .png)")
    pl.set_defaults(func=_cmd_place)


def _os_error_text(e: OSError, out=None) -> str:
    """An OSError as one line: what failed on which file (``Permission denied: out/p.json``). One that
    names no file (a full disk's ENOSPC from a ``write()`` call) names the command's ``--out``."""
    if e.filename is not None and e.strerror:
        return f"{e.strerror}: {e.filename}"
    text = e.strerror or str(e) or type(e).__name__
    return f"{text} (while writing {out})" if out is not None else text


def _configure(args: argparse.Namespace) -> None:
    """Logging level and progress bars of ``-v`` / ``-q``."""
    from .._core.runtime import set_progress

    level = logging.INFO if args.verbose else logging.WARNING
    logging.basicConfig(level=level, format="%(levelname)s %(message)s")
    if args.verbose or args.quiet:
        logging.getLogger("probeplace").setLevel(level)
    set_progress(not args.quiet)


def main(argv: list[str] | None = None) -> int:
    """Run the ``probeplace`` command; returns its exit status. A user's mistake (bad input, a file that
    cannot be read or written) is one line ``probeplace: error: ...`` and status 2; Ctrl-C is one line
    ``probeplace: interrupted`` and status 130 (with ``argv`` None, the process's own command, the
    process ends there). Neither prints a traceback."""
    from .._core.runtime import interruptible

    args = None
    try:
        with interruptible():
            parser = build_parser()
            args = parser.parse_args(argv)
            if args.verbose and args.quiet:
                parser.error("-v/--verbose and -q/--quiet exclude each other")
            _configure(args)
            from ._cache import enable_from_args  # JAX's compilation cache, before any compile

            enable_from_args(args)
            return int(args.func(args) or 0)
    except ProbeplaceError as e:  # user-facing errors: one clear line, no traceback
        return _fail(str(e))
    except OSError as e:  # a file the user named could not be read or written
        return _fail(_os_error_text(e, getattr(args, "out", None)))
    except KeyboardInterrupt:
        print("probeplace: interrupted", file=sys.stderr, flush=True)
        if argv is None:  # the process's own command: end now, before interpreter shutdown meets
            sys.stdout.flush()  # XLA threads cut short (seen: a segfault, status -11, instead of 130)
            os._exit(130)
        return 130


def _fail(message: str) -> int:
    print(f"probeplace: error: {' '.join(message.split())}", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
