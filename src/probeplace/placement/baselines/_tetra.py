"""Tetrahedral light-probe interpolation (Cupisz 2012) and its local update when one probe is removed.

Unity's light probes (and the Unity prototype of Vardis et al. 2021, "Illumination-driven Light Probe
Placement", Eurographics posters) interpolate probe values inside a Delaunay tetrahedralisation of the
probe positions with the barycentric weights of the enclosing tetrahedron (R. Cupisz, "Light probe
interpolation using tetrahedral tessellations", GDC 2012). Points outside the convex hull of the probes use
the **nearest probe** (weight 1); Unity instead extrapolates from the hull's outer faces, which needs the
hull-face projection and its cubic solve — we keep the simpler, documented rule.

Removing a vertex ``v`` from a Delaunay tetrahedralisation changes only its star: every other tetrahedron
keeps its empty circumsphere. The star's cavity is re-filled by Delaunay tetrahedra of ``v``'s link (its
1-ring), which are exactly the tetrahedra of ``Delaunay(link)`` that lie inside the cavity (general
position; for a hull vertex, those inside the old star region — the rest of it falls outside the new
hull). :class:`TetMesh` keeps the tetrahedra, which evaluation points lie in which tetrahedron, and plans
and applies such removals locally (:meth:`TetMesh.plan_removal`, :meth:`TetMesh.apply`).

Host-side NumPy/SciPy bookkeeping: the state is mutable by design (one object per simplification run).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial import ConvexHull, Delaunay, QhullError, cKDTree

# Barycentric coordinates ≥ −BARY_EPS count as inside (points on shared faces belong to either side).
BARY_EPS = 1e-9


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product (k, 3) (np.cross has per-call overhead that dominates on small arrays)."""
    ax, ay, az = a.T
    bx, by, bz = b.T
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=1)


def _inverse_edges(tet_pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``(e1 e2 e3)⁻¹`` (t, 3, 3) with ``e_i = v_i − v_3`` (cross-product form), and a flat mask."""
    d = tet_pts[:, 3]
    e1, e2, e3 = tet_pts[:, 0] - d, tet_pts[:, 1] - d, tet_pts[:, 2] - d
    c23, c31, c12 = _cross(e2, e3), _cross(e3, e1), _cross(e1, e2)
    det = np.einsum("ti,ti->t", e1, c23)
    scale = np.abs(np.stack([e1, e2, e3])).max(initial=0.0) ** 3
    flat = np.abs(det) <= 1e-12 * scale  # relative: a degenerate (flat) tetrahedron
    return np.stack([c23, c31, c12], axis=1) / np.where(flat, 1.0, det)[:, None, None], flat


def barycentric(tet_pts: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (k, 4) of points (k, 3) in tetrahedra (k, 4, 3); NaN rows for flat ones."""
    inv, flat = _inverse_edges(tet_pts)
    l3 = np.einsum("kij,kj->ki", inv, pts - tet_pts[:, 3])
    lam = np.concatenate([l3, 1.0 - l3.sum(-1, keepdims=True)], axis=-1)
    lam[flat] = np.nan
    return lam


def locate(tet_pts: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each point (p, 3): the tetrahedron among ``tet_pts`` (t, 4, 3) with the largest minimum
    barycentric coordinate and those coordinates; tet −1 (weights 0) where none contains the point."""
    t, p = len(tet_pts), len(pts)
    if t == 0 or p == 0:
        return np.full(p, -1, np.int64), np.zeros((p, 4))
    inv, flat = _inverse_edges(tet_pts)
    l3 = np.einsum("tij,tpj->tpi", inv, pts[None, :, :] - tet_pts[:, None, 3, :])
    lam = np.concatenate([l3, 1.0 - l3.sum(-1, keepdims=True)], axis=-1)  # (t, p, 4)
    score = np.where(flat[:, None], -np.inf, lam.min(-1))
    best = np.argmax(score, axis=0)
    inside = score[best, np.arange(p)] >= -BARY_EPS
    w = np.clip(lam[best, np.arange(p)], 0.0, None)
    w /= np.maximum(w.sum(1, keepdims=True), 1e-300)
    return np.where(inside, best, -1), np.where(inside[:, None], w, 0.0)


def locate_in_delaunay(pos: np.ndarray, simplices: np.ndarray, pts: np.ndarray, k: int = 32) -> np.ndarray:
    """Containing simplex of each point (−1 outside the convex hull): hull facet planes say outside, then
    the ``k`` tetrahedra with the nearest centroids, then all of them (chunked) for the rare misses.
    (SciPy's ``find_simplex`` first builds every simplex's transform with one LAPACK call each — slower
    than the whole search here for a few hundred points.)"""
    eq = ConvexHull(pos).equations
    scale = float(np.abs(pos).max()) + 1.0
    out = (pts @ eq[:, :3].T + eq[:, 3]).max(axis=1) > 1e-9 * scale
    res = np.full(len(pts), -1, np.int64)
    ids = np.flatnonzero(~out)
    if len(ids) == 0:
        return res
    k = min(k, len(simplices))
    nn = cKDTree(pos[simplices].mean(1)).query(pts[ids], k)[1].reshape(len(ids), k)
    lam = barycentric(pos[simplices[nn]].reshape(-1, 4, 3), np.repeat(pts[ids], k, axis=0)).reshape(-1, k, 4)
    score = np.nan_to_num(lam.min(-1), nan=-np.inf)
    best = np.argmax(score, axis=1)
    found = score[np.arange(len(ids)), best] >= -BARY_EPS
    res[ids[found]] = nn[np.arange(len(ids)), best][found]
    miss = ids[~found]
    tet_pts = pos[simplices]
    for s in range(0, len(miss), 64):
        chunk = miss[s : s + 64]
        res[chunk] = locate(tet_pts, pts[chunk])[0]
    return res


def _pairs(na: np.ndarray, nb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All (a, b) index pairs within each group g (a over ``na[g]`` items, b over ``nb[g]``), as global
    indices into the concatenated a and b arrays; a-major within a group."""
    cnt = na * nb
    g = np.repeat(np.arange(len(na)), cnt)
    q = np.arange(int(cnt.sum())) - np.repeat(np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
    a_off = np.concatenate([[0], np.cumsum(na)[:-1]])
    b_off = np.concatenate([[0], np.cumsum(nb)[:-1]])
    nbg = np.maximum(nb[g], 1)
    return a_off[g] + q // nbg, b_off[g] + q % nbg


def _lam(inv: np.ndarray, d3: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (k, 4) from per-row inverse edge matrices (k, 3, 3) and 4th vertices."""
    l3 = np.einsum("kij,kj->ki", inv, pts - d3)
    return np.concatenate([l3, 1.0 - l3.sum(-1, keepdims=True)], axis=-1)


@dataclasses.dataclass(eq=False)
class RemovalPlan:
    """What removing one vertex changes (:meth:`TetMesh.plan_removal`).

    Attributes:
        vertex: the removed vertex.
        points: affected evaluation points (a,).
        idx: their new interpolation vertices (a, 4).
        w: their new weights (a, 4); outside-hull points have weight 1 on ``idx[:, 0]``.
        point_tet: their new tetrahedron as an index into ``new_tets``, −1 when outside the hull.
        new_tets: the cavity's new tetrahedra (k, 4), global vertex ids; ``None`` until applied when no
            point is affected.
        touch: vertices whose state the removal reads or changes (link and nearest replacements).
    """

    vertex: int
    points: np.ndarray
    idx: np.ndarray
    w: np.ndarray
    point_tet: np.ndarray
    new_tets: np.ndarray | None
    touch: frozenset


class TetMesh:
    """A Delaunay tetrahedralisation of probes with evaluation points located in it (module docstring).

    Args:
        positions: probe positions (n, 3) used for the tetrahedralisation.
        points: evaluation points (p, 3).
    """

    def __init__(self, positions: np.ndarray, points: np.ndarray):
        self.pos = np.asarray(positions, np.float64)
        self.pts = np.asarray(points, np.float64)
        n, p = len(self.pos), len(self.pts)
        self.alive = np.ones(n, bool)
        tri = Delaunay(self.pos)
        self.tets = [np.asarray(s, np.int64) for s in tri.simplices]
        self.T = np.zeros((2 * len(self.tets) + 16, 4), np.int64)  # array mirror of ``tets`` (grows)
        self.T[: len(self.tets)] = tri.simplices
        self.tet_alive = [True] * len(self.tets)
        self.vert_tets: list[set[int]] = [set() for _ in range(n)]
        for t, s in enumerate(self.tets):
            for v in s:
                self.vert_tets[v].add(t)
        simplex = locate_in_delaunay(self.pos, tri.simplices, self.pts)
        self.idx = np.zeros((p, 4), np.int64)
        self.w = np.zeros((p, 4))
        self.pt_tet = np.full(p, -1, np.int64)
        self.tet_pts: list[set[int]] = [set() for _ in self.tets]
        self.near_pts: list[set[int]] = [set() for _ in range(n)]
        inside = simplex >= 0
        if inside.any():
            s = simplex[inside]
            lam = barycentric(self.pos[tri.simplices[s]], self.pts[inside])
            lam = np.clip(np.nan_to_num(lam), 0.0, None)
            lam /= np.maximum(lam.sum(1, keepdims=True), 1e-300)
            self.idx[inside] = tri.simplices[s]
            self.w[inside] = lam
            self.pt_tet[inside] = s
            for i, t in zip(np.flatnonzero(inside), s, strict=True):
                self.tet_pts[t].add(int(i))
        out = np.flatnonzero(~inside)
        if len(out):
            near = cKDTree(self.pos).query(self.pts[out])[1]
            self._set_outside(out, near)

    def _set_outside(self, pts: np.ndarray, near: np.ndarray) -> None:
        self.idx[pts] = 0
        self.idx[pts, 0] = near
        self.w[pts] = 0.0
        self.w[pts, 0] = 1.0
        self.pt_tet[pts] = -1
        for i, v in zip(pts, near, strict=True):
            self.near_pts[v].add(int(i))

    def link(self, v: int) -> np.ndarray:
        """Sorted vertices sharing a tetrahedron with ``v``."""
        star = self.vert_tets[v]
        if not star:
            return np.zeros(0, np.int64)
        u = np.unique(self.T[list(star)])
        return u[u != v]

    def nearest_alive(self, pts: np.ndarray, exclude: int) -> np.ndarray:
        """Nearest alive vertex other than ``exclude`` for each point (brute force; few points)."""
        ids = np.flatnonzero(self.alive)
        ids = ids[ids != exclude]
        d2 = ((self.pts[pts][:, None, :] - self.pos[ids][None, :, :]) ** 2).sum(-1)
        return ids[np.argmin(d2, axis=1)]

    def _cavity_tets(self, star: list[int], link: np.ndarray) -> np.ndarray:
        """Tetrahedra of ``Delaunay(link)`` inside the star (module docstring), (k, 4) global ids."""
        if len(link) < 4 or not star:
            return np.zeros((0, 4), np.int64)
        try:
            d = Delaunay(self.pos[link])
        except QhullError:  # flat link (degenerate cavity): its points fall back to the nearest probe
            return np.zeros((0, 4), np.int64)
        cand = link[d.simplices]
        star_pts = self.pos[np.stack([self.tets[t] for t in star])]
        return cand[locate(star_pts, self.pos[cand].mean(1))[0] >= 0]

    def plan_removal(self, v: int) -> RemovalPlan:
        """The local re-tetrahedralisation and re-interpolation if ``v`` were removed (module docstring)."""
        star = sorted(self.vert_tets[v])
        link = self.link(v)
        in_star = np.array(sorted(set().union(*(self.tet_pts[t] for t in star))) if star else [], np.int64)
        near = np.array(sorted(self.near_pts[v]), np.int64)
        touch = frozenset(int(u) for u in link)
        if len(in_star) == 0 and len(near) == 0:  # nothing to re-interpolate: cavity tets built on apply
            e = np.zeros(0, np.int64)
            return RemovalPlan(int(v), e, np.zeros((0, 4), np.int64), np.zeros((0, 4)), e, None, touch)
        new_tets = self._cavity_tets(star, link)
        tet_of, w_in = locate(self.pos[new_tets], self.pts[in_star])
        idx_in = new_tets[np.maximum(tet_of, 0)] if len(new_tets) else np.zeros((len(tet_of), 4), np.int64)
        out = np.concatenate([in_star[tet_of < 0], near])
        points = np.concatenate([in_star[tet_of >= 0], out])
        idx = np.zeros((len(points), 4), np.int64)
        w = np.zeros((len(points), 4))
        k = int((tet_of >= 0).sum())
        idx[:k], w[:k] = idx_in[tet_of >= 0], w_in[tet_of >= 0]
        repl = np.zeros(0, np.int64)
        if len(out):
            repl = self.nearest_alive(out, v)
            idx[k:, 0], w[k:, 0] = repl, 1.0
        point_tet = np.concatenate([tet_of[tet_of >= 0], np.full(len(out), -1, np.int64)])
        touch = touch | frozenset(int(u) for u in repl)
        return RemovalPlan(int(v), points, idx, w, point_tet, new_tets, touch)

    def _removal_work(self, v: int):
        """Removal inputs of ``v`` (star, link, star points, nearest-probe points, candidate cavity tets);
        its finished plan instead when it has no points to re-interpolate."""
        star = sorted(self.vert_tets[v])
        link = self.link(v)
        in_star = np.array(sorted(set().union(*(self.tet_pts[t] for t in star))), np.int64)
        near = np.array(sorted(self.near_pts[v]), np.int64)
        if len(in_star) == 0 and len(near) == 0:
            e = np.zeros(0, np.int64)
            touch = frozenset(link.tolist())
            return RemovalPlan(v, e, np.zeros((0, 4), np.int64), np.zeros((0, 4)), e, None, touch)
        cand = np.zeros((0, 4), np.int64)
        if len(link) >= 4 and star:
            try:
                cand = link[Delaunay(self.pos[link]).simplices]
            except QhullError:  # flat link: its points fall back to the nearest probe
                pass
        return v, np.asarray(star, np.int64), link, in_star, near, cand

    def _keep_star_tets(self, work: list) -> tuple[np.ndarray, np.ndarray]:
        """Step 1 of :meth:`plan_removals`: each vertex's candidate tets whose centroid lies in its star.

        Returns the kept tets of every work item, concatenated, and how many each item kept.
        """
        nw = len(work)
        # 1. keep the candidate tetrahedra whose centroid lies in the star (pairs within one vertex)
        kc = np.array([len(w[6]) for w in work])
        sc = np.array([len(w[2]) for w in work])
        cand_all = np.concatenate([w[6] for w in work])
        star_all = np.concatenate([w[2] for w in work])
        i_pair, j_pair = _pairs(kc, sc)
        keep = np.zeros(len(cand_all), bool)
        if len(i_pair):
            inv, flat = _inverse_edges(self.pos[self.T[star_all]])
            d3 = self.pos[self.T[star_all, 3]]
            lam = _lam(inv[j_pair], d3[j_pair], self.pos[cand_all[i_pair]].mean(1))
            ok = (lam.min(-1) >= -BARY_EPS) & ~flat[j_pair]
            keep = np.bincount(i_pair, weights=ok, minlength=len(cand_all)) > 0
        seg_cand = np.repeat(np.arange(nw), kc)
        return cand_all[keep], np.bincount(seg_cand[keep], minlength=nw)

    def _locate_in_new_tets(self, work: list, new_all: np.ndarray, nc: np.ndarray):
        """Step 2 of :meth:`plan_removals`: locate each vertex's star points in its own new tetrahedra.

        Returns ``(tet_of, w_in, a_off)``: per point its tet (a row of ``new_all``, −1 outside) and
        barycentric weights, and the offsets of each work item's points.
        """
        # 2. locate the star's points in the new tetrahedra
        ac = np.array([len(w[4]) for w in work])
        a_all = np.concatenate([w[4] for w in work])
        a_off = np.concatenate([[0], np.cumsum(ac)])
        ia, jn = _pairs(ac, nc)
        tet_of = np.full(len(a_all), -1, np.int64)
        w_in = np.zeros((len(a_all), 4))
        if len(ia):
            inv, flat = _inverse_edges(self.pos[new_all])
            lam = _lam(inv[jn], self.pos[new_all[jn, 3]], self.pts[a_all[ia]])
            score = np.where(flat[jn], -np.inf, lam.min(-1))
            best = np.full(len(a_all), -np.inf)
            np.maximum.at(best, ia, score)
            hit = (score == best[ia]) & (score >= -BARY_EPS)
            first = np.unique(ia[hit], return_index=True)[1]
            sel = np.flatnonzero(hit)[first]
            tet_of[ia[sel]] = jn[sel]
            wv = np.clip(lam[sel], 0.0, None)
            w_in[ia[sel]] = wv / np.maximum(wv.sum(1, keepdims=True), 1e-300)
        return tet_of, w_in, a_off

    def _assemble_plan(
        self, v, link, in_star, near, t_loc, w_loc, new_k, off, alive_ids, tree
    ) -> RemovalPlan:
        """Step 3 of :meth:`plan_removals`: one vertex's plan; points left outside its new tets take the
        nearest alive probe other than ``v``."""
        inside = t_loc >= 0
        out = np.concatenate([in_star[~inside], near])
        points = np.concatenate([in_star[inside], out])
        m = int(inside.sum())
        idx = np.zeros((len(points), 4), np.int64)
        w = np.zeros((len(points), 4))
        idx[:m] = new_k[t_loc[inside] - off]
        w[:m] = w_loc[inside]
        repl = np.zeros(0, np.int64)
        if len(out):
            nn = alive_ids[tree.query(self.pts[out], k=min(2, len(alive_ids)))[1].reshape(len(out), -1)]
            repl = np.where(nn[:, 0] == v, nn[:, -1], nn[:, 0])
            idx[m:, 0], w[m:, 0] = repl, 1.0
        point_tet = np.concatenate([t_loc[inside] - off, np.full(len(out), -1, np.int64)])
        touch = frozenset(link.tolist()) | frozenset(repl.tolist())
        return RemovalPlan(v, points, idx, w, point_tet, new_k, touch)

    def plan_removals(self, vs) -> list[RemovalPlan]:
        """:meth:`plan_removal` for many vertices, the geometry vectorised across them (same plans)."""
        vs = [int(v) for v in vs]
        plans: list[RemovalPlan | None] = [None] * len(vs)
        work = []  # (slot, v, star, link, in_star, near, candidate tets)
        for i, v in enumerate(vs):
            item = self._removal_work(v)
            if isinstance(item, RemovalPlan):
                plans[i] = item
            else:
                work.append((i, *item))
        if not work:
            return plans  # type: ignore[return-value]
        new_all, nc = self._keep_star_tets(work)
        n_off = np.concatenate([[0], np.cumsum(nc)])
        tet_of, w_in, a_off = self._locate_in_new_tets(work, new_all, nc)
        # 3. nearest alive replacement (other than the removed vertex) for points left outside
        alive_ids = np.flatnonzero(self.alive)
        tree = cKDTree(self.pos[alive_ids])
        for k, (i, v, _star, link, in_star, near, _cand) in enumerate(work):
            pts = slice(a_off[k], a_off[k + 1])
            new_k = new_all[n_off[k] : n_off[k + 1]]
            plans[i] = self._assemble_plan(
                v, link, in_star, near, tet_of[pts], w_in[pts], new_k, n_off[k], alive_ids, tree
            )
        return plans  # type: ignore[return-value]

    def apply(self, plan: RemovalPlan) -> set[int]:
        """Remove ``plan.vertex``; returns the vertices whose removal plans are now stale."""
        v = plan.vertex
        dirty = set(int(u) for u in self.link(v))
        if plan.new_tets is None:
            plan.new_tets = self._cavity_tets(sorted(self.vert_tets[v]), self.link(v))
        for t in list(self.vert_tets[v]):
            self.tet_alive[t] = False
            for u in self.tets[t]:
                self.vert_tets[u].discard(t)
            for i in self.tet_pts[t]:
                self.pt_tet[i] = -1
            self.tet_pts[t] = set()
        self.near_pts[v] = set()
        first = len(self.tets)
        for s in plan.new_tets:
            t = len(self.tets)
            self.tets.append(s)
            if t >= len(self.T):
                self.T = np.concatenate([self.T, np.zeros_like(self.T)])
            self.T[t] = s
            self.tet_alive.append(True)
            self.tet_pts.append(set())
            for u in s:
                self.vert_tets[u].add(t)
        self.alive[v] = False
        inside = plan.point_tet >= 0
        for i, lt in zip(plan.points[inside], plan.point_tet[inside], strict=True):
            self.tet_pts[first + lt].add(int(i))
            self.pt_tet[i] = first + lt
        self.idx[plan.points] = plan.idx
        self.w[plan.points] = plan.w
        out = plan.points[~inside]
        for i, u in zip(out, plan.idx[~inside, 0], strict=True):
            self.near_pts[u].add(int(i))
            dirty.add(int(u))
        return dirty
