"""Exact budgets: a method asked for N probes returns exactly N usable probes.

A method first lays or searches its own set (the nearest lattice to N, the skeleton search's best ≤ N,
Vardis's simplification to N), the set is made valid (``_valid``: relocated out of geometry, kept in the
region), and then this module trims or fills it to N by one stated rule, the same for every method:

* **trim** (more than N): remove, one at a time, the probe whose removal loses the least covered area (its
  *unique* area under the binary visibility of the coverage problem: the area no other probe sees);
  ties — common once coverage is saturated — go to the probe nearest another probe (the most redundant),
  then to the highest index. Removing probe j loses exactly its unique area, so the counts update
  incrementally (as the automatic search's removal step, ``_auto``).
* **fill** (fewer than N): add, one at a time, the pool point farthest from every probe so far
  (farthest-point sampling: the emptiest part of the valid space first); ties go to the lowest index. The
  pool is the method's own spare candidates (unchosen seeds) and a lattice over the valid space, refined
  until it holds enough points.

Coverage is not the fill's criterion on purpose: a set trimmed or searched to N already holds the best
coverage its method found, and filling by coverage gain would make every method the greedy search.

A **memory budget** (bytes) becomes a count here too: ``count_for_memory(bytes, bytes_per_probe)``, where the
bake stage gives ``bytes_per_probe`` from its settings (``probes.probe_bytes``; placement does not import
the bake).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import spatial

from ..._core import ConfigError, check_memory
from ..._core.runtime import parse_bytes as parse_bytes  # re-exported: placement's public API


def check_probe_count(n: int, bytes_per_probe: int, what: str, settings: str, hint: str) -> None:
    """Refuse, before placing, a probe count whose baked maps would not fit in memory (issue 31:
    ``--budget 1000000000`` ran for minutes and could never have been baked). The maps are the larger
    cost: a probe's candidate position and visibility row hold far fewer bytes than its maps.

    Args:
        n: the probe count asked for.
        bytes_per_probe: one baked probe's maps (``probes.probe_bytes``).
        what: the option that asked, e.g. ``"--budget 1000000000"``.
        settings: the bake settings the estimate is for, e.g. ``"radiance_res=32, geometry_res=32"``.
        hint: how to ask for fewer, in the caller's terms.

    Raises:
        ResourceError: ``n × bytes_per_probe`` is over the memory limit (``_core.check_memory``).
    """
    n, per = int(n), int(bytes_per_probe)
    check_memory(n * per, f"{what}: baking {n} probes ({per} bytes each at {settings})", hint)


def count_for_memory(memory: int | str, bytes_per_probe: int) -> int:
    """The most probes whose baked maps fit in ``memory`` (ConfigError when not even one does)."""
    total = parse_bytes(memory)
    n = total // int(bytes_per_probe)
    if n < 1:
        raise ConfigError(
            f"memory budget {memory!r} ({total} bytes) is smaller than one probe ({bytes_per_probe} bytes "
            "at these bake settings)"
        )
    return int(n)


@dataclass(frozen=True)
class BudgetFit:
    """What :func:`fit_to_budget` did.

    Attributes:
        pos: exactly ``budget`` positions (fewer only when the valid space cannot hold them: ``short``).
        n_before: probes the method gave.
        n_trimmed: probes removed (least unique coverage first).
        n_filled: probes added (farthest point first).
        short: probes still missing (the pool ran out; 0 normally).
        kept: indices (into the method's set) of the probes kept, in order: they are the first
            ``len(kept)`` rows of ``pos``; the rows after them are the filled ones.
    """

    pos: np.ndarray
    n_before: int
    n_trimmed: int
    n_filled: int
    short: int = 0
    kept: np.ndarray | None = None

    @property
    def filled(self) -> np.ndarray:
        """Indices (into ``pos``) of the filled probes."""
        n_kept = self.n_before - self.n_trimmed
        return np.arange(n_kept, len(self.pos), dtype=np.int64)

    def record(self) -> dict:
        """The JSON record for the metadata (``budget_fit``)."""
        return {
            "n_before": self.n_before,
            "n_trimmed": self.n_trimmed,
            "n_filled": self.n_filled,
            "short": self.short,
            "rule": "trim least unique coverage; fill farthest valid point",
        }


def trim_order(rows: np.ndarray, area: np.ndarray, pos: np.ndarray, n_remove: int) -> np.ndarray:
    """Indices of the ``n_remove`` probes to remove (module docstring's trim rule), in removal order.

    ``rows``: binary visibility (n_probes, n_samples); ``area``: each sample's coverable area.
    """
    rows = np.asarray(rows, bool)
    count = rows.sum(axis=0).astype(np.int64)
    alive = np.ones(len(rows), bool)
    removed = []
    for _ in range(int(n_remove)):
        unique = (rows & (count == 1)[None]) @ area  # area only probe j sees
        live = np.flatnonzero(alive)
        near = _nearest_other(pos[live])
        # lexsort: last key first — least unique area, then nearest neighbour, then highest index
        j = live[np.lexsort((-live, near, unique[live]))[0]]
        removed.append(j)
        alive[j] = False
        count -= rows[j]
    return np.asarray(removed, np.int64)


def _nearest_other(pos: np.ndarray) -> np.ndarray:
    if len(pos) < 2:
        return np.full(len(pos), np.inf)
    d, _ = spatial.cKDTree(pos).query(pos, k=2)
    return d[:, 1]


def fill_order(pos: np.ndarray, pool: np.ndarray, n_add: int) -> np.ndarray:
    """Indices into ``pool`` of the ``n_add`` points to add, farthest from every probe so far first."""
    pool = np.asarray(pool, np.float64).reshape(-1, 3)
    n_add = min(int(n_add), len(pool))
    if n_add <= 0:
        return np.zeros(0, np.int64)
    if len(pos):
        d = spatial.cKDTree(np.asarray(pos, np.float64)).query(pool)[0]
    else:
        d = np.full(len(pool), np.inf)
    picked = []
    for _ in range(n_add):
        j = int(np.argmax(d))  # argmax: the lowest index among ties
        picked.append(j)
        d = np.minimum(d, np.linalg.norm(pool - pool[j], axis=1))
        d[j] = -np.inf
    return np.asarray(picked, np.int64)


def fit_to_budget(pos: np.ndarray, budget: int, *, visibility, area: np.ndarray, pool_fn) -> BudgetFit:
    """Trim or fill ``pos`` to exactly ``budget`` probes (module docstring).

    Args:
        pos: the method's valid probes (n, 3).
        budget: the count asked for.
        visibility: ``visibility(pos) -> (n, n_samples) bool``, the coverage problem's binary visibility
            (only called to trim).
        area: each sample's coverable area (0 where not coverable).
        pool_fn: ``pool_fn(n_needed) -> (m, 3)`` valid fill candidates, at least ``n_needed`` when the
            valid space holds that many (only called to fill).
    """
    pos = np.asarray(pos, np.float32).reshape(-1, 3)
    n, budget = len(pos), int(budget)
    if n > budget:
        drop = trim_order(visibility(pos), np.asarray(area, np.float64), pos, n - budget)
        keep = np.setdiff1d(np.arange(n), drop)
        return BudgetFit(pos[keep], n, n - budget, 0, kept=keep)
    if n < budget:
        pool = np.asarray(pool_fn(budget - n), np.float32).reshape(-1, 3)
        add = fill_order(pos, pool, budget - n)
        out = np.concatenate([pos, pool[add]])
        return BudgetFit(out, n, 0, len(add), short=budget - len(out), kept=np.arange(n))
    return BudgetFit(pos, n, 0, 0, kept=np.arange(n))
