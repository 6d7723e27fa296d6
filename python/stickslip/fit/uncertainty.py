"""The uncertainty of a fit at its optimum, and whether the residuals are what the noise
model says they are.

**Covariance.** With J = ∂r/∂θ (normalized residuals r = (model − measured)/s, s the
channel's standard deviation: noise and encoder rounding, ``Channel.std``):

* the classical σ̂² (JᵀJ)⁻¹, right when the residuals are independent with a common scale;
* the sandwich (JᵀJ)⁻¹ S (JᵀJ)⁻¹ (Newey and West, 1987), S the long-run covariance of the
  scores g_t = J_tᵀ r_t, summed over lags within each channel's time series with Bartlett
  weights 1 − l/(L+1). It holds when the residuals are correlated in time: a quantized
  encoder reads the same count through a stiction phase, so its error is one constant per
  phase, and the FMU's error control adds a smooth model error of its own. The lag window L
  of each series is twice the lag at which its residuals' autocorrelation falls to the
  noise level (:func:`bartlett_window`), at most a fifth of the series (at an optimum
  Σ g_t = 0, so a window as long as the series would cancel the very covariance it measures).

Why the sandwich and not a bootstrap: it costs no FMU run (J is there already), and a
moving-block bootstrap that refits each resample would cost hundreds of fits; one that does
not refit is the same long-run covariance estimated more noisily. The standard error
reported is the larger of the two (the sandwich can come out below the classical one by
chance where the residuals are white).

**Goodness of fit** (:func:`goodness_of_fit`), per channel of each experiment and in total:
the χ² test of Σr² against m − p degrees of freedom, and a split of the residual variance
into a white part, from the differences of successive residuals (mean(Δr²)/2, which a slow
error does not reach), and a slow part (the rest): a slow part beyond what the encoder's
rounding can explain is structure the model does not follow (a local minimum, or a model
that misses something); a white part above 1 means the stated sigma is too small.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

LEVEL = 1e-3  # the χ² test's level: a misfit is reported below this p-value
STRUCTURE_Z = 4.0  # a slow residual variance this many standard deviations above its allowance is structure


@dataclass
class Uncertainty:
    std_error: np.ndarray  # reported: the larger of the classical and the sandwich standard errors
    std_error_classical: np.ndarray
    std_error_sandwich: np.ndarray
    covariance: np.ndarray  # of the reported standard errors (the sandwich's correlations)
    correlation: np.ndarray
    scale: float  # σ̂² (1 with absolute sigmas)
    singular: list  # (relative singular value, {name: component}) of near-singular directions
    condition: float
    lags: list = field(default_factory=list)  # the sandwich's lag window per series


def uncertainty(J, r, blocks: list, names: list, absolute_sigma: bool, weights=None, clusters=None) -> Uncertainty:
    """The covariance of θ from J (m × p, ∂r/∂θ in θ's units) and r at the optimum; ``blocks``:
    the (start, stop) rows of each channel's time series; ``weights``: √ρ′ of a robust loss;
    ``clusters``: row indices of residuals that share an error (the samples of one
    multiple-shooting segment, all channels: its start state comes from filtered
    measurements), for a cluster-robust sandwich Σ_c (Jᵀr)_c (Jᵀr)_cᵀ · C/(C−1) (Liang and
    Zeger 1986), whose standard error joins the others' maximum."""
    m, p = J.shape
    w = np.ones(m) if weights is None else np.asarray(weights)
    Jw, rw = J * w[:, None], r * w
    scale = 1.0 if absolute_sigma else float(rw @ rw) / max(m - p, 1)
    norms = np.linalg.norm(Jw, axis=0)
    norms[norms == 0] = 1.0
    _, S, Vt = np.linalg.svd(Jw / norms, full_matrices=False)
    condition = float(S[0] / S[-1]) if S[-1] > 0 else math.inf
    determined = np.all(S > S[0] * 1e-12) and S[0] > 0
    singular = []
    for k in range(len(S)):
        rel = S[k] / S[0] if S[0] > 0 else 0.0
        if rel < 1e-6:
            v = Vt[k]
            singular.append((float(rel), {names[j]: float(v[j]) for j in np.argsort(-np.abs(v)) if abs(v[j]) > 0.1}))
    if not determined:
        inf = np.full((p, p), math.inf)
        se = np.full(p, math.inf)
        return Uncertainty(se, se, se, inf, np.full((p, p), math.nan), scale, singular, condition)
    # (JᵀJ)⁻¹ through the SVD of the column-scaled J.
    inverse = (Vt.T / S**2) @ Vt / np.outer(norms, norms)
    classical = scale * inverse
    long_run, lags = long_run_covariance(Jw, rw, blocks)
    sandwich = inverse @ long_run @ inverse
    se_classical = np.sqrt(np.abs(np.diag(classical)))
    se_sandwich = np.sqrt(np.abs(np.diag(sandwich)))
    if clusters is not None and len(clusters) > 1:
        scores = np.array([Jw[rows].T @ rw[rows] for rows in clusters])
        grouped = inverse @ (scores.T @ scores * len(clusters) / (len(clusters) - 1)) @ inverse
        se_grouped = np.sqrt(np.abs(np.diag(grouped)))
        if np.sum(se_grouped / np.maximum(se_sandwich, 1e-300)) > len(se_sandwich):
            sandwich = grouped  # its correlations, where the segments' shared errors dominate
        se_sandwich = np.maximum(se_sandwich, se_grouped)
    se = np.maximum(se_classical, se_sandwich)
    # The reported covariance: the sandwich's correlations at the reported standard errors.
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = sandwich / np.outer(se_sandwich, se_sandwich)
    corr = np.where(np.isfinite(corr), corr, classical / np.outer(se_classical, se_classical))
    cov = corr * np.outer(se, se)
    return Uncertainty(se, se_classical, se_sandwich, cov, corr, scale, singular, condition, lags)


def bartlett_window(r) -> int:
    """The lag window for Bartlett weights: twice the first lag at which the sample
    autocorrelation of the series falls to its noise level (max(2/sqrt(n), 0.05)), at most
    n/5. An error held constant through phases of B samples (a quantized encoder while the
    link sticks) has an autocorrelation falling linearly to 0 at B, and the window must reach
    past B for the weights to count most of it; an AR(1) plug-in (Andrews, 1991) sees only
    its first lag and stops far short of B."""
    r = np.asarray(r, dtype=np.float64)
    n = len(r)
    if n < 3:
        return 0
    d = r - r.mean()
    variance = float(d @ d)
    if variance <= 0:
        return 0
    floor = max(2.0 / math.sqrt(n), 0.05)
    cap = n // 5
    spectrum = np.fft.rfft(d, 2 * n)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[: cap + 1] / variance
    below = np.flatnonzero(acf[1:] < floor)
    first = int(below[0]) + 1 if len(below) else cap
    return int(min(2 * (first - 1), cap))


def long_run_covariance(J, r, blocks: list) -> tuple:
    """(S, lag windows): Σ over the series of Σ_l k(l) Σ_t g_t g_{t+l}ᵀ with g_t = J_t r_t and
    Bartlett weights k(l) = 1 − |l|/(L+1), L per series (:func:`bartlett_window`).

    The Bartlett kernel is a box of L+1 samples correlated with itself, so the sum is that of
    the moving sums h_s = Σ_{t=s}^{s+L} g_t (g = 0 outside the series): Σ_s h_s h_sᵀ/(L+1)
    weighs g_t g_uᵀ by the windows holding both, L+1−|t−u|. One pass of cumulative sums, p²
    per sample, where the lag-by-lag sum cost p² per sample and lag (a 5000-sample series with
    a window of 1000 lags: 1000 times as much)."""
    p = J.shape[1]
    S = np.zeros((p, p))
    lags = []
    for start, stop in blocks:
        g = J[start:stop] * r[start:stop, None]
        L = bartlett_window(r[start:stop])
        lags.append(L)
        c = np.vstack([np.zeros((1, p)), np.cumsum(g, axis=0)])
        n = len(g)
        s = np.arange(-L, n)  # window s covers rows s..s+L, clipped to the series
        h = c[np.minimum(s + L + 1, n)] - c[np.maximum(s, 0)]
        S += h.T @ h / (L + 1.0)
    return S, lags


def lag1_autocorrelation(r) -> float:
    r = np.asarray(r, dtype=np.float64)
    if len(r) < 3:
        return 0.0
    d = r - r.mean()
    denominator = float(d @ d)
    return float(d[1:] @ d[:-1]) / denominator if denominator > 0 else 0.0


@dataclass
class ChannelFit:
    """The residuals of one channel of one experiment, in units of its standard deviation."""

    name: str  # "q[3]" or "experiment:q[3]"
    n: int
    variance: float  # mean r²: 1 when the residuals are the stated noise
    white: float  # mean(Δr²)/2: the part of it that changes from sample to sample
    slow: float  # variance − white
    allowance: float  # the slow part the encoder's rounding can explain
    rho: float  # lag-1 autocorrelation
    p_value: float  # of Σr² under χ²(n)
    structure_z: float  # (slow − allowance) in standard deviations of the slow part
    white_z: float  # (white − 1) in standard deviations


def channel_fit(name: str, r, sigma: float, resolution: float) -> ChannelFit:
    """The residual statistics of one channel (r normalized by sqrt(sigma² + resolution²/12))."""
    from scipy.stats import chi2

    r = np.asarray(r, dtype=np.float64)
    n = len(r)
    variance = float(np.mean(r**2))
    white = float(np.mean(np.diff(r) ** 2) / 2.0) if n > 1 else variance
    std2 = sigma**2 + resolution**2 / 12.0
    # A quantized encoder's rounding error is one constant per stiction phase where the
    # noise is too small to dither it (σ well below q/2): up to q²/12 of slow variance.
    undithered = min(1.0, max(0.0, 1.0 - 2.0 * sigma / resolution)) if resolution > 0 else 0.0
    allowance = undithered * resolution**2 / 12.0 / std2
    slow = variance - white
    # For white Gaussian residuals, variance − white has a standard deviation of 1/sqrt(n);
    # white − 1 has sqrt(3/(2n)) (the differences are correlated at lag 1).
    structure_z = (slow - allowance) * math.sqrt(n)
    white_z = (white - 1.0) / math.sqrt(1.5 / n) if n else 0.0
    p_value = float(chi2.sf(variance * n, n))
    return ChannelFit(name, n, variance, white, slow, allowance, lag1_autocorrelation(r), p_value, structure_z, white_z)


def goodness_of_fit(r, blocks: list, channels: list, p: int) -> dict:
    """The χ² test of all residuals against m − p degrees of freedom and per channel
    (:func:`channel_fit`); ``channels``: (name, sigma, resolution) of each block."""
    from scipy.stats import chi2

    m = len(r)
    chi_square = float(r @ r)
    dof = max(m - p, 1)
    per_channel = [
        channel_fit(name, r[a:b], sigma, resolution)
        for (a, b), (name, sigma, resolution) in zip(blocks, channels, strict=True)
    ]
    return {
        "chi_square": chi_square,
        "degrees_of_freedom": dof,
        "reduced_chi_square": chi_square / dof,
        "p_value": float(chi2.sf(chi_square, dof)),
        "channels": per_channel,
    }


def misfit_warnings(gof: dict, absolute_sigma: bool) -> list:
    """One warning per channel whose residuals the noise model does not explain, saying what
    it means: structure (a local minimum or a model that misses something) or a sigma that
    is too small; with absolute sigmas also a sigma that is too large."""
    out = []
    for c in gof["channels"]:
        rejected = c.p_value < LEVEL
        if rejected and c.structure_z > STRUCTURE_Z:
            out.append(
                f"misfit in {c.name}: residual variance {c.variance:.3g}× the stated noise (χ² p = {c.p_value:.1e}), "
                f"of which {c.slow:.3g} varies slowly (lag-1 autocorrelation {c.rho:.2f}; the encoder's rounding "
                f"explains {c.allowance:.2g}): the model does not follow this channel. Either the fit ended in a "
                "local minimum (more starts, another motion) or the model misses something (a parameter held at a "
                "wrong value, an unmodelled effect); the estimates and standard errors cannot be trusted"
            )
        elif rejected and c.white_z > STRUCTURE_Z:
            out.append(
                f"noise in {c.name} is {math.sqrt(c.white):.3g}× the stated sigma (χ² p = {c.p_value:.1e}, the "
                f"residuals white: lag-1 autocorrelation {c.rho:.2f}): the sigma in the SPEC is too small"
                + (
                    "; with absolute_sigma = true the standard errors are too small by that factor"
                    if absolute_sigma
                    else " (the standard errors are scaled by the residuals, absolute_sigma = false)"
                )
            )
        elif absolute_sigma and c.n > 10 and c.white_z < -STRUCTURE_Z:
            out.append(
                f"noise in {c.name} is {math.sqrt(max(c.white, 0.0)):.3g}× the stated sigma: the sigma in the SPEC is "
                "too large, and with absolute_sigma = true the standard errors are too large by that factor"
            )
    return out


def robust_cost(r, loss: str, f_scale: float) -> float:
    """The cost least_squares minimizes with this loss: ½·f_scale²·Σρ((r/f_scale)²)."""
    z = (np.asarray(r, dtype=np.float64) / f_scale) ** 2
    if loss == "soft_l1":
        rho = 2.0 * (np.sqrt(1.0 + z) - 1.0)
    elif loss == "huber":
        rho = np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0)
    elif loss == "cauchy":
        rho = np.log1p(z)
    elif loss == "arctan":
        rho = np.arctan(z)
    else:
        rho = z
    return 0.5 * f_scale**2 * float(rho.sum())


def rho_prime(r, loss: str, f_scale: float):
    """ρ′(r²) of scipy's robust losses, the weights of iteratively reweighted least squares."""
    z = (r / f_scale) ** 2
    if loss == "soft_l1":
        return 1.0 / np.sqrt(1.0 + z)
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1e-300)))
    if loss == "cauchy":
        return 1.0 / (1.0 + z)
    if loss == "arctan":
        return 1.0 / (1.0 + z**2)
    return np.ones_like(r)
