"""Up-front memory checks (issue 9): a derived allocation over the limit is refused, naming its size and
the fix, before any slow work. Plain Python (no JAX)."""

from __future__ import annotations

import os

from .._errors import ConfigError, ResourceError
from ._sizes import parse_bytes

MAX_BYTES_ENV = "PROBEPLACE_MAX_BYTES"


def memory_limit_bytes() -> int:
    """Largest derived allocation probeplace attempts: ``$PROBEPLACE_MAX_BYTES`` if set, else half the
    machine's physical memory (a single array or batch above it would swap or be OOM-killed)."""
    env = os.environ.get(MAX_BYTES_ENV)
    if env:
        try:
            return parse_bytes(env)
        except ConfigError as e:
            fix = "unset it or give a size such as 8GiB"
            raise ConfigError(f"${MAX_BYTES_ENV}={env!r}: {e}; {fix}") from None
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") // 2
    except (ValueError, OSError, AttributeError):  # no sysconf (Windows): assume 16 GiB
        return 8 << 30


def check_memory(need_bytes: int, what: str, hint: str) -> None:
    """Raise :class:`ResourceError` naming the estimate when ``need_bytes`` exceeds the memory limit.

    Args:
        need_bytes: estimated bytes the operation would allocate.
        what: what would be allocated, e.g. ``"bake of 10 probes at radiance_res=4096"``.
        hint: how to make it fit.
    """
    limit = memory_limit_bytes()  # the message names where it came from: the variable or the machine
    if need_bytes > limit:
        size = (
            f"{need_bytes / 2**30:.1f} GiB" if need_bytes >= 2**30 // 10 else f"{need_bytes / 2**20:.1f} MiB"
        )
        whose = (
            f"${MAX_BYTES_ENV}"
            if os.environ.get(MAX_BYTES_ENV)
            else f"half the physical memory; ${MAX_BYTES_ENV} overrides"
        )
        raise ResourceError(
            f"{what} needs ~{int(need_bytes)} bytes ({size}), over the limit of {limit} bytes ({whose}); "
            f"{hint}"
        )
