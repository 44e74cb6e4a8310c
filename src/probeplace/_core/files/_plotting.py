"""matplotlib for charts written to files (STYLE §8: the Agg backend, no display or GUI toolkit)."""

from __future__ import annotations

from types import ModuleType


def load_pyplot() -> ModuleType:
    """``matplotlib.pyplot`` with the file-only Agg backend selected (imported on first call, so the
    package imports without matplotlib)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
