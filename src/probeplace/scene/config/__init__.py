"""The scene sidecar config (docs/scenes.md, "Sidecar config"): the ``<stem>.probeplace.yaml`` keys and
their parser (``_sidecar``, with the checked value readers of ``_config_values``), their one-line CLI
forms (``_sidecar_cli``: ``--sun``, ``--sky``, ``--camera``), the layers known external scenes get
(``_known``) and applying a config to a built scene (``_sidecar_apply``).

This ``__init__`` is the group's face for the rest of ``scene``. The parsing is plain Python and loads
eagerly; applying a config on first use (PEP 562 ``__getattr__``): it imports JAX."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..._core._lazy import lazy_exports
from ._known import KNOWN_SCENES as KNOWN_SCENES
from ._sidecar import SIDECAR_SUFFIX as SIDECAR_SUFFIX
from ._sidecar import CameraSpec as CameraSpec
from ._sidecar import EmitterSpec as EmitterSpec
from ._sidecar import MaterialSpec as MaterialSpec
from ._sidecar import SceneConfig as SceneConfig
from ._sidecar import SunSpec as SunSpec
from ._sidecar import merge_scene_configs as merge_scene_configs
from ._sidecar import no_light_hint as no_light_hint
from ._sidecar import parse_scene_config as parse_scene_config
from ._sidecar import read_sidecar as read_sidecar
from ._sidecar import sidecar_path as sidecar_path
from ._sidecar_cli import parse_camera as parse_camera
from ._sidecar_cli import parse_sky as parse_sky
from ._sidecar_cli import parse_sun as parse_sun
from ._sidecar_cli import scene_overrides as scene_overrides

# name -> the private module defining it (it imports JAX)
_LAZY = dict.fromkeys(("apply_scene_config", "camera_origin", "check_layer"), "_sidecar_apply")

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._sidecar_apply import apply_scene_config as apply_scene_config
    from ._sidecar_apply import camera_origin as camera_origin
    from ._sidecar_apply import check_layer as check_layer


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), [*_LAZY])
