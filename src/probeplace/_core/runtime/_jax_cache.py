"""JAX's persistent compilation cache, on by default (issue 32): the one place that sets it up.

Most of what a user waits for in a fresh process is XLA compiling the same programs again. With the cache on,
every compiled program is written to a per-user folder and the next process loads it instead of compiling:

* folder: ``$XDG_CACHE_HOME/probeplace/<tag>`` (``~/.cache/probeplace/<tag>`` without XDG_CACHE_HOME), where
  ``<tag>`` is ``jax-<jax version>-<jaxlib version>-<machine>-<CPU feature hash>``: a JAX upgrade starts
  a new folder, and a home directory shared by machines of different CPUs never hands one machine code
  compiled for another's instruction set. (JAX's own cache key already covers the program, the compile
  options, ``XLA_FLAGS`` and the backend.)
* ``PROBEPLACE_JAX_CACHE=<dir>`` (or the command's ``--jax-cache DIR``) moves it to ``<dir>/<tag>``;
  ``off`` (also ``0``, ``no``, ``none``, ``false``) turns it off.
* thresholds: every program is kept, however fast it compiled or small it is
  (``jax_persistent_cache_min_compile_time_secs=0``, ``jax_persistent_cache_min_entry_size_bytes=-1``:
  no size floor and no backend override of it); no size cap (``probeplace cache clear`` empties it).
* never a folder others can write to: an entry is code that runs in this process, so a folder (or one of
  its parents) writable by every user without the sticky bit, or one owned by another user, is refused
  with a warning and the process runs without the cache.

:func:`enable_compilation_cache` imports nothing heavy: it sets the environment variables JAX reads when it
is imported (``JAX_COMPILATION_CACHE_DIR``, ``JAX_ENABLE_COMPILATION_CACHE``,
``JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS``, ``JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES``; child
processes inherit them) and, only when JAX is already imported, updates ``jax.config`` to the same values.
Either way it must run before the first compilation it should cover.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import platform
import stat
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

ENV = "PROBEPLACE_JAX_CACHE"
#: Set (to anything but an off word) to log every compilation and why JAX's caches missed (debugging).
EXPLAIN_ENV = "PROBEPLACE_EXPLAIN_COMPILES"
OFF_WORDS = frozenset({"off", "0", "no", "none", "false", "disable", "disabled"})

#: JAX's environment variables (read when ``jax`` is imported) and the matching ``jax.config`` names.
_JAX_ENV = {
    "JAX_ENABLE_COMPILATION_CACHE": "jax_enable_compilation_cache",
    "JAX_COMPILATION_CACHE_DIR": "jax_compilation_cache_dir",
    "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "jax_persistent_cache_min_compile_time_secs",
    "JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES": "jax_persistent_cache_min_entry_size_bytes",
}
#: An entry's file name ends with this (jax/_src/lru_cache.py); ``-atime`` files exist only with a size cap.
_ENTRY_SUFFIXES = ("-cache", "-atime")

log = logging.getLogger("probeplace")


@dataclass(frozen=True)
class CacheState:
    """Where the cache is (``folder``, None when off) and why: ``source`` names the setting that decided
    (``default``, ``$PROBEPLACE_JAX_CACHE``, ``--jax-cache``); ``refused`` says why a folder was not used."""

    folder: Path | None
    root: Path | None
    source: str
    refused: str | None = None


_state: CacheState | None = None


def _dist_version(name: str) -> str:
    """A distribution's version from its ``<name>-<version>.dist-info`` folder beside the package (no
    import; ``importlib.metadata`` costs ~40 ms of imports, a fifth of the command's ``--help`` budget),
    else ``importlib.metadata``."""
    import importlib.util

    spec = importlib.util.find_spec(name)
    if spec is not None and spec.origin:
        site = Path(spec.origin).resolve().parent.parent
        found = sorted(site.glob(f"{name}-*.dist-info"))
        if len(found) == 1:
            return found[0].name[len(name) + 1 : -len(".dist-info")]
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(name)
    except PackageNotFoundError:
        return "unknown"


def _versions() -> tuple[str, str]:
    """(jax, jaxlib) versions of the installed distributions: without importing JAX, and the same
    whether JAX is imported or not."""
    return _dist_version("jax"), _dist_version("jaxlib")


def _cpu_fingerprint() -> str:
    """Eight hex digits of the CPU's model and feature flags (``/proc/cpuinfo``; ``platform`` elsewhere)."""
    text = ""
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            keep = {}
            for line in f:
                key, _, value = line.partition(":")
                key = key.strip()
                if key in ("flags", "Features", "model name", "CPU part", "isa") and key not in keep:
                    keep[key] = value.strip()
                elif not line.strip() and keep:  # the first processor's block is enough
                    break
            text = repr(sorted(keep.items()))
    text = text or f"{platform.processor()}|{platform.platform()}"
    return hashlib.sha256(text.encode()).hexdigest()[:8]


def cache_tag() -> str:
    """The per-version, per-CPU folder name: ``jax-<jax>-<jaxlib>-<machine>-<cpu hash>``."""
    jax_v, jaxlib_v = _versions()
    return f"jax-{jax_v}-{jaxlib_v}-{platform.machine() or 'unknown'}-{_cpu_fingerprint()}"


def default_root() -> Path:
    """``$XDG_CACHE_HOME/probeplace``, else ``~/.cache/probeplace``."""
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".cache"
    return base / "probeplace"


def resolve(setting: str | None = None) -> CacheState:
    """The cache folder a setting asks for, without creating or checking it: ``setting`` (the
    ``--jax-cache`` value) if given, else ``$PROBEPLACE_JAX_CACHE``, else the default."""
    if setting is not None:
        source, value = "--jax-cache", setting
    elif os.environ.get(ENV, "").strip():
        source, value = f"${ENV}", os.environ[ENV]
    else:
        source, value = "default", ""
    value = value.strip()
    if value.lower() in OFF_WORDS:
        return CacheState(None, None, source)
    root = Path(value).expanduser().absolute() if value else default_root()
    return CacheState(root / cache_tag(), root, source)


def _unsafe(path: Path) -> str | None:
    """Why ``path`` (an existing directory) must not hold code this process runs, or None."""
    st = path.stat()
    if not stat.S_ISDIR(st.st_mode):
        return f"{path} is not a directory"
    if hasattr(os, "getuid") and st.st_uid != os.getuid():
        return f"{path} is owned by another user (uid {st.st_uid})"
    if st.st_mode & stat.S_IWOTH:
        return f"{path} is writable by every user"
    return None


def _unsafe_parent(path: Path) -> str | None:
    """A parent others could use to swap the folder: writable by every user without the sticky bit."""
    for parent in path.parents:
        with contextlib.suppress(OSError):
            mode = parent.stat().st_mode
            if mode & stat.S_IWOTH and not mode & stat.S_ISVTX:
                return f"its parent {parent} is writable by every user"
    return None


def prepare(state: CacheState) -> CacheState:
    """Create the folder (mode 0700) and check that only this user can write to it; a refused or
    uncreatable folder gives a state with ``folder=None`` and ``refused`` saying why."""
    if state.folder is None or state.root is None:
        return state
    try:
        why = _unsafe_parent(state.root)
        for path in (state.root, state.folder):
            if why is not None:
                break
            if not path.exists():
                path.mkdir(mode=0o700, parents=True, exist_ok=True)
            why = _unsafe(path)
    except OSError as e:
        why = f"cannot create {e.filename or state.folder}: {e.strerror or e}"
    if why is not None:
        return CacheState(None, state.root, state.source, refused=f"{state.folder}: {why}")
    return state


def _env_text(value: bool | float | int | str) -> str:
    """A setting as its environment variable spells it: ``true``/``false``, ``0`` for 0.0, ``-1``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _apply(folder: Path | None) -> None:
    settings = {  # jax.config name -> value; each is also set as its environment variable (_JAX_ENV)
        "jax_enable_compilation_cache": folder is not None,
        "jax_compilation_cache_dir": str(folder) if folder is not None else None,
        "jax_persistent_cache_min_compile_time_secs": 0.0,
        "jax_persistent_cache_min_entry_size_bytes": -1,
    }
    for env, name in _JAX_ENV.items():
        value = settings[name]
        if value is None:
            os.environ.pop(env, None)
        else:
            os.environ[env] = _env_text(value)
    if "jax" not in sys.modules:  # JAX reads the variables when it is imported
        return
    import jax
    from jax.experimental.compilation_cache import compilation_cache

    for name, value in settings.items():
        jax.config.update(name, value)
    compilation_cache.reset_cache()  # forget a folder (or "no folder") an earlier compile settled on


def explain_compiles(on: bool | None = None) -> bool:
    """Log each compilation (``jax_log_compiles``: the function, its shapes, the time) and why it was not
    reused (``jax_explain_cache_misses``: which argument's shape, dtype or static value changed), at
    WARNING level. ``on`` None reads ``$PROBEPLACE_EXPLAIN_COMPILES``; True also sets it for child
    processes. Like the cache settings, the environment variables JAX reads at import, plus ``jax.config``
    when JAX is already imported. Returns whether it is on."""
    if on is None:
        on = os.environ.get(EXPLAIN_ENV, "").strip().lower() not in ("", *OFF_WORDS)
    elif on:
        os.environ[EXPLAIN_ENV] = "1"
    if not on:
        return False
    os.environ["JAX_LOG_COMPILES"] = os.environ["JAX_EXPLAIN_CACHE_MISSES"] = "true"
    if "jax" in sys.modules:
        import jax

        jax.config.update("jax_log_compiles", True)
        jax.config.update("jax_explain_cache_misses", True)
    return True


def enable_compilation_cache(setting: str | None = None) -> CacheState:
    """Turn the persistent compilation cache on (or off) for this process and the processes it starts.

    ``setting``: a folder or ``off`` (the ``--jax-cache`` value; it is also put in ``$PROBEPLACE_JAX_CACHE``
    for child processes); None reads ``$PROBEPLACE_JAX_CACHE``, else the default folder. A folder that is
    unsafe or cannot be created is refused with one warning and the cache is off. Returns the state."""
    global _state
    if setting is not None:
        os.environ[ENV] = setting
    state = prepare(resolve(setting))
    if state.refused is not None:
        log.warning("not using the JAX compilation cache: %s", state.refused)
    _apply(state.folder)
    explain_compiles()  # $PROBEPLACE_EXPLAIN_COMPILES: every front door that sets up the cache honours it
    _state = state
    return state


def current() -> CacheState | None:
    """What the last :func:`enable_compilation_cache` set up (None before any call)."""
    return _state


@contextlib.contextmanager
def persistent_cache_disabled() -> Iterator[None]:
    """No persistent cache inside the block (JAX must be imported): for code that measures real compile
    time. The earlier configuration is restored afterwards."""
    import jax
    from jax.experimental.compilation_cache import compilation_cache

    names = tuple(_JAX_ENV.values())
    old = {name: getattr(jax.config, name) for name in names}
    jax.config.update("jax_enable_compilation_cache", False)
    compilation_cache.reset_cache()
    try:
        yield
    finally:
        for name, value in old.items():
            jax.config.update(name, value)
        compilation_cache.reset_cache()


def entries(folder: Path) -> tuple[int, int]:
    """(entries, bytes) of a cache folder: the ``*-cache`` files and the size of every file in it."""
    n = size = 0
    with contextlib.suppress(FileNotFoundError):
        for p in folder.iterdir():
            with contextlib.suppress(FileNotFoundError):
                if p.is_file():
                    size += p.stat().st_size
                    n += p.name.endswith("-cache")
    return n, size


def version_folders(root: Path) -> list[Path]:
    """The ``jax-*`` folders under a cache root (this version's and older ones)."""
    with contextlib.suppress(FileNotFoundError, NotADirectoryError):
        return sorted(p for p in root.iterdir() if p.is_dir() and p.name.startswith("jax-"))
    return []


def clear(folder: Path) -> tuple[int, int]:
    """Delete the cache entries of ``folder`` (only JAX's entry files, then the folder if it is left
    empty); returns the (entries, bytes) removed."""
    n = size = 0
    with contextlib.suppress(FileNotFoundError):
        for p in folder.iterdir():
            if p.is_file() and (p.name.endswith(_ENTRY_SUFFIXES) or p.name == ".lockfile"):
                with contextlib.suppress(FileNotFoundError):
                    s = p.stat().st_size
                    p.unlink()
                    size += s
                    n += p.name.endswith("-cache")
        with contextlib.suppress(OSError):
            folder.rmdir()
    return n, size
