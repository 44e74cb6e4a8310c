"""pipeline: the stages' shared steps, once — the backend, view and budget checks, writing a placement,
the bake of a placed set and the engine exports (``_stages``). The runner (``experiment``), the CLI and
the stage tour (``probeplace demo``) translate their options into the stages' library configs and call
these; no front door bakes or checks on its own (docs/architecture.md, "One pipeline")."""

from ._stages import Baked as Baked
from ._stages import bake as bake
from ._stages import check_backend as check_backend
from ._stages import check_view as check_view
from ._stages import export_baked as export_baked
from ._stages import probe_budget as probe_budget
from ._stages import write_placement as write_placement
