"""PEP 562 lazy exports: a package whose public names import JAX loads each on first use, so that what
needs none of them (``probeplace --help``, ``scenes``, ``export``, the NumPy-only export stage) does not
import JAX. One implementation for ``_core``, ``scene`` and ``render``. Plain Python."""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_exports(
    package: str, table: dict[str, str], namespace: dict, public: list[str]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of package ``package``: a name of ``table`` (name → the private
    module defining it) is imported on first access and kept in ``namespace`` (the package's
    ``globals()``), so later lookups skip ``__getattr__``; ``dir()`` lists ``public`` too."""

    def __getattr__(name: str):
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{table[name]}", package), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted({*namespace, *public})

    return __getattr__, __dir__
