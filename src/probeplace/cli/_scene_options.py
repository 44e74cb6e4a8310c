"""The scene options every command that loads a scene takes: ``--sun``, ``--sky``, ``--camera``, one-off
overrides of the scene's sidecar keys (their one-line forms: ``scene.config._sidecar_cli``)."""

from __future__ import annotations

from typing import Any

from ..scene import scene_overrides


def add_scene_options(parser) -> None:
    """``--sun``, ``--sky`` and ``--camera`` on an argparse (sub)parser: one-off overrides of the scene's
    sidecar keys (``scene.scene_overrides`` gives the forms)."""
    parser.add_argument("--sun", default=None, help="sun, e.g. az=120,el=35,irradiance=8 (or none)")
    parser.add_argument("--sky", default=None, help="sky: daylight | none | r,g,b radiance")
    parser.add_argument(
        "--camera",
        action="append",
        default=[],
        help="named camera, e.g. name=door,pos=1,1.6,4,look_at=0,1,0,fov=60 (repeatable)",
    )


def scene_overrides_from_args(args) -> dict[str, Any]:
    """``scene.scene_overrides`` of the options :func:`add_scene_options` added (checked before any work)."""
    return scene_overrides(sun=args.sun, sky=args.sky, cameras=args.camera or ())
