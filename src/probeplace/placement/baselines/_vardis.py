"""Vardis et al. 2021 ("Illumination-driven Light Probe Placement", Eurographics 2021 posters): greedy
simplification of a dense probe set driven by the radiance it reconstructs at evaluation points.

Setup (§2): a dense probe set (a uniform grid, :func:`~probeplace.placement.uniform_probe_grid`, or a
Poisson-disk set in free space, :func:`poisson_disk_probes`) with SH L2 incident radiance per probe
(:func:`dense_probe_sh`, path traced), evaluation points (:func:`evaluation_points`: on surfaces, on a
grid in free space, or along paths) and the *reference*: the dense set's interpolation at the points.
Interpolation is tetrahedral (Cupisz 2012, as the authors' Unity prototype; :mod:`._tetra`).

Error (§2, "Illumination criteria"): values are converted to YCoCg (Malvar & Sullivan 2003) and compared
with the reference per colour component, weighted by ``(w_Y, w_C, w_C)`` — the paper's presets
``chrominance`` (0.1, 0.45) and ``luminance`` (1.0, 0.0). ``error=`` picks what is compared: ``"sh"``
the 9 SH coefficients, ``"directions"`` the radiance in a fixed Fibonacci direction set, ``"average"``
the mean radiance over the sphere (the paper's "individual sampling directions or average"); absolute
differences are averaged over coefficients / directions. The paper's *percentage* error divides by the
reference; Co and Cg of a grey value are 0, so every component is divided by the point's reference
**mean luminance** (floored at 1e-3 of the mean over points) — a percentage of the local brightness. The
total error is the mean over evaluation points.

Simplification (§2): repeatedly remove the probe whose removal gives the smallest total error, until a
target count or until the next removal would exceed an error tolerance. Each candidate's removal is scored
locally: only points in tetrahedra incident to it (and outside-hull points using it as nearest) change;
their new weights come from a local re-tetrahedralisation of its cavity (:class:`._tetra.TetMesh`), and
all candidates are scored in one jitted, padded JAX reduction. Past the poster (its "Future work"): scores
are cached and only candidates whose neighbourhood changed are re-scored (local connectivity update), and
``per_iteration > 1`` removes several non-interacting probes per iteration (an independent set: no
candidate is in another's 1-ring or nearest-replacement set, so their affected points are disjoint and
their scores add up exactly).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ..._core import ConfigError, Scene, SceneError, next_pow2, scene_box
from ..._core.maths import sh_basis
from ..space import fibonacci_directions
from ._tetra import RemovalPlan, TetMesh

ERROR_MODES = ("sh", "directions", "average")
# (w_Y, w_C) presets of Vardis et al. 2021 §2.
WEIGHT_PRESETS = {"chrominance": (0.1, 0.45), "luminance": (1.0, 0.0)}
# YCoCg (Malvar & Sullivan 2003): rows Y, Co, Cg of RGB.
YCOCG = np.array([[0.25, 0.5, 0.25], [0.5, 0.0, -0.5], [-0.25, 0.5, -0.25]])
Y00 = 0.282095  # SH band-0 basis constant (R&H 2001 Eq. 3); mean radiance = c00 · Y00
# lazy greedy: candidates of the ranking's head re-scored together when one of them is stale
LAZY_HEAD = 32
# float32 elements per scoring chunk (candidates × points × 4 × features × 3): bounds the gather's memory.
CHUNK_ELEMENTS = 1 << 24


def check_vardis_light(scene: Scene) -> None:
    """Refuse a scene without light before any work: Vardis ranks probes by the radiance they reconstruct
    (path-traced, :func:`dense_probe_sh`), so unlike the geometric methods it needs a light.

    Raises:
        SceneError: one line naming the method, the scene and the sidecar keys that add light.
    """
    from ...scene import no_light_hint

    if not scene.has_light:
        raise SceneError(
            f"vardis placement ranks probes by the light they see, and scene {scene.name!r} has no light (no "
            f"emissive material, sun or sky); {no_light_hint(stem=scene.name)}; or use a method that needs "
            "no light (skeleton+medial, grid, lod-grid)"
        )


def stratified_directions(n_probes: int, n_dirs: int, *, key: jax.Array) -> np.ndarray:
    """(n_probes, k², 3) unit directions, one jittered sample per cell of a k × k split of (cos θ, φ)
    (equal-area strata), ``k = ⌈√n_dirs⌉``; fresh jitter per probe."""
    k = max(1, math.ceil(math.sqrt(n_dirs)))
    xi = np.asarray(jax.random.uniform(key, (n_probes, k * k, 2), jnp.float32), np.float64)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    u = (i.ravel()[None] + xi[..., 0]) / k
    v = (j.ravel()[None] + xi[..., 1]) / k
    z = 1.0 - 2.0 * u
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * v
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1).astype(np.float32)


def dense_probe_sh(
    scene: Scene,
    pos,
    *,
    n_dirs: int = 64,
    spp: int = 4,
    max_depth: int = 4,
    key: jax.Array,
    caster=None,
) -> Float[Array, "n_probes 9 3"]:
    """SH L2 incident radiance (three.js convention, :mod:`probeplace._core.maths._sh`) at each probe.

    Traces ``k² ≥ n_dirs`` stratified directions per probe with :func:`probeplace.render.trace_rays`
    (the ``full`` component: emitted + reflected, what the probe sees) and projects with Monte Carlo
    weights ``4π / k²``: ``c_lm = 4π/N Σ L(ω_i) Y_lm(ω_i)``.

    Args:
        scene: the scene.
        pos: probe positions (n, 3), world frame.
        n_dirs: directions per probe (rounded up to a square).
        spp: paths per direction.
        max_depth: path length.
        key: PRNG key (directions, paths).
        caster: ray caster for the tracer (default: the tracer's).

    Returns:
        (n, 9, 3) float32 coefficients.
    """
    from ...render import trace_rays

    pos = np.asarray(pos, np.float32).reshape(-1, 3)
    if len(pos) == 0:
        raise ConfigError("dense_probe_sh needs at least one probe position")
    if n_dirs < 1 or spp < 1:
        raise ConfigError(f"n_dirs and spp must be ≥ 1, got {n_dirs} and {spp}")
    k_dir, k_tr = jax.random.split(key)
    dirs = stratified_directions(len(pos), n_dirs, key=k_dir)  # (n, N, 3)
    n, m = dirs.shape[:2]
    origins = np.repeat(pos, m, axis=0)
    rad = trace_rays(
        scene,
        jnp.asarray(origins, jnp.float32),
        jnp.asarray(dirs.reshape(-1, 3), jnp.float32),
        spp=spp,
        key=k_tr,
        max_depth=max_depth,
        caster=caster,
    )
    radiance = np.asarray(rad.component("full"), np.float64).reshape(n, m, 3)
    basis = sh_basis(dirs.astype(np.float64))  # (n, N, 9)
    sh = np.einsum("nmk,nmc->nkc", basis, radiance) * (4.0 * np.pi / m)
    return jnp.asarray(sh, jnp.float32)


def _sdf_values(sdf, pts: np.ndarray) -> np.ndarray:
    from ...geometry import lookup_sdf

    return lookup_sdf(sdf, pts).astype(np.float64)


def poisson_disk_probes(
    scene: Scene, radius: float, *, key: jax.Array, sdf=None, clearance: float | None = None, bounds=None
) -> np.ndarray:
    """Poisson-disk probe positions in free space (dart throwing over 30 candidates per disk volume,
    accepted in random order when no accepted point is within ``radius`` and the SDF exceeds
    ``clearance``, default one voxel); (n, 3) float32."""
    from scipy.spatial import cKDTree

    from ...geometry import build_sdf

    if not (np.isfinite(radius) and radius > 0):
        raise ConfigError(f"radius must be a positive number, got {radius!r}")
    lo, hi = scene_box(scene, bounds)
    n_cand = int(30 * np.prod(hi - lo) / (4.0 / 3.0 * np.pi * (radius / 2) ** 3))
    if n_cand > 2_000_000:
        raise ConfigError(f"radius {radius} is too small for the scene box (over 2e6 candidates)")
    sdf = build_sdf(scene) if sdf is None else sdf
    clear = float(sdf.voxel_size) if clearance is None else float(clearance)
    cand = lo + (hi - lo) * np.asarray(jax.random.uniform(key, (max(n_cand, 1), 3), jnp.float32), np.float64)
    cand = cand[_sdf_values(sdf, cand) > clear]
    taken = np.zeros(len(cand), bool)
    gone = np.zeros(len(cand), bool)
    nbrs = cKDTree(cand).query_ball_point(cand, radius)
    for i in range(len(cand)):
        if not gone[i]:
            taken[i] = True
            gone[nbrs[i]] = True
    return cand[taken].astype(np.float32)


def evaluation_points(
    scene: Scene,
    n: int,
    *,
    key: jax.Array,
    kind: str = "surface",
    offset: float | None = None,
    paths=None,
    sdf=None,
    bounds=None,
) -> np.ndarray:
    """Evaluation points (n, 3) float32 (Vardis et al. 2021 §2: "scattered with a user-selected
    space-filling strategy").

    Args:
        scene: the scene.
        n: number of points.
        key: PRNG key.
        kind: ``"surface"`` (area-uniform surface samples, :func:`probeplace.geometry.sample_surface`,
            moved ``offset`` along the normal to the side where the SDF is larger, among sides inside the
            scene box), ``"grid"`` (a jittered
            lattice in free space, SDF > one voxel) or ``"paths"`` (evenly by arc length along polylines).
        offset: surface offset (default two SDF voxels).
        paths: list of (k ≥ 2, 3) polylines, for ``"paths"``.
        sdf: SDF (built when needed).
        bounds: (lo, hi) box of ``"grid"`` and ``"surface"`` (default the scene box).
    """
    from ...geometry import build_sdf, sample_surface

    if not (isinstance(n, int | np.integer) and n >= 1):
        raise ConfigError(f"n must be a positive integer, got {n!r}")
    if kind == "paths":
        if not paths:
            raise ConfigError("kind='paths' needs paths: a list of (k ≥ 2, 3) polylines")
        segs = []
        for pl in paths:
            pl = np.asarray(pl, np.float64)
            if pl.ndim != 2 or pl.shape[1] != 3 or len(pl) < 2:
                raise ConfigError(f"each path must be (k ≥ 2, 3), got {pl.shape}")
            segs.extend(itertools.pairwise(pl))
        a, b = np.array([s[0] for s in segs]), np.array([s[1] for s in segs])
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(b - a, axis=1))])
        if cum[-1] <= 0:
            raise ConfigError("paths have zero length")
        s = (np.arange(n) + 0.5) / n * cum[-1]
        i = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(a) - 1)
        t = ((s - cum[i]) / np.maximum(cum[i + 1] - cum[i], 1e-300))[:, None]
        return (a[i] + t * (b[i] - a[i])).astype(np.float32)
    sdf = build_sdf(scene) if sdf is None else sdf
    h = float(sdf.voxel_size)
    k_s, k_c = jax.random.split(key)
    if kind == "surface":
        from ...geometry import default_sample_spacing

        spacing = default_sample_spacing(scene)
        tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = 0.5 * float(np.linalg.norm(cross, axis=1).sum())
        spacing = min(spacing, math.sqrt(area / (2 * n)))
        smp = sample_surface(scene, key=k_s, spacing=spacing)
        pick = np.asarray(jax.random.choice(k_c, len(smp.area), (n,), replace=len(smp.area) < n))
        x = np.asarray(smp.position, np.float64)[pick]
        nrm = np.asarray(smp.normal, np.float64)[pick]
        off = 2.0 * h if offset is None else float(offset)
        front, back = x + off * nrm, x - off * nrm
        lo, hi = scene_box(scene, bounds)
        inbox = lambda q: np.all((q > lo) & (q < hi), axis=1)
        # the side with the larger SDF, among sides inside the scene box (open scenes: not behind walls)
        flip = np.where(inbox(back), _sdf_values(sdf, back), -np.inf) > np.where(
            inbox(front), _sdf_values(sdf, front), -np.inf
        )
        return np.where(flip[:, None], back, front).astype(np.float32)
    if kind == "grid":
        lo, hi = scene_box(scene, bounds)
        pts = np.zeros((0, 3))
        m = n
        for _ in range(8):  # grow the lattice until enough free points
            k = max(1, math.ceil((2 * m) ** (1 / 3)))
            step = (hi - lo) / k
            g = np.stack(np.meshgrid(*[np.arange(k)] * 3, indexing="ij"), -1).reshape(-1, 3)
            xi = np.asarray(jax.random.uniform(k_s, g.shape, jnp.float32), np.float64)
            pts = lo + (g + xi) * step
            pts = pts[_sdf_values(sdf, pts) > h]
            if len(pts) >= n:
                break
            m *= 2
        if len(pts) < n:
            raise ConfigError(f"found only {len(pts)} free grid points for n={n}")
        pick = np.sort(np.asarray(jax.random.choice(k_c, len(pts), (n,), replace=False)))
        return pts[pick].astype(np.float32)
    raise ConfigError(f"kind must be 'surface', 'grid' or 'paths', got {kind!r}")


def error_features(sh: np.ndarray, mode: str = "sh", n_dirs: int = 32) -> np.ndarray:
    """YCoCg features (n, m, 3) the error compares: SH coefficients (m = 9), radiance in ``n_dirs``
    Fibonacci directions, or the mean radiance (m = 1). Linear in ``sh``, so interpolating features
    equals featurising interpolated values."""
    sh = np.asarray(sh, np.float64)
    if mode == "sh":
        rgb = sh
    elif mode == "directions":
        rgb = np.einsum("dk,nkc->ndc", sh_basis(fibonacci_directions(n_dirs).astype(np.float64)), sh)
    elif mode == "average":
        rgb = sh[:, :1] * Y00
    else:
        raise ConfigError(f"error must be one of {ERROR_MODES}, got {mode!r}")
    return rgb @ YCOCG.T


def _weights(weights) -> np.ndarray:
    if isinstance(weights, str):
        if weights not in WEIGHT_PRESETS:
            raise ConfigError(f"weights must be {tuple(WEIGHT_PRESETS)} or (w_Y, w_C), got {weights!r}")
        weights = WEIGHT_PRESETS[weights]
    w = np.asarray(weights, np.float64).reshape(-1)
    if w.shape != (2,) or not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ConfigError(f"weights (w_Y, w_C) must be two non-negative numbers, not both 0; got {weights}")
    return np.array([w[0], w[1], w[1]])


@jax.jit
def _score_chunk(feat, ref, inv_den, wc, err_cur, pt, idx, w, mask):
    """Per candidate: new per-point errors (c, a) and the change of the summed error (c,)."""
    val = jnp.einsum("cak,cakmj->camj", w, feat[idx])
    e = jnp.mean(jnp.einsum("camj,j->cam", jnp.abs(val - ref[pt]), wc), axis=-1) * inv_den[pt]
    e = jnp.where(mask, e, jnp.zeros_like(e))
    return e, jnp.sum(e - jnp.where(mask, err_cur[pt], jnp.zeros_like(e)), axis=-1)


@dataclasses.dataclass(frozen=True, eq=False)
class VardisResult:
    """Outcome of :func:`vardis_simplify`.

    Attributes:
        keep: surviving probes (n,) bool.
        removal_order: removed probe indices, in removal order.
        history_count: probe count after each iteration (starts with n).
        history_error: total (mean) error after each iteration (starts with 0).
        error: final total error.
        n_iterations: iterations of the outer loop.
        n_scored: candidate evaluations (batched) over the run.
        timings: seconds: ``setup_s`` (tetrahedralisation, reference), ``loop_s``.
    """

    keep: np.ndarray
    removal_order: np.ndarray
    history_count: np.ndarray
    history_error: np.ndarray
    error: float
    n_iterations: int
    n_scored: int
    timings: dict


class _Scorer:
    """Device-side constants of one run and the padded batched scoring of removal plans."""

    def __init__(self, feat, ref, inv_den, wc):
        self.feat = jnp.asarray(feat, jnp.float32)
        self.ref = jnp.asarray(ref, jnp.float32)
        self.inv_den = jnp.asarray(inv_den, jnp.float32)
        self.wc = jnp.asarray(wc, jnp.float32)
        self.m = int(feat.shape[1])

    def score(self, plans, err_cur: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
        """(Δ summed error per plan, per-plan new point errors), one padded jitted call per chunk."""
        if not plans:
            return np.zeros(0), []
        a = next_pow2(max(len(p.points) for p in plans), lo=8)
        cmax = max(1, 1 << int(math.log2(max(1, CHUNK_ELEMENTS // (a * 4 * self.m * 3)))))
        c = min(next_pow2(len(plans), lo=8), cmax)
        err = jnp.asarray(err_cur, jnp.float32)
        deltas, errs = [], []
        for s in range(0, len(plans), c):
            chunk = plans[s : s + c]
            pt = np.zeros((c, a), np.int32)
            idx = np.zeros((c, a, 4), np.int32)
            w = np.zeros((c, a, 4), np.float32)
            mask = np.zeros((c, a), bool)
            for i, p in enumerate(chunk):
                k = len(p.points)
                pt[i, :k], idx[i, :k], w[i, :k], mask[i, :k] = p.points, p.idx, p.w, True
            e, d = _score_chunk(self.feat, self.ref, self.inv_den, self.wc, err, pt, idx, w, mask)
            e, d = np.asarray(e), np.asarray(d)
            deltas.append(d[: len(chunk)])
            errs.extend(e[i, : len(p.points)] for i, p in enumerate(chunk))
        return np.concatenate(deltas).astype(np.float64), errs


def tet_positions(positions: np.ndarray, tet_jitter: float, tet_seed: int = 0) -> np.ndarray:
    """Positions the tetrahedralisation uses: a perturbation of ``tet_jitter`` × the mean spacing, drawn
    from ``tet_seed`` (the run's ``"vardis-tet"`` stream in ``place``), breaks the co-spherical quadruples
    of grids (Delaunay is otherwise not unique); the same seed gives the same tetrahedralisation."""
    pos = np.asarray(positions, np.float64)
    if tet_jitter <= 0:
        return pos
    ext = np.ptp(pos, axis=0)
    spacing = float(np.prod(np.maximum(ext, 1e-12 * ext.max())) / len(pos)) ** (1 / 3)
    return pos + tet_jitter * spacing * np.random.default_rng(tet_seed).uniform(-1.0, 1.0, pos.shape)


def _setup(positions, values, points, error, n_dirs, weights, tet_jitter, tet_seed=0):
    pos = np.asarray(positions, np.float64)
    vals = np.asarray(values, np.float64)
    pts = np.asarray(points, np.float64)
    if pos.ndim != 2 or pos.shape[1] != 3 or len(pos) < 5:
        raise ConfigError(f"positions must be (n ≥ 5, 3), got {pos.shape}")
    if vals.shape != (len(pos), 9, 3):
        raise ConfigError(f"values must be (n_probes, 9, 3) SH L2 RGB, got {vals.shape}")
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise ConfigError(f"evaluation points must be (p ≥ 1, 3), got {pts.shape}")
    if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vals)) and np.all(np.isfinite(pts))):
        raise ConfigError("positions, values and evaluation points must be finite")
    if len(np.unique(pos, axis=0)) != len(pos):
        raise ConfigError("probe positions must be distinct")
    wc = _weights(weights)
    feat = error_features(vals, error, n_dirs)
    mesh = TetMesh(tet_positions(pos, tet_jitter, tet_seed), pts)
    ref = np.einsum("pk,pkmc->pmc", mesh.w, feat[mesh.idx])
    lum = np.einsum("pk,pk->p", mesh.w, (vals[:, 0] * Y00 @ YCOCG.T)[:, 0][mesh.idx])
    floor = max(1e-3 * float(np.mean(np.abs(lum))), 1e-30)
    inv_den = 1.0 / np.maximum(np.abs(lum), floor)
    return mesh, _Scorer(feat, ref, inv_den, wc)


def leave_one_out_scores(
    positions, values, points, *, error: str = "sh", n_dirs: int = 32, weights="chrominance", tet_jitter=0.0
) -> np.ndarray:
    """Total (mean) error after removing each probe alone from the full set, all candidates in one batched
    evaluation (the first iteration of :func:`vardis_simplify`); (n,)."""
    mesh, scorer = _setup(positions, values, points, error, n_dirs, weights, tet_jitter)
    plans = mesh.plan_removals(range(len(mesh.pos)))
    deltas, _ = scorer.score(plans, np.zeros(len(mesh.pts)))
    return deltas / len(mesh.pts)


def _check_stopping(positions, target, tolerance, per_iteration) -> int:
    """Reject a missing stopping rule and bad ``target`` / ``tolerance`` / ``per_iteration`` values before
    the (costly) tetrahedralisation; returns the probe count n."""
    if target is None and tolerance is None:
        raise ConfigError("give a target probe count, an error tolerance, or both")
    n = len(np.asarray(positions).reshape(-1, 3))
    if target is not None and not (isinstance(target, int | np.integer) and 4 <= target <= n):
        raise ConfigError(f"target must be an integer in [4, {n}], got {target!r}")
    if tolerance is not None and not (np.isfinite(tolerance) and tolerance >= 0):
        raise ConfigError(f"tolerance must be a non-negative number, got {tolerance!r}")
    if not (
        (isinstance(per_iteration, int | np.integer) and per_iteration >= 1)
        or (isinstance(per_iteration, float) and 0 < per_iteration < 1)
    ):
        raise ConfigError(f"per_iteration must be an int ≥ 1 or a fraction in (0, 1), got {per_iteration!r}")
    return n


@dataclasses.dataclass(eq=False)
class _GreedyState:
    """Host-side bookkeeping of one :func:`vardis_simplify` run (mutated in place by the loop's steps):
    cached removal plans and their scores, who depends on whom, and the current per-point errors."""

    mesh: TetMesh
    scorer: _Scorer
    err_cur: np.ndarray  # (p,) current error per evaluation point
    delta: np.ndarray  # (n,) cached change of the summed error if the probe were removed; inf once gone
    users: list[set[int]]  # users[u]: candidates whose plan reads u
    plans: dict[int, RemovalPlan] = dataclasses.field(default_factory=dict)
    plan_err: dict[int, np.ndarray] = dataclasses.field(default_factory=dict)
    stale: set[int] = dataclasses.field(default_factory=set)  # lazy greedy: cached scores not re-scored
    order: list[int] = dataclasses.field(default_factory=list)
    n_scored: int = 0


def _start_state(mesh: TetMesh, scorer: _Scorer, n: int) -> _GreedyState:
    """Empty bookkeeping for ``n`` probes: no plans yet, zero error (the dense set is its own reference)."""
    return _GreedyState(
        mesh=mesh,
        scorer=scorer,
        err_cur=np.zeros(len(mesh.pts)),
        delta=np.full(n, np.inf),
        users=[set() for _ in range(n)],
    )


def _refresh(st: _GreedyState, todo: list[int]) -> None:
    """Re-plan and re-score the removal of each probe in ``todo`` (one batched scoring), updating the cache
    and the dependency sets (local connectivity update, past the poster's "Future work")."""
    new = st.mesh.plan_removals(todo)
    d, errs = st.scorer.score(new, st.err_cur)
    st.n_scored += len(new)
    for p, dv, ev in zip(new, d, errs, strict=True):
        old = st.plans.get(p.vertex)
        if old is not None:  # forget the stale plan's dependencies (fewer needless re-plans)
            for u in old.touch - p.touch:
                st.users[u].discard(p.vertex)
        st.plans[p.vertex], st.plan_err[p.vertex], st.delta[p.vertex] = p, ev, dv
        for u in p.touch:
            st.users[u].add(p.vertex)
    st.stale.difference_update(todo)


def _rescore(st: _GreedyState, dirty: set[int], lazy: bool) -> None:
    """Bring the scores of the live ``dirty`` candidates up to date: all at once, or (lazy greedy) only
    while a stale candidate heads the ranking, the head's stale run re-scored together."""
    if not lazy or not st.plans:
        _refresh(st, sorted(v for v in dirty if st.mesh.alive[v]))
        return
    # lazy greedy: re-score stale candidates only while one of them heads the ranking
    st.stale |= {v for v in dirty if st.mesh.alive[v]}
    while st.stale:
        alive_ids = np.flatnonzero(st.mesh.alive)
        head = alive_ids[np.argsort(st.delta[alive_ids], kind="stable")[:LAZY_HEAD]]
        flags = [int(v) in st.stale for v in head]
        first_fresh = flags.index(False) if False in flags else len(head)
        if first_fresh == 0:
            break
        _refresh(st, sorted(int(v) for v in head[:first_fresh]))


def _removal_count(per_iteration: int | float, n_alive: int, left: int) -> int:
    """Probes to remove this iteration at most: ``per_iteration`` (or that fraction of the live count),
    at least 1 and never past the target."""
    frac = not isinstance(per_iteration, int | np.integer)
    k = int(per_iteration * n_alive) if frac else int(per_iteration)
    return max(1, min(k, left))


def _choose_removals(st: _GreedyState, k: int, total: float, tolerance: float | None) -> list[int]:
    """Up to ``k`` removals, smallest error first (Vardis et al. 2021 §2), as an independent set so their
    scores add up exactly (module docstring); stops before the error would exceed ``tolerance``."""
    n_pts = len(st.mesh.pts)
    alive_ids = np.flatnonzero(st.mesh.alive)
    cand = alive_ids[np.argsort(st.delta[alive_ids], kind="stable")]
    chosen: list[int] = []
    blocked: set[int] = set()
    acc = 0.0
    for v in cand:
        v = int(v)
        if v in st.stale or v in blocked or not st.plans[v].touch.isdisjoint(chosen):
            continue
        if tolerance is not None and (total + (acc + st.delta[v]) / n_pts) > tolerance:
            break
        chosen.append(v)
        acc += st.delta[v]
        blocked |= st.plans[v].touch | {v}
        if len(chosen) == k:
            break
    return chosen


def _apply_removals(st: _GreedyState, chosen: list[int]) -> set[int]:
    """Remove ``chosen`` from the mesh with their cached plans and per-point errors; returns the live
    candidates whose plans they invalidated (to re-score next iteration)."""
    dirty: set[int] = set()
    for v in chosen:
        p = st.plans[v]
        dirty |= st.mesh.apply(p)
        dirty |= st.users[v]
        st.err_cur[p.points] = st.plan_err[v]
        st.order.append(v)
        st.delta[v] = np.inf
    return dirty - set(chosen)


def vardis_simplify(
    positions,
    values,
    points,
    *,
    target: int | None = None,
    tolerance: float | None = None,
    error: str = "sh",
    n_dirs: int = 32,
    weights="chrominance",
    per_iteration: int | float = 1,
    tet_jitter: float = 1e-3,
    tet_seed: int = 0,
    lazy: bool = False,
    progress: bool = False,
) -> VardisResult:
    """Greedy illumination-driven simplification (module docstring).

    Args:
        positions: dense probe positions (n, 3).
        values: their SH L2 radiance (n, 9, 3) (:func:`dense_probe_sh`).
        points: evaluation points (p, 3).
        target: stop at this many probes (≥ 4); or
        tolerance: stop before the total error (mean over points, fraction of local luminance) exceeds it.
            Both may be given (first reached wins).
        error: ``"sh"``, ``"directions"`` or ``"average"`` (what is compared).
        n_dirs: directions of ``error="directions"``.
        weights: ``"chrominance"``, ``"luminance"`` or ``(w_Y, w_C)``.
        per_iteration: probes removed per iteration at most: an int, or a fraction (0, 1) of the current
            count; > 1 removes an independent set (module docstring). 1 is the paper's loop.
        tet_jitter: relative perturbation of the tetrahedralisation positions (:func:`tet_positions`).
        tet_seed: seed of that perturbation.
        lazy: lazy greedy — after a removal, the candidates it affects keep their old score (marked
            stale) and are re-scored only when one reaches the head of the ranking. Exact when scores only
            grow after neighbouring removals; an approximation otherwise (``False``: re-score them all).
        progress: tqdm bar.

    Returns:
        A :class:`VardisResult`.

    Raises:
        ConfigError: bad shapes or options, no stopping rule.
    """
    n = _check_stopping(positions, target, tolerance, per_iteration)
    from ..._core.runtime import progress_bar

    t0 = time.perf_counter()
    mesh, scorer = _setup(positions, values, points, error, n_dirs, weights, tet_jitter, tet_seed)
    stop = 4 if target is None else int(target)
    timings = {"setup_s": time.perf_counter() - t0}
    t0 = time.perf_counter()
    st = _start_state(mesh, scorer, n)
    total = 0.0
    dirty = set(range(n))
    hist_c, hist_e = [n], [0.0]
    bar = progress_bar(total=n - stop, disable=not progress, desc="vardis", leave=False)
    while int(mesh.alive.sum()) > stop:
        _rescore(st, dirty, lazy)
        n_alive = int(mesh.alive.sum())
        k = _removal_count(per_iteration, n_alive, n_alive - stop)
        chosen = _choose_removals(st, k, total, tolerance)
        if not chosen:
            break
        dirty = _apply_removals(st, chosen)
        total = float(st.err_cur.sum() / len(mesh.pts))
        hist_c.append(int(mesh.alive.sum()))
        hist_e.append(total)
        bar.update(len(chosen))
    bar.close()
    timings["loop_s"] = time.perf_counter() - t0
    return VardisResult(
        keep=mesh.alive.copy(),
        removal_order=np.asarray(st.order, np.int64),
        history_count=np.asarray(hist_c),
        history_error=np.asarray(hist_e),
        error=total,
        n_iterations=len(hist_c) - 1,
        n_scored=st.n_scored,
        timings=timings,
    )
