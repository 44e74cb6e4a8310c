"""Core pytree types and safe math shared by every stage."""

from ._errors import ConfigError as ConfigError
from ._errors import ProbeplaceError as ProbeplaceError
from ._errors import ResourceError as ResourceError
from ._errors import SceneError as SceneError
from ._math import luminance as luminance
from ._math import safe_norm as safe_norm
from ._math import safe_normalize as safe_normalize
from ._math import safe_sqrt as safe_sqrt
from ._types import Camera as Camera
from ._types import Hit as Hit
from ._types import LightFieldProbes as LightFieldProbes
from ._types import Materials as Materials
from ._types import ProbeSet as ProbeSet
from ._types import Scene as Scene
from ._types import Sun as Sun
