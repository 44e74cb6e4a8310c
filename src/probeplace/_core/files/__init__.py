"""Files on disk: atomic writes and EXR images (``_io``), the probe files read and named in one place
(``_probe_files``: the ProbeSet JSON, the baked light-field ``.npz``, the per-probe sidecars), the ProbeSet
as pytrees (``_probe_io``) and matplotlib for charts written to files (``_plotting``).

This ``__init__`` is the group's face for the rest of the package. Every name loads on first use (PEP 562
``__getattr__``): ``_io`` and ``_probe_files`` are NumPy only, for the NumPy-only ``export`` stage, and
reading one of their names must not import ``_probe_io`` (JAX) or matplotlib."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

# name -> the private module defining it (only _probe_io imports JAX)
_LAZY = {
    **dict.fromkeys(
        (
            "atomic_path",
            "naming_the_file",
            "read_exr",
            "write_atomic",
            "write_bytes_atomic",
            "write_exr",
            "write_json_atomic",
            "write_text_atomic",
        ),
        "_io",
    ),
    "load_pyplot": "_plotting",
    "RunFiles": "_run_files",
    **dict.fromkeys(
        (
            "COVERAGE_DETAIL_FORMAT",
            "LIGHT_FIELD_FORMAT",
            "LIGHT_FIELD_FORMAT_V1",
            "PROBE_ERROR_FILE",
            "PROBE_ERROR_FORMAT",
            "PROBE_SET_FORMAT",
            "coverage_detail_path",
            "parse_probe_set",
            "read_json_doc",
            "read_light_field_arrays",
        ),
        "_probe_files",
    ),
    **dict.fromkeys(("load_probe_set", "save_probe_set"), "_probe_io"),
}

if TYPE_CHECKING:  # what static checkers and IDEs see; __getattr__ gives the same at run time
    from ._io import atomic_path as atomic_path
    from ._io import naming_the_file as naming_the_file
    from ._io import read_exr as read_exr
    from ._io import write_atomic as write_atomic
    from ._io import write_bytes_atomic as write_bytes_atomic
    from ._io import write_exr as write_exr
    from ._io import write_json_atomic as write_json_atomic
    from ._io import write_text_atomic as write_text_atomic
    from ._plotting import load_pyplot as load_pyplot
    from ._probe_files import COVERAGE_DETAIL_FORMAT as COVERAGE_DETAIL_FORMAT
    from ._probe_files import LIGHT_FIELD_FORMAT as LIGHT_FIELD_FORMAT
    from ._probe_files import LIGHT_FIELD_FORMAT_V1 as LIGHT_FIELD_FORMAT_V1
    from ._probe_files import PROBE_ERROR_FILE as PROBE_ERROR_FILE
    from ._probe_files import PROBE_ERROR_FORMAT as PROBE_ERROR_FORMAT
    from ._probe_files import PROBE_SET_FORMAT as PROBE_SET_FORMAT
    from ._probe_files import coverage_detail_path as coverage_detail_path
    from ._probe_files import parse_probe_set as parse_probe_set
    from ._probe_files import read_json_doc as read_json_doc
    from ._probe_files import read_light_field_arrays as read_light_field_arrays
    from ._probe_io import load_probe_set as load_probe_set
    from ._probe_io import save_probe_set as save_probe_set
    from ._run_files import RunFiles as RunFiles


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals(), [*_LAZY])
