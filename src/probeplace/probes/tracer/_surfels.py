"""Surfel maps for the light-field tracer: which march cells hold one surface, and conservative depth
bounds per cell (built once per probe set by ``make_tracer``).

**Surfels.** Each texel of a probe's geometry maps is a surfel (McGuire et al. 2017 §4.1, "a planar
patch at distance r with normal n"): the plane through x = r·ω_c with the baked normal, turned toward the
probe. Along a unit direction ω the plane lies at r(ω) = (x·n)/(ω·n) when that is positive; otherwise the
direction never meets it (∞).

**Texels that are not one surfel.** The texel-centre sample says nothing about where, inside the texel,
a silhouette lies: between the centres of a texel that sees a near surface N and of its neighbour that
sees a far surface F, the boundary between N and F can be anywhere. The tracer therefore marches
``sub`` × ``sub`` cells per texel (``sub`` = 2: the half-texel next to each neighbour) and marks a cell
*ambiguous* when the texel and one of the neighbours on the cell's side (the 2×2 bilinear footprint
around the cell; all eight for ``sub`` = 1) are not one surface. Two neighbouring surfels A, B are one
surface when

* *smooth*: their planes meet the mid direction ω_m = normalize(ω_A + ω_B) within ``tol``·r of each
  other (a continuous surface sampled twice; a plane seen at a grazing angle passes exactly), or
* *a crease*: the surface between them is the nearer (concave corner) or the farther (convex corner) of
  the two planes, i.e. each sample lies in front of (behind) the other's plane along its own direction,
  to within ``tol``;

or the texel's own ray escapes (no surfel to extend: its cells are never ambiguous, and a surface edge
reaching into them goes unseen, as in McGuire's model). Anything else is a depth discontinuity
(silhouette) or a surface beside sky, whose edge may lie anywhere in the half-texel next to it. In an
ambiguous cell the probe cannot tell which surface a point belongs to, so the tracer accepts only "in
front of every candidate surfel" (free) and "every candidate met at about one point" (a hit), and calls
everything else unknown — neither a hit in free space nor a guess; another probe decides (McGuire §4:
"when a probe knows that it does not have the required visibility information").

**Bounds.** For the hierarchy, each cell carries a lower bound of the radial distance of its candidate
surfels (its own; in an ambiguous cell also the footprint neighbours') over its cone, and an upper bound
beyond which a point is deep behind its surfel (in an ambiguous cell: behind the nearest candidate), so
that a ray entering a cell there is unknown at once, without descending (Wang 2019 §4.2 uses both
bounds). Both are closed forms over a cone that contains the cell (:func:`cell_cones`; a neighbour's
plane over its whole texel's cone: looser, four times cheaper): along ω a plane at distance d from the
probe lies at d / (ω·n̂), so over a cone of half-angle θ around an axis at angle α from n̂ it is nearest
at d / cos(max(α − θ, 0)) and deep behind (by τ) beyond (d + τ) / cos(α + θ). One evaluation per cell,
exact — nine plane samples per cell less 2 % cost 0.8 s a probe at 512² and were not a bound (issue 33).
"""

from __future__ import annotations

import functools
import math

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

from ..._core import dot3, norm3

#: (row, col) offsets of the eight neighbours of a texel.
NEIGHBOURS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


def plane_distance(x: Array, n: Array, w: Array) -> Array:
    """Distance along unit direction(s) ``w`` from the probe to the plane through ``x`` with normal ``n``
    (broadcasting over leading axes); ∞ where the direction never meets it."""
    xn, wn = dot3(x, n), dot3(w, n)
    ok = (wn * xn > 0) & (jnp.abs(wn) > 1e-6)
    return jnp.where(ok, xn / jnp.where(ok, wn, 1.0), jnp.inf)


def _octahedron_point64(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``_core.maths._octahedral``'s uv → octahedron point in float64 NumPy (the cones are built once, on
    the host, where float32 rounding would have to be argued away)."""
    z = 1.0 - np.abs(u) - np.abs(v)
    sign = lambda a: np.where(a >= 0, 1.0, -1.0)
    x = np.where(z < 0, (1.0 - np.abs(v)) * sign(u), u)
    y = np.where(z < 0, (1.0 - np.abs(u)) * sign(v), v)
    p = np.stack([x, y, z], axis=-1)
    return p / np.linalg.norm(p, axis=-1, keepdims=True)


@functools.lru_cache(maxsize=4)
def _cell_cones_host(m: int) -> np.ndarray:
    """:func:`cell_cones` as a read-only float32 NumPy array (5, m, m), computed once per resolution."""
    h = 2.0 / m
    edge = np.arange(m + 1) * h - 1.0
    out = np.empty((m, m, 5), np.float32)
    u0, u1 = edge[None, :-1], edge[None, 1:]
    uc = (u0 + u1) / 2
    for r0 in range(0, m, 256):  # rows in chunks: 8 points × 3 float64 per cell is 200 MB at m = 1024
        v0, v1 = edge[r0 : r0 + 256, None][: m - r0], edge[r0 + 1 : r0 + 257, None][: m - r0]
        vc = (v0 + v1) / 2
        u0b, u1b, ucb, v0b, v1b, vcb = np.broadcast_arrays(u0, u1, uc, v0, v1, vc)
        su, sv = np.sign(ucb), np.sign(vcb)  # a cell lies in one quadrant (m even: 0 is a cell edge)
        # Where each edge crosses the fold |u| + |v| = 1 (clipped: a corner when it does not cross):
        # on the edge u = uf at v = sv·(1 − |uf|), on the edge v = vf at u = su·(1 − |vf|).
        cross_u0, cross_u1 = (np.clip(sv * (1.0 - np.abs(uf)), v0b, v1b) for uf in (u0b, u1b))
        cross_v0, cross_v1 = (np.clip(su * (1.0 - np.abs(vf)), u0b, u1b) for vf in (v0b, v1b))
        pts = [
            (u0b, v0b), (u1b, v0b), (u0b, v1b), (u1b, v1b),
            (u0b, cross_u0), (u1b, cross_u1), (cross_v0, v0b), (cross_v1, v1b),
        ]  # fmt: skip
        axis = _octahedron_point64(ucb, vcb)
        cos_t = np.min([np.sum(_octahedron_point64(pu, pv) * axis, axis=-1) for pu, pv in pts], axis=0)
        # Outward by 1e-4 of the angle (and 1e-7 rad): float32 storage must not shrink the cone.
        theta = np.arccos(np.clip(cos_t, -1.0, 1.0)) * (1 + 1e-4) + 1e-7
        trig = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        out[r0 : r0 + len(v0)] = np.concatenate([axis, trig], axis=-1)
    out = np.ascontiguousarray(np.moveaxis(out, -1, 0))  # channels first (cell_cones)
    out.flags.writeable = False
    return out


def cell_cones(m: int) -> Float[Array, "5 m m"]:
    """A cone containing each cell of an m×m octahedral grid (rows v, columns u): its axis (the cell centre's
    unit direction) and cos θ, sin θ of its half-angle θ, as five planes (channels first: read per cell
    with a stride of 5 floats, XLA:CPU did not vectorise the bounds). The cell's image on the sphere is the
    union of at most two pieces of planar octahedron faces (the fold |u| + |v| = 1 may cross it), each
    projected radially: spherically convex polygons, whose farthest point from the axis is a vertex — a
    corner of the cell or a crossing of its edges with the fold. θ is the largest of those angles,
    computed in float64 and rounded outward (``tests/probes/test_surfels.py`` holds it against dense
    samples; there the corners alone always held the farthest point, the fold's crossings are kept as
    candidates all the same)."""
    return jnp.asarray(_cell_cones_host(m))


def _planes(x, n, thickness):
    """Per surfel, what :func:`_cone_bounds` reads of its plane (points ``x``, normals ``n``): the plane's
    distance d from the probe, the sign of x·n and |n| (to turn n toward x), and the thickness τ =
    thickness·|x|. Computed once a texel: a neighbour's plane is bounded over several cones (issue 33)."""
    xn = dot3(x, n)
    n_len = jnp.maximum(norm3(n), 1e-12)
    return jnp.abs(xn) / n_len, jnp.sign(xn), n_len, thickness * norm3(x)


def _cone_bounds(planes, n, has, cone, big):
    """(lower, upper) bounds of each cell's surfel plane (:func:`_planes` of it, normals ``n``) over the
    cell's cone ``cone`` (:func:`cell_cones`): the lower bound of its radial distance, and the radial
    distance beyond which a point is behind the plane by more than τ (module docstring); ``big`` where
    there is no surface or no bound. Rounded outward by 1e-4 (float32 arithmetic here and in the march)."""
    d, sign, n_len, tau = planes
    axis, cos_t, sin_t = jnp.moveaxis(cone[:3], 0, -1), cone[3], cone[4]
    cos_a = jnp.clip(sign * dot3(axis, n) / n_len, -1.0, 1.0)  # axis vs n̂ toward x
    sin_a = jnp.sqrt(jnp.maximum(1.0 - cos_a * cos_a, 0.0))
    max_cos = jnp.where(cos_a >= cos_t, 1.0, cos_a * cos_t + sin_a * sin_t)  # cos(max(α − θ, 0))
    min_cos = cos_a * cos_t - sin_a * sin_t  # cos(α + θ); ≤ 0 when the cone reaches the plane's horizon
    lo = jnp.where(max_cos > 1e-6, d / jnp.maximum(max_cos, 1e-6), big) * (1 - 1e-4)
    # Behind by τ in signed plane distance is (ω·n̂)·(ρ − r(ω)) > τ, i.e. ρ > (d + τ) / (ω·n̂).
    hi = jnp.where(min_cos > 1e-6, (d + tau) / jnp.maximum(min_cos, 1e-6), big) * (1 + 1e-4)
    return jnp.where(has, jnp.minimum(lo, big), big), jnp.where(has, jnp.minimum(hi, big), big)


def _bounds(x, n, has, cone, thickness, big):
    """:func:`_cone_bounds` of the planes through ``x`` with normals ``n`` (``thickness``: τ's fraction of
    |x|)."""
    return _cone_bounds(_planes(x, n, thickness), n, has, cone, big)


def crease(xa, na, wa, xx, nx, wx, tol: float) -> tuple[Array, Array]:
    """(concave, convex): do surfels A and X (points, normals turned toward the probe, sample directions;
    broadcasting) meet in a concave or a convex crease (module docstring)? A concave crease's surface is
    the *nearer* of the two planes, so a point is free only in front of both — the march's fine test and
    its skip bounds use both planes there (``_march._surfel_test``)."""
    ra, rx = norm3(xa), norm3(xx)
    pa_x, px_a = plane_distance(xa, na, wx), plane_distance(xx, nx, wa)
    fin = jnp.isfinite(pa_x) & jnp.isfinite(px_a)
    concave = fin & (ra <= px_a * (1 + tol)) & (rx <= pa_x * (1 + tol))
    convex = fin & (ra >= px_a * (1 - tol)) & (rx >= pa_x * (1 - tol))
    return concave, convex


def _one_surface(xa, na, ha, wa, xx, nx, hx, wx, tol: float) -> tuple[Array, Array]:
    """(one surface?, a concave crease?) of surfels A and X that both have a surface (module docstring):
    points, normals turned toward the probe, has-surface flags and sample directions. Symmetric in A and
    X, to the bit: swapping them swaps the two operands of every sum, min and comparison pair."""
    wm = wa + wx
    wm = wm / jnp.maximum(norm3(wm), 1e-12)[..., None]
    pa_m, px_m = plane_distance(xa, na, wm), plane_distance(xx, nx, wm)
    smooth = jnp.isfinite(pa_m) & jnp.isfinite(px_m)
    smooth = smooth & (jnp.abs(pa_m - px_m) <= tol * jnp.minimum(pa_m, px_m))
    concave, convex = crease(xa, na, wa, xx, nx, wx, tol)
    both = ha & hx
    return both & (smooth | concave | convex), both & concave


def _pair(xb, nb, hb, wb, di: int, dj: int, tol: float) -> tuple[Bool[Array, "r r"], Bool[Array, "r r"]]:
    """Per interior texel and its neighbour at offset (di, dj): (one surface?, a concave crease of two
    surfaces?) (module docstring); a texel whose own ray escapes is one surface with every neighbour.

    Args:
        xb, nb, hb, wb: ONE probe's bordered (R+2)² maps: surfel points (probe-relative), normals turned
            toward the probe, has-surface flags and sample directions (the border ring holds the
            neighbours across the octahedral fold, with their own directions).
    """
    r = xb.shape[0] - 2
    own = lambda a: a[1 : r + 1, 1 : r + 1]
    nbr = lambda a: a[1 + di : r + 1 + di, 1 + dj : r + 1 + dj]
    one, concave = _one_surface(own(xb), own(nb), own(hb), own(wb), nbr(xb), nbr(nb), nbr(hb), nbr(wb), tol)
    return one | ~own(hb), concave


#: One offset of each opposite pair in :data:`NEIGHBOURS`: the test of a texel and its neighbour at the
#: other offset is this one's, read from the neighbour (:func:`_pairs`).
_HALF_NEIGHBOURS = ((0, 1), (1, -1), (1, 0), (1, 1))


def neighbour_pairs(xb, nb, hb, wb, tol: float | None) -> dict[tuple[int, int], tuple[Array, Array]]:
    """:func:`_pair` for every offset of :data:`NEIGHBOURS` (empty for ``tol`` None: no ambiguity test),
    with half the tests (issue 33: they were three quarters of ``make_tracer``): :func:`_one_surface` is
    symmetric, so each pair of bordered texels (t, t + o) is tested once, for o in
    :data:`_HALF_NEIGHBOURS`, and serves t at offset o and t + o at −o. The border ring holds the texels
    across the octahedral fold, so a pair across it is a pair of the bordered grid like any other.

    Call it in a compiled program of its own and hand the result to :func:`probe_cells_quadrants`: in one
    program with the bounds, XLA:CPU fused each test into every consumer of the ambiguity it decides and
    computed it there again (45 ms a probe at 512² against 12 + 19 ms apart)."""
    if tol is None:
        return {}
    rb, r = xb.shape[0], xb.shape[0] - 2
    out = {}
    for di, dj in _HALF_NEIGHBOURS:
        # s[i, j]: bordered texels (i, j + c) and (i + di, j + c + dj), c = max(0, −dj), every such pair
        c = max(0, -dj)
        first = [a[: rb - di, c : rb - max(0, dj)] for a in (xb, nb, hb, wb)]
        second = [a[di:, c + dj : rb + min(0, dj)] for a in (xb, nb, hb, wb)]
        one, concave = _one_surface(*first, *second, tol)
        escaped = ~hb[1 : r + 1, 1 : r + 1]
        # the interior texels (bordered 1 … r) as the first of a pair, then as the second
        rows, cols = slice(1, r + 1), slice(1 - c, r + 1 - c)
        out[di, dj] = one[rows, cols] | escaped, concave[rows, cols]
        rows, cols = slice(1 - di, r + 1 - di), slice(1 - dj - c, r + 1 - dj - c)
        out[-di, -dj] = one[rows, cols] | escaped, concave[rows, cols]
    return out


def _uses(sub: int, di: int, dj: int, m: int) -> Array:
    """(m, m) or scalar: which cells have the neighbour (di, dj) in their footprint."""
    if sub == 1:
        return jnp.bool_(True)
    q = jnp.arange(m) % 2
    row = jnp.bool_(True) if di == 0 else q[:, None] == (1 if di > 0 else 0)
    col = jnp.bool_(True) if dj == 0 else q[None, :] == (1 if dj > 0 else 0)
    return row & col


def probe_cells_quadrants(xb, nb, hb, pairs, cones_cells, cones_texels, *, sub, thickness, big):
    """:func:`probe_cells_reference`, computed per cell quadrant (issue 33): lists of sub² (R, R) maps
    (:func:`interleave_quadrants` makes each the (m, m) cell map). The cells of one quadrant
    (row and column parity ``qr``, ``qc``) form an R×R grid aligned with the texels, so every cell-level
    quantity is computed there, on texel-sized arrays (no ``repeat`` of the texel maps, no strided
    scatter). A neighbour's plane bounds only the cells on its side of the texel (one quadrant for a
    diagonal neighbour, two for an edge one), so its cell-level (concave-crease partner) bound is
    evaluated on those quadrants only: 12 instead of 32 bound evaluations per texel at ``sub`` = 2. Same
    values: each cell's bound is the minimum of the same bounds. ``pairs``: :func:`neighbour_pairs` of the
    same maps (empty: no ambiguity test)."""
    r = xb.shape[0] - 2
    own = lambda a: a[1 : r + 1, 1 : r + 1]
    nbr = lambda a, di, dj: a[1 + di : r + 1 + di, 1 + dj : r + 1 + dj]
    quads = [(qr, qc) for qr in range(sub) for qc in range(sub)]
    cone_q = {q: cones_cells[:, q[0] :: sub, q[1] :: sub] for q in quads}
    planes = _planes(xb, nb, thickness)  # once a texel: each neighbour's plane is bounded over 2-3 cones
    own_planes = tuple(own(a) for a in planes)
    lower = {q: [] for q in quads}  # per quadrant: the candidate bounds, reduced once at the end
    upper = {q: [] for q in quads}
    for q in quads:
        lo, hi = _cone_bounds(own_planes, own(nb), own(hb), cone_q[q], big)
        lower[q].append(lo)
        upper[q].append(hi)
    ambiguous = {q: jnp.zeros((r, r), bool) for q in quads}
    for (di, dj), (one, _) in pairs.items():
        for q in _quadrants(sub, di, dj):
            ambiguous[q] = ambiguous[q] | ~one
    for (di, dj), (_, concave) in pairs.items():
        pn, nn, hn = tuple(nbr(a, di, dj) for a in planes), nbr(nb, di, dj), nbr(hb, di, dj)
        lo, hi = _cone_bounds(pn, nn, hn, cones_texels, big)
        for q in _quadrants(sub, di, dj):
            amb = ambiguous[q]
            lower[q].append(jnp.where(amb, lo, big))
            upper[q].append(jnp.where(amb, hi, big))
            # A concave crease partner of a one-surface cell bounds the cell too
            # (probe_cells_reference), over the cell's own cone (at sub = 1 the cell is the texel).
            cell_lo = lo if sub == 1 else _cone_bounds(pn, nn, hn, cone_q[q], big)[0]
            lower[q].append(jnp.where(~amb & concave, cell_lo, big))
    lower = {q: jnp.min(jnp.stack(v), axis=0) for q, v in lower.items()}
    upper = {q: jnp.min(jnp.stack(v), axis=0) for q, v in upper.items()}
    # Lists, not stacked: a stack fused the quadrants' computation into its copy as the interleave did.
    return [lower[q] for q in quads], [upper[q] for q in quads], [ambiguous[q] for q in quads]


def interleave_quadrants(quadrants: list[Array]) -> Array:
    """The sub² per-quadrant (R, R) cell maps of :func:`probe_cells_quadrants` (row-major quadrant order)
    → the (m, m) cell grid, cell (i·sub + qr, j·sub + qc) = quadrant (qr, qc)[i, j]. Call it on
    materialised arrays (another compiled program): fused into the quadrants' computation, this transposing
    copy computed them in its own order, three times slower than the two apart (0.08 s a probe at 512²;
    XLA:CPU drops optimisation barriers)."""
    sub, r = math.isqrt(len(quadrants)), quadrants[0].shape[0]
    a = jnp.stack(quadrants).reshape(sub, sub, r, r)
    return a.transpose(2, 0, 3, 1).reshape(r * sub, r * sub)


def probe_cells(xb, nb, hb, wb, cones_cells, cones_texels, *, sub, tol, thickness, big):
    """:func:`probe_cells_quadrants` as (m, m) cell maps (lower bound, upper bound, ambiguous): the form
    :func:`probe_cells_reference` computes."""
    pairs = neighbour_pairs(xb, nb, hb, wb, tol)
    out = probe_cells_quadrants(
        xb, nb, hb, pairs, cones_cells, cones_texels, sub=sub, thickness=thickness, big=big
    )
    return tuple(interleave_quadrants(a) for a in out)


def _quadrants(sub: int, di: int, dj: int) -> list[tuple[int, int]]:
    """The (row, col) parities of the cells whose footprint holds neighbour (di, dj) (:func:`_uses`)."""
    if sub == 1:
        return [(0, 0)]
    rows = [0, 1] if di == 0 else [1 if di > 0 else 0]
    cols = [0, 1] if dj == 0 else [1 if dj > 0 else 0]
    return [(a, b) for a in rows for b in cols]


def probe_cells_reference(xb, nb, hb, wb, cones_cells, cones_texels, *, sub, tol, thickness, big):
    """ONE probe's march cells (m = sub·R per axis): (lower bound, upper bound, ambiguous) maps, (m, m).
    The simple form, every bound on every cell; :func:`probe_cells` must agree with it.

    The lower bound is that of the candidate surfels' planes (in front of it: free); the upper bound the
    radial distance beyond which a point is deep behind (by the thickness) the cell's surfel — in an
    ambiguous cell, behind some candidate's — so the tracer's fine test says unknown. The own surfel is
    bounded over each cell's cone (``cones_cells``), a neighbour's over the whole texel's (``cones_texels``;
    looser, cheaper). ``tol`` None: no ambiguity test (every cell is its texel's surfel).
    """
    r = xb.shape[0] - 2
    m = r * sub
    up = lambda a: jnp.repeat(jnp.repeat(a, sub, axis=0), sub, axis=1)
    own = lambda a: a[1 : r + 1, 1 : r + 1]
    lower, upper = _bounds(up(own(xb)), up(own(nb)), up(own(hb)), cones_cells, thickness, big)
    ambiguous = jnp.zeros((m, m), bool)
    if tol is None:
        return lower, upper, ambiguous
    pairs = {(di, dj): _pair(xb, nb, hb, wb, di, dj, tol) for di, dj in NEIGHBOURS}
    for (di, dj), (one, _) in pairs.items():
        ambiguous = ambiguous | (_uses(sub, di, dj, m) & ~up(one))
    for (di, dj), (_, concave) in pairs.items():
        nbr = lambda a, di=di, dj=dj: a[1 + di : r + 1 + di, 1 + dj : r + 1 + dj]
        lo, hi = _bounds(nbr(xb), nbr(nb), nbr(hb), cones_texels, thickness, big)
        use = _uses(sub, di, dj, m) & ambiguous
        lower = jnp.where(use, jnp.minimum(lower, up(lo)), lower)
        upper = jnp.where(use, jnp.minimum(upper, up(hi)), upper)
        # A concave crease partner of a one-surface cell: its plane also bounds the cell (the fine test
        # reads it), bounded over the cell's own cone — a ray skipped past it would slip through the corner.
        partner = _uses(sub, di, dj, m) & ~ambiguous & up(concave)
        lo_cell, _ = _bounds(up(nbr(xb)), up(nbr(nb)), up(nbr(hb)), cones_cells, thickness, big)
        lower = jnp.where(partner, jnp.minimum(lower, lo_cell), lower)
    return lower, upper, ambiguous
