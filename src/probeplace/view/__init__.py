"""view stage (issue 36): ``probeplace view``, a web viewer of a run folder or a probes file (viser).

It sits on top of the pipeline: it reads what the other stages wrote (``experiment``'s run folders,
``export``'s probe files, ``scene``'s scenes) and computes nothing new (docs/view.md).
"""

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
from ._server import pick_probe as pick_probe
from ._server import start_viewer as start_viewer
