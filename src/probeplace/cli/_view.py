"""``probeplace view``: check the input, load it, serve it until Ctrl-C (which ends it with status 0)."""

from __future__ import annotations

import argparse
import contextlib
import signal
import threading
from collections.abc import Iterator

DEFAULT_PORT = 8080


def add_parser(v: argparse.ArgumentParser) -> None:
    """The options of ``probeplace view`` (imports nothing heavy: ``--help`` stays fast)."""
    v.description = (
        "A web viewer (viser) of a run folder or a probes file: the scene, the probes (by status or reach), "
        "the evaluation's cameras and error image, and a clicked probe's maps. Over SSH: "
        "ssh -L PORT:localhost:PORT HOST, then open http://localhost:PORT (docs/view.md)."
    )
    v.add_argument(
        "path", help="a run folder (holding probes.json) or a probes file (.json, .npz, .glb, ...)"
    )
    v.add_argument(
        "--scene",
        default=None,
        metavar="NAME_OR_PATH",
        help="the scene (default: the run's config.yaml, or the scene the probes file records)",
    )
    v.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help="port to serve on (the next free one if taken)"
    )
    v.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to bind (default: this machine only, reached over SSH with -L; 0.0.0.0: every "
        "interface)",
    )
    v.set_defaults(func=cmd_view)


def checked_input(args: argparse.Namespace):
    """Every input checked before the scene is loaded or the server started (the catalogue's entry point)."""
    from .._core import ConfigError
    from ..view import resolve_input

    if not 0 <= args.port <= 65535:
        raise ConfigError(f"--port must be in 0..65535, got {args.port}")
    return resolve_input(args.path, args.scene)


def cmd_view(args: argparse.Namespace) -> int:
    from ..view import hostname, load_view_model, start_viewer

    inp = checked_input(args)
    model = load_view_model(inp)
    viewer = start_viewer(model, host=args.host, port=args.port)
    port = viewer.server.get_port()
    try:
        # The handlers go in before the URL is printed: a Ctrl-C from someone who has read it is a stop.
        with stop_signals() as stopped:
            print(
                f"probeplace view: {viewer.url}  ({model.title}: {len(model.positions)} probes)", flush=True
            )
            print(
                f"  over SSH: ssh -L {port}:localhost:{port} {hostname()}  then open http://localhost:{port}",
                flush=True,
            )
            print("  Ctrl-C stops the viewer", flush=True)
            while not stopped.wait(0.5):
                pass
    finally:
        viewer.stop()
    print("probeplace view: stopped", flush=True)
    return 0


@contextlib.contextmanager
def stop_signals() -> Iterator[threading.Event]:
    """An event that Ctrl-C (SIGINT) or SIGTERM sets while the block runs: the viewer then stops as a
    normal end of the command (status 0), not as the interrupt every other command turns into 130. Off
    the main thread (no signal handlers there) only the caller sets it."""
    done = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield done
        return
    previous = {s: signal.signal(s, lambda *_: done.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield done
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
