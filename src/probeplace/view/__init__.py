"""view stage (issue 36): ``probeplace view``, a web viewer of a run folder or a probes file (viser).

It sits on top of the pipeline: it reads what the other stages wrote (``experiment``'s run folders,
``export``'s probe files, ``scene``'s scenes) and computes nothing new (docs/view.md). Names load on first
use (PEP 562, ``_core._lazy``): importing the package imports neither viser nor JAX.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._core._lazy import lazy_exports

# name -> the private module defining it
_LAZY = {
    **dict.fromkeys(("ViewInput", "check_scene_found", "resolve_input"), "_input"),
    **dict.fromkeys(("STATUS_LABELS", "STATUS_RGB", "ViewCamera", "ViewModel", "load_view_model"), "_model"),
    **dict.fromkeys(("Viewer", "camera_wxyz", "hostname", "pick_probe", "start_viewer"), "_server"),
}
__all__ = [*_LAZY]

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._input import ViewInput as ViewInput
    from ._input import check_scene_found as check_scene_found
    from ._input import resolve_input as resolve_input
    from ._model import STATUS_LABELS as STATUS_LABELS
    from ._model import STATUS_RGB as STATUS_RGB
    from ._model import ViewCamera as ViewCamera
    from ._model import ViewModel as ViewModel
    from ._model import load_view_model as load_view_model
    from ._server import Viewer as Viewer
    from ._server import camera_wxyz as camera_wxyz
    from ._server import hostname as hostname
    from ._server import pick_probe as pick_probe
    from ._server import start_viewer as start_viewer

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), __all__)
