"""The output-error stage: bounded nonlinear least squares from several starts, the Jacobian
by finite differences run in parallel.

Each start runs ``scipy.optimize.least_squares`` (trust region reflective, bounds [0, 1] in
the normalized space of :class:`~stickslip.fit.problem.Transform`). Where the experiments
can be restarted from their measurements, a start goes through a **continuation in the
segment length** of multiple shooting: segments of ``segment`` s, then three times as long,
and so on while a segment is shorter than half the longest experiment, each stage started
where the last ended; then single shooting, the simulation-error cost itself, whose minimum
is the maximum-likelihood estimate. Short segments cannot drift far from the measured
motion, so a stick-slip pattern that differs early does not decide the cost of what follows,
and the trust region walks into the basin; but their start states come from filtered
measurements, which biases the short-segment minimum. Each longer stage weakens that bias
and hands the next a point in its own basin, instead of single shooting starting from the
short-segment minimum and stopping in the nearest minimum of its own (measured on new arms:
4–11 standard errors from the truth). Bock's direct multiple shooting (the segment states
as unknowns with continuity conditions) would remove the bias too, at the price of
2·joints·segments more unknowns and a stick/slip phase per segment start: the
continuation ends at the same estimate with the parameters as the only unknowns.

Every start's single-shooting cost is compared at its start point and where the
continuation ended; single shooting goes on from the better of the two, so the
equation-error estimate is a candidate of its own and multiple shooting can only help.

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
    ms_cost: float | None = None  # the last multiple-shooting stage's cost
    start_cost: float = math.inf  # the single-shooting cost at the start point
    continuation_cost: float | None = None  # … where the continuation ended
    step: float | None = None  # the Jacobian step single shooting ended with
    nfev: int = 0
    status: str = ""
    message: str = ""
    history: list = field(default_factory=list)


def jacobian(problem: Problem, z, r0, segment: float | None, step: float) -> tuple:
    """(J, notes): J of the residuals at z: from the FMU's sensitivities (one native call an
    experiment, :mod:`stickslip.experiment`) where the SPEC's ``jacobian`` says so and the FMU
    has them; forward differences of free runs with ``step`` for the columns whose event
    pattern changed within the sensitivities' step, and for all where there are none."""
    if problem.exact_jacobians:
        runs = problem.runs([z], segment, problem.sensitivity_steps(z))[0]
        J, exact = (None, None) if Problem.failed(runs) else problem.residual_jacobian(runs, z)
        if J is not None:
            problem.count_columns(exact)
            if exact.all():
                return J, []
            columns = np.flatnonzero(~exact)
            Jd, notes = differences(problem, z, r0, segment, step, columns)
            J[:, columns] = Jd
            names = ", ".join(problem.spec.estimates[j].name for j in columns)
            return J, [*notes, f"{names}: the event pattern changed within the sensitivities' step; differences"]
    return differences(problem, z, r0, segment, step)


def differences(problem: Problem, z, r0, segment: float | None, step: float, columns=None) -> tuple:
    """(J, notes): forward differences of free runs (in parallel) for ``columns`` (default all)
    of the residuals' Jacobian at z."""
    columns = list(range(len(z))) if columns is None else list(columns)
    points, signs = [], []
    for j in columns:
        s = -1.0 if z[j] + step > 1.0 else 1.0
        zz = np.array(z, dtype=np.float64)
        zz[j] += s * step
        points.append(zz)
        signs.append(s)
    runs = problem.runs(points, segment)
    retry = [m for m in range(len(columns)) if Problem.failed(runs[m])]
    notes = []
    if retry:
        back = []
        for m in retry:
            zz = np.array(z, dtype=np.float64)
            zz[columns[m]] -= signs[m] * step
            back.append(zz)
            signs[m] = -signs[m]
        for m, res in zip(retry, problem.runs(back, segment), strict=True):
            runs[m] = res
            name = problem.spec.estimates[columns[m]].name
            notes.append(f"{name}: the forward point failed ({runs[m][0].status}); one-sided the other way")
    J = np.empty((len(r0), len(columns)))
    for m in range(len(columns)):
        J[:, m] = (problem.residual(runs[m]) - r0) / (signs[m] * step)
    return J, notes


# Stopping tolerances (relative change of the cost, of z): multiple shooting only has to
# bring a start into the basin of the measured stick-slip pattern; single shooting gives
# the estimate, to well below its standard error. On the FMU's sensitivities, whose steps
# are not blurred by a difference's, multiple shooting stops at 1e-3 (docs/performance.md,
# "Fits": what it saves, and that the answers stay).
TOLERANCE = {"multiple": 1e-5, "single": 1e-10, "multiple_exact": 1e-3}


def local_fit(problem: Problem, z0, segment: float | None, options: dict, max_nfev: int | None = None) -> tuple:
    """least_squares from z0 on the single-shooting (``segment=None``) or multiple-shooting
    cost: (OptimizeResult, history)."""
    from scipy.optimize import least_squares

    cache = {}
    history = []
    tol = TOLERANCE["single" if segment is None else "multiple"]
    if segment is not None and problem.exact_jacobians:
        tol = TOLERANCE["multiple_exact"]

    def fun(z):
        key = tuple(np.round(z, 15))
        if key not in cache:
            cache.clear()
            cache[key] = problem.residuals([z], segment)[0]
            history.append((problem.transform.named(problem.transform.theta(z)), 0.5 * float(cache[key] @ cache[key])))
        return cache[key]

    def jac(z):
        J, _ = jacobian(problem, z, fun(z), segment, options["diff_step"])
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
        max_nfev=max_nfev or options["max_evaluations"],
        xtol=tol,
        ftol=tol,
        gtol=tol,
    )
    return result, history


# Single shooting's Jacobian steps, as fractions of ``diff_step``: coarse to fine.
STEP_FACTORS = (1.0, 0.3, 0.1, 0.03)


def refine(problem: Problem, z, options: dict, start=None, nfev: int = 0) -> tuple:
    """Single shooting from z with a Jacobian step going from ``diff_step`` down by STEP_FACTORS
    while each finer step still lowers the cost by more than ½ (implicit filtering, Kelley):
    (the last OptimizeResult, evaluations so far).

    A coarse difference smooths the cost's small-scale roughness far from the minimum, but
    near it a step of 1e-3 of a range is hundreds of standard errors of a well-determined
    parameter (k[3] of the calibration example: 2,500 N/m for a standard error of 4), so its
    secant does not see the bowl the estimate lies in, and the trust region stops where
    every step it tries fails: measured on the calibration example, cost 5361.5 with 1e-3
    against 5278.1 after 3e-4 (the truth: 5287.8), every estimate moved to within 0.3 % of
    the truth. Each stage starts where the last ended; the best stage's step is the one the
    uncertainty's Jacobian takes (``res.step_factor``). With the FMU's sensitivities
    (``[options] jacobian``) there is no step to refine, and one stage is taken."""
    best = None
    # Sensitivities have no step to refine: one stage (the differences of a column whose event
    # pattern changes within their step take diff_step).
    for factor in STEP_FACTORS[:1] if problem.exact_jacobians else STEP_FACTORS:
        step = factor * options["diff_step"]
        res, hist = local_fit(problem, z if best is None else best.x, None, dict(options, diff_step=step))
        nfev += res.nfev
        if start is not None:
            start.history += [(f"single, step {factor:g}", *h) for h in hist]
        improved = best is None or res.cost < best.cost - 0.5
        if best is None or res.cost < best.cost:
            res.step_factor = factor
            best = res
        if not improved:
            break
    return best, nfev


def segment_lengths(problem: Problem, first: float) -> list:
    """The continuation's segment lengths: ``first``, 3×, 9×, … while shorter than half the
    longest experiment (at least ``first``)."""
    longest = max(float(e.time[-1] - e.time[0]) for e in problem.spec.experiments)
    if problem.horizon is not None:  # the final cost is over the horizon: shorter ones lead to it
        out = [min(first, problem.horizon)]
        while 3.0 * out[-1] < problem.horizon:
            out.append(3.0 * out[-1])
        return [x for x in out if x < problem.horizon] or [first]
    out = [first]
    while 3.0 * out[-1] < 0.5 * longest:
        out.append(3.0 * out[-1])
    return out


def run_start(problem: Problem, start: StartResult, multiple: bool, options: dict, say=None) -> StartResult:
    """One start through the continuation and single shooting; ``say(line)`` reports each
    stage as it ends."""
    say = say or (lambda line: None)
    t0 = time.perf_counter()
    z0 = problem.transform.z(list(start.initial.values()))
    z, nfev = z0, 0
    at_start = problem.runs([z0])[0]
    refused = [r for r in at_start if r.status == "refused"]
    if refused:
        # Not a point of the model: the optimizer would only walk the penalty's plateau.
        problem.residual(at_start)  # the refusal counted in failed_runs, with the FMU's reason
        start.status = "dropped"
        start.message = f"the FMU refuses its parameters: {' '.join(refused[0].message.split())}"
        say(f"fit: start {start.origin!r} dropped: {start.message}")
        return start
    start.start_cost = problem.cost_of(at_start)
    if multiple:
        for length in segment_lengths(problem, options["segment"]):
            res, hist = local_fit(problem, z, length, options)
            z, nfev = res.x, nfev + res.nfev
            start.ms_cost = float(res.cost)
            start.history += [(f"multiple {length:g} s", *h) for h in hist]
            say(
                f"fit: start {start.origin!r}: multiple shooting, {length:g} s segments: cost {res.cost:.6g} "
                f"({res.nfev} iterations, {problem.evaluator.runs} FMU runs so far, {time.perf_counter() - t0:.0f} s)"
            )
        start.continuation_cost = problem.cost(z)
        if not start.continuation_cost <= start.start_cost:
            z = z0  # the continuation made the simulation error worse: single shooting from the start
    res, nfev = refine(problem, z, options, start, nfev)
    start.z, start.cost, start.nfev = res.x, float(res.cost), nfev
    start.step = res.step_factor * options["diff_step"]
    start.status, start.message = ("converged" if res.status > 0 else "stopped"), res.message
    failed = [r for r in problem.runs([res.x])[0] if r.status != "ok"]
    if failed:
        # A start that ends where the FMU refuses or discards has no cost to compare.
        start.cost, start.status = math.inf, "failed"
        start.message = f"ended at a point whose run ended {failed[0].status}: {failed[0].message}"
    after = f", after the continuation {start.continuation_cost:.6g}" if start.continuation_cost is not None else ""
    say(
        f"fit: start {start.origin!r}: cost {start.cost:.6g} (at its start {start.start_cost:.6g}{after}), "
        f"{start.status}, {problem.evaluator.runs} FMU runs so far, {time.perf_counter() - t0:.0f} s"
    )
    return start


def guarded_start(problem: Problem, start: StartResult, multiple: bool, options: dict, say=None) -> StartResult:
    """:func:`run_start`, whose failure (an exception anywhere inside it) ends this start only:
    it comes back ``failed`` with the reason, without a cost, and the other starts go on."""
    try:
        return run_start(problem, start, multiple, options, say)
    except Exception as e:  # noqa: BLE001 -- one start's failure must not end the fit
        start.z, start.cost, start.status = None, math.inf, "failed"
        start.message = f"{type(e).__name__}: {' '.join(str(e).split())}"
        (say or (lambda line: None))(f"fit: start {start.origin!r} failed: {start.message}")
        return start


def run_starts(problem: Problem, starts: list, multiple: bool, options: dict, threads: int, say=None) -> list:
    """Every start (in ``threads`` threads sharing the evaluator), results in the same order;
    a start that fails is returned ``failed`` with its reason (:func:`guarded_start`)."""
    if threads <= 1 or len(starts) == 1:
        return [guarded_start(problem, s, multiple, options, say) for s in starts]
    with ThreadPoolExecutor(max_workers=threads) as pool:
        return list(pool.map(lambda s: guarded_start(problem, s, multiple, options, say), starts))


def latin_hypercube(p: int, n: int, seed: int) -> np.ndarray:
    """n points in [0, 1]^p, a seeded Latin hypercube (scipy.stats.qmc)."""
    from scipy.stats import qmc

    if n <= 0:
        return np.empty((0, p))
    return qmc.LatinHypercube(d=p, seed=seed).random(n)
