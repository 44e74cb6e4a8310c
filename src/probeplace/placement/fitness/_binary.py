"""Binary visibility, coverage and Wang fitness: what a placement is reported and accepted on.

The same predicate as the soft objectives of ``_fitness`` (a sample is seen when it faces the probe and
nothing along the probe→sample segment is nearer than the sample minus its texel footprint; ``_fitness``
docstring), decided by exact rays: the SDF sphere tracer by default, or an exact caster (Embree). Coverage
reported in metadata, the automatic budget's search and a refinement's acceptance use these.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from ...geometry import SDFGrid, trace_sdf_rays
from ._fitness import PlacementProblem, _texel_angle, probe_clearance

_CHUNK = 1 << 16  # rays per jitted trace (SDF tracer, jittable casters): one compilation
_HOST_CHUNK = 1 << 20  # rays per call of a host caster (Embree): large batches keep its threads busy


def binary_visibility(problem: PlacementProblem, pos, *, caster=None, samples=None) -> np.ndarray:
    """Binary visibility (n_probes, n_samples) as the probes' octahedral maps decide it (module docstring).

    Sample x (distance d from probe p) is visible when nothing is hit on the segment from p toward x
    before d − tol, tol = max(2h, d·θ/2) the map's texel footprint (θ = √(4π)/R): the depth a texel of an
    R×R map stores is then no nearer than the sample minus the texel's extent, so the sample is in the
    map. With an exact caster this is one occlusion (any-hit) ray per (probe, facing sample) pair with
    t_max = d − tol; with the SDF tracer it is the first sphere-traced hit compared with d − tol. Both
    decide the same predicate; they differ only where the SDF (voxel h) blurs geometry thinner than ~h.

    Args:
        problem: the fitness model.
        pos: probe positions (n_probes, 3), host or device array.
        caster: optional exact ray caster (``geometry`` :class:`AbstractRayCaster`); default the SDF tracer.
            A host caster (``caster.jittable`` false: Embree) answers through ``occluded_host`` in large
            batches; a jittable one through its jitted ``occluded`` in fixed-size chunks (one compilation).
        samples: optional indices of the samples to test (columns of the result); default all.

    Returns:
        Host boolean array (n_probes, n_samples or len(samples)); coverable-ness is not applied (use
        :func:`binary_coverage`).
    """
    pos = np.asarray(pos, np.float32).reshape(-1, 3)
    x = np.asarray(problem.position, np.float32)
    nrm = np.asarray(problem.normal, np.float32)
    if samples is not None:
        sel = np.asarray(samples, np.int64).ravel()
        x, nrm = x[sel], nrm[sel]
    h = float(problem.voxel)
    theta = _texel_angle(problem.config.map_res)
    out = np.zeros((len(pos), len(x)), bool)
    if len(pos) == 0 or len(x) == 0:
        return out
    inside = probe_clearance(problem, pos) <= 0.0
    host = caster is not None and not caster.jittable
    chunk = _HOST_CHUNK if host else _CHUNK
    # The rays of several probes share one cast (a probe's few thousand facing samples would otherwise
    # pad a whole chunk): probes are gathered until a chunk is full, then cast at once.
    batch: list[tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    n_batch = 0

    def flush():
        o = np.concatenate([np.broadcast_to(pos[k], (len(i), 3)) for k, i, _, _, _ in batch])
        u = np.concatenate([b[2] for b in batch])
        reach = np.concatenate([b[4] for b in batch])  # d − tol: a hit nearer than this hides the sample
        if host:
            blocked = caster.occluded_host(o, u, reach)
        else:
            blocked = _blocked(problem.grid, o, u, np.concatenate([b[3] for b in batch]), reach, caster)
        blocked &= reach > 0.0  # nothing can hide a sample closer than its own texel footprint
        s = 0
        for k, idx, _, _, _ in batch:
            out[k, idx] = ~blocked[s : s + len(idx)]
            s += len(idx)
        batch.clear()

    for k in range(len(pos)):
        if inside[k]:
            continue
        v = x - pos[k][None]
        d = np.sqrt(np.einsum("ij,ij->i", v, v))
        # Only rays that can count are traced: facing samples (unless two-sided).
        if problem.config.two_sided:
            idx = np.flatnonzero(d > 0.0)
        else:
            idx = np.flatnonzero(np.einsum("ij,ij->i", v, nrm) < 0.0)
        if n_batch and n_batch + len(idx) > chunk:
            flush()
            n_batch = 0
        dk = d[idx]
        u = v[idx] / np.maximum(dk, 1e-30)[:, None]
        batch.append((k, idx, u, dk, dk - np.maximum(2.0 * h, dk * (theta / 2.0))))
        n_batch += len(idx)
    if batch:
        flush()
    return out


def _blocked(
    grid: SDFGrid, o: np.ndarray, u: np.ndarray, d: np.ndarray, reach: np.ndarray, caster
) -> np.ndarray:
    """Whether each ray hits something with 0 < t < reach, in fixed-size chunks (one compilation).

    The SDF tracer marches to the sample (t_max = d) and its first hit is compared with ``reach``; an
    exact caster answers the occlusion query up to ``reach`` directly.
    """
    n = len(o)
    out = np.empty(n, bool)
    for s in range(0, n, _CHUNK):
        e = min(n, s + _CHUNK)
        pad = _CHUNK - (e - s)
        oo = jnp.asarray(np.pad(o[s:e], ((0, pad), (0, 0))))
        uu = jnp.asarray(np.pad(u[s:e], ((0, pad), (0, 0)), constant_values=1.0 / math.sqrt(3.0)))
        if caster is None:
            t, _ = trace_sdf_rays(grid, oo, uu, jnp.asarray(np.pad(d[s:e], (0, pad))))
            b = np.asarray(t)[: e - s] < reach[s:e]
        else:
            tm = jnp.asarray(np.pad(np.maximum(reach[s:e], 0.0), (0, pad)))
            b = caster.occluded(oo, uu, tm)
        out[s:e] = np.asarray(b)[: e - s]
    return out


def binary_coverage(problem: PlacementProblem, vis: np.ndarray, active: np.ndarray | None = None) -> float:
    """Share of coverable area seen by at least one (active) probe, from :func:`binary_visibility`."""
    if active is not None:
        vis = vis[np.asarray(active, bool)]
    cov = np.asarray(problem.coverable)
    a = np.asarray(problem.area, np.float64) * cov
    seen = vis.any(axis=0) if len(vis) else np.zeros(len(a), bool)
    return float((a * seen).sum() / max(a.sum(), 1e-300))


@dataclass(frozen=True, eq=False)
class CoverageDetail:
    """Each probe's part in the binary coverage of a set (:func:`coverage_counts`), over the *coverable*
    samples of the coverage problem (the samples ``binary_coverage`` weighs; the others no probe in the
    box can see and count nowhere here).

    Attributes:
        seen: (n_probes,) int64, how many coverable samples each probe sees.
        unique: (n_probes,) int64, how many coverable samples only that probe sees.
        seen_area: (n_probes,) float64, the coverable area each probe sees, as a share of all of it.
        unique_area: (n_probes,) float64, the coverable area only that probe sees, as a share of all of it.
        n_multiple: coverable samples seen by two probes or more.
        uncovered: (n_uncovered,) int64 indices of the coverable samples no probe sees.
        uncovered_pos: (n_uncovered, 3) float32 their positions, world frame, scene units.
        uncovered_normal: (n_uncovered, 3) float32 their unit normals.
        n_samples: samples of the coverage problem (coverable or not).
        n_coverable: its coverable samples; ``unique.sum() + n_multiple + len(uncovered) == n_coverable``.
        coverage: share of the coverable area seen by at least one probe (``binary_coverage``).
    """

    seen: np.ndarray
    unique: np.ndarray
    seen_area: np.ndarray
    unique_area: np.ndarray
    n_multiple: int
    uncovered: np.ndarray
    uncovered_pos: np.ndarray
    uncovered_normal: np.ndarray
    n_samples: int
    n_coverable: int
    coverage: float

    def save(self, path) -> None:
        """Write the detail as an ``.npz`` (atomically): :meth:`arrays` and ``format`` =
        ``probeplace.CoverageDetail/1``, read by ``probeplace view`` without JAX."""
        from ..._core import write_atomic
        from ..._core.files import COVERAGE_DETAIL_FORMAT

        arrays = {"format": np.asarray(COVERAGE_DETAIL_FORMAT), **self.arrays()}
        write_atomic(path, lambda f: np.savez_compressed(f, **arrays))

    def arrays(self) -> dict[str, np.ndarray]:
        """The detail as named arrays (``np.savez``; scalars as 0-d arrays): the keys are the attribute
        names (docs/placement.md "Coverage detail")."""
        return {
            "seen": self.seen,
            "unique": self.unique,
            "seen_area": self.seen_area,
            "unique_area": self.unique_area,
            "n_multiple": np.asarray(self.n_multiple, np.int64),
            "uncovered": self.uncovered,
            "uncovered_pos": self.uncovered_pos,
            "uncovered_normal": self.uncovered_normal,
            "n_samples": np.asarray(self.n_samples, np.int64),
            "n_coverable": np.asarray(self.n_coverable, np.int64),
            "coverage": np.asarray(self.coverage, np.float64),
        }


def coverage_counts(problem: PlacementProblem, vis: np.ndarray) -> CoverageDetail:
    """Per-probe seen / unique counts and the uncovered samples of binary visibility ``vis``
    ((n_probes, n_samples) from :func:`binary_visibility`: the same rows ``binary_coverage`` reads)."""
    vis = np.asarray(vis, bool)
    cov = np.asarray(problem.coverable, bool)
    if vis.ndim != 2 or vis.shape[1] != len(cov):
        raise ValueError(f"vis must be (n_probes, {len(cov)}), got {vis.shape}")
    area = np.asarray(problem.area, np.float64) * cov
    total = max(float(area.sum()), 1e-300)
    v = vis & cov[None]
    count = v.sum(axis=0)
    only = v & (count == 1)[None]
    none = np.flatnonzero(cov & (count == 0))
    return CoverageDetail(
        seen=v.sum(axis=1).astype(np.int64),
        unique=only.sum(axis=1).astype(np.int64),
        seen_area=(v @ area) / total,
        unique_area=(only @ area) / total,
        n_multiple=int((count >= 2).sum()),
        uncovered=none.astype(np.int64),
        uncovered_pos=np.asarray(problem.position, np.float32)[none].reshape(-1, 3),
        uncovered_normal=np.asarray(problem.normal, np.float32)[none].reshape(-1, 3),
        n_samples=len(cov),
        n_coverable=int(cov.sum()),
        coverage=binary_coverage(problem, vis),
    )


def wang_fitness_binary(problem: PlacementProblem, pos, vis: np.ndarray | None = None) -> float:
    """Eq. 1–2 with binary visibility (d̄ₖ from the same binary visibility, see probe_distance_term)."""
    vis = binary_visibility(problem, pos) if vis is None else vis
    pos = jnp.asarray(pos, jnp.float32).reshape(-1, 3)
    x = np.asarray(problem.position, np.float64)
    n = np.asarray(problem.normal, np.float64)
    v = x[None] - np.asarray(pos, np.float64)[:, None]
    omega = -np.sum(v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-30) * n[None], axis=-1)
    if problem.config.two_sided:
        omega = np.abs(omega)
    w = np.asarray(problem.weight, np.float64)
    # Eq. 2's d̄ₖ with the binary visibility (probe_distance_term)
    dbar = (vis * np.linalg.norm(v, axis=-1)) @ w / float(problem.diag)
    cfg = problem.config
    term = (cfg.w1 * omega + cfg.w2 * dbar[:, None]) * vis
    return float((term @ w).sum())
