"""The methods placement is compared against, registered on import (``_methods``): uniform grids
(``_uniform``), Yang 2023's mixed-resolution grid (``_lod_grid``) and Vardis 2021's simplification of a
dense set (``_vardis``, on ``_tetra``'s tetrahedral interpolation).

This ``__init__`` is the group's face for the rest of ``placement``."""

from ._lod_grid import LODGrid as LODGrid
from ._lod_grid import lod_probe_grid as lod_probe_grid
from ._methods import GridOptions as GridOptions
from ._methods import LodGridOptions as LodGridOptions
from ._methods import VardisOptions as VardisOptions
from ._uniform import INSIDE_CHOICES as INSIDE_CHOICES
from ._uniform import UniformGridResult as UniformGridResult
from ._uniform import uniform_probe_grid as uniform_probe_grid
from ._vardis import ERROR_MODES as ERROR_MODES
from ._vardis import VardisResult as VardisResult
from ._vardis import dense_probe_sh as dense_probe_sh
from ._vardis import error_features as error_features
from ._vardis import evaluation_points as evaluation_points
from ._vardis import leave_one_out_scores as leave_one_out_scores
from ._vardis import poisson_disk_probes as poisson_disk_probes
from ._vardis import vardis_simplify as vardis_simplify
