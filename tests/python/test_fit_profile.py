"""The profile-likelihood intervals (stickslip.fit.profile) on least-squares problems whose
profile is known in closed form, and the side-by-side walk against each walk alone.

The problems here are residual functions of θ written out in numpy, standing in for the FMU's
runs: the profile's arithmetic (the path, the others' Gauss-Newton step, the doubling walk and
its regula falsi) is what is tested, and it sees nothing of the FMU but (cost, residual) per point.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.stats import chi2

from stickslip.fit.problem import Transform
from stickslip.fit.profile import REFINEMENTS, Lowest, _crossing, _drive, _profile_side, profile_intervals, profiles
from stickslip.fit.spec import Estimate


class ClosedForm:
    """A least-squares problem r(θ) with the surface of stickslip.fit.problem.Problem that the
    profiles use; ``asked`` records every batch of points, in order."""

    def __init__(self, residual, estimates):
        self.residual_of = residual
        self.spec = SimpleNamespace(estimates=estimates)
        self.transform = Transform(estimates)
        self.asked = []

    def runs(self, zs):
        self.asked.append([np.array(z) for z in zs])
        return [[SimpleNamespace(status="ok", theta=self.transform.theta(z))] for z in zs]

    def residual(self, runs):
        return np.asarray(self.residual_of(runs[0].theta), dtype=np.float64)


def _linear(A, b, bounds):
    estimates = [Estimate(f"p[{j}]", 0.0, lo, hi) for j, (lo, hi) in enumerate(bounds)]
    return ClosedForm(lambda theta: A @ theta - b, estimates)


def test_a_linear_models_profile_interval_is_the_standard_errors_1_96_times():
    """For r = Aθ − b the profile cost is cost0 + ½δ²/C_jj exactly (C = (AᵀA)⁻¹) and the one
    Gauss-Newton step of the others is exact, so the interval's ends are θ̂_j ± 1.96 SE_j: the
    walk's first point, at 2 SE, lies outside, and regula falsi in δ² from the optimum meets
    the crossing with its first point, to rounding."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(40, 3)) @ np.diag([1.0, 30.0, 0.2])
    b = rng.normal(size=40)
    problem = _linear(A, b, [(-100.0, 100.0)] * 3)
    theta = np.linalg.lstsq(A, b, rcond=None)[0]
    r0 = A @ theta - b
    cost0 = 0.5 * float(r0 @ r0)
    C = np.linalg.inv(A.T @ A)
    se = np.sqrt(np.diag(C))  # σ̂² = 1: the threshold is ½ χ²₁(0.95)
    threshold = 0.5 * float(chi2.ppf(0.95, 1))
    got = profile_intervals(problem, theta, cost0, A, C, {j: (se[j], threshold) for j in range(3)})
    for j in range(3):
        low, high = got[j]["interval_95"]
        exact = math.sqrt(2.0 * threshold * C[j, j])  # = 1.96 SE_j
        assert abs(exact / se[j] - 1.959964) < 1e-5
        resolution = 1e-9 * se[j]
        assert abs((theta[j] - low) - exact) <= resolution, (j, theta[j] - low, exact)
        assert abs((high - theta[j]) - exact) <= resolution, (j, high - theta[j], exact)
        assert got[j]["open"] == [False, False]
        assert abs(got[j]["std_error_profile"] * 1.96 - exact) <= resolution
        # 2 SE (outside), then the refinements: two runs each, a side; the second refinement is
        # skipped where the first lands on the crossing to the last bit
        assert 2 * 2 * (1 + 1) <= got[j]["runs"] <= 2 * 2 * (1 + REFINEMENTS)


def test_a_bound_inside_the_interval_leaves_that_side_open_at_the_bound():
    A = np.eye(2)
    b = np.array([0.5, 0.0])
    problem = _linear(A, b, [(0.0, 10.0), (-10.0, 10.0)])
    theta = np.array([0.5, 0.0])
    C = np.eye(2)
    got = profile_intervals(problem, theta, 0.0, A, C, {0: (1.0, 1.92)})[0]
    assert got["interval_95"][0] == pytest.approx(0.0, abs=1e-12)  # the bound, before the cost reached 1.92
    assert got["open"] == [False, False]  # the bound stopped it: not open, the data cannot go there
    assert got["interval_95"][1] == pytest.approx(0.5 + math.sqrt(2 * 1.92), abs=1e-9)


def _one_sided():
    """A cost that rises steeply on one side of θ̂_0 and slowly on the other, coupled to θ_1,
    like a μ_s whose too-early breakaways cost much and too-late ones little."""

    def residual(theta):
        d = theta[0] - 0.3
        return np.array([8.0 * d if d > 0 else 0.4 * d, theta[1] - 0.5 * theta[0], 0.3 * (theta[1] - 0.2) + d**2])

    estimates = [Estimate("mu_s[1]", 0.3, 0.0, 1.0), Estimate("mu_k[1]", 0.2, -1.0, 1.0)]
    return ClosedForm(residual, estimates)


def test_walks_side_by_side_see_what_each_sees_alone():
    """The batched walk evaluates the same points and ends at the same ends as each walk run by
    itself, and asks for the points of all walks in rounds, not one after the other."""
    theta = np.array([0.3, 0.15])
    J = np.array([[8.0, 0.0], [-0.5, 1.0], [0.0, 0.3]])
    C = np.linalg.inv(J.T @ J)
    problem = _one_sided()
    r0 = problem.residual([SimpleNamespace(theta=theta)])
    cost0 = 0.5 * float(r0 @ r0)
    keys = [(j, side) for j in (0, 1) for side in (-1.0, 1.0)]
    alone = []
    for j, side in keys:
        solo = _one_sided()
        alone.append((_drive(solo, [_profile_side(solo, theta, cost0, J, C, j, 0.05, 0.5, side)]), solo.asked))
    together = _drive(problem, [_profile_side(problem, theta, cost0, J, C, j, 0.05, 0.5, side) for j, side in keys])
    for k, ((result, _), joint) in enumerate(zip(alone, together, strict=True)):
        assert result[0] == joint, keys[k]
    points = sorted(tuple(z) for batch in problem.asked for z in batch)
    assert points == sorted(tuple(batch[0]) for _, asked in alone for batch in asked)
    assert len(problem.asked) == max(len(a) for _, a in alone)  # rounds: the longest walk's points
    # the slow side reaches the bound 0 below a cost of 0.5 (½(0.4δ)² < 0.5 up to δ = 2.5); the
    # steep side passes it near δ = 1/8 (½(8δ)² = 0.5; the coupling to θ_1 moves it by a few %)
    (low, low_open), _ = together[0]
    (high, high_open), _ = together[1]
    assert low == 0.0 and not low_open and not high_open
    assert abs(high - theta[0] - 0.125) < 0.005


def test_the_crossing_is_exact_for_a_parabola_and_stays_in_its_bracket():
    """_crossing: for g = a·δ² − T the line through two points in δ² meets g = 0 exactly;
    it never leaves the bracket; a failed run's infinite cost gives the bracket's middle."""
    a, T = 3.0, 1.92
    g = lambda d: a * d * d - T  # noqa: E731
    for d_in, d_out in ((0.0, 1.0), (0.5, 0.9), (0.79, 0.81)):
        assert _crossing((d_in, g(d_in)), (d_out, g(d_out))) == pytest.approx(math.sqrt(T / a), rel=1e-14)
    # a cost far from a parabola: the answer stays inside
    assert 0.2 <= _crossing((0.2, -1.0), (0.3, 1e9)) <= 0.3
    assert _crossing((0.2, -1.0), (0.4, math.inf)) == pytest.approx(0.3)


def test_a_lower_point_on_a_profile_is_seen():
    """An answer that is not the minimum: the profile's points find the lower cost, and where."""
    A = np.eye(2)
    b = np.array([0.3, 0.0])
    problem = _linear(A, b, [(-10.0, 10.0)] * 2)
    theta = np.array([0.0, 0.0])  # the minimum is at (0.3, 0)
    lowest = Lowest(0.045)
    profile_intervals(problem, theta, 0.045, A, np.eye(2), {0: (0.25, 1.92)}, lowest)
    assert lowest.cost < 0.045 and lowest.theta is not None
    assert abs(lowest.theta[0] - 0.5) < 1e-12  # the first point of the upper walk, two SE along


def test_the_walks_begin_at_the_quadratic_checks_points():
    """profiles(): the first point of each μ_s walk is the quadratic check's point at 2
    classical SE, bit for bit, so the problem's memory of recent runs serves it; with the
    sandwich SE larger, the interval is wider than the classical one by its inflation."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(30, 2))
    b = rng.normal(size=30)
    estimates = [Estimate("mu_s[1]", 0.0, -100.0, 100.0), Estimate("k[1]", 0.0, -100.0, 100.0)]
    problem = ClosedForm(lambda theta: A @ theta - b, estimates)
    theta = np.linalg.lstsq(A, b, rcond=None)[0]
    r0 = A @ theta - b
    cost0 = 0.5 * float(r0 @ r0)
    classical = np.sqrt(np.diag(np.linalg.inv(A.T @ A)))
    unc = SimpleNamespace(std_error_classical=classical, std_error_sandwich=1.5 * classical, std_error=1.5 * classical)
    got = profiles(problem, theta, cost0, A, unc, 1.0)
    check, first = problem.asked[0], problem.asked[1]
    assert len(check) == 4 and len(first) == 2  # ±2 SE of both; the μ_s walk's two sides
    assert np.array_equal(first[0], check[0]) and np.array_equal(first[1], check[1])
    low, high = got["mu_s[1]"]["interval_95"]
    exact = 1.959964 * 1.5 * classical[0]  # the threshold inflated by (sandwich/classical)²
    assert abs((theta[0] - low) - exact) < 1e-5 * exact and abs((high - theta[0]) - exact) < 1e-5 * exact
    assert "k[1]" not in got  # quadratic: not profiled
