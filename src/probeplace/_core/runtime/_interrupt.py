"""Ctrl-C that is never lost. Python raises ``KeyboardInterrupt`` wherever the main thread happens to be
when the signal is handled, and two kinds of place drop it: a garbage-collector callback or ``__del__``
(the exception is printed as "Exception ignored in ..." and discarded; JAX registers a gc callback), and
library code that catches ``BaseException`` (trimesh wraps its optional imports so). Seen with
``probeplace place``: a Ctrl-C two to three seconds in, during those imports or in JAX's
``_xla_gc_callback``, was discarded and the placement went on to finish with status 0.

:func:`interruptible` installs a SIGINT handler that raises ``KeyboardInterrupt`` as usual (not inside a
gc callback, a ``__del__`` or an XLA compilation: see :func:`_defer`) and re-sends the signal every
:data:`REDELIVER_S` seconds until the interrupt has reached the end of the ``with`` block, so a
discarded one comes again (while an ``except`` block handles it, the re-sent signal is let pass: the
clean-up runs to its end).
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from types import FrameType

#: Seconds between re-sent signals while an interrupt has not reached the end of the block.
REDELIVER_S = 0.5

_pending = False
_raised: BaseException | None = None


def _defer(frame: FrameType | None) -> bool:
    """Whether ``frame`` runs where a raised interrupt is dropped (a gc callback, a ``__del__``) or
    unsafe (an XLA compilation: interrupting it sometimes crashed the process, status -11); the
    re-sent signal comes back when the frame has returned."""
    callbacks = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        code = frame.f_code
        if code in callbacks or code.co_name in ("__del__", "backend_compile_and_load"):
            return True
        frame = frame.f_back
    return False


def _redeliver(pid: int, signum: int) -> None:
    while True:
        time.sleep(REDELIVER_S)
        if not _pending:
            return
        os.kill(pid, signum)


def _on_sigint(signum: int, frame: FrameType | None) -> None:
    global _pending, _raised
    if not _pending:
        _pending = True
        threading.Thread(target=_redeliver, args=(os.getpid(), signum), daemon=True).start()
    elif _raised is not None and sys.exc_info()[1] is _raised:
        return  # the interrupt is being handled (an ``except`` cleaning up): let it finish
    if not _defer(frame):
        _raised = KeyboardInterrupt()
        raise _raised


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """Within the block, a Ctrl-C always ends the block with ``KeyboardInterrupt`` (module docstring).

    Only in the main thread and where SIGINT has Python's default handler (an ignored SIGINT, as under
    ``nohup``, stays ignored). After an interrupt SIGINT is ignored (the program is ending: a re-sent
    signal must not break its last words); otherwise the previous handler is restored.
    """
    global _pending, _raised
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is not signal.default_int_handler:
        yield
        return
    _pending, _raised = False, None
    signal.signal(signal.SIGINT, _on_sigint)
    try:
        yield
    finally:
        interrupted, _pending, _raised = _pending, False, None
        signal.signal(signal.SIGINT, signal.SIG_IGN if interrupted else previous)
    if interrupted:  # the block ran to its end although an interrupt was discarded on the way
        raise KeyboardInterrupt
