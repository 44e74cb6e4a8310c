"""The pure-JAX BVH caster and :func:`make_caster`, which picks a backend for a scene.

Backends (all behind :class:`AbstractRayCaster`, all returning the same :class:`~probeplace._core.Hit`):

* ``"embree"`` — :class:`EmbreeCaster`, Intel Embree on the host. The fastest on CPU and the reference;
  not jittable.
* ``"bvh"`` — :class:`BVHCaster`, a binned-SAH BVH built once in NumPy and traversed in jitted JAX
  (:mod:`._bvh_traverse`). Jittable, runs on GPU; on CPU about a tenth of Embree's single-thread speed
  (docs/raycast.md).
* ``"brute"`` — :class:`BruteForceCaster`, every ray against every triangle in JAX. Jittable; the fastest
  JAX choice for tiny scenes (the Cornell box's 36 triangles), refused above 4096 triangles.
"""

from __future__ import annotations

import logging
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from .._core import ConfigError, Hit, Scene
from ._bvh_build import ThreadedBVH, build_bvh, pack_boxes, pack_items, pack_triangles, thread_bvh
from ._bvh_traverse import traverse
from ._embree import EmbreeCaster, EmbreeUnavailableError
from ._raycast import AbstractJaxRayCaster, AbstractRayCaster, BruteForceCaster, complete_hit

log = logging.getLogger(__name__)

SCHEDULES = ("deferred", "fused")
BACKENDS = ("auto", "embree", "bvh", "brute")
#: What the caller does with a caster; decides ``make_caster``'s "auto" choice.
USES = ("host", "jit", "render")
# "auto" for use="jit" or "render": brute force up to this many triangles (it beats the BVH there: no
# traversal overhead, one fused loop over the triangles), the BVH or Embree above.
BRUTE_FORCE_MAX_TRIANGLES = 256


def _default_lanes() -> int:
    # CPU: a wavefront small enough that its per-lane state stays in L2 (2048 measured best of 1k–8k on
    # Sponza); accelerators want many lanes in flight to hide memory latency.
    return 2048 if jax.default_backend() == "cpu" else 131072


class BVHCaster(AbstractJaxRayCaster):
    """Exact ray casting through a BVH traversed in JAX: jittable, runs on CPU or GPU, not differentiable.

    Build (NumPy, once per scene): binned-SAH binary BVH with one triangle per leaf (Wald 2007), threaded
    for stack-free traversal in eight per-octant orderings (:mod:`._bvh_build`). Traversal: a wavefront
    of ``lanes`` rays walking the threaded items (:mod:`._bvh_traverse`). Intersection: Möller–Trumbore
    in the rays' dtype (float32 normally), boxes rounded outward and slab exits scaled by 1 + 2γ(3) (Ize
    2013) so rounding never culls a box the ray enters.

    Rays: ``origins``/``directions`` world frame, directions unit length; hits with ``0 < t < t_max``.
    Coplanar overlapping triangles hit at the same distance are a tie: the one met first in traversal
    order wins, which may differ from Embree's choice.

    Args:
        scene: the scene.
        schedule: ``"deferred"`` (default; triangle tests batched every ``box_steps`` box steps) or
            ``"fused"`` (box and triangle test on every step); see :mod:`._bvh_traverse`.
        lanes: rays in flight (static); ``None``: 2048 on CPU, 131072 on accelerators.
        box_steps: box steps per triangle step (deferred) / steps per round minus one (fused).
        rounds: rounds between wavefront refills.
        sort_rays: sort rays by direction octant and origin Morton code before tracing (results are
            returned in the input order).
        n_bins: SAH bins of the build.
    """

    scene: Scene
    items: Float[Array, "n_items c"]
    triangles: Float[Array, "n_tri1 16"] | None
    n_items: int = eqx.field(static=True)
    sentinel: int = eqx.field(static=True)
    schedule: str = eqx.field(static=True)
    lanes: int = eqx.field(static=True)
    box_steps: int = eqx.field(static=True)
    rounds: int = eqx.field(static=True)
    sort_rays: bool = eqx.field(static=True)
    # A leaf, not static: a timing differs for every build, and a static field would make every new
    # caster (even over the same scene) a new jit cache key.
    build_seconds: Float[Array, ""]

    def __init__(
        self,
        scene: Scene,
        *,
        schedule: str = "deferred",
        lanes: int | None = None,
        box_steps: int = 4,
        rounds: int = 2,
        sort_rays: bool = True,
        n_bins: int = 16,
        threaded: ThreadedBVH | None = None,
    ):
        if schedule not in SCHEDULES:
            raise ConfigError(f"schedule must be one of {SCHEDULES}, got {schedule!r}")
        if box_steps < 1 or rounds < 1 or (lanes is not None and lanes < 1):
            raise ConfigError(f"need box_steps, rounds, lanes >= 1, got {box_steps}, {rounds}, {lanes}")
        if scene.n_triangles == 0:
            raise ConfigError(f"scene {scene.name!r} has no triangles to build a BVH over")
        t0 = time.perf_counter()
        tri = np.asarray(scene.vertices, np.float64)[np.asarray(scene.faces)]
        if threaded is None:
            threaded = thread_bvh(build_bvh(tri, n_bins=n_bins), tri)
        self.scene = scene
        if schedule == "fused":
            self.items = jnp.asarray(pack_items(threaded))
            self.triangles = None
        else:
            self.items = jnp.asarray(pack_boxes(threaded))
            self.triangles = jnp.asarray(pack_triangles(tri))
        self.n_items = threaded.n_items
        self.sentinel = threaded.sentinel
        self.schedule = schedule
        self.lanes = int(lanes or _default_lanes())
        self.box_steps = int(box_steps)
        self.rounds = int(rounds)
        self.sort_rays = bool(sort_rays)
        seconds = time.perf_counter() - t0
        self.build_seconds = jnp.asarray(seconds, jnp.float32)
        log.info("BVH over %d triangles built in %.2f s", scene.n_triangles, seconds)

    def _trace(self, origins, directions, t_max, any_hit):
        if origins.ndim != 2 or origins.shape[-1] != 3 or directions.shape != origins.shape:
            raise ValueError(
                f"origins and directions must both be (n_rays, 3), got {origins.shape} and {directions.shape}"
            )
        n = origins.shape[0]
        t_max = jnp.broadcast_to(jnp.asarray(t_max, origins.dtype), (n,))
        if n == 0:
            z = jnp.zeros(0, origins.dtype)
            return z, jnp.zeros(0, jnp.int32), z, z
        return traverse(
            self.items,
            self.triangles,
            origins,
            directions.astype(origins.dtype),
            t_max,
            n_items=self.n_items,
            sentinel=self.sentinel,
            schedule=self.schedule,
            any_hit=any_hit,
            lanes=self.lanes,
            rounds=self.rounds,
            box_steps=self.box_steps,
            sort_rays=self.sort_rays,
        )

    @eqx.filter_jit
    def closest_hit(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float = jnp.inf,
    ) -> Hit:
        """Nearest intersection with ``0 < t < t_max`` per ray (``tri = -1`` and ``t = inf`` on a miss)."""
        t, tri, u, v = self._trace(origins, directions, t_max, any_hit=False)
        return complete_hit(self.scene, t, tri, jnp.stack([u, v], axis=1))

    @eqx.filter_jit
    def occluded(
        self,
        origins: Float[Array, "n_rays 3"],
        directions: Float[Array, "n_rays 3"],
        t_max: Float[Array, " n_rays"] | float,
    ) -> Bool[Array, " n_rays"]:
        """True where any triangle is hit with ``0 < t < t_max`` (shadow rays); stops at the first hit."""
        _, tri, _, _ = self._trace(origins, directions, t_max, any_hit=True)
        return tri >= 0


def make_caster(scene: Scene, backend: str = "auto", *, use: str = "host", **options) -> AbstractRayCaster:
    """A ray caster for ``scene``: the one place a backend is chosen.

    ``backend="auto"`` picks by what the caller will do with the caster (``use``):

    * ``"host"`` (default; the caller drives it from Python with concrete arrays: baking, exact
      G-buffers, occlusion rays of the placement): Embree when embreex imports — the fastest exact caster
      on CPU — else the JAX BVH (with a warning).
    * ``"jit"`` (the caster is traced inside ``jax.jit``/``vmap``, or must run on a GPU): brute force for
      tiny scenes (≤ ``BRUTE_FORCE_MAX_TRIANGLES`` triangles), else the JAX BVH.
    * ``"render"`` (the path tracer and the evaluation's primary hits, which take either kind): brute
      force for tiny scenes, as for ``"jit"`` (the whole bounce loop then compiles into one function,
      faster there than Embree's host loop), else as for ``"host"``.

    Args:
        scene: the scene.
        backend: ``"auto"``, ``"embree"``, ``"bvh"`` or ``"brute"``.
        use: ``"host"``, ``"jit"`` or ``"render"`` (above); only ``"jit"`` restricts an explicit backend.
        **options: passed to the chosen caster's constructor (e.g. ``threads`` for Embree,
            ``schedule``/``lanes`` for the BVH, ``chunk`` for brute force).

    Raises:
        ConfigError: unknown backend or use; or ``"embree"`` asked for together with ``use="jit"``.
        EmbreeUnavailableError: ``"embree"`` asked for and embreex is not installed.
    """
    if backend not in BACKENDS:
        raise ConfigError(f"unknown ray-casting backend {backend!r}; choose one of {BACKENDS}")
    if use not in USES:
        raise ConfigError(f"unknown caster use {use!r}; choose one of {USES}")
    if backend == "auto":
        if use != "host" and scene.n_triangles <= BRUTE_FORCE_MAX_TRIANGLES:
            backend = "brute"
        elif use == "jit":
            backend = "bvh"
        else:
            try:
                return EmbreeCaster(scene, **options)
            except EmbreeUnavailableError:
                log.warning("embreex is not available; using the JAX BVH caster on the host")
                backend = "bvh"
    if backend == "embree":
        if use == "jit":
            raise ConfigError("the 'embree' backend is host code and cannot be jitted; use 'bvh' or 'brute'")
        return EmbreeCaster(scene, **options)
    if backend == "bvh":
        return BVHCaster(scene, **options)
    return BruteForceCaster(scene, **options)
