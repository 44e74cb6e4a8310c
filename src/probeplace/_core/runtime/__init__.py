"""The process a command runs in: checks made before any slow work (``_checks``: writable outputs, free
disk, NumPy archives, image memory), the memory limit (``_memory``, its sizes parsed by ``_sizes``), Ctrl-C
that is never lost (``_interrupt``), JAX's persistent compilation cache (``_jax_cache``) and progress bars
(``_progress``).

This ``__init__`` is the group's face for the rest of the package. The modules are plain Python
(``_jax_cache`` imports JAX only inside functions); each loads on first use of one of its names (PEP 562
``__getattr__``), so that a command reading one pays for no other. What reads or patches a module's own
state (``cli``'s cache commands, the progress setting, the tests) imports ``_jax_cache`` or ``_progress``
itself."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

# name -> the private module defining it (none imports JAX)
_LAZY = {
    **dict.fromkeys(
        ("check_image_memory", "check_npz_archive", "check_writable_file", "check_writable_folder"), "_checks"
    ),
    "interruptible": "_interrupt",
    "enable_compilation_cache": "_jax_cache",
    **dict.fromkeys(("MAX_BYTES_ENV", "check_memory", "memory_limit_bytes"), "_memory"),
    **dict.fromkeys(("progress_bar", "set_progress"), "_progress"),
    "parse_bytes": "_sizes",
    **dict.fromkeys(("check_settings", "rekeyed", "setting"), "_settings"),
}

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._checks import check_image_memory as check_image_memory
    from ._checks import check_npz_archive as check_npz_archive
    from ._checks import check_writable_file as check_writable_file
    from ._checks import check_writable_folder as check_writable_folder
    from ._interrupt import interruptible as interruptible
    from ._jax_cache import enable_compilation_cache as enable_compilation_cache
    from ._memory import MAX_BYTES_ENV as MAX_BYTES_ENV
    from ._memory import check_memory as check_memory
    from ._memory import memory_limit_bytes as memory_limit_bytes
    from ._progress import progress_bar as progress_bar
    from ._progress import set_progress as set_progress
    from ._settings import check_settings as check_settings
    from ._settings import rekeyed as rekeyed
    from ._settings import setting as setting
    from ._sizes import parse_bytes as parse_bytes


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), [*_LAZY])
