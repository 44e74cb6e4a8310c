"""One-line values for the sidecar keys ``sun``, ``sky`` and ``cameras`` (the CLI's ``--sun``, ``--sky``,
``--camera``): ``key=value`` pairs separated by commas, where a vector's numbers run on after its key::

    --sun az=120,el=35,irradiance=8
    --sun dir=0.3,1,0.2,radiance=1e5,angular_diameter=0.53
    --sky daylight            --sky none            --sky 0.4,0.5,0.6
    --camera name=door,pos=1,1.6,4,look_at=0,1,0,fov=60

Each parser checks the value with the sidecar's own rules and returns the sidecar form (plain data that
YAML can hold), so ``scene_overrides(...)`` goes straight into ``load_scene(..., overrides=...)`` and into
a run's recorded config.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from ..._core import ConfigError
from ._config_values import show
from ._sidecar import _CAMERA, _SUN, NO_SUN, parse_camera_spec, parse_sky_value, parse_sun_spec


def _value(tokens: list[str], at: str) -> Any:
    """One token: a number if it reads as one, else the text; several tokens: a vector of numbers."""

    def num(t: str) -> float:
        try:
            return float(t)
        except ValueError:
            raise ConfigError(f"{at}: {t!r} is not a number") from None

    if len(tokens) == 1:
        try:
            return float(tokens[0])
        except ValueError:
            return tokens[0]
    return [num(t) for t in tokens]


def parse_pairs(text: str, flag: str) -> dict[str, Any]:
    """``"a=1,b=2,3,4"`` → ``{"a": 1.0, "b": [2.0, 3.0, 4.0]}``.

    Raises:
        ConfigError: empty text, a leading value without a key, an empty key or value, a key given twice.
    """
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"{flag}: empty value; write key=value pairs separated by commas")
    out: dict[str, list[str]] = {}
    key: str | None = None
    for raw in text.split(","):
        tok = raw.strip()
        if "=" in tok:
            key, _, val = (s.strip() for s in tok.partition("="))
            if not key:
                raise ConfigError(f"{flag}: {tok!r} has no key before '='")
            if key in out:
                raise ConfigError(f"{flag}: {key}: given twice")
            out[key] = [val] if val else []
        elif key is None:
            raise ConfigError(f"{flag}: {tok!r} has no key; write key=value pairs, e.g. {flag} az=120,el=35")
        elif tok:
            out[key].append(tok)
    for k, toks in out.items():
        if not toks:
            raise ConfigError(f"{flag}: {k}: no value after '='")
    return {k: _value(toks, f"{flag}: {k}") for k, toks in out.items()}


def _canonical(pairs: dict[str, Any], spellings: dict[str, str]) -> dict[str, Any]:
    return {spellings[k]: v for k, v in pairs.items()}


def parse_sun(text: str) -> dict[str, Any] | str:
    """A ``--sun`` value (``az=120,el=35,irradiance=8``, ``dir=x,y,z,...`` or ``none``) in sidecar form.

    Keys: ``azimuth``/``az``, ``elevation``/``el`` (degrees), ``direction``/``dir`` (x,y,z, toward the sun),
    ``irradiance`` or ``radiance`` (one number or r,g,b), ``angular_diameter`` (degrees).

    Raises:
        ConfigError: one line naming the bad key (``--sun: el: must be in [-90, 90], got 120``).
    """
    if isinstance(text, str) and text.strip() == NO_SUN:
        return NO_SUN
    pairs = parse_pairs(text, "--sun")
    parse_sun_spec(pairs, "--sun: ")
    return _canonical(pairs, _SUN)


def parse_sky(text: str) -> str | list[float]:
    """A ``--sky`` value: ``daylight``, ``none``, one number (grey) or ``r,g,b`` (linear radiance).

    Raises:
        ConfigError: anything else, e.g. ``--sky: must be 'daylight', 'none', one number or [r, g, b], ...``.
    """
    if not isinstance(text, str) or not text.strip():
        raise ConfigError("--sky: empty value; use daylight, none, one number or r,g,b")
    t = text.strip()
    if t in ("daylight", "none"):
        return t
    parts = [p.strip() for p in t.split(",")]
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise ConfigError(
            f"--sky: must be 'daylight', 'none', one number or r,g,b, got {show(text)}"
        ) from None
    value = vals[0] if len(vals) == 1 else vals
    parse_sky_value(value, "--sky")
    return [value] * 3 if isinstance(value, float) else vals


def parse_camera(text: str) -> tuple[str, dict[str, Any]]:
    """A ``--camera`` value: ``name=door,pos=1,1.6,4,look_at=0,1,0[,up=0,1,0][,fov=60]``.

    Returns:
        (name, the camera's sidecar mapping); the name defaults to ``camera``.

    Raises:
        ConfigError: one line naming the bad key (unknown key, look_at equal to pos, fov outside (0, 180)).
    """
    pairs = parse_pairs(text, "--camera")
    name = pairs.pop("name", "camera")
    if not isinstance(name, str):
        name = show(name)  # a numeric name such as name=2 reads as a float; keep its text
        name = name[:-2] if name.endswith(".0") else name
    parse_camera_spec(pairs, f"--camera {name}: ")
    return name, _canonical(pairs, _CAMERA)


def scene_overrides(
    sun: str | None = None, sky: str | None = None, cameras: Sequence[str] = ()
) -> dict[str, Any]:
    """The ``overrides`` mapping for ``load_scene`` from the CLI's ``--sun``, ``--sky`` and ``--camera``
    values (unset ones are left out, so the sidecar's value stands).

    Raises:
        ConfigError: a bad value (see the parsers), or two cameras with one name.
    """
    out: dict[str, Any] = {}
    if sun is not None:
        out["sun"] = parse_sun(sun)
    if sky is not None:
        out["sky"] = parse_sky(sky)
    cams: dict[str, Any] = {}
    for text in cameras:
        name, spec = parse_camera(text)
        if name in cams:
            raise ConfigError(f"--camera: name {name!r} is given twice")
        cams[name] = spec
    if cams:
        out["cameras"] = cams
    return out
