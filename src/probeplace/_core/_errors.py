"""Exceptions with messages meant for users: they name the input and the problem."""


class ProbeplaceError(Exception):
    """Base class of every error probeplace raises on purpose."""


class SceneError(ProbeplaceError, ValueError):
    """A scene file or scene data is missing, unreadable or unusable."""


class ConfigError(ProbeplaceError, ValueError):
    """A configuration value is invalid; the message names the key."""


class ResourceError(ProbeplaceError, MemoryError):
    """A derived size (grid, image, batch) would not fit in memory; refused before allocating."""


# --- RELIAB: up-front memory checks (issue 9) ---
MAX_BYTES_ENV = "PROBEPLACE_MAX_BYTES"


def memory_limit_bytes() -> int:
    """Largest derived allocation probeplace attempts: ``$PROBEPLACE_MAX_BYTES`` if set, else half the
    machine's physical memory (a single array or batch above it would swap or be OOM-killed)."""
    import os

    env = os.environ.get(MAX_BYTES_ENV)
    if env:
        from ._sizes import parse_bytes

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
    import os

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
