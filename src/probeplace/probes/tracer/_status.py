"""The light-field tracer's status codes: one enumeration for the single-probe march and the whole ray.

McGuire et al. 2017 §4.1 (Listing 1): a single-probe trace ends in a *hit*, a *miss* or *unknown* (the
ray passed behind what the probe sees); the ray's trace tries probes until one says hit or miss, and a
ray no probe decides is *unresolved* — the same code as "unknown", named for the ray. The values are what
``TraceResult.status`` holds and what the evaluation's per-status breakdown is keyed by.
"""

from __future__ import annotations

import enum


class TraceStatus(enum.IntEnum):
    """Outcome of a trace (an ``int`` subclass: usable in ``jnp.where`` and array comparisons)."""

    MISS = 0
    HIT = 1
    UNRESOLVED = 2
    UNKNOWN = 2  # alias: a single probe's "unknown" is the ray's "unresolved" when no probe is left

    @property
    def message(self) -> str:
        """What the status means, in a sentence."""
        return _MESSAGES[self]

    @property
    def label(self) -> str:
        """Lower-case name used as a metrics key (``miss``, ``hit``, ``unresolved``)."""
        return self.name.lower()


_MESSAGES = {
    TraceStatus.MISS: "miss: the ray leaves the scene in free space (every probe it used saw the way clear)",
    TraceStatus.HIT: "hit: a probe saw the ray meet a surface; t and probe say where and which",
    TraceStatus.UNRESOLVED: (
        "unresolved (single probe: unknown): the ray passed behind what the probes tried can see; "
        "t is the last point one of them saw free"
    ),
}
