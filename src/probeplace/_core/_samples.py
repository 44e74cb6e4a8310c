"""Sample counts chosen from a noise target (issue 33, "Samples from a noise target"). Plain Python.

A count field (the reference's paths per pixel, the CRN reference's paths per GGX direction, the bake's
paths per texel ray) holds either a fixed int or :data:`AUTO`. With ``"auto"`` a pilot pass at a small
count measures the noise; the variance of a Monte Carlo mean falls as 1/n, so the pilot predicts the
noise at any count, and the run takes the smallest count (:func:`smallest_count`) whose prediction meets
the target, never more than a cap. The evaluation (``evaluate._samples``) and the bake
(``probes._bake_samples``) each say what their noise and their target are; this module holds what they
share: the value checks and the search.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ._errors import ConfigError

#: The value of a count field that asks for the count to be chosen from the noise target.
AUTO = "auto"
#: Standard errors added to a pilot's noise figure: its one-sided 95 % upper bound (normal quantile; each
#: figure is a mean over hundreds of independent pixels or thousands of texels, so its sampling
#: distribution is near normal). Per-pixel and per-texel variances from a few paths are skewed (a rare
#: bright path is usually missed), so the point estimate tends to fall short of the truth.
PILOT_Z = 1.645


def is_auto(value) -> bool:
    """``value`` asks for a chosen count (``"auto"``)."""
    return isinstance(value, str) and value == AUTO


def check_count(value, name: str, *, minimum: int = 1) -> None:
    """Refuse a count field that is neither an int ≥ ``minimum`` nor ``"auto"``.

    Raises:
        ConfigError: ``{name} must be a positive int or 'auto', got ...`` (``an int ≥ {minimum}`` for a
            ``minimum`` above 1; one line).
    """
    if is_auto(value):
        return
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        what = "a positive int" if minimum == 1 else f"an int ≥ {minimum}"
        raise ConfigError(f"{name} must be {what} or {AUTO!r}, got {value!r}")


def check_target(owner: str, *, noise_target, pilot_spp, max_spp, min_pilot: int = 1) -> None:
    """Refuse a noise target outside (0, 1), a pilot count below ``min_pilot`` or a cap below the pilot
    count (the chosen count lies between them). ``owner`` prefixes the field names (``EvalConfig``).

    Raises:
        ConfigError: one line naming the field.
    """
    if (
        isinstance(noise_target, bool)
        or not isinstance(noise_target, int | float)
        or not 0 < noise_target < 1
    ):
        raise ConfigError(f"{owner}.noise_target must be a number in (0, 1), got {noise_target!r}")
    for name, v, lo in (("pilot_spp", pilot_spp, min_pilot), ("max_spp", max_spp, min_pilot)):
        if isinstance(v, bool) or not isinstance(v, int) or v < lo:
            raise ConfigError(f"{owner}.{name} must be an int ≥ {lo}, got {v!r}")
    if max_spp < pilot_spp:
        raise ConfigError(
            f"{owner}.max_spp must be ≥ pilot_spp ({pilot_spp}): the chosen count lies between them, "
            f"got {max_spp!r}"
        )


def mean_and_se(values) -> tuple[float, float]:
    """The mean of ``values`` (an array) and its standard error (sample σ / √n; 0 for one value). NumPy is
    imported here: this module is plain Python, imported by every front door at start-up."""
    import numpy as np

    x = np.asarray(values)
    se = float(np.std(x, ddof=1) / np.sqrt(x.size)) if x.size > 1 else 0.0
    return float(np.mean(x)), se


def json_number(value):
    """``value``, or None for an infinity (JSON has none: e.g. a noise ratio of an image without signal)."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def smallest_count(meets: Callable[[int], bool], *, lo: int, cap: int) -> tuple[int, bool]:
    """The smallest count among ``lo`` and the powers of two above it for which ``meets(count)``, and
    True; when none up to ``cap`` does, ``(cap, False)``.

    Powers of two: a count twice as large halves the variance, so finer steps would buy little, and a
    few distinct counts keep the compiled programs few (their batch shapes depend on the count).
    """
    n = lo
    while n < cap:
        if meets(n):
            return n, True
        n = 1 << n.bit_length()  # the next power of two above n
    return cap, bool(meets(cap))
