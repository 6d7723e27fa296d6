"""The fit's statistics against closed forms and Monte Carlo (stickslip.fit.uncertainty and the
SPEC's encoder resolution), no FMU involved:

* the classical covariance is the ordinary least squares formula σ̂²(XᵀX)⁻¹;
* the sandwich's standard error of a mean under AR(1) noise matches the spread of the mean
  over 400 draws (the classical one is too small by sqrt((1 + ρ)/(1 − ρ)));
* under an error that is one constant per block (an encoder's count held through a stiction
  phase), the sandwich's standard error holds across draws where the classical one fails;
* the goodness-of-fit split flags a slow structure as a misfit, white noise above the stated
  sigma as a wrong sigma, and neither for white noise at the stated level, nor for a rounding
  error held constant within the allowance q²/12;
* the encoder's quantum is detected from samples on a grid, and nothing from samples off it.
"""

import math

import numpy as np
import pytest

from helpers import allowed_misses
from stickslip.fit.spec import Channel, detect_resolution
from stickslip.fit.uncertainty import (
    bartlett_window,
    goodness_of_fit,
    lag1_autocorrelation,
    misfit_warnings,
    uncertainty,
)


def ar1(rng, n, rho, sigma=1.0):
    e = rng.standard_normal(n) * sigma * math.sqrt(1 - rho**2)
    x = np.empty(n)
    x[0] = rng.standard_normal() * sigma
    for t in range(1, n):
        x[t] = rho * x[t - 1] + e[t]
    return x


def ols(X, y):
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    return beta, X @ beta - y  # residual as the fit defines it: model − measured


def test_classical_covariance_is_the_least_squares_formula():
    rng = np.random.default_rng(1)
    n = 500
    X = np.column_stack([np.ones(n), np.linspace(0, 1, n)])
    y = X @ [2.0, -1.0] + 0.3 * rng.standard_normal(n)
    _, r = ols(X, y)
    u = uncertainty(X, r, [(0, n)], ["a", "b"], absolute_sigma=False)
    s2 = float(r @ r) / (n - 2)
    expected = np.sqrt(np.diag(s2 * np.linalg.inv(X.T @ X)))
    assert np.allclose(u.std_error_classical, expected, rtol=1e-10)
    assert u.scale == pytest.approx(s2, rel=1e-12)
    # White residuals: the sandwich agrees with the classical one within its sampling error.
    assert np.all(np.abs(u.std_error_sandwich / u.std_error_classical - 1) < 0.2)


def test_sandwich_holds_under_ar1_noise_where_the_classical_fails():
    rng = np.random.default_rng(2)
    n, rho, draws = 1000, 0.9, 400
    X = np.ones((n, 1))
    estimates, classical, sandwich = [], [], []
    for _ in range(draws):
        beta, r = ols(X, ar1(rng, n, rho))
        u = uncertainty(X, r, [(0, n)], ["mean"], absolute_sigma=False)
        estimates.append(beta[0])
        classical.append(u.std_error_classical[0])
        sandwich.append(u.std_error_sandwich[0])
    spread = np.std(estimates)
    # The long-run standard deviation of the mean: sqrt((1 + ρ)/(1 − ρ)/n).
    assert spread == pytest.approx(math.sqrt((1 + rho) / (1 - rho) / n), rel=0.1)
    assert np.median(classical) < 0.3 * spread
    assert np.median(sandwich) == pytest.approx(spread, rel=0.2)
    z = np.abs(np.array(estimates)) / np.array(sandwich)
    # sized (issue 41): a draw may miss with p = 0.01; allowed_misses(400, 0.01) = 11,
    # P(X >= 12 | 400, 0.01) < 1e-3; the classical errors (below 0.3 of the spread) fail it
    assert np.sum(z >= 3) <= allowed_misses(draws, 0.01)
    assert np.sum(np.abs(np.array(estimates)) / np.array(classical) >= 3) > allowed_misses(draws, 0.01)


def test_sandwich_holds_for_an_error_constant_through_each_phase():
    """A slope fitted to data whose error is white noise plus one constant per 50-sample
    phase (a quantized encoder's count held while the link sticks): the truth within 3
    sandwich standard errors in all but at most 10 of 300 draws (P(X >= 11 | 300, 0.01) =
    2.65e-4; measured 98.3 %), within 3 classical
    ones in 44 %. With 20 phases of 100 the sandwich's coverage is 94.7 %: with so few
    independent phases the long-run covariance is itself uncertain."""
    rng = np.random.default_rng(3)
    n, phase, draws = 2000, 50, 300
    t = np.linspace(-1, 1, n)
    X = np.column_stack([np.ones(n), t])
    hit_sandwich, hit_classical = 0, 0
    for _ in range(draws):
        held = np.repeat(rng.uniform(-0.5, 0.5, n // phase), phase)
        y = 0.2 * rng.standard_normal(n) + held
        beta, r = ols(X, y)
        u = uncertainty(X, r, [(0, n)], ["a", "b"], absolute_sigma=False)
        hit_sandwich += abs(beta[1]) < 3 * u.std_error[1]
        hit_classical += abs(beta[1]) < 3 * u.std_error_classical[1]
    # sized (issue 41): a draw may miss with p = 0.01; allowed_misses(300, 0.01) = 10,
    # P(X >= 11 | 300, 0.01) = 2.65e-4; the classical errors (44 % coverage) fail it
    assert draws - hit_sandwich <= allowed_misses(draws, 0.01)
    assert draws - hit_classical > allowed_misses(draws, 0.01)


def test_lag_window_grows_with_the_autocorrelation():
    rng = np.random.default_rng(4)
    assert bartlett_window(rng.standard_normal(2000)) <= 5
    slow = ar1(rng, 2000, 0.95)
    assert lag1_autocorrelation(slow) == pytest.approx(0.95, abs=0.03)
    assert 20 <= bartlett_window(slow) <= 400  # at most a fifth of the series


def gof(r, sigma=1.0, resolution=0.0):
    return goodness_of_fit(np.asarray(r), [(0, len(r))], [("q[3]", sigma, resolution)], 1)


def test_white_noise_at_the_stated_sigma_passes():
    rng = np.random.default_rng(5)
    g = gof(rng.standard_normal(3000))
    assert g["p_value"] > 1e-3
    assert misfit_warnings(g, absolute_sigma=False) == []


def test_slow_structure_is_a_misfit_named_by_channel():
    rng = np.random.default_rng(6)
    t = np.linspace(0, 3, 3000)
    warnings = misfit_warnings(gof(rng.standard_normal(3000) + 0.6 * np.sin(2 * np.pi * t)), absolute_sigma=False)
    assert len(warnings) == 1 and warnings[0].startswith("misfit in q[3]")
    assert "local minimum" in warnings[0] and "misses something" in warnings[0]


def test_white_noise_above_the_stated_sigma_is_a_wrong_sigma():
    rng = np.random.default_rng(7)
    warnings = misfit_warnings(gof(1.3 * rng.standard_normal(3000)), absolute_sigma=True)
    assert len(warnings) == 1 and "sigma in the SPEC is too small" in warnings[0], warnings
    assert "too small by that factor" in warnings[0]


def test_rounding_held_through_phases_within_its_allowance_is_no_misfit():
    """Samples with noise σ = 0.1 q (too small to dither the rounding): the rounding error is
    one constant per 150-sample phase, uniform over a count; normalized by
    sqrt(σ² + q²/12) that is the white noise plus a slow part within the allowance."""
    rng = np.random.default_rng(8)
    q, sigma, n = 1.0, 0.1, 3000
    held = np.repeat(rng.uniform(-q / 2, q / 2, n // 150), 150)
    r = (held + sigma * rng.standard_normal(n)) / math.sqrt(sigma**2 + q**2 / 12)
    g = gof(r, sigma, q)
    c = g["channels"][0]
    assert c.allowance == pytest.approx((1 - 2 * sigma / q) * (q**2 / 12) / (sigma**2 + q**2 / 12), rel=1e-12)
    assert misfit_warnings(g, absolute_sigma=False) == []


def test_resolution_is_detected_from_a_grid_and_only_from_one():
    rng = np.random.default_rng(9)
    q = 2 * math.pi / 2**20
    x = 0.3 + np.cumsum(rng.integers(-3, 4, 2000)) * q  # levels with gaps, an offset, repeats
    assert detect_resolution(x) == pytest.approx(q, rel=1e-6)
    assert detect_resolution(x + 1e-3 * q * rng.standard_normal(2000)) == 0.0
    assert detect_resolution(rng.standard_normal(2000)) == 0.0
    assert detect_resolution(np.full(10, 0.5)) == 0.0


def test_channel_std_adds_the_rounding_of_one_count():
    c = Channel("q[1]", "link1", 2e-6, resolution=3e-6)
    assert c.std == pytest.approx(math.sqrt(4e-12 + 9e-12 / 12), rel=1e-14)
    assert Channel("q[1]", "link1", 2e-6).std == 2e-6
