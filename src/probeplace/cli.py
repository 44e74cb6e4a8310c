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
    from .demo import run_demo

    return run_demo(out_dir=args.out)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="probeplace", description=__doc__)
    p.add_argument("-v", "--verbose", action="store_true", help="log at INFO level")
    sub = p.add_subparsers(dest="command", required=True)
    s = sub.add_parser("scenes", help="list built-in scenes and scenes found on the search path")
    s.set_defaults(func=_cmd_scenes)
    d = sub.add_parser("demo", help="run the default experiment on the built-in Cornell box")
    d.add_argument("--out", default="results/demo", help="output folder (default: results/demo)")
    d.set_defaults(func=_cmd_demo)
    return p


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
