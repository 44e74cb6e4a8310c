"""probes stage: light-field probe baking (McGuire et al. 2017), pre-filtering, save/load."""

from ._bake import BakeConfig as BakeConfig
from ._bake import RadianceFn as RadianceFn
from ._bake import bake_probes as bake_probes
from ._bake import default_radiance_res as default_radiance_res
from ._bake import path_traced_radiance as path_traced_radiance
from ._filter import distance_moments as distance_moments
from ._filter import irradiance_map as irradiance_map
from ._filter import mip_chains as mip_chains
from ._io import load_probes as load_probes
from ._io import save_probes as save_probes
from ._plot import save_contact_sheet as save_contact_sheet
