"""``probeplace cache info|clear`` and the top-level ``--jax-cache DIR|off`` (issue 32): JAX's persistent
compilation cache (``probeplace._core.runtime._jax_cache``). Imports no JAX."""

from __future__ import annotations

import argparse

from .._core.runtime import _jax_cache


def add_parser(parser: argparse.ArgumentParser, sub) -> None:
    """Register ``--jax-cache`` on the top-level ``parser`` and the ``cache`` subcommand on ``sub``."""
    parser.add_argument(
        "--jax-cache",
        default=None,
        metavar="DIR|off",
        help=f"JAX compilation cache: compiled programs are kept in DIR/<jax version tag> and reused by "
        f"later runs; 'off' compiles everything anew (default: ${_jax_cache.ENV}, else "
        f"$XDG_CACHE_HOME/probeplace or ~/.cache/probeplace; see `probeplace cache info`)",
    )
    parser.add_argument(
        "--explain-compiles",
        action="store_true",
        help=f"debugging: log every XLA compilation and why no compiled program was reused (which "
        f"argument's shape, dtype or setting changed); also ${_jax_cache.EXPLAIN_ENV}=1",
    )
    c = sub.add_parser(
        "cache",
        help="the JAX compilation cache: `cache info` (folder, entries, size), `cache clear` (delete it)",
    )
    c.add_argument("action", choices=("info", "clear"), help="info: where and how big; clear: delete it")
    c.add_argument(
        "--all",
        action="store_true",
        help="clear: also the folders of other JAX versions and machines under the same root",
    )
    c.set_defaults(func=_cmd_cache)


def enable_from_args(args: argparse.Namespace) -> _jax_cache.CacheState:
    """The cache as the command asks (``--jax-cache``, else ``$PROBEPLACE_JAX_CACHE``, else the default);
    call before the first compilation."""
    if getattr(args, "explain_compiles", False):
        _jax_cache.explain_compiles(True)
    return _jax_cache.enable_compilation_cache(getattr(args, "jax_cache", None))


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


def _cmd_cache(args: argparse.Namespace) -> int:
    state = _jax_cache.current() or _jax_cache.resolve(getattr(args, "jax_cache", None))
    if args.action == "info":
        return _info(state)
    return _clear(state, every=args.all)


def _info(state: _jax_cache.CacheState) -> int:
    if state.folder is None:
        why = state.refused or f"turned off by {state.source}"
        print(f"JAX compilation cache: off ({why})")
    else:
        n, size = _jax_cache.entries(state.folder)
        print(f"JAX compilation cache: on ({state.source})")
        print(f"folder:  {state.folder}")
        print(f"entries: {n}")
        print(f"size:    {_mib(size)}")
    if state.root is not None:
        others = [p for p in _jax_cache.version_folders(state.root) if p != state.folder]
        for p in others:
            n, size = _jax_cache.entries(p)
            print(f"other:   {p} ({n} entries, {_mib(size)}; `probeplace cache clear --all` deletes it)")
    return 0


def _clear(state: _jax_cache.CacheState, *, every: bool) -> int:
    if state.root is None:
        print(f"JAX compilation cache: off ({state.source}); nothing cleared")
        return 0
    this = state.root / _jax_cache.cache_tag()
    folders = _jax_cache.version_folders(state.root) if every else [this]
    for folder in folders:
        n, size = _jax_cache.clear(folder)
        print(f"cleared {folder}: {n} entries, {_mib(size)}")
    if not folders:
        print(f"nothing to clear under {state.root}")
    return 0
