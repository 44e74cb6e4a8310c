"""The glossy error taken apart, relative MSE and bootstrap confidence intervals (pure NumPy).

Samples are pixel-major: sample i belongs to pixel i // S (S samples per pixel). A pixel's glossy
value is mean_s(w_s · L_s), so its error against the CRN reference is

    e_px = Σ_s e_s,   e_s = w_s (L_probe,s − L_ref,s) / S.

**Additive split by ray status.** e_px² = Σ_k e_px · e_px⁽ᵏ⁾ with e_px⁽ᵏ⁾ = Σ_{s: status k} e_s, so the
per-status terms MSE_k = mean_px,c(e_px · e_px⁽ᵏ⁾) add up to the MSE *exactly* (the covariance or
"Euler" allocation of a sum of squares: each sample is charged its own error times its pixel's total
error). A term can be negative when a status's errors cancel the others'. ``resolved_only`` is the MSE
of the image whose unresolved rays carry the reference radiance, mean((e − e⁽ᵘⁿʳᵉˢᵒˡᵛᵉᵈ⁾)²): the
resolved rays scored apart.

**Converged MSE.** e_px² overstates the error of the image the probes would give with infinitely many
glossy rays and reference paths a pixel. Given the pixel (and the bake), its S samples' errors
d_s = S·e_s are independent and identically distributed — each has its own camera jitter, GGX direction
and reference paths — so E[e_px²] = (E d)² + Var(d)/S: the reference's noise floor and the scatter of
the lobe's directions ride on the squared error. The U-statistic of the pairs (Hoeffding 1948, "A class
of statistics with asymptotically normal distribution"),

    U_px = Σ_{s≠t} d_s d_t / (S(S − 1)) = S/(S − 1) · (e_px² − Σ_s e_s²),

is unbiased for (E d)², the converged image's squared error, and holds no d_s² term: one sample's large
error (a glossy ray that alone in its pixel meets a sun glint, a reference firefly) enters only through
its products with the pixel's other samples, where e_px² takes its square — part of the heavy tail
behind the plain MSE's seed-to-seed spread (issue 33, experiments/README.md §2). A pixel's U can be
negative; the image's mean is the estimate. It needs S ≥ 2.

**Perfect trace.** The same estimator with the radiance read at the exact hit (L_perfect): its MSE is
the representation floor; the trace's share is MSE − MSE_perfect and ``trace_excess`` = MSE /
MSE_perfect − 1.

**Relative MSE.** mean over pixels of (p − r)² / (r² + ε) on per-pixel luminance (Rousselle, Knaus &
Zwicker 2011, "Adaptive sampling and reconstruction using greedy error minimization", §6; the metric of
Bako et al. 2017 KPCN, Bitterli et al. 2016 and most Monte Carlo denoising papers, there with ε = 0.01
on display-range images). Our radiance has no fixed scale, so ε = ``eps`` × (mean reference
luminance)²: the usual ε = 0.01 for an image scaled to mean luminance 1.

**Confidence intervals.** Percentile bootstrap over pixels (Efron & Tibshirani 1993, ch. 13): the mean
of the per-pixel squared error over ``n_resamples`` resamples of the pixels with replacement, from a
fixed seed (deterministic); the interval between the (1 ± level)/2 quantiles.

**Light leak against the reference's own noise** (:func:`light_leak`). A pixel leaks when the probe
image is brighter than the reference by more than k standard errors of the reference pixel mean
(k = :data:`LEAK_SIGMAS`), in luminance: p − r > k·σ_r. σ_r is bounded above by Σ_c a_c σ_c (the Rec. 709
weights a_c and each channel's standard error σ_c = √Var[mean]; the sd of a weighted sum of correlated
channels is at most the weighted sum of their sds), so the test errs towards not flagging. Only pixels
whose standard error is *known* are judged: a pixel whose paths all returned the same value (typically
all zero at 16 spp, where indirect light arrives through rare paths) has a sample variance of 0, which
says nothing about its noise; judging it against 0 flagged ~30 % of the pixels for every method. With
Gaussian pixel noise a perfect probe image is flagged on about 3·10⁻⁵ of the judged pixels at k = 4.
Truly black regions (a sealed room) are never judged here: tests/evaluate/test_rooms_leak.py measures
leaks there against an exact zero.
"""

from __future__ import annotations

import numpy as np

from .._core import REC709_LUMA
from ..probes import TraceStatus

#: Tracer status codes (``probes.TraceStatus``) → their metrics names.
STATUS_NAMES = {int(s): s.label for s in TraceStatus}
_LUMA = np.array(REC709_LUMA)  # as _core.luminance
#: Standard errors of the reference by which a probe pixel must exceed it to count as leaked light.
LEAK_SIGMAS = 4.0


def mean_sq_error(a: np.ndarray, b: np.ndarray) -> float:
    """MSE of ``a`` against ``b`` over every element, in float64."""
    return float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))


def pixel_sq_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-pixel squared error of two (h, w, 3) images, mean over RGB, flat: the bootstrap's unit."""
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    return np.mean(d * d, axis=-1).reshape(-1)


def tail_count(n_pixels: int, percent: float = 1.0) -> int:
    """How many pixels an error's tail holds: ``percent`` % of ``n_pixels``, rounded down, one at least
    (1 %: 30 of a 64×48 image's 3,072)."""
    return max(1, int(n_pixels * percent // 100))


def top_share(sq_px: np.ndarray, k: int) -> float | None:
    """The share of the summed per-pixel squared error made by the ``k`` pixels with the largest (None
    for no error): the sum of the k largest, whatever their order or ties."""
    sq = np.ravel(sq_px)
    total = float(np.sum(sq))
    k = min(k, sq.size)
    return float(np.sum(np.partition(sq, sq.size - k)[sq.size - k :])) / total if total > 0 else None


def tail_index(sq_px: np.ndarray, k: int) -> float | None:
    """Hill's estimate of the tail index α of the per-pixel squared error from its ``k`` largest values
    (Hill 1975, "A simple general approach to inference about the tail of a distribution"): 1 / mean of
    ln(x_(i) / x_(k+1)) over the k largest x_(i), x_(k+1) the next one. A tail P(X > x) ∝ x^−α with α < 2
    has no finite variance over the range it was sampled in: there the MSE, a mean of such values, neither
    settles as 1/√n nor has a bootstrap interval that holds — more pixels draw larger ones (issue 33,
    experiments/README.md §2). None when fewer than k + 1 values are positive, or the k largest equal the
    next one (no tail to measure)."""
    x = np.ravel(np.asarray(sq_px, np.float64))
    x = x[x > 0]
    if not 0 < k < x.size:
        return None
    top = np.partition(x, x.size - k - 1)[x.size - k - 1 :]  # x_(k+1) first, then the k largest
    mean_log = float(np.mean(np.log(top[1:] / top[0])))
    return 1.0 / mean_log if mean_log > 0 else None


def pixel_means(v: np.ndarray, n_pixels: int, spp: int) -> np.ndarray:
    """(n_pixels·spp, …) pixel-major samples → (n_pixels, …) per-pixel means."""
    v = np.asarray(v, np.float64)
    return v.reshape(n_pixels, spp, *v.shape[1:]).mean(axis=1)


def sample_errors(w, l_est, l_ref, spp: int) -> tuple[np.ndarray, np.ndarray]:
    """(e_s, e_px): each sample's part e_s = w_s (L_est,s − L_ref,s) / S (n, 3) of its pixel's error, and
    the pixels' errors e_px = Σ_s e_s (n / S, 3) — samples pixel-major, S = ``spp``."""
    w = np.asarray(w, np.float64)
    if w.shape[0] % spp:
        raise ValueError(f"the sample count {w.shape[0]} is not a multiple of spp={spp}")
    e_s = w * (np.asarray(l_est, np.float64) - np.asarray(l_ref, np.float64)) / spp
    return e_s, e_s.reshape(w.shape[0] // spp, spp, -1).sum(axis=1)


def converged_sq_error(e_s: np.ndarray, e_px: np.ndarray) -> np.ndarray:
    """Per pixel (mean over RGB), the unbiased estimate of the squared error it would have with
    infinitely many samples: S/(S − 1)·(e_px² − Σ_s e_s²) from :func:`sample_errors`' ``e_s`` (n, 3) and
    ``e_px`` (n / S, 3) (module docstring, "Converged MSE"). Raises ValueError below 2 samples a pixel."""
    n_px = e_px.shape[0]
    spp = e_s.shape[0] // n_px
    if spp < 2:
        raise ValueError(f"the converged MSE needs at least 2 samples a pixel, got {spp}")
    sum_sq = (e_s.reshape(n_px, spp, -1) ** 2).sum(axis=1)
    return np.mean(spp / (spp - 1) * (e_px**2 - sum_sq), axis=1)


def sample_charges(e_part: np.ndarray, e_px: np.ndarray) -> np.ndarray:
    """Each sample's charge in the MSE (module docstring, "Additive split"): its error ``e_part`` (n, 3;
    a sample's whole error e_s or any additive part of it) times its pixel's total error ``e_px``
    (n / S, 3), / (pixels × channels). Over any parts that add up to e_s, the charges of all samples add
    up to the MSE mean(e_px²); over the samples of some pixels, to those pixels' share of it."""
    spp = e_part.shape[0] // e_px.shape[0]
    return np.sum(np.repeat(e_px, spp, axis=0) * e_part, axis=1) / e_px.size


def glossy_terms(
    w: np.ndarray,
    l_probe: np.ndarray,
    l_ref: np.ndarray,
    l_perfect: np.ndarray,
    status: np.ndarray,
    spp: int,
) -> dict:
    """The glossy MSE and its parts from per-sample arrays (module docstring).

    Args:
        w: (n, 3) estimator weights w = f_s cos θ / pdf (0 where a sample has no glossy ray).
        l_probe, l_ref, l_perfect: (n, 3) radiance from the probes, the CRN reference and the perfect trace.
        status: (n,) tracer status (``probes.TraceStatus``; other values: no ray, weight 0).
        spp: samples per pixel S (n = pixels × S, pixel-major).

    Returns:
        ``mse``, ``mse_perfect_trace``, ``trace_share``, ``trace_excess`` (None when the floor is 0),
        ``by_status`` {miss, hit, unresolved} (adds up to ``mse``), ``resolved_only``, ``converged`` (the
        converged image's MSE, module docstring; None at one sample a pixel), and the per-pixel squared
        errors ``sq_px`` / ``sq_px_perfect`` / ``sq_px_converged`` ((n_pixels,), mean over RGB; the last
        None at one sample a pixel) for confidence intervals.
    """
    status = np.asarray(status)
    e_s, e_px = sample_errors(w, l_probe, l_ref, spp)
    n_px = e_px.shape[0]
    e_perf = sample_errors(w, l_perfect, l_ref, spp)[1]
    mse = float(np.mean(e_px**2))
    mse_p = float(np.mean(e_perf**2))
    charge = sample_charges(e_s, e_px)
    by_status = {name: float(np.sum(charge[status == k])) for k, name in STATUS_NAMES.items()}
    e_res = (e_s * (status != TraceStatus.UNRESOLVED)[:, None]).reshape(n_px, spp, -1).sum(axis=1)
    sq_conv = converged_sq_error(e_s, e_px) if spp > 1 else None
    return {
        "mse": mse,
        "mse_perfect_trace": mse_p,
        "trace_share": mse - mse_p,
        "trace_excess": mse / mse_p - 1.0 if mse_p > 0 else None,
        "by_status": by_status,
        "resolved_only": float(np.mean(e_res**2)),
        "converged": None if sq_conv is None else float(np.mean(sq_conv)),
        "sq_px": np.mean(e_px**2, axis=1),
        "sq_px_converged": sq_conv,
        "sq_px_perfect": np.mean(e_perf**2, axis=1),
    }


def bootstrap_ci(
    per_pixel: np.ndarray, *, n_resamples: int = 1000, level: float = 0.95, seed: int = 0
) -> list[float]:
    """[lo, hi] percentile-bootstrap interval of mean(per_pixel) (module docstring); deterministic."""
    v = np.asarray(per_pixel, np.float64).reshape(-1)
    if v.size == 0:
        return [float("nan"), float("nan")]
    rng = np.random.default_rng(seed)
    means = np.empty(n_resamples)
    batch = max(1, (1 << 22) // v.size)  # bound the (batch, pixels) index array to ~32 MB
    for s in range(0, n_resamples, batch):
        b = min(batch, n_resamples - s)
        means[s : s + b] = v[rng.integers(0, v.size, (b, v.size))].mean(axis=1)
    a = (1.0 - level) / 2.0
    lo, hi = np.quantile(means, [a, 1.0 - a])
    return [float(lo), float(hi)]


def relative_mse(probe: np.ndarray, ref: np.ndarray, *, eps: float = 0.01) -> float | None:
    """mean over pixels of (p − r)² / (r² + ε) on luminance, ε = eps × mean(r)² (module docstring);
    None when the reference is black."""
    p = np.asarray(probe, np.float64) @ _LUMA
    r = np.asarray(ref, np.float64) @ _LUMA
    scale = float(np.mean(r)) ** 2
    if not scale > 0:
        return None
    return float(np.mean((p - r) ** 2 / (r * r + eps * scale)))


def agreeing_hits(
    t_lf: np.ndarray, t_exact: np.ndarray, status: np.ndarray, *, rtol: float = 0.02, atol: float = 0.0
) -> np.ndarray:
    """Per ray: a TraceStatus.HIT whose exact hit is finite and within |t_lf − t_exact| ≤ rtol·t_exact + atol
    (an exact miss disagrees)."""
    te = np.asarray(t_exact, np.float64)
    finite = np.isfinite(te)
    close = (
        np.abs(np.asarray(t_lf, np.float64) - np.where(finite, te, 0.0))
        <= rtol * np.where(finite, te, 0.0) + atol
    )
    return (np.asarray(status) == TraceStatus.HIT) & finite & close


def hit_agreement(
    t_lf: np.ndarray, t_exact: np.ndarray, status: np.ndarray, *, rtol: float = 0.02, atol: float = 0.0
) -> tuple[float | None, int]:
    """(share of TraceStatus.HIT rays that are :func:`agreeing_hits`, number of TraceStatus.HIT rays); the
    share is None when there is none."""
    n = int(np.sum(np.asarray(status) == TraceStatus.HIT))
    if n == 0:
        return None, 0
    return float(np.sum(agreeing_hits(t_lf, t_exact, status, rtol=rtol, atol=atol)) / n), n


def light_leak(
    ref: np.ndarray, ref_var: np.ndarray, probe: np.ndarray, judge: np.ndarray, *, sigmas: float = LEAK_SIGMAS
) -> dict:
    """Pixels where the probe image exceeds the reference by more than ``sigmas`` of the reference's own
    standard error (module docstring, "Light leak").

    Args:
        ref: (h, w, 3) reference pixel means.
        ref_var: (h, w, 3) variance of those means (sample variance / spp).
        probe: (h, w, 3) probe image.
        judge: (h, w) bool, the pixels that may be judged (primary hits).
        sigmas: k, the excess in standard errors that counts as a leak.

    Returns:
        ``flagged`` and ``judged`` (h, w) bool masks (judged: ``judge`` and a positive, finite standard
        error), and ``energy``: Σ over flagged pixels of the excess luminance p − r, / number of pixels.
    """
    r = np.asarray(ref, np.float64) @ _LUMA
    p = np.asarray(probe, np.float64) @ _LUMA
    se = np.sqrt(np.maximum(np.asarray(ref_var, np.float64), 0.0)) @ _LUMA
    judged = np.asarray(judge, bool) & np.isfinite(se) & (se > 0) & np.isfinite(r) & np.isfinite(p)
    flagged = judged & (p - r > sigmas * np.where(judged, se, 0.0))
    energy = float(np.sum(np.where(flagged, p - r, 0.0)) / max(flagged.size, 1))
    return {"flagged": flagged, "judged": judged, "energy": energy}
