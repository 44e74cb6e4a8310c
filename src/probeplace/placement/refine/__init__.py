"""The refiners (one table, ``_refine``): Wang's Gibbs + stochastic-direction sampler, gradient ascent,
and optimistix / jaxopt (``_optimistix``, ``_jaxopt``) on the differentiable fitness.

This ``__init__`` is the group's face for the rest of ``placement``."""

from ._refine import OBJECTIVES as OBJECTIVES
from ._refine import REFINERS as REFINERS
from ._refine import AbstractRefiner as AbstractRefiner
from ._refine import GibbsRefiner as GibbsRefiner
from ._refine import RefineResult as RefineResult
from ._refine import get_refiner as get_refiner
from ._refine import objective_fn as objective_fn
from ._refine import stochastic_direction as stochastic_direction
