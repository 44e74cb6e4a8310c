"""Progress bars that behave in logs: tqdm's bar on a terminal (or in a notebook), none when stderr is a
file or a pipe (a log would fill with carriage-return redraws) or when a command runs ``--quiet``."""

from __future__ import annotations

import sys

_enabled = True


def set_progress(enabled: bool) -> None:
    """Allow (the default) or suppress every progress bar of this process (``probeplace --quiet``)."""
    global _enabled
    _enabled = bool(enabled)


def _on_terminal() -> bool:
    stream = sys.stderr
    try:
        return stream is not None and stream.isatty()
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def progress_bar(*args, disable: bool = False, **kwargs):
    """``tqdm.auto.tqdm(*args, **kwargs)``, disabled when ``disable``, when bars are suppressed
    (:func:`set_progress`) or when stderr is not a terminal; a notebook's widget bar is kept (it draws no
    carriage returns)."""
    from tqdm import std
    from tqdm.auto import tqdm
    from tqdm.autonotebook import tqdm as chosen  # imported (warnings filtered) by tqdm.auto

    widget = chosen is not std.tqdm  # tqdm.auto picked the notebook bar
    show = _enabled and not disable and (widget or _on_terminal())
    return tqdm(*args, disable=not show, **kwargs)
