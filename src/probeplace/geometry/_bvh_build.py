"""Build a bounding-volume hierarchy over a scene's triangles, in NumPy, once per scene.

The build is a *binned SAH* (surface-area heuristic) top-down split (Wald 2007, "On fast construction
of SAH-based bounding volume hierarchies", §3), done level by level: every node of one tree level is
split at once with vectorised NumPy (bincount / ufunc.at over (node, axis, bin) keys), so the Python
loop runs once per *level* (≈ 40 for 262k triangles), not once per node.

The binary tree is then laid out for stack-free traversal (:func:`thread_bvh`): for each of the 8
octants of ray-direction signs the nodes are written in depth-first pre-order, visiting first the child
on the ray's near side of the node's split plane, and each node stores a *skip* link to the next item
after its subtree (a "threaded" BVH, Smits 1998, "Efficiency issues for ray tracing"; one threading per
direction class as in Hachisuka's multiple-threaded BVH, 2015). A ray then walks forward through one
array: box hit → next item, box miss → skip. No stack, so the per-step work is the same for every ray —
which is what a vmapped ``lax.while_loop`` needs.
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class BinaryBVH:
    """A binary BVH in breadth-first node order (children always after their parent).

    Attributes:
        lo, hi: (n_nodes, 3) node bounds, float64.
        left, right: (n_nodes,) child node ids, -1 for a leaf.
        axis: (n_nodes,) split axis of an inner node (the left child holds the smaller centroids).
        start, count: (n_nodes,) a leaf's triangles are ``order[start:start+count]``.
        order: (n_tri,) triangle ids grouped by leaf.
        depth: (n_nodes,) depth of each node (root 0).
    """

    lo: np.ndarray
    hi: np.ndarray
    left: np.ndarray
    right: np.ndarray
    axis: np.ndarray
    start: np.ndarray
    count: np.ndarray
    order: np.ndarray
    depth: np.ndarray

    @property
    def n_nodes(self) -> int:
        return int(self.lo.shape[0])

    @property
    def is_leaf(self) -> np.ndarray:
        return self.left < 0


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    e = np.maximum(hi - lo, 0.0)
    return e[..., 0] * e[..., 1] + e[..., 1] * e[..., 2] + e[..., 2] * e[..., 0]


def _segment_bounds(x_lo, x_hi, seg_start, n_seg):
    """Min of x_lo and max of x_hi over contiguous segments beginning at ``seg_start``."""
    del n_seg
    return np.minimum.reduceat(x_lo, seg_start, axis=0), np.maximum.reduceat(x_hi, seg_start, axis=0)


def _level_triangles(order, level_start, nodes, cnt):
    """Segment layout of the candidate nodes' triangles, which lie contiguously in ``order``.

    Returns ``(seg_start, seg_id, pos, ids)``: each node's first row, each row's node, each row's
    position in ``order`` and its triangle id (a copy, so the caller may permute it).
    """
    # triangles of the candidate nodes, segment by segment (they are contiguous in `order`)
    seg_start = np.concatenate([[0], np.cumsum(cnt)[:-1]])
    total = int(cnt.sum())
    seg_id = np.repeat(np.arange(nodes.size), cnt)
    pos = np.arange(total) - seg_start[seg_id] + level_start[nodes][seg_id]
    ids = order[pos]
    return seg_start, seg_id, pos, ids


def _centroid_bins(c, seg_start, seg_id, n_bins):
    """Bin index of each centroid along each axis over its node's centroid extent (Wald 2007, §3.1)."""
    c_lo = np.minimum.reduceat(c, seg_start, axis=0)
    c_hi = np.maximum.reduceat(c, seg_start, axis=0)
    ext = c_hi - c_lo
    scale = np.where(ext > 0, n_bins * (1 - 1e-9) / np.where(ext > 0, ext, 1.0), 0.0)
    b = ((c - c_lo[seg_id]) * scale[seg_id]).astype(np.int64)
    np.clip(b, 0, n_bins - 1, out=b)  # (total, 3)
    return b, ext


def _bin_stats(b, seg_id, tl, th, n_nodes, n_bins):
    """Triangle count and box bounds per (node, axis, bin): the inputs of the SAH sweep."""
    # per (node, axis, bin): count and bounds of the triangles' boxes
    key = (seg_id[:, None] * 3 + np.arange(3)) * n_bins + b  # (total, 3)
    n_keys = n_nodes * 3 * n_bins
    bin_cnt = np.bincount(key.ravel(), minlength=n_keys).reshape(n_nodes, 3, n_bins)
    bin_lo = np.full((n_keys, 3), np.inf)
    bin_hi = np.full((n_keys, 3), -np.inf)
    for ax in range(3):
        np.minimum.at(bin_lo, key[:, ax], tl)
        np.maximum.at(bin_hi, key[:, ax], th)
    bin_lo = bin_lo.reshape(n_nodes, 3, n_bins, 3)
    bin_hi = bin_hi.reshape(n_nodes, 3, n_bins, 3)
    return bin_cnt, bin_lo, bin_hi


def _sah_best_split(bin_cnt, bin_lo, bin_hi, cnt, n_bins):
    """Cheapest bin plane of each node by the SAH sweep: ``(best_cost, best_axis, best_s)``.

    ``best_cost`` is inf when no plane leaves triangles on both sides; ``best_s`` is the first bin
    on the right.
    """
    n_nodes = cnt.shape[0]
    # sweep: left side = bins [0, s), right side = bins [s, n_bins), s = 1..n_bins-1
    l_cnt = np.cumsum(bin_cnt, axis=2)[:, :, :-1]
    l_area = _half_area(
        np.minimum.accumulate(bin_lo, axis=2)[:, :, :-1],
        np.maximum.accumulate(bin_hi, axis=2)[:, :, :-1],
    )
    r_lo = np.minimum.accumulate(bin_lo[:, :, ::-1], axis=2)[:, :, ::-1][:, :, 1:]
    r_hi = np.maximum.accumulate(bin_hi[:, :, ::-1], axis=2)[:, :, ::-1][:, :, 1:]
    r_cnt = cnt[:, None, None] - l_cnt
    r_area = _half_area(r_lo, r_hi)
    with np.errstate(invalid="ignore"):
        cost = l_area * l_cnt + r_area * r_cnt
    cost = np.where((l_cnt > 0) & (r_cnt > 0), cost, np.inf).reshape(n_nodes, -1)
    best = np.argmin(cost, axis=1)
    best_cost = cost[np.arange(n_nodes), best]
    best_axis, best_s = best // (n_bins - 1), best % (n_bins - 1) + 1
    return best_cost, best_axis, best_s


def _sort_fallback(ids, c, seg_id, fallback, median_axis):
    """Order, in place, the triangles of nodes without a usable bin split by centroid on the widest axis."""
    total = ids.shape[0]
    # order the fallback nodes' triangles by centroid on the widest axis first
    fb_tri = fallback[seg_id]
    ax_val = c[np.arange(total), median_axis[seg_id]]
    sub = np.lexsort((ax_val[fb_tri], seg_id[fb_tri]))
    fb_pos = np.flatnonzero(fb_tri)
    ids[fb_pos] = ids[fb_pos[sub]]


def _split_level(order, cen, t_lo, t_hi, level_start, level_count, level_lo, level_hi, *, sah):
    """Choose and apply the split of every node of one tree level, reordering ``order`` in place.

    Returns ``(split_nodes, split_at, axis)``: the level-local ids of the nodes that split, the
    number of triangles each node sends left, and each node's split axis.
    """
    n_bins, max_leaf, traversal_cost, intersect_cost = sah
    n_lvl = level_start.shape[0]
    axis = np.zeros(n_lvl, np.int64)
    cand = level_count > 1
    split_at = np.zeros(n_lvl, np.int64)  # number of triangles going left
    if not cand.any():
        return np.zeros(0, np.int64), split_at, axis
    nodes = np.flatnonzero(cand)
    cnt = level_count[nodes]
    seg_start, seg_id, pos, ids = _level_triangles(order, level_start, nodes, cnt)
    total = ids.shape[0]
    c = cen[ids]
    b, ext = _centroid_bins(c, seg_start, seg_id, n_bins)
    bin_cnt, bin_lo, bin_hi = _bin_stats(b, seg_id, t_lo[ids], t_hi[ids], nodes.size, n_bins)
    best_cost, best_axis, best_s = _sah_best_split(bin_cnt, bin_lo, bin_hi, cnt, n_bins)
    node_area = _half_area(level_lo[nodes], level_hi[nodes])
    sah_split = traversal_cost + intersect_cost * best_cost / np.maximum(node_area, 1e-300)
    sah_leaf = intersect_cost * cnt
    binned_ok = np.isfinite(best_cost)
    do_split = (cnt > max_leaf) | (binned_ok & (sah_split < sah_leaf))
    # partition: stable sort by (segment, side) keeps each node's triangles contiguous
    side = np.where(
        binned_ok[seg_id],
        b[np.arange(total), best_axis[seg_id]] >= best_s[seg_id],
        # no usable bin split: median by index along the widest centroid axis
        (np.arange(total) - seg_start[seg_id]) >= (cnt[seg_id] // 2),
    )
    median_axis = np.argmax(ext, axis=1)
    fallback = ~binned_ok
    if fallback.any():
        _sort_fallback(ids, c, seg_id, fallback, median_axis)
    side = side & do_split[seg_id]
    perm = np.lexsort((side, seg_id))
    order[pos] = ids[perm]
    n_left = np.bincount(seg_id, weights=~side, minlength=nodes.size).astype(np.int64)
    split_at[nodes] = n_left
    axis[nodes] = np.where(binned_ok, best_axis, median_axis)
    return nodes[do_split], split_at, axis


def _child_level(order, t_lo, t_hi, level_start, level_count, split_nodes, split_at):
    """Triangle ranges and bounds of the next level's nodes, in id order (left0, right0, left1, ...)."""
    # children of this level, in id order: (left0, right0, left1, right1, ...)
    s0 = level_start[split_nodes]
    nl = split_at[split_nodes]
    ch_start = np.stack([s0, s0 + nl], axis=1).ravel()
    ch_count = np.stack([nl, level_count[split_nodes] - nl], axis=1).ravel()
    seg_ids = np.repeat(np.arange(ch_start.size), ch_count)
    tri_pos = np.arange(ch_count.sum()) - np.repeat(np.cumsum(ch_count) - ch_count, ch_count)
    tri_ids = order[ch_start[seg_ids] + tri_pos]
    seg_starts = np.cumsum(ch_count) - ch_count
    ch_lo, ch_hi = _segment_bounds(t_lo[tri_ids], t_hi[tri_ids], seg_starts, ch_start.size)
    return ch_start, ch_count, ch_lo, ch_hi


def build_bvh(
    triangles: np.ndarray,
    *,
    n_bins: int = 16,
    max_leaf: int = 1,
    traversal_cost: float = 1.0,
    intersect_cost: float = 1.0,
) -> BinaryBVH:
    """Binned-SAH binary BVH over triangles.

    Args:
        triangles: (n_tri, 3, 3) corner positions.
        n_bins: SAH bins per axis (Wald 2007 uses 16–32; more bins rarely pay off).
        max_leaf: a node with more triangles than this is always split; a node with at most this
            many becomes a leaf when the SAH says a split does not pay (``max_leaf = 1``: one
            triangle per leaf).
        traversal_cost, intersect_cost: SAH constants C_trav and C_isect (relative cost of a box
            test and a triangle test).

    Returns:
        The tree. A node whose triangles cannot be separated by centroid bins (identical centroids)
        is split at its median index, so every leaf ends with at most ``max_leaf`` triangles.
    """
    tri = np.asarray(triangles, np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3) or tri.shape[0] == 0:
        raise ValueError(f"triangles must have shape (n_tri >= 1, 3, 3), got {tri.shape}")
    if n_bins < 2 or max_leaf < 1:
        raise ValueError(f"need n_bins >= 2 and max_leaf >= 1, got {n_bins}, {max_leaf}")
    n_tri = tri.shape[0]
    t_lo, t_hi = tri.min(axis=1), tri.max(axis=1)
    cen = 0.5 * (t_lo + t_hi)
    sah = (n_bins, max_leaf, traversal_cost, intersect_cost)

    order = np.arange(n_tri)
    # Node arrays grow level by level (Python lists of per-level arrays, concatenated at the end).
    lo_l, hi_l = [t_lo.min(0, keepdims=True)], [t_hi.max(0, keepdims=True)]
    start_l, count_l = [np.zeros(1, np.int64)], [np.full(1, n_tri, np.int64)]
    left_l, right_l, axis_l, depth_l = [], [], [], []
    level_start = np.zeros(1, np.int64)
    level_count = np.full(1, n_tri, np.int64)
    level_lo, level_hi = lo_l[0], hi_l[0]
    next_id = 1
    depth = 0
    while True:
        n_lvl = level_start.shape[0]
        split_nodes, split_at, axis = _split_level(
            order, cen, t_lo, t_hi, level_start, level_count, level_lo, level_hi, sah=sah
        )
        n_split = split_nodes.size
        left = np.full(n_lvl, -1, np.int64)
        right = np.full(n_lvl, -1, np.int64)
        left[split_nodes] = next_id + 2 * np.arange(n_split)
        right[split_nodes] = next_id + 2 * np.arange(n_split) + 1
        left_l.append(left)
        right_l.append(right)
        axis_l.append(axis)
        depth_l.append(np.full(n_lvl, depth, np.int64))
        if n_split == 0:
            break
        ch_start, ch_count, ch_lo, ch_hi = _child_level(
            order, t_lo, t_hi, level_start, level_count, split_nodes, split_at
        )
        lo_l.append(ch_lo)
        hi_l.append(ch_hi)
        start_l.append(ch_start)
        count_l.append(ch_count)
        level_start, level_count, level_lo, level_hi = ch_start, ch_count, ch_lo, ch_hi
        next_id += ch_start.size
        depth += 1
    return BinaryBVH(
        lo=np.concatenate(lo_l),
        hi=np.concatenate(hi_l),
        left=np.concatenate(left_l),
        right=np.concatenate(right_l),
        axis=np.concatenate(axis_l),
        start=np.concatenate(start_l),
        count=np.concatenate(count_l),
        order=order,
        depth=np.concatenate(depth_l),
    )


@dataclasses.dataclass(frozen=True)
class ThreadedBVH:
    """Eight pre-order layouts of one binary BVH (one per octant of ray-direction signs), concatenated.

    Item ``i`` is either a *box* (its subtree's bounds) or a *triangle*. Fields are structure-of-arrays
    (one flat array per component) so that a vmapped gather reads one float per lane per field.

    Attributes:
        a: (9, n_total) float32. Box: rows 0–2 are the box's *near* corner for this octant (the min
            coordinate where the ray direction is positive, the max where negative), rows 3–5 the far
            corner, rows 6–8 unused. Triangle: v0, e1 = v1 − v0, e2 = v2 − v0 (Möller–Trumbore form).
        link: (n_total,) int32. Box: index of the item after its subtree (where a ray that misses
            the box goes). Triangle: ``~next`` (bitwise not, so negative), the item after it.
        tri: (n_total,) int32 scene triangle id of a triangle item, -1 for a box.
        n_items: items per octant layout; octant ``k``'s layout starts at ``k * n_items``.
        sentinel: ``8 * n_items``, the "done" index; item ``sentinel`` is a padding box that is never hit.
    """

    a: np.ndarray
    link: np.ndarray
    tri: np.ndarray
    n_items: int
    sentinel: int


def thread_bvh(bvh: BinaryBVH, triangles: np.ndarray) -> ThreadedBVH:
    """Lay a binary BVH out for stack-free, ordered traversal (see the module docstring).

    A leaf with one triangle becomes one triangle item (no box: testing the triangle costs the same
    step as testing its box). A leaf with k > 1 triangles becomes its box followed by k triangle items.
    """
    tri = np.asarray(triangles, np.float64)
    n = bvh.n_nodes
    leaf = bvh.is_leaf
    own = np.where(leaf, np.where(bvh.count == 1, 1, bvh.count + 1), 1)  # items a node writes itself
    # subtree sizes, bottom-up: children always have larger ids than their parent (BFS ids)
    size = own.copy()
    for d in range(int(bvh.depth.max()), 0, -1):
        at = np.flatnonzero((bvh.depth == d - 1) & ~leaf)
        size[at] += size[bvh.left[at]] + size[bvh.right[at]]
    n_items = int(size[0])
    sentinel = 8 * n_items
    a = np.zeros((9, sentinel + 1), np.float32)
    link = np.zeros(sentinel + 1, np.int64)
    tri_id = np.full(sentinel + 1, -1, np.int64)
    # padding item: a NaN box that links to itself. NaN makes every slab comparison false, so it is
    # never entered whatever the ray's direction signs (an "empty" box near = +inf, far = -inf is
    # entered by rays with a negative component, whose slab distances flip sign).
    a[:, sentinel] = np.nan
    link[sentinel] = sentinel
    # float32 boxes rounded outward so that rounding never shrinks a box below its triangles
    lo32 = np.nextafter(bvh.lo.astype(np.float32), np.float32(-np.inf))
    hi32 = np.nextafter(bvh.hi.astype(np.float32), np.float32(np.inf))

    v0 = tri[:, 0]
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    by_depth = [np.flatnonzero(bvh.depth == d) for d in range(int(bvh.depth.max()) + 1)]
    for octant in range(8):
        sign_pos = np.array([(octant >> k) & 1 == 0 for k in range(3)])  # bit k set: d_k < 0
        base = octant * n_items
        pos = np.zeros(n, np.int64)
        for nodes in by_depth:
            inner = nodes[~leaf[nodes]]
            near_left = sign_pos[bvh.axis[inner]]
            first = np.where(near_left, bvh.left[inner], bvh.right[inner])
            second = np.where(near_left, bvh.right[inner], bvh.left[inner])
            pos[first] = pos[inner] + 1
            pos[second] = pos[inner] + 1 + size[first]
        p = pos + base
        end = p + size  # item after the subtree
        end = np.where(end == base + n_items, sentinel, end)
        # boxes: inner nodes and multi-triangle leaves
        box = ~leaf | (bvh.count > 1)
        bp = p[box]
        near = np.where(sign_pos, lo32[box], hi32[box])
        far = np.where(sign_pos, hi32[box], lo32[box])
        a[0:3, bp] = near.T
        a[3:6, bp] = far.T
        link[bp] = end[box]
        # triangles of each leaf, after the leaf's box when it has one
        lf = np.flatnonzero(leaf)
        k = bvh.count[lf]
        first_item = p[lf] + (k > 1)
        rep = np.repeat(np.arange(lf.size), k)
        j = np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)
        ip = first_item[rep] + j
        tid = bvh.order[bvh.start[lf][rep] + j]
        a[0:3, ip] = v0[tid].T
        a[3:6, ip] = e1[tid].T
        a[6:9, ip] = e2[tid].T
        nxt = ip + 1
        nxt = np.where(nxt == base + n_items, sentinel, nxt)
        link[ip] = ~nxt
        tri_id[ip] = tid
    return ThreadedBVH(
        a=a,
        link=link.astype(np.int32),
        tri=tri_id.astype(np.int32),
        n_items=n_items,
        sentinel=sentinel,
    )


# Row layouts for the JAX traversal (:mod:`._bvh_traverse`). On CPU a row gather of 32 or 64 contiguous
# bytes costs about one cache miss, while nine gathers from nine separate (n,) arrays cost nine: measured
# 27 vs 236 ns per lane and step for random rows of a 4.2M-item table (XLA CPU, docs/raycast.md).
ITEM_COLS = 16  # fused schedule: one 64-byte row per item (box or triangle)
BOX_COLS = 8  # deferred schedule: 32-byte box rows ...
TRI_COLS = 16  # ... and a separate 64-byte triangle table shared by the eight octant layouts


def _as_f32_bits(x: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(x.astype(np.int32)).view(np.float32)


def pack_items(th: ThreadedBVH) -> np.ndarray:
    """(n_total, 16) float32: cols 0–8 as ``th.a``, col 9 the link, col 10 the triangle id (int32 bits)."""
    rows = np.zeros((th.link.shape[0], ITEM_COLS), np.float32)
    rows[:, :9] = th.a.T
    rows[:, 9] = _as_f32_bits(th.link)
    rows[:, 10] = _as_f32_bits(th.tri)
    return rows


def pack_boxes(th: ThreadedBVH) -> np.ndarray:
    """(n_total, 8) float32: cols 0–5 near/far corner (boxes), col 6 the link, col 7 the triangle id."""
    rows = np.zeros((th.link.shape[0], BOX_COLS), np.float32)
    rows[:, :6] = th.a[:6].T
    rows[th.tri >= 0, :6] = np.nan  # triangle items are never box-tested (NaN fails every slab test)
    rows[:, 6] = _as_f32_bits(th.link)
    rows[:, 7] = _as_f32_bits(th.tri)
    return rows


def pack_triangles(triangles: np.ndarray) -> np.ndarray:
    """(n_tri + 1, 16) float32 rows v0, e1, e2 (Möller–Trumbore form); the last row is NaN ("no triangle")."""
    tri = np.asarray(triangles, np.float64)
    rows = np.zeros((tri.shape[0] + 1, TRI_COLS), np.float32)
    rows[:-1, 0:3] = tri[:, 0]
    rows[:-1, 3:6] = tri[:, 1] - tri[:, 0]
    rows[:-1, 6:9] = tri[:, 2] - tri[:, 0]
    rows[-1] = np.nan
    return rows
