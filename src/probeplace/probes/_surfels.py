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
surfels (its own; in an ambiguous cell also the footprint neighbours') over its cone: each plane sampled
at the centre, corners and edge midpoints of the cell (own surfel) or of its whole texel (neighbours:
looser, four times cheaper), less 2%; and an upper bound beyond which a point is deep behind its
surfel (in an ambiguous cell: behind the nearest candidate), so that a ray entering a cell there is
unknown at once, without descending (Wang 2019 §4.2 uses both bounds).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

from .._core._octahedral import _octahedron_point

#: (row, col) offsets of the eight neighbours of a texel.
NEIGHBOURS = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))


def plane_distance(x: Array, n: Array, w: Array) -> Array:
    """Distance along unit direction(s) ``w`` from the probe to the plane through ``x`` with normal ``n``
    (broadcasting over leading axes); ∞ where the direction never meets it."""
    xn = jnp.sum(x * n, axis=-1)
    wn = jnp.sum(w * n, axis=-1)
    ok = (wn * xn > 0) & (jnp.abs(wn) > 1e-6)
    return jnp.where(ok, xn / jnp.where(ok, wn, 1.0), jnp.inf)


@partial(jax.jit, static_argnames=("m", "dtype"))
def cell_directions(m: int, dtype=jnp.float32) -> Float[Array, "m m 9 3"]:
    """Unit directions of each cell of an m×m octahedral grid: centre, corners and edge midpoints."""
    h = 2.0 / m
    c = (jnp.arange(m, dtype=dtype) + 0.5) * h - 1.0
    offs = jnp.asarray([-0.5, 0.0, 0.5], dtype) * h
    ou, ov = jnp.meshgrid(offs, offs, indexing="ij")
    uu = c[None, :, None] + ou.reshape(-1)[None, None, :]  # (1, m, 9) u per column
    vv = c[:, None, None] + ov.reshape(-1)[None, None, :]  # (m, 1, 9)
    uv = jnp.stack(jnp.broadcast_arrays(uu, vv), axis=-1)
    p = _octahedron_point(jnp.clip(uv, -1.0, 1.0))
    return p / jnp.linalg.norm(p, axis=-1, keepdims=True)


def _bounds(x, n, has, w9, thickness, big):
    """(m, m) lower bound of each cell's plane over its cone, and upper bound of the radial distance
    beyond which a point is behind the plane by more than the thickness τ = thickness·|x| (module
    docstring); ``big`` where there is no surface or no bound."""
    r = plane_distance(x[..., None, :], n[..., None, :], w9)
    lo = jnp.min(jnp.where(jnp.isfinite(r), r, big), axis=-1) * 0.98  # 9 samples, not an exact bound
    # Behind by τ in signed plane distance is |ω·n|·(ρ − r(ω)) > τ, i.e. ρ > r(ω) + τ/|ω·n|.
    wn = jnp.abs(jnp.sum(w9 * n[..., None, :], axis=-1))
    tau = thickness * jnp.linalg.norm(x, axis=-1)[..., None]
    deep = r + tau / jnp.maximum(wn, 1e-6)
    hi = jnp.max(jnp.where(jnp.isfinite(deep), deep, big), axis=-1) * 1.02
    return jnp.where(has, lo, big), jnp.where(has, jnp.minimum(hi, big), big)


def crease(xa, na, wa, xx, nx, wx, tol: float) -> tuple[Array, Array]:
    """(concave, convex): do surfels A and X (points, normals turned toward the probe, sample directions;
    broadcasting) meet in a concave or a convex crease (module docstring)? A concave crease's surface is
    the *nearer* of the two planes, so a point is free only in front of both — the march's fine test and
    its skip bounds use both planes there (``_march._surfel_test``)."""
    ra, rx = jnp.linalg.norm(xa, axis=-1), jnp.linalg.norm(xx, axis=-1)
    pa_x, px_a = plane_distance(xa, na, wx), plane_distance(xx, nx, wa)
    fin = jnp.isfinite(pa_x) & jnp.isfinite(px_a)
    concave = fin & (ra <= px_a * (1 + tol)) & (rx <= pa_x * (1 + tol))
    convex = fin & (ra >= px_a * (1 - tol)) & (rx >= pa_x * (1 - tol))
    return concave, convex


def _pair(xb, nb, hb, wb, di: int, dj: int, tol: float) -> tuple[Bool[Array, "r r"], Bool[Array, "r r"]]:
    """Per interior texel and its neighbour at offset (di, dj): (one surface?, a concave crease of two
    surfaces?) (module docstring).

    Args:
        xb, nb, hb, wb: ONE probe's bordered (R+2)² maps: surfel points (probe-relative), normals turned
            toward the probe, has-surface flags and sample directions (the border ring holds the
            neighbours across the octahedral fold, with their own directions).
    """
    r = xb.shape[0] - 2
    own = lambda a: a[1 : r + 1, 1 : r + 1]
    nbr = lambda a: a[1 + di : r + 1 + di, 1 + dj : r + 1 + dj]
    xa, na, ha, wa = own(xb), own(nb), own(hb), own(wb)
    xx, nx, hx, wx = nbr(xb), nbr(nb), nbr(hb), nbr(wb)
    wm = wa + wx
    wm = wm / jnp.maximum(jnp.linalg.norm(wm, axis=-1, keepdims=True), 1e-12)
    pa_m, px_m = plane_distance(xa, na, wm), plane_distance(xx, nx, wm)
    smooth = jnp.isfinite(pa_m) & jnp.isfinite(px_m)
    smooth = smooth & (jnp.abs(pa_m - px_m) <= tol * jnp.minimum(pa_m, px_m))
    concave, convex = crease(xa, na, wa, xx, nx, wx, tol)
    both = ha & hx
    return (both & (smooth | concave | convex)) | ~ha, both & concave


def _uses(sub: int, di: int, dj: int, m: int) -> Array:
    """(m, m) or scalar: which cells have the neighbour (di, dj) in their footprint."""
    if sub == 1:
        return jnp.bool_(True)
    q = jnp.arange(m) % 2
    row = jnp.bool_(True) if di == 0 else q[:, None] == (1 if di > 0 else 0)
    col = jnp.bool_(True) if dj == 0 else q[None, :] == (1 if dj > 0 else 0)
    return row & col


def probe_cells(xb, nb, hb, wb, w9_cells, w9_texels, *, sub, tol, thickness, big):
    """:func:`probe_cells_reference`, computed per cell quadrant (issue 33): a neighbour's plane bounds
    only the cells on its side of the texel (one quadrant for a diagonal neighbour, two for an edge one), so
    its cell-level bound is evaluated there and not on all ``sub``² cells of every texel — 108 instead of
    288 plane samples per texel for the concave-crease partners at ``sub`` = 2, and none of their own at
    ``sub`` = 1, where a cell is its texel and the partner bound is the neighbour bound already computed.
    Same values: each cell's bound is the minimum of the same samples."""
    r = xb.shape[0] - 2
    m = r * sub
    up = lambda a: jnp.repeat(jnp.repeat(a, sub, axis=0), sub, axis=1)
    own = lambda a: a[1 : r + 1, 1 : r + 1]
    lower, upper = _bounds(up(own(xb)), up(own(nb)), up(own(hb)), w9_cells, thickness, big)
    ambiguous = jnp.zeros((m, m), bool)
    if tol is None:
        return lower, upper, ambiguous
    pairs = {(di, dj): _pair(xb, nb, hb, wb, di, dj, tol) for di, dj in NEIGHBOURS}
    for (di, dj), (one, _) in pairs.items():
        ambiguous = ambiguous | (_uses(sub, di, dj, m) & ~up(one))
    for (di, dj), (_, concave) in pairs.items():
        nbr = lambda a, di=di, dj=dj: a[1 + di : r + 1 + di, 1 + dj : r + 1 + dj]
        lo, hi = _bounds(nbr(xb), nbr(nb), nbr(hb), w9_texels, thickness, big)
        use = _uses(sub, di, dj, m) & ambiguous
        lower = jnp.where(use, jnp.minimum(lower, up(lo)), lower)
        upper = jnp.where(use, jnp.minimum(upper, up(hi)), upper)
        # A concave crease partner of a one-surface cell bounds the cell too (probe_cells_reference), over
        # the cell's own cone: evaluated on the quadrants of cells on the neighbour's side only.
        for qr, qc in _quadrants(sub, di, dj):
            sl = (slice(qr, None, sub), slice(qc, None, sub))  # the quadrant's cells, one per texel
            cell_lo = lo if sub == 1 else _bounds(nbr(xb), nbr(nb), nbr(hb), w9_cells[sl], thickness, big)[0]
            partner = ~ambiguous[sl] & concave
            lower = lower.at[sl].set(jnp.where(partner, jnp.minimum(lower[sl], cell_lo), lower[sl]))
    return lower, upper, ambiguous


def _quadrants(sub: int, di: int, dj: int) -> list[tuple[int, int]]:
    """The (row, col) parities of the cells whose footprint holds neighbour (di, dj) (:func:`_uses`)."""
    if sub == 1:
        return [(0, 0)]
    rows = [0, 1] if di == 0 else [1 if di > 0 else 0]
    cols = [0, 1] if dj == 0 else [1 if dj > 0 else 0]
    return [(a, b) for a in rows for b in cols]


def probe_cells_reference(xb, nb, hb, wb, w9_cells, w9_texels, *, sub, tol, thickness, big):
    """ONE probe's march cells (m = sub·R per axis): (lower bound, upper bound, ambiguous) maps, (m, m).
    The simple form, every bound on every cell; :func:`probe_cells` must agree with it.

    The lower bound is that of the candidate surfels' planes (in front of it: free); the upper bound the
    radial distance beyond which a point is deep behind (by the thickness) the cell's surfel — in an
    ambiguous cell, behind some candidate's — so the tracer's fine test says unknown. The own surfel is
    bounded over each cell's cone (``w9_cells``), a neighbour's over the whole texel's (``w9_texels``;
    looser, cheaper). ``tol`` None: no ambiguity test (every cell is its texel's surfel).
    """
    r = xb.shape[0] - 2
    m = r * sub
    up = lambda a: jnp.repeat(jnp.repeat(a, sub, axis=0), sub, axis=1)
    own = lambda a: a[1 : r + 1, 1 : r + 1]
    lower, upper = _bounds(up(own(xb)), up(own(nb)), up(own(hb)), w9_cells, thickness, big)
    ambiguous = jnp.zeros((m, m), bool)
    if tol is None:
        return lower, upper, ambiguous
    pairs = {(di, dj): _pair(xb, nb, hb, wb, di, dj, tol) for di, dj in NEIGHBOURS}
    for (di, dj), (one, _) in pairs.items():
        ambiguous = ambiguous | (_uses(sub, di, dj, m) & ~up(one))
    for (di, dj), (_, concave) in pairs.items():
        nbr = lambda a, di=di, dj=dj: a[1 + di : r + 1 + di, 1 + dj : r + 1 + dj]
        lo, hi = _bounds(nbr(xb), nbr(nb), nbr(hb), w9_texels, thickness, big)
        use = _uses(sub, di, dj, m) & ambiguous
        lower = jnp.where(use, jnp.minimum(lower, up(lo)), lower)
        upper = jnp.where(use, jnp.minimum(upper, up(hi)), upper)
        # A concave crease partner of a one-surface cell: its plane also bounds the cell (the fine test
        # reads it), bounded over the cell's own cone — a ray skipped past it would slip through the corner.
        partner = _uses(sub, di, dj, m) & ~ambiguous & up(concave)
        lo_cell, _ = _bounds(up(nbr(xb)), up(nbr(nb)), up(nbr(hb)), w9_cells, thickness, big)
        lower = jnp.where(partner, jnp.minimum(lower, lo_cell), lower)
    return lower, upper, ambiguous
