"""The reference path tracer's model compiled by Mitsuba 3 / Dr.Jit on the CPU (``backend="mitsuba"``).

Same estimator as the JAX backend (:mod:`._integrator`), term for term: the BRDF of :mod:`._brdf`
(Lambert + GGX, glTF metal-rough with the KHR specular factor, lobe chosen by estimated albedo, VNDF
sampling, per-lobe weight at x₁), the lights of :mod:`._lights` (power-sampled one-sided emissive
triangles, the sun's disk, the constant sky), MIS with the power heuristic, two-sided shading by the
geometric normal, Russian roulette, ``max_depth`` in segments, and the component split (emission,
direct, indirect by x₁'s sampled lobe, direct's specular-lobe share ``glossy_direct``). Even the random
numbers are the same: :func:`._sampling.path_uniforms` (PCG4D of seed, stream, sample, bounce) is
re-implemented in Dr.Jit's uint32 arithmetic, so both backends draw the same numbers for the same (ray,
sample, bounce) and a Mitsuba render is a common-random-numbers partner of the probe renderer just as a
JAX one is.

Mitsuba contributes the ray casts (its Embree BVH, ``Scene.ray_intersect_preliminary`` /
``ray_test``) and Dr.Jit the compiler: one symbolic ``dr.while_loop`` runs every bounce of a lane in
one LLVM kernel, so a path that dies early costs nothing more and no per-bounce state goes to memory.
Mitsuba's own BSDF and emitter plugins are *not* used: its ``principled`` BSDF differs from the glTF
model (Disney's diffuse retro-reflection, its own lobe sampling), and its area emitters do not split
the components by the first lobe, so the whole shading model is ours, only written in Dr.Jit.

Where the backends can differ: the ray–triangle tests (Embree's watertight test vs ours) disagree on
rays that graze an edge to within float32 round-off, and the float32 arithmetic is ordered differently,
so a path can take another branch at a Russian-roulette or lobe threshold. Both change single samples,
never the expectation; ``tests/render/test_mitsuba_backend.py`` checks the agreement.

Speed notes (benchmarks/pathtrace.py): every output of the loop is evaluated in one ``dr.eval`` —
reading outputs one by one would re-run the whole loop per output (``Integrator.sample`` read that way
ran 4× slower than ``mi.render``) — and every number that changes between calls (seed, offsets,
depth, camera) is ``dr.opaque`` so the kernel is compiled once per scene and setting, not per batch.
"""

from __future__ import annotations

import collections
import math

import numpy as np

from .._core import REC709_LUMA, Scene
from ._brdf import ALPHA_MIN, DIELECTRIC_F0, P_LOBE_MIN
from ._integrator import COMPONENTS, RAY_EPS, SHADOW_EPS
from ._lights import light_table
from ._sampling import pcg4d_lanes

if COMPONENTS != ("emission", "direct", "diffuse_indirect", "glossy_indirect", "full", "glossy_direct"):
    # _trace returns these six in this order; a new component must be added there too.
    raise ImportError(f"_mitsuba_backend does not produce the components {COMPONENTS}")

#: The Mitsuba variant the backend compiles for (the CPU one: LLVM, RGB).
VARIANT = "llvm_ad_rgb"
_INV_PI = 1.0 / math.pi


def load_mitsuba():
    """Import Mitsuba with :data:`VARIANT` set and proven to compile; return the module.

    Raises:
        ImportError: Mitsuba is not installed or its LLVM backend cannot load (one line with the fix).
    """
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        raise ImportError(f"backend='mitsuba' needs Mitsuba 3 (pip install mitsuba): {e}") from e
    if mi.variant() != VARIANT:
        if VARIANT not in mi.variants():
            raise ImportError(f"backend='mitsuba' needs Mitsuba's {VARIANT} variant, not in this build")
        try:
            mi.set_variant(VARIANT)
            dr.eval(mi.Float(1.0) + 1.0)  # the LLVM backend only fails when a first kernel is built
        except Exception as e:
            raise ImportError(
                f"backend='mitsuba': Mitsuba's {VARIANT} variant cannot load ({e}); install an LLVM "
                "shared library (Debian: apt-get install libllvm19) or use backend='jax'"
            ) from e
    return mi


class _Prepared:
    """One scene on the Mitsuba side: the BVH and every table shading reads (Dr.Jit arrays)."""

    def __init__(self, scene: Scene):
        mi = load_mitsuba()
        verts = np.asarray(scene.vertices, np.float32)
        faces = np.asarray(scene.faces, np.uint32)
        mesh = mi.Mesh("probeplace", len(verts), len(faces), has_vertex_normals=False)
        params = mi.traverse(mesh)
        params["vertex_positions"] = mi.Float(verts.ravel())
        params["faces"] = mi.UInt32(faces.ravel())
        params.update()
        # One mesh: Mitsuba's prim_index is our triangle index, so materials, normals and the area-light
        # pdf are plain gathers (no per-shape virtual calls).
        self.mi_scene = mi.load_dict({"type": "scene", "mesh": mesh})
        tris = verts[faces].astype(np.float32)
        cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        geo = cross / np.maximum(np.linalg.norm(cross, axis=1, keepdims=True), 1e-30)
        cn = np.asarray(scene.corner_normals, np.float32)
        # Flat triangles (every corner normal = the face normal, as in the Cornell box): skip the
        # interpolation, 9 gathers per bounce.
        self.flat = bool(np.all(np.abs(cn - geo[:, None, :]) < 1e-6))
        lt = light_table(scene)
        self.p_area = float(lt.p_area)
        self.sun_h = float(lt.sun_h)
        # Light types present: the kernel leaves out what a scene lacks (a sky-only scene has neither,
        # and no light sample: the sky is reached by BRDF sampling alone, as in _lights).
        self.has_area = self.p_area > 0
        self.has_sun = self.sun_h > 0
        self.n_emit = int(lt.cdf.shape[0])
        m = scene.materials
        f32 = lambda a: mi.Float(np.asarray(a, np.float32))
        # Every array the kernel reads, handed to _batch with the per-call numbers.
        self.tables = {
            "geo_n": _vec(mi, geo),
            **{f"corner_n{i}": _vec(mi, cn[:, i]) for i in range(3)},
            "tri_mat": mi.UInt32(np.asarray(scene.tri_material, np.uint32)),
            "base_color": _vec(mi, np.asarray(m.base_color)),
            "roughness": f32(m.roughness),
            "metallic": f32(m.metallic),
            "emission": _vec(mi, np.asarray(m.emission)),
            "l_v0": _vec(mi, np.asarray(lt.v0)),
            "l_e1": _vec(mi, np.asarray(lt.e1)),
            "l_e2": _vec(mi, np.asarray(lt.e2)),
            "l_normal": _vec(mi, np.asarray(lt.normal)),
            "l_radiance": _vec(mi, np.asarray(lt.radiance)),
            "l_cdf": f32(lt.cdf),
            "pdf_area_of_tri": f32(lt.pdf_area_of_tri),
            "mi_scene": self.mi_scene,
        }
        self.sun_dir = np.asarray(lt.sun_dir, np.float32)
        self.sun_radiance = np.asarray(lt.sun_radiance, np.float32)
        self.sun_t, self.sun_b = _frame_np(self.sun_dir)
        self.sky = np.asarray(scene.sky_radiance, np.float32)


def _vec(mi, a: np.ndarray):
    a = np.ascontiguousarray(a, np.float32)
    return mi.Vector3f(mi.Float(a[:, 0].copy()), mi.Float(a[:, 1].copy()), mi.Float(a[:, 2].copy()))


def _lit3(mi, v):
    # a constant 3-vector as three literals (from a NumPy array Dr.Jit would make a memory-backed array)
    return mi.Vector3f(*(float(c) for c in v))


def _frame_np(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # make_frame (Duff et al. 2017) on the host, for the constant sun direction.
    n = n.astype(np.float64)
    sign = 1.0 if n[2] >= 0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]], np.float32)
    bt = np.array([b, sign + n[1] * n[1] * a, -n[1]], np.float32)
    return t, bt


_CACHE: collections.OrderedDict[int, tuple[Scene, _Prepared]] = collections.OrderedDict()
_CACHE_SIZE = 2


def prepare(scene: Scene) -> _Prepared:
    """The Mitsuba side of ``scene``, built once and kept for the last few scenes (keyed by identity)."""
    hit = _CACHE.get(id(scene))
    if hit is not None and hit[0] is scene:
        _CACHE.move_to_end(id(scene))
        return hit[1]
    prep = _Prepared(scene)
    _CACHE[id(scene)] = (scene, prep)
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return prep


# --------------------------------------------------------------------------------------------------
# Dr.Jit twins of _sampling / _brdf / _lights (one lane each, vectorised by Dr.Jit)
# --------------------------------------------------------------------------------------------------


def _pcg4d(mi, x, y, z, w):
    """_sampling's PCG4D on Dr.Jit lanes (uint32 arithmetic wraps in Dr.Jit as in JAX)."""
    return pcg4d_lanes(x, y, z, w)


def _uniforms(mi, seed, stream, sample, bounce):
    """The eight numbers of _sampling.path_uniforms (same bits: top 24 of each hash word)."""
    lo = _pcg4d(mi, stream, sample, bounce * 2, seed)
    hi = _pcg4d(mi, stream, sample, bounce * 2 + 1, seed)
    return [mi.Float(v >> 8) * 2.0**-24 for v in (*lo, *hi)]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _safe_normalize(dr, mi, v):
    sq = _dot(v, v)
    small = sq < 1e-12
    return v * dr.select(small, 0.0, dr.rsqrt(dr.select(small, 1.0, sq)))


def _make_frame(dr, mi, n):
    sign = dr.select(n[2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = mi.Vector3f(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    bt = mi.Vector3f(b, sign + n[1] * n[1] * a, -n[1])
    return t, bt


def _to_local(mi, v, t, b, n):
    return mi.Vector3f(_dot(v, t), _dot(v, b), _dot(v, n))


def _to_world(v, t, b, n):
    return v[0] * t + v[1] * b + v[2] * n


def _power(dr, a, b):
    a2 = a * a
    den = a2 + b * b
    ok = (den > 0) & dr.isfinite(den)
    w = dr.select(ok, a2 / dr.select(ok, den, 1.0), 0.0)
    return dr.select(dr.isinf(a), 1.0, dr.select(dr.isinf(b), 0.0, w))


def _schlick(dr, f0, c):
    m = dr.clip(1.0 - c, 0.0, 1.0)
    m2 = m * m
    return f0 + (1.0 - f0) * (m2 * m2 * m)


def _lum(c):
    wr, wg, wb = REC709_LUMA  # the JAX integrator's _brdf._lum, term for term
    return wr * c[0] + wg * c[1] + wb * c[2]


def _ggx_d(dr, h, a):
    a2 = a * a
    den = h[0] * h[0] + h[1] * h[1] + a2 * h[2] * h[2]
    return dr.select(h[2] > 0, a2 * _INV_PI / (den * den), 0.0)


def _smith_g1(dr, v, a):
    c = dr.maximum(v[2], 0.0)
    root = dr.sqrt(a * a * (v[0] * v[0] + v[1] * v[1]) + c * c)
    den = c + root
    return dr.select(c > 0, 2.0 * c / dr.select(den > 0, den, 1.0), 0.0)


class _Brdf:
    """BrdfParams at one lane, with the quantities every evaluation at this wo shares."""

    def __init__(self, dr, mi, base, rough, metal, spec, wo):
        self.base, self.metal, self.spec, self.wo = base, metal, spec, wo
        self.alpha = dr.maximum(rough * rough, ALPHA_MIN)
        self.g1_o = _smith_g1(dr, wo, self.alpha)
        # lobe_probability at wo
        cos_o = dr.clip(wo[2], 0.0, 1.0)
        f_diel, f_spec = self.fresnel(dr, cos_o)
        a_s = _lum(f_spec)
        a_d = (1.0 - metal) * _lum(base) * (1.0 - f_diel)
        tot = a_s + a_d
        ps = dr.clip(
            dr.select(tot > 0, a_s / dr.select(tot > 0, tot, 1.0), 0.5), P_LOBE_MIN, 1.0 - P_LOBE_MIN
        )
        has_s = (metal > 0) | (spec > 0)
        has_d = (1.0 - metal) * dr.maximum(dr.maximum(base[0], base[1]), base[2]) > 0
        self.ps = dr.select(~has_s, 0.0, dr.select(~has_d, 1.0, ps))

    def fresnel(self, dr, cos_vh):
        f_diel = self.spec * _schlick(dr, DIELECTRIC_F0, cos_vh)
        f_metal = _schlick(dr, self.base, cos_vh)
        return f_diel, (1.0 - self.metal) * f_diel + self.metal * f_metal

    def eval_pdf(self, dr, mi, wi):
        """(f_d, f_s, pdf_d, pdf_s) of eval_brdf and pdf_brdf at (wo, wi)."""
        wo = self.wo
        up = (wo[2] > 0) & (wi[2] > 0)
        h = _safe_normalize(dr, mi, wo + wi)
        cos_vh_raw = _dot(wo, h)
        f_diel, f_spec = self.fresnel(dr, dr.clip(cos_vh_raw, 0.0, 1.0))
        f_d = (1.0 - self.metal) * (1.0 - f_diel) * self.base * _INV_PI
        d = _ggx_d(dr, h, self.alpha)
        cos_prod = dr.select(up, wo[2] * wi[2], 1.0)
        s = d * self.g1_o * _smith_g1(dr, wi, self.alpha) / (4.0 * cos_prod)
        ok_o = wo[2] > 0
        pdf_d = dr.select(ok_o, dr.maximum(wi[2], 0.0) * _INV_PI, 0.0)
        pdf_s = dr.select(ok_o & (cos_vh_raw > 0), self.g1_o * d / (4.0 * dr.select(ok_o, wo[2], 1.0)), 0.0)
        zero = mi.Vector3f(0.0)
        return dr.select(up, f_d, zero), dr.select(up, f_spec * s, zero), pdf_d, pdf_s

    def sample(self, dr, mi, u0, u1, u2):
        """(wi, specular, weight_lobe, weight, pdf) of _brdf.sample_brdf."""
        wo = self.wo
        spec = u0 < self.ps
        wo_s = dr.select(wo[2] > 0, wo, mi.Vector3f(0.0, 0.0, 1.0))
        h = _sample_vndf(dr, mi, wo_s, self.alpha, u1, u2)
        wi_s = 2.0 * _dot(wo, h) * h - wo
        r = dr.sqrt(u1)
        phi = 2.0 * math.pi * u2
        sp, cp = dr.sincos(phi)
        wi_d = mi.Vector3f(r * cp, r * sp, dr.sqrt(dr.maximum(1.0 - u1, 0.0)))
        wi = _safe_normalize(dr, mi, dr.select(spec, wi_s, wi_d))
        f_d, f_s, pdf_d, pdf_s = self.eval_pdf(dr, mi, wi)
        pdf = (1.0 - self.ps) * pdf_d + self.ps * pdf_s
        cos_i = dr.maximum(wi[2], 0.0)
        p_lobe = dr.select(spec, self.ps * pdf_s, (1.0 - self.ps) * pdf_d)
        f_lobe = dr.select(spec, f_s, f_d)
        ok_lobe = p_lobe > 0
        w_lobe = dr.select(ok_lobe, f_lobe * (cos_i / dr.select(ok_lobe, p_lobe, 1.0)), 0.0)
        ok = pdf > 0
        w = dr.select(ok, (f_d + f_s) * (cos_i / dr.select(ok, pdf, 1.0)), 0.0)
        return wi, spec, w_lobe, w, pdf


def _sample_vndf(dr, mi, wo, alpha, u1, u2):
    # _brdf.sample_ggx_vndf (Heitz 2018, Listing 1), component by component.
    vx, vy, vz = alpha * wo[0], alpha * wo[1], wo[2]
    inv_len = dr.rsqrt(dr.maximum(vx * vx + vy * vy + vz * vz, 1e-30))
    vx, vy, vz = vx * inv_len, vy * inv_len, vz * inv_len
    lensq = vx * vx + vy * vy
    pos = lensq > 0
    inv = dr.select(pos, dr.rsqrt(dr.select(pos, lensq, 1.0)), 0.0)
    t1x = dr.select(pos, -vy * inv, 1.0)
    t1y = dr.select(pos, vx * inv, 0.0)
    t2x = -vz * t1y
    t2y = vz * t1x
    t2z = vx * t1y - vy * t1x
    r = dr.sqrt(u1)
    sp, cp = dr.sincos(2.0 * math.pi * u2)
    p1 = r * cp
    p2 = r * sp
    s = 0.5 * (1.0 + vz)
    p2 = (1.0 - s) * dr.sqrt(dr.maximum(1.0 - p1 * p1, 0.0)) + s * p2
    p3 = dr.sqrt(dr.maximum(1.0 - p1 * p1 - p2 * p2, 0.0))
    nx = p1 * t1x + p2 * t2x + p3 * vx
    ny = p1 * t1y + p2 * t2y + p3 * vy
    nz = p2 * t2z + p3 * vz
    hx, hy, hz = alpha * nx, alpha * ny, dr.maximum(nz, 0.0)
    inv_h = dr.rsqrt(dr.maximum(hx * hx + hy * hy + hz * hz, 1e-30))
    return mi.Vector3f(hx * inv_h, hy * inv_h, hz * inv_h)


def _sample_light(dr, mi, P: _Prepared, s: dict, x, u4, u5, u6, u7):
    """(wi, dist, radiance, pdf) of _lights.sample_light; the branch of a light type the scene lacks is
    left out of the kernel (its choice probability is 0 there)."""
    if not (P.has_area or P.has_sun):  # pdf 0: no light sample (sample_light's answer there)
        return mi.Vector3f(0.0, 0.0, 1.0), mi.Float(math.inf), mi.Vector3f(0.0), mi.Float(0.0)
    if P.has_area:
        k = dr.binary_search(0, P.n_emit - 1, lambda i: dr.gather(mi.Float, s["l_cdf"], i) <= u5)
        su = dr.sqrt(u6)
        b1, b2 = su * (1.0 - u7), su * u7
        e1 = dr.gather(mi.Vector3f, s["l_e1"], k)
        e2 = dr.gather(mi.Vector3f, s["l_e2"], k)
        y = dr.gather(mi.Vector3f, s["l_v0"], k) + b1 * e1 + b2 * e2
        d = y - x
        dist2 = _dot(d, d)
        dist = dr.sqrt(dist2)
        wi_a = d / dr.select(dist > 0, dist, 1.0)
        cos_l = -_dot(dr.gather(mi.Vector3f, s["l_normal"], k), wi_a)
        area2 = dr.norm(dr.cross(e1, e2))
        prob_k = dr.gather(mi.Float, s["l_cdf"], k) - dr.gather(mi.Float, s["l_cdf"], k - 1, k > 0)
        ok_a = (cos_l > 0) & (dist > 0) & (area2 > 0) & (prob_k > 0)
        pdf_a = dr.select(ok_a, P.p_area * prob_k * 2.0 * dist2 / dr.select(ok_a, area2 * cos_l, 1.0), 0.0)
        rad_a = dr.select(ok_a, dr.gather(mi.Vector3f, s["l_radiance"], k), mi.Vector3f(0.0))
        if not P.has_sun:
            return wi_a, dist, rad_a, pdf_a
    uh = u6 * P.sun_h
    sin_t = dr.sqrt(dr.maximum(uh * (2.0 - uh), 0.0))
    sp, cp = dr.sincos(2.0 * math.pi * u7)
    local = mi.Vector3f(sin_t * cp, sin_t * sp, 1.0 - uh)
    wi_s = _to_world(local, _lit3(mi, P.sun_t), _lit3(mi, P.sun_b), _lit3(mi, P.sun_dir))
    pdf_s = (1.0 - P.p_area) / (2.0 * math.pi * P.sun_h)
    sun_rad = _lit3(mi, P.sun_radiance)
    if not P.has_area:
        return wi_s, mi.Float(math.inf), sun_rad, mi.Float(pdf_s)
    use_area = u4 < P.p_area
    return (
        dr.select(use_area, wi_a, wi_s),
        dr.select(use_area, dist, math.inf),
        dr.select(use_area, rad_a, sun_rad),
        dr.select(use_area, pdf_a, pdf_s),
    )


class _Hit(collections.namedtuple("_Hit", "pi found is_hit tri t x wo ng cos_l mat")):
    """What one bounce's ray cast found: Mitsuba's preliminary intersection and the values read at it."""

    __slots__ = ()


def _intersect(dr, mi, s: dict, o, d, alive) -> _Hit:
    """Cast a bounce's ray; gather the hit's position, geometric normal and material (zeros on a miss)."""
    pi = s["mi_scene"].ray_intersect_preliminary(mi.Ray3f(o, d), coherent=False, active=alive)
    found = pi.is_valid()
    is_hit = alive & found
    tri = dr.select(is_hit, pi.prim_index, 0)
    t = dr.select(is_hit, pi.t, 0.0)
    x = o + t * d
    wo = -d
    ng = dr.gather(mi.Vector3f, s["geo_n"], tri, is_hit)
    cos_l = _dot(ng, wo)
    mat = dr.gather(mi.UInt32, s["tri_mat"], tri, is_hit)
    return _Hit(pi, found, is_hit, tri, t, x, wo, ng, cos_l, mat)


def _route(dr, zero3, acc, value, depth, glossy):
    """Add radiance to the (emission, direct, indirect, glossy_direct) sums by its emitter's vertex depth."""
    # _integrator._route: radiance that left its emitter at vertex depth 1, 2 or ≥ 3; ``glossy`` is
    # the share of a direct value that x₁'s specular lobe reflected.
    em, di, ind, gd = acc
    return (
        em + dr.select(depth == 1, value, zero3),
        di + dr.select(depth == 2, value, zero3),
        ind + dr.select(depth >= 3, value, zero3),
        gd + dr.select(depth == 2, glossy, zero3),
    )


def _emitted(dr, mi, P: _Prepared, h: _Hit, s: dict, d, alive, prev_pdf, sky, zero3):
    """Radiance arriving along the ray before throughput: the hit emitter's or the sky/sun's, MIS-weighted."""
    # ---- emission at x_k (front faces), MIS against the light sample from x_{k−1}
    le = dr.gather(mi.Vector3f, s["emission"], h.mat, h.is_hit & (h.cos_l > 0))
    pa = dr.gather(mi.Float, s["pdf_area_of_tri"], h.tri, h.is_hit)
    ok_pa = h.is_hit & (h.cos_l > 0) & (pa > 0)
    w_le = _power(dr, prev_pdf, dr.select(ok_pa, pa * h.t * h.t / dr.select(ok_pa, h.cos_l, 1.0), 0.0))
    # ---- escaped rays: the sky and, MIS-weighted, the sun's disk
    env = sky
    if P.has_sun:
        diff = d - _lit3(mi, P.sun_dir)
        in_sun = _dot(diff, diff) <= 2.0 * P.sun_h
        pdf_sun = (1.0 - P.p_area) / (2.0 * math.pi * P.sun_h)
        w_sun = dr.select(in_sun, _power(dr, prev_pdf, mi.Float(pdf_sun)), 0.0)
        env = env + w_sun * _lit3(mi, P.sun_radiance)
    return le * w_le + dr.select(alive & ~h.found, env, zero3)


def _shading_frame(dr, mi, P: _Prepared, h: _Hit, s: dict):
    """Normals flipped to the ray's side (two-sided shading) and the shading frame: (ng_f, ns_f, tb, bb)."""
    flip = dr.select(h.cos_l < 0, -1.0, 1.0)
    ng_f = h.ng * flip
    if P.flat:
        ns_f = ng_f
    else:
        # a miss's prim_uv is undefined (NaN at times): zero it as the JAX casters do
        b1 = dr.select(h.is_hit, h.pi.prim_uv[0], 0.0)
        b2 = dr.select(h.is_hit, h.pi.prim_uv[1], 0.0)
        ns = (
            (1.0 - b1 - b2) * dr.gather(mi.Vector3f, s["corner_n0"], h.tri, h.is_hit)
            + b1 * dr.gather(mi.Vector3f, s["corner_n1"], h.tri, h.is_hit)
            + b2 * dr.gather(mi.Vector3f, s["corner_n2"], h.tri, h.is_hit)
        )
        ns_f = _safe_normalize(dr, mi, ns) * flip
    tb, bb = _make_frame(dr, mi, ns_f)
    return ng_f, ns_f, tb, bb


def _hit_brdf(dr, mi, h: _Hit, s: dict, wo_l) -> _Brdf:
    """The BRDF of the hit's material, for the outgoing direction ``wo_l`` in the shading frame."""
    return _Brdf(
        dr,
        mi,
        dr.gather(mi.Vector3f, s["base_color"], h.mat, h.is_hit),
        dr.gather(mi.Float, s["roughness"], h.mat, h.is_hit),
        dr.gather(mi.Float, s["metallic"], h.mat, h.is_hit),
        s["specular"],
        wo_l,
    )


def _next_event(dr, mi, P: _Prepared, s: dict, h: _Hit, frame, brdf, x_off, u, ok, thr, zero3):
    """Next-event estimation with MIS and a shadow ray: (contribution, light term, specular f, mask).

    ``frame`` is :func:`_shading_frame`'s output; ``ok`` marks lanes that continue with ``wo`` above
    the surface. The light term ``thr · L · weight`` and ``f_s`` give the glossy_direct share at x₁.
    """
    ng_f, ns_f, tb, bb = frame
    l_wi, l_dist, l_rad, l_pdf = _sample_light(dr, mi, P, s, h.x, u[4], u[5], u[6], u[7])
    wi_l = _to_local(mi, l_wi, tb, bb, ns_f)
    f_d, f_s, pdf_d, pdf_s = brdf.eval_pdf(dr, mi, wi_l)
    pdf_b = (1.0 - brdf.ps) * pdf_d + brdf.ps * pdf_s
    cont, wo_up = ok
    ok_l = cont & (l_pdf > 0) & (_dot(l_wi, ng_f) > 0) & wo_up
    scale = dr.maximum(wi_l[2], 0.0) * _power(dr, l_pdf, pdf_b) / dr.select(ok_l, l_pdf, 1.0)
    shadow = mi.Ray3f(x_off, l_wi)
    shadow.maxt = l_dist * (1.0 - SHADOW_EPS)
    ok_l &= ~s["mi_scene"].ray_test(shadow, active=ok_l)
    light = thr * l_rad * scale
    # select after the product: a lane without a light sample may hold NaN in f
    nee = dr.select(ok_l, light * (f_d + f_s), zero3)
    return nee, light, f_s, ok_l


def _russian_roulette(dr, s: dict, k, u3, thr_new, ok_b):
    """Mitsuba's Russian roulette on the new throughput: (reweighted throughput, lane still alive)."""
    q = dr.minimum(dr.maximum(dr.maximum(thr_new[0], thr_new[1]), thr_new[2]), 0.95)
    use_rr = k >= s["rr_depth"]
    survive = ~use_rr | (u3 < q)
    thr_new = dr.select(use_rr & survive & (q > 0), thr_new / dr.select(q > 0, q, 1.0), thr_new)
    alive_new = ok_b & survive & ((thr_new[0] > 0) | (thr_new[1] > 0) | (thr_new[2] > 0))
    return thr_new, alive_new


def _trace(P: _Prepared, o, d, stream, sample, valid, s: dict):
    """Every bounce of every lane (one symbolic loop); the components in :data:`COMPONENTS` order, three
    Float arrays (RGB) each."""
    import drjit as dr
    import mitsuba as mi

    zero3 = mi.Vector3f(0.0)
    sky = _lit3(mi, P.sky)

    def cond(k, o, d, thr, alive, prev_pdf, spec_first, acc):
        return alive

    def body(k, o, d, thr, alive, prev_pdf, spec_first, acc):
        u = _uniforms(mi, s["seed"], stream, sample, k)
        h = _intersect(dr, mi, s, o, d, alive)
        got = thr * _emitted(dr, mi, P, h, s, d, alive, prev_pdf, sky, zero3)
        # an emitter found at x₂ was reached by x₁'s BRDF sample, of x₁'s lobe (spec_first)
        acc = _route(dr, zero3, acc, got, k, dr.select(spec_first, got, zero3))

        # ---- continue from x_k (max_depth counts segments)
        cont = h.is_hit & (k < s["max_depth"])
        frame = _shading_frame(dr, mi, P, h, s)
        ng_f, ns_f, tb, bb = frame
        brdf = _hit_brdf(dr, mi, h, s, _to_local(mi, h.wo, tb, bb, ns_f))
        x = h.x
        ax = dr.maximum(dr.maximum(dr.abs(x[0]), dr.abs(x[1])), dr.abs(x[2]))
        x_off = x + ((1.0 + ax) * RAY_EPS) * ng_f
        wo_up = _dot(h.wo, ng_f) > 0
        first = k == 1
        # ---- next-event estimation with MIS
        nee, light, f_s, ok_l = _next_event(dr, mi, P, s, h, frame, brdf, x_off, u, (cont, wo_up), thr, zero3)
        acc = _route(dr, zero3, acc, nee, k + 1, dr.select(ok_l & first, light * f_s, zero3))
        # ---- BRDF sample → next ray; the per-lobe weight at x₁ keeps the lobe split unbiased
        wi_bl, b_spec, w_lobe, w_mix, b_pdf = brdf.sample(dr, mi, u[0], u[1], u[2])
        wi = _to_world(wi_bl, tb, bb, ns_f)
        ok_b = cont & (_dot(wi, ng_f) > 0) & wo_up
        thr_new = dr.select(ok_b, thr * dr.select(first, w_lobe, w_mix), zero3)
        spec_first = dr.select(first, b_spec, spec_first)
        # ---- Russian roulette (Mitsuba's rule)
        thr_new, alive_new = _russian_roulette(dr, s, k, u[3], thr_new, ok_b)
        return k + 1, x_off, wi, thr_new, alive_new, b_pdf, spec_first, acc

    state = (
        mi.UInt32(1),
        mi.Vector3f(o),
        mi.Vector3f(d),
        mi.Vector3f(1.0),
        mi.Bool(valid),
        dr.full(mi.Float, math.inf, dr.width(valid)),
        mi.Bool(False),
        tuple(mi.Vector3f(0.0) for _ in range(4)),
    )
    # Symbolic: the whole path in one kernel. An evaluated loop compressed to the live lanes after each
    # bounce (a wavefront) ran 2× slower here: the state round-trips through memory every bounce.
    out = dr.while_loop(state, cond, body, mode="symbolic", label="probeplace_path")
    spec_first, (em, di, ind, gd) = out[6], out[7]
    diff_ind = dr.select(spec_first, zero3, ind)
    gloss_ind = dr.select(spec_first, ind, zero3)
    full = em + di + ind
    return [c[i] for c in (em, di, diff_ind, gloss_ind, full, gd) for i in range(3)]


def _opaque3(dr, mi, v):
    # a 3-vector the kernel reads from memory, so a new value does not recompile it
    return mi.Vector3f(*(dr.opaque(mi.Float, float(c)) for c in np.asarray(v, np.float32)))


def _camera_rays(dr, mi, a: dict, pixel, u1, u2):
    """_camera.camera_ray in Dr.Jit (box filter: the sample lands at (col + u₁, row + u₂))."""
    row = mi.Float(pixel // a["width"])
    col = mi.Float(pixel % a["width"])
    w, h, tan_y = a["w"], a["h"], a["tan_y"]
    x = (2.0 * (col + u1) / w - 1.0) * (tan_y * (w / h))
    y = (1.0 - 2.0 * (row + u2) / h) * tan_y
    return a["position"], _safe_normalize(dr, mi, a["fwd"] + x * a["right"] + y * a["up"])


def _batch(prep: _Prepared, a: dict, p: int, g: int):
    """Trace p items × g samples (item-major lanes) and reduce them per item: (means, m2s, count), each
    component channel one Float of width p. ``a`` holds the opaque per-call numbers and the rays (or the
    camera); (p, g) and the dict's keys are the only things that select a kernel."""
    import drjit as dr
    import mitsuba as mi

    lane = dr.arange(mi.UInt32, p * g)
    item = lane // a["g"]
    pix = a["pix0"] + item
    smp = a["smp0"] + (lane - item * a["g"])
    valid = (pix < a["n_items"]) & (smp < a["spp"])
    pix = dr.minimum(pix, a["n_items"] - 1)
    stream = pix + a["offset"]
    if "origins" in a:
        o = dr.gather(mi.Vector3f, a["origins"], item)
        d = dr.gather(mi.Vector3f, a["directions"], item)
    else:
        u = _uniforms(mi, a["seed"], stream, smp, mi.UInt32(0))
        o, d = _camera_rays(dr, mi, a, pix, u[1], u[2])
    vals = _trace(prep, o, d, stream, smp, valid, a)
    w = dr.select(valid, 1.0, 0.0)
    dr.eval(vals, w)  # one kernel for every output: evaluating them apart would re-run the loop
    cnt = dr.block_sum(w, g)
    means = [dr.block_sum(v, g) / dr.maximum(cnt, 1.0) for v in vals]
    dr.eval(means)
    m2 = [
        dr.block_sum(w * dr.square(v - dr.gather(mi.Float, m, item)), g)
        for v, m in zip(vals, means, strict=True)
    ]
    dr.eval(cnt, m2)
    return means, m2, cnt


def batch_runner(scene: Scene, *, max_depth: int, rr_depth: int, specular: float):
    """A batch function for ``_render._accumulate``: ``run(ctx, caster, source, seed, offset, pix0, smp0,
    spp, n_items, p, g) -> (mean (p, c, 3), m2 (p, c, 3), count (p,))`` as NumPy for c components, the
    contract of the JAX batches (``ctx`` and ``caster`` are unused: the scene is prepared here).

    Raises:
        ImportError: Mitsuba's LLVM variant cannot load.
    """
    prep = prepare(scene)

    def run(ctx, caster, source, seed, offset, pix0, smp0, spp, n_items, p: int, g: int):
        del ctx, caster
        import drjit as dr
        import mitsuba as mi

        load_mitsuba()
        u32 = lambda v: dr.opaque(mi.UInt32, int(v))
        f32 = lambda v: dr.opaque(mi.Float, float(v))
        a = {
            "seed": u32(np.asarray(seed)),
            "max_depth": u32(max_depth),
            "rr_depth": u32(rr_depth),
            "specular": f32(specular),
            "offset": u32(offset),
            "pix0": u32(pix0),
            "smp0": u32(smp0),
            "spp": u32(spp),
            "n_items": u32(n_items),
            "g": u32(g),
        }
        if hasattr(source, "camera"):
            from ._camera import camera_basis

            cam = source.camera
            a["position"] = _opaque3(dr, mi, cam.position)
            a["fwd"], a["right"], a["up"] = (_opaque3(dr, mi, v) for v in camera_basis(cam))
            a["width"] = u32(source.width)
            a["w"], a["h"] = f32(source.width), f32(source.height)
            a["tan_y"] = f32(np.tan(np.float32(0.5) * np.deg2rad(np.float32(cam.fov_y_deg))))
        else:
            a["origins"] = _vec(mi, np.asarray(source.origins))
            a["directions"] = _vec(mi, np.asarray(source.directions))
        means, m2, cnt = _batch(prep, {**a, **prep.tables}, p, g)
        shape = (p, len(COMPONENTS), 3)
        stack = lambda xs: np.stack([np.asarray(x) for x in xs], axis=1).reshape(shape)
        return stack(means), stack(m2), np.asarray(cnt)

    return run
