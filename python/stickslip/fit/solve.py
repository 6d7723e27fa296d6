"""The output-error stage: bounded nonlinear least squares from several starts, the Jacobian
by finite differences run in parallel, and the uncertainty of the result.

Each start runs ``scipy.optimize.least_squares`` (trust region reflective, bounds [0, 1] in
the normalized space of :class:`~stickslip.fit.problem.Transform`) first on the
multiple-shooting cost, when the experiments allow it, then on the simulation-error cost
(single shooting) from where that ended: multiple shooting brings a start into the basin of
the stick-slip pattern the measurement shows, single shooting gives the estimate and its
covariance (the maximum-likelihood estimate for independent Gaussian noise on the samples).

The Jacobian is a forward difference of step ``diff_step`` in z (a fraction of each
parameter's bound range, or of its log range), taken backward at the upper bound and where
the forward point is refused or discarded; its p runs go to the cluster at once. The starts
run in threads of this process, so their runs fill the cluster together.
"""

from __future__ import annotations

import math
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from .problem import Problem


@dataclass
class StartResult:
    initial: dict  # θ of the start
    origin: str  # "initial", "equation-error", "latin hypercube k"
    z: np.ndarray = None
    cost: float = math.inf
    ms_cost: float | None = None
    nfev: int = 0
    status: str = ""
    message: str = ""
    history: list = field(default_factory=list)


def jacobian(problem: Problem, z, r0, shooting: str, step: float) -> tuple:
    """(J, notes): J of the residuals at z (forward differences, in parallel)."""
    p = len(z)
    points, signs = [], []
    for j in range(p):
        s = -1.0 if z[j] + step > 1.0 else 1.0
        zz = np.array(z, dtype=np.float64)
        zz[j] += s * step
        points.append(zz)
        signs.append(s)
    runs = problem.runs(points, shooting)
    retry = [j for j in range(p) if Problem.failed(runs[j])]
    notes = []
    if retry:
        back = []
        for j in retry:
            zz = np.array(z, dtype=np.float64)
            zz[j] -= signs[j] * step
            back.append(zz)
            signs[j] = -signs[j]
        for j, res in zip(retry, problem.runs(back, shooting), strict=True):
            runs[j] = res
            name = problem.spec.estimates[j].name
            notes.append(f"{name}: the forward point failed ({runs[j][0].status}); one-sided the other way")
    J = np.empty((len(r0), p))
    for j in range(p):
        J[:, j] = (problem.residual(runs[j]) - r0) / (signs[j] * step)
    return J, notes


# Stopping tolerances (relative change of the cost, of z): multiple shooting only has to
# bring a start into the basin of the measured stick-slip pattern; single shooting gives
# the estimate, to well below its standard error.
TOLERANCE = {"multiple": 1e-5, "single": 1e-10}


def local_fit(problem: Problem, z0, shooting: str, options: dict) -> tuple:
    """least_squares from z0 on the ``shooting`` cost: (OptimizeResult, history)."""
    from scipy.optimize import least_squares

    cache = {}
    history = []

    def fun(z):
        key = tuple(np.round(z, 15))
        if key not in cache:
            cache.clear()
            cache[key] = problem.residuals([z], shooting)[0]
            history.append((problem.transform.named(problem.transform.theta(z)), 0.5 * float(cache[key] @ cache[key])))
        return cache[key]

    def jac(z):
        J, _ = jacobian(problem, z, fun(z), shooting, options["diff_step"])
        return J

    result = least_squares(
        fun,
        np.clip(z0, 0.0, 1.0),
        jac=jac,
        bounds=(0.0, 1.0),
        method="trf",
        loss=options["loss"],
        f_scale=options["f_scale"],
        x_scale="jac",
        max_nfev=options["max_evaluations"],
        xtol=TOLERANCE[shooting],
        ftol=TOLERANCE[shooting],
        gtol=TOLERANCE[shooting],
    )
    return result, history


def run_start(problem: Problem, start: StartResult, multiple: bool, options: dict) -> StartResult:
    z = problem.transform.z(list(start.initial.values()))
    nfev = 0
    if multiple:
        res, hist = local_fit(problem, z, "multiple", options)
        z, nfev, start.ms_cost = res.x, res.nfev, float(res.cost)
        start.history += [("multiple", *h) for h in hist]
    res, hist = local_fit(problem, z, "single", options)
    start.history += [("single", *h) for h in hist]
    start.z, start.cost, start.nfev = res.x, float(res.cost), nfev + res.nfev
    start.status, start.message = ("converged" if res.status > 0 else "stopped"), res.message
    failed = [r for r in problem.runs([res.x], "single")[0] if r.status != "ok"]
    if failed:
        # A start that ends where the FMU refuses or discards has no cost to compare.
        start.cost, start.status = math.inf, "failed"
        start.message = f"ended at a point whose run ended {failed[0].status}: {failed[0].message}"
    return start


def run_starts(problem: Problem, starts: list, multiple: bool, options: dict, threads: int) -> list:
    """Every start (in ``threads`` threads sharing the evaluator), results in the same order."""
    if threads <= 1 or len(starts) == 1:
        return [run_start(problem, s, multiple, options) for s in starts]
    with ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(lambda s: run_start(problem, s, multiple, options), starts))


def latin_hypercube(p: int, n: int, seed: int) -> np.ndarray:
    """n points in [0, 1]^p, a seeded Latin hypercube (scipy.stats.qmc)."""
    from scipy.stats import qmc

    if n <= 0:
        return np.empty((0, p))
    return qmc.LatinHypercube(d=p, seed=seed).random(n)


@dataclass
class Uncertainty:
    std_error: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    scale: float  # σ̂² (1 with absolute sigmas)
    singular: list  # (relative singular value, {name: component}) of near-singular directions
    condition: float


def uncertainty(problem: Problem, z, r, J_z, options: dict) -> Uncertainty:
    """Covariance of θ at the optimum: s² (JᵀJ)⁻¹ with J = ∂r/∂θ (J_z (dθ/dz)⁻¹), by SVD of
    the column-scaled J; s² = Σρ'r²/(m − p) unless the sigmas are absolute. A robust loss
    weights the rows by √ρ'(r²) (iteratively reweighted least squares at the optimum)."""
    D = problem.transform.jacobian(z)
    J = J_z @ np.linalg.inv(D)
    m, p = J.shape
    w = np.ones(m)
    if options["loss"] != "linear":
        w = np.sqrt(_rho_prime(r, options["loss"], options["f_scale"]))
    Jw = J * w[:, None]
    rw = r * w
    scale = 1.0 if options["absolute_sigma"] else float(rw @ rw) / max(m - p, 1)
    norms = np.linalg.norm(Jw, axis=0)
    norms[norms == 0] = 1.0
    _, S, Vt = np.linalg.svd(Jw / norms, full_matrices=False)
    condition = float(S[0] / S[-1]) if S[-1] > 0 else math.inf
    inv = np.where(S > S[0] * 1e-12, 1.0 / np.where(S > 0, S, 1.0) ** 2, math.inf)
    cov_scaled = (Vt.T * np.where(np.isfinite(inv), inv, 0.0)) @ Vt
    cov = scale * cov_scaled / np.outer(norms, norms)
    if not np.all(np.isfinite(inv)):
        cov[:] = math.inf
    se = np.sqrt(np.abs(np.diag(cov)))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(se, se)
    names = [e.name for e in problem.spec.estimates]
    singular = []
    for k in range(len(S)):
        rel = S[k] / S[0] if S[0] > 0 else 0.0
        if rel < 1e-6:
            v = Vt[k]
            singular.append((float(rel), {names[j]: float(v[j]) for j in np.argsort(-np.abs(v)) if abs(v[j]) > 0.1}))
    return Uncertainty(se, cov, corr, scale, singular, condition)


def _rho_prime(r, loss: str, f_scale: float):
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


def elapsed(t0: float) -> float:
    return time.perf_counter() - t0
