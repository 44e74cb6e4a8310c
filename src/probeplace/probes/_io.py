"""Save and load baked probes as one ``.npz`` (lossless: every leaf is stored with its dtype; the
normal maps are the two int16 components the probes hold, ``_core.maths._packed``).

Beside the maps, the file holds the ``backface`` map and the bake settings
(:class:`~probeplace._core.BakeSettings`, as a JSON string under ``bake_settings``). Files written before
those existed still load: ``backface`` and ``bake`` are then ``None``, and the evaluation refuses the
probes (``probes.check_bake_settings``) until they are re-baked.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from .._core import BakeSettings, LightFieldProbes, ProbeplaceError, pack_normal, write_atomic
from .._core.files import LIGHT_FIELD_FORMAT, LIGHT_FIELD_FORMAT_V1, read_light_field_arrays

_MAPS = (
    "pos_world",
    "active",
    "inside",
    "radiance",
    "emission",
    "normal16",
    "distance",
    "irradiance",
    "moments",
)


def save_probes(path: str | os.PathLike, probes: LightFieldProbes) -> Path:
    """Write ``probes`` to ``path`` (.npz) atomically (a temporary file renamed into place)."""
    path = Path(path)
    arrays = {name: np.asarray(getattr(probes, name)) for name in _MAPS}
    arrays["far"] = np.asarray(probes.far)
    arrays["format"] = np.asarray(LIGHT_FIELD_FORMAT)
    if probes.backface is not None:
        arrays["backface"] = np.asarray(probes.backface)
    if probes.bake is not None:
        arrays["bake_settings"] = np.asarray(json.dumps(probes.bake.to_dict()))
    return write_atomic(path, lambda f: np.savez_compressed(f, **arrays))


def load_probes(path: str | os.PathLike) -> LightFieldProbes:
    """Read probes written by :func:`save_probes`.

    Raises:
        ProbeplaceError: missing file, not an npz, not a probe file, or unreadable bake settings.
    """
    data = read_light_field_arrays(path)
    fmt = str(data["format"])
    if fmt == LIGHT_FIELD_FORMAT_V1 and "normal" in data:
        data["normal16"] = np.asarray(pack_normal(data.pop("normal")))
    missing = [k for k in (*_MAPS, "far") if k not in data]
    if missing:
        raise ProbeplaceError(f"{path}: probe file lacks {missing}")
    bake = None
    if "bake_settings" in data:
        try:
            bake = BakeSettings.from_dict(json.loads(str(data["bake_settings"])))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
            raise ProbeplaceError(f"{path}: unreadable bake settings ({type(e).__name__}: {e})") from None
    return LightFieldProbes(
        **{k: jnp.asarray(data[k]) for k in _MAPS},
        far=jnp.asarray(data["far"]),
        backface=jnp.asarray(data["backface"]) if "backface" in data else None,
        bake=bake,
    )
