"""Profile-likelihood intervals for the parameters whose cost is not quadratic.

A standard error describes a cost that is a parabola in the parameter. Stick-slip's is
often not: μ_s decides only when a stuck joint breaks away, so the cost rises steeply on one
side (breakaways that come too early) and barely on the other. For such a parameter θ_j the
95 % interval is where the profile cost — the cost with θ_j held and every other parameter
re-optimized — stays within Δ* = ½ χ²₁(0.95) σ̂² c of the minimum, c = (SE_sandwich/SE)²
(≥ 1) the inflation that correlated residuals give the likelihood ratio (the adjusted
profile likelihood of composite-likelihood inference).

The profile is followed from the optimum along the profile path of the quadratic model,
θ(δ) = θ̂ + δ · C[:, j] / C[j, j] (C = (JᵀJ)⁻¹: the conditional optimum of the others for
θ_j = θ̂_j + δ), and at every point the others get one Gauss-Newton step on the point's own
residuals with the optimum's J, so the FMU runs two experiments' worth per point, never a
fit. A parameter is profiled when it is a static friction coefficient μ_s, or when the cost
at ±2 standard errors along the path departs from the parabola's 2σ̂² by more than a factor
of two. The interval's half-width, divided by 1.96, stands as the parameter's standard
error where it is the larger (fit.json keeps both).

Each side of each profiled parameter is a walk of points that depend on the costs before them;
the walks go side by side (:func:`_drive`), one batch of runs per round, so the cluster's
workers are all busy and the profiles take the wall time of the longest walk, with the same
points and answers as walks taken one after another.
"""

from __future__ import annotations

import math

import numpy as np

from .problem import Problem

QUADRATIC = (0.5, 2.0)  # a cost ratio (actual / parabola) at ±2 SE outside this is not quadratic
# Points that refine a side's bracket (regula falsi in δ², :func:`_crossing`): a cost that is a
# parabola in δ is met exactly by the first. Measured on the calibration example's μ_s[1] and
# μ_s[3]: the second point moved the ends by at most 5e-5 of a standard error; it stays for
# costs with a kink (a breakaway that comes or goes), where the Illinois halving shrinks the
# bracket. The four bisections before left an end up to 1/32 of a standard error off (the
# ends moved by up to 0.018 standard errors), in 4 points a side against these 2.
REFINEMENTS = 2
MAX_DOUBLINGS = 5


class Lowest:
    """The lowest cost met among the points a profile evaluates, and where: a point below the
    optimum's cost means the optimum is not a minimum along that profile."""

    def __init__(self, cost: float):
        self.cost, self.theta = cost, None

    def see(self, cost: float, theta) -> None:
        if cost < self.cost:
            self.cost, self.theta = cost, np.array(theta, dtype=np.float64)


def _evaluate(problem: Problem, points: list, lowest: Lowest | None = None) -> list:
    """(cost, residual) of single shooting at each θ (inf where a run failed)."""
    zs = [problem.transform.z(theta) for theta in points]
    out = []
    for theta, runs in zip(points, problem.runs(zs), strict=True):
        if Problem.failed(runs):
            out.append((math.inf, None))
        else:
            r = problem.residual(runs)
            out.append((0.5 * float(r @ r), r))
            if lowest is not None:
                lowest.see(out[-1][0], theta)
    return out


def _project(problem: Problem, theta) -> np.ndarray:
    """θ clipped into its bounds as the transform sees it."""
    return problem.transform.theta(problem.transform.z(theta))


def quadratic_check(problem: Problem, theta, cost0: float, C, se, scale: float, lowest: Lowest | None = None) -> dict:
    """{j: actual/parabola cost ratio at θ̂ ± 2 SE along the profile path (the smaller of the two)}."""
    p = len(theta)
    points, index = [], []
    for j in range(p):
        if not (math.isfinite(se[j]) and se[j] > 0 and C[j, j] > 0):
            continue
        if problem.spec.estimates[j].start_of is not None:  # a start unknown is not profiled
            continue
        path = C[:, j] / C[j, j]
        for side in (-1.0, 1.0):
            points.append(_project(problem, theta + side * 2.0 * se[j] * path))
            index.append(j)
    ratios = {}
    for j, (cost, _) in zip(index, _evaluate(problem, points, lowest), strict=True):
        ratio = (cost - cost0) / (2.0 * scale)  # the parabola: ½ (2 SE)²/SE² σ̂²
        ratios[j] = min(ratios.get(j, math.inf), ratio)
    return ratios


def _profile_cost(problem: Problem, theta, path, j: int, others: list, lstsq, delta: float):
    """A generator of the profile cost at θ_j = θ̂_j + δ: it yields the two points it needs in
    turn (the point on the profile path, then the others' Gauss-Newton step from there on its
    own residuals with the optimum's J), is sent each one's (cost, residual), and returns the
    lower cost."""
    base = _project(problem, theta + delta * path)
    cost, r = yield base
    if r is None:
        return math.inf
    step = np.zeros_like(theta)
    step[others] = -lstsq @ r
    moved = _project(problem, base + step)
    moved[j] = base[j]
    cost2, _ = yield moved
    return min(cost, cost2)


def _crossing(inside: tuple, outside: tuple) -> float:
    """Where the profile cost crosses the threshold between ``inside`` and ``outside`` ((δ, g):
    g = profile cost − cost0 − threshold, ≤ 0 inside, > 0 outside): the straight line through
    the two in δ², exact for a cost that is a parabola in δ; the bracket's middle where the
    outside's cost is not finite (a failed run)."""
    (d_in, g_in), (d_out, g_out) = inside, outside
    if not math.isfinite(g_out):
        return 0.5 * (d_in + d_out)
    u = d_in**2 + (d_out**2 - d_in**2) * (-g_in) / (g_out - g_in)
    return min(max(math.sqrt(u), d_in), d_out)


def _profile_side(problem: Problem, theta, cost0: float, J, C, j: int, se_j: float, threshold: float, side: float):
    """A generator of one side of θ_j's 95 % profile interval (yields points, is sent their
    (cost, residual), :func:`_drive`): walk in doubling steps from two SE until the profile cost
    passes ``threshold`` above ``cost0`` (or a bound stops it), then refine the bracket by
    REFINEMENTS points of regula falsi in δ² (Illinois: the end kept twice in a row has its
    excess halved, so a curved cost cannot hold one end forever). Returns (end, open): open
    where the walk ended before the cost passed the threshold."""
    est = problem.spec.estimates[j]
    path = C[:, j] / C[j, j]
    others = [k for k in range(len(theta)) if k != j]
    lstsq = np.linalg.pinv(J[:, others])

    def excess(delta: float):
        cost = yield from _profile_cost(problem, theta, path, j, others, lstsq, side * delta)
        return cost - cost0 - threshold

    limit = (est.low - theta[j]) if side < 0 else (est.high - theta[j])
    inside, outside, bounded = (0.0, -threshold), None, False
    # The walk begins at 2 SE: a parabola crosses the threshold at 1.96 SE·sqrt(inflation), so
    # a point at 1 SE (the walk before) only narrowed a bracket that regula falsi from the
    # optimum (g = −threshold) closes exactly for a parabola; with the classical SE as the
    # unit (:func:`profiles`), the point is the quadratic check's and its run is remembered.
    delta = 2.0 * se_j
    for _ in range(MAX_DOUBLINGS):
        if abs(delta) >= abs(limit):
            delta, bounded = abs(limit), True
        g = yield from excess(delta)
        if g > 0.0:
            outside = (delta, g)
            break
        inside = (delta, g)
        if bounded:
            break
        delta *= 2.0
    if outside is None:
        return theta[j] + side * inside[0], not bounded
    kept = None
    for _ in range(REFINEMENTS):
        delta = _crossing(inside, outside)
        if not inside[0] < delta < outside[0]:
            break
        g = yield from excess(delta)
        if g > 0.0:
            outside = (delta, g)
            if kept == "inside":
                inside = (inside[0], 0.5 * inside[1])
            kept = "inside"
        else:
            inside = (delta, g)
            if kept == "outside":
                outside = (outside[0], 0.5 * outside[1])
            kept = "outside"
    return theta[j] + side * _crossing(inside, outside), False


def _drive(problem: Problem, walks: list, lowest: Lowest | None = None) -> list:
    """Runs the point generators ``walks`` side by side: each round evaluates the next point of
    every walk not yet ended in one batch (their runs go to the cluster together), so the walks
    take the wall time of the longest, not of their sum. Returns [(value, runs)] per walk: what
    it returned and how many points it asked for. Each walk sees exactly the points and costs
    it would alone, so the answer does not depend on how many run beside it."""
    out = [None] * len(walks)
    runs = [0] * len(walks)
    pending = {}

    def advance(k: int, sent) -> None:
        try:
            pending[k] = walks[k].send(sent)
            runs[k] += 1
        except StopIteration as end:
            pending.pop(k, None)
            out[k] = (end.value, runs[k])

    for k in range(len(walks)):
        advance(k, None)
    while pending:
        ks = list(pending)
        for k, result in zip(ks, _evaluate(problem, [pending[k] for k in ks], lowest), strict=True):
            advance(k, result)
    return out


def profile_intervals(problem: Problem, theta, cost0: float, J, C, wanted: dict, lowest: Lowest | None = None) -> dict:
    """The 95 % profile intervals of the parameters in ``wanted`` ({j: (se_j, threshold)}), both
    sides of every one walked side by side (:func:`_drive`): {j: entry}."""
    keys = [(j, side) for j in wanted for side in (-1.0, 1.0)]
    walks = [_profile_side(problem, theta, cost0, J, C, j, *wanted[j], side) for j, side in keys]
    ends = dict(zip(keys, _drive(problem, walks, lowest), strict=True))
    out = {}
    for j in wanted:
        ((low, low_open), low_runs), ((high, high_open), high_runs) = ends[(j, -1.0)], ends[(j, 1.0)]
        out[j] = {
            "interval_95": [float(low), float(high)],
            "open": [bool(low_open), bool(high_open)],  # the walk ended before the cost passed the threshold
            "std_error_profile": float(max(theta[j] - low, high - theta[j]) / 1.96),
            "runs": low_runs + high_runs,
        }
    return out


def profiles(problem: Problem, theta, cost0: float, J, unc, scale: float, lowest: Lowest | None = None) -> dict:
    """The profile of every parameter that is a μ_s or whose cost is not quadratic; ``lowest``
    receives the lowest cost met on the way (:class:`Lowest`)."""
    from scipy.stats import chi2

    names = [e.name for e in problem.spec.estimates]
    C = np.linalg.pinv(J.T @ J)
    ratios = quadratic_check(problem, theta, cost0, C, unc.std_error_classical, scale, lowest)
    wanted, ratio_of = {}, {}
    for j, name in enumerate(names):
        if problem.spec.estimates[j].start_of is not None:  # a start unknown: its standard error is enough
            continue
        ratio = ratios.get(j, math.nan)
        quadratic = QUADRATIC[0] <= ratio <= QUADRATIC[1]
        if quadratic and not name.startswith("mu_s["):
            continue
        if not (math.isfinite(unc.std_error[j]) and unc.std_error[j] > 0):
            continue
        inflation = max(1.0, (unc.std_error_sandwich[j] / unc.std_error_classical[j]) ** 2)
        threshold = 0.5 * float(chi2.ppf(0.95, 1)) * scale * inflation
        # The walk's unit is the standard error the quadratic check stepped by, so its first
        # points (2 units out) are the check's own, whose runs the problem remembers.
        classical = float(unc.std_error_classical[j])
        wanted[j] = (classical if math.isfinite(classical) and classical > 0 else float(unc.std_error[j]), threshold)
        ratio_of[j] = (ratio, quadratic)
    out = {}
    for j, entry in profile_intervals(problem, theta, cost0, J, C, wanted, lowest).items():
        ratio, quadratic = ratio_of[j]
        entry["cost_ratio_at_2se"] = float(ratio) if math.isfinite(ratio) else None
        entry["quadratic"] = bool(quadratic)
        out[names[j]] = entry
    return out
