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
the forward point is refused or discarded; its p runs go to the cluster at once.

A stage also ends where the Gauss-Newton step is a small fraction of its standard errors
(:func:`settled`). The starts run in threads of this process, so their runs fill the cluster
together; after each multiple-shooting stage a start that ended it in the same basin as a
better-ranked start is not followed further (:class:`_Meeting`, deterministic whatever the load).
"""

from __future__ import annotations

import math
import threading
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
    from_continuation: bool = False  # single shooting goes on from where the continuation ended
    step: float | None = None  # the Jacobian step single shooting ended with
    nfev: int = 0
    status: str = ""
    message: str = ""
    history: list = field(default_factory=list)
    z_start: np.ndarray = None  # z of the start point
    se: np.ndarray = None  # standard errors in z at the last stage's last Jacobian
    merged_into: StartResult = None  # the start this one joined (status "merged")
    t0: float = 0.0


def jacobian(problem: Problem, z, r0, segment: float | None, step: float, columns=None) -> tuple:
    """(J, notes): J of the residuals at z (its ``columns``, default all): from the FMU's
    sensitivities (one native call an experiment, :mod:`stickslip.experiment`) where the SPEC's
    ``jacobian`` says so and the FMU has them; forward differences of free runs with ``step``
    for the columns whose event pattern changed within the sensitivities' step, and for all
    where there are none."""
    columns = np.arange(len(z)) if columns is None else np.asarray(columns, dtype=int)
    if problem.exact_jacobians:
        runs = problem.runs([z], segment, problem.sensitivity_steps(z))[0]
        J, exact = (None, None) if Problem.failed(runs) else problem.residual_jacobian(runs, z)
        if J is not None:
            J, exact = J[:, columns], exact[columns]
            problem.count_columns(exact)
            if exact.all():
                return J, []
            again = np.flatnonzero(~exact)
            Jd, notes = differences(problem, z, r0, segment, step, columns[again])
            J[:, again] = Jd
            names = ", ".join(problem.spec.estimates[j].name for j in columns[again])
            return J, [*notes, f"{names}: the event pattern changed within the sensitivities' step; differences"]
    return differences(problem, z, r0, segment, step, columns)


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
# the estimate, to well below its standard error. Multiple shooting stops at 1e-3 whether its
# Jacobians are the FMU's sensitivities or differences: at 1e-5 a start of the benchmark's
# reference-201 crawled through 40 Jacobians of its 0.1 s stage, each lowering the cost by
# 0.1 of 6120 (docs/performance.md, "Fits": what it saves, and that the answers stay).
TOLERANCE = {"multiple": 1e-3, "single": 1e-10}
# A stage also ends as soon as the Gauss-Newton step from its point is smaller than this many
# of its own standard errors in every free parameter (:func:`settled`): the estimate would not
# move by more in any further iteration of a quadratic model, and the trust region's own
# tolerances above spend 2-4 more Jacobians on moves of 1e-3 standard errors (measured on
# scripts/bench_fit.py; docs/performance.md, "Fits").
SETTLED = {"multiple": 0.2, "single": 0.05}


class _Settled(Exception):
    """Raised inside least_squares' Jacobian where :func:`settled` ends the stage."""

    def __init__(self, z, shift: float):
        super().__init__()
        self.z, self.shift = np.array(z, dtype=np.float64), shift


def settled(J, r, z, weights=None) -> tuple:
    """(shift, se): the Gauss-Newton step from z in units of its standard errors (the largest
    over the parameters that are not held at a bound by the gradient), and the standard errors
    in z. The standard errors are those of the residuals as given (normalized by their sigma),
    or of the cost's own noise scale where that is smaller, so that a fit whose sigma are too
    large does not stop early. inf where the Gauss-Newton matrix is singular."""
    J = np.asarray(J, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    if weights is not None:
        J, r = J * weights[:, None], r * weights
    m, p = J.shape
    g = J.T @ r  # the cost's gradient
    z = np.asarray(z, dtype=np.float64)
    held = ((z <= 1e-12) & (g > 0.0)) | ((z >= 1.0 - 1e-12) & (g < 0.0))
    free = ~held
    se = np.full(p, np.inf)
    if not free.any():
        return 0.0, se
    Jf = J[:, free]
    H = Jf.T @ Jf
    try:
        inv = np.linalg.inv(H)
        step = -inv @ (Jf.T @ r)
    except np.linalg.LinAlgError:
        return math.inf, se
    scale = min(1.0, float(r @ r) / max(m - p, 1))
    se[free] = np.sqrt(np.maximum(np.diag(inv) * scale, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        shift = np.abs(step) / se[free]
    if not np.all(np.isfinite(shift)):
        return math.inf, se
    return float(shift.max()), se


def local_fit(problem: Problem, z0, segment: float | None, options: dict, max_nfev: int | None = None) -> tuple:
    """least_squares from z0 on the single-shooting (``segment=None``) or multiple-shooting
    cost: (OptimizeResult, history). The result carries ``se``, the standard errors in z at the
    last Jacobian (None before one), and ends early where the point has settled (SETTLED)."""
    from scipy.optimize import OptimizeResult, least_squares

    from .uncertainty import rho_prime, robust_cost

    cache = {}
    history = []
    kind = "single" if segment is None else "multiple"
    tol = TOLERANCE[kind]
    last = {"se": None, "njev": 0}
    # Multiple shooting moves the model's parameters only: each experiment's first segment
    # starts from its start unknowns where they are (as read: multiple shooting comes before
    # single shooting), the other segments from their own reading, so the start unknowns would
    # only add a column each to its Jacobians.
    base = np.clip(np.asarray(z0, dtype=np.float64), 0.0, 1.0)
    free = np.arange(len(base)) if segment is None else problem.model_columns()

    def full(x):
        z = base.copy()
        z[free] = x
        return z

    def fun(x):
        z = full(x)
        key = tuple(np.round(z, 15))
        if key not in cache:
            cache.clear()
            cache[key] = problem.residuals([z], segment)[0]
            history.append((problem.transform.named(problem.transform.theta(z)), 0.5 * float(cache[key] @ cache[key])))
        return cache[key]

    def jac(x):
        r = fun(x)
        z = full(x)
        J, _ = jacobian(problem, z, r, segment, options["diff_step"], free)
        last["njev"] += 1
        weights = None if options["loss"] == "linear" else np.sqrt(rho_prime(r, options["loss"], options["f_scale"]))
        shift, se = settled(J, r, np.clip(x, 0.0, 1.0), weights)
        last["se"] = np.zeros(len(base))  # a held column does not move: 0 apart between starts
        last["se"][free] = se
        if shift <= SETTLED[kind] and np.all(np.isfinite(r)):
            raise _Settled(z, shift)
        return J

    try:
        result = least_squares(
            fun,
            base[free],
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
    except _Settled as done:
        r = fun(done.z[free])
        result = OptimizeResult(
            x=np.clip(done.z[free], 0.0, 1.0),
            cost=robust_cost(r, options["loss"], options["f_scale"]),
            fun=r,
            nfev=len(history),
            njev=last["njev"],
            status=5,
            success=True,
            message=f"settled: the Gauss-Newton step is {done.shift:.2g} of a standard error",
        )
    result.x = full(result.x)
    result.se = last["se"]
    return result, history


# Single shooting's Jacobian steps, as fractions of ``diff_step``: coarse to fine.
STEP_FACTORS = (1.0, 0.3, 0.1, 0.03)


def refine(problem: Problem, z, options: dict, start=None, nfev: int = 0, factors=STEP_FACTORS) -> tuple:
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
    (``[options] jacobian``) there is no step to refine, and one stage is taken. ``factors``:
    the steps to go through (a refit from an answer whose step is known takes that one only)."""
    best = None
    # Sensitivities have no step to refine: one stage (the differences of a column whose event
    # pattern changes within their step take diff_step).
    for factor in factors[:1] if problem.exact_jacobians else factors:
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


# Two starts whose multiple-shooting stage ends within MEET of the stage's standard errors of
# each other in every parameter are in the same basin: the one that comes later in the starts'
# order (by the cost at their start points) is not followed further (``merged``), since from
# the same point the stages to come are the same.
MEET = 0.5
# A start whose multiple-shooting cost at the end of a stage is more than BEHIND times that of a
# start ranked before it is in a basin whose stick-slip pattern is far from the measured one:
# it is not followed further (``abandoned``). Measured on the identification benchmark (15
# draws of three arms): starts 4 to 25 times behind the best at their last stage ended 20 to
# 3000 times above the best's final cost, and took most of the fits' runs.
BEHIND = 10.0


def _begin(problem: Problem, start: StartResult, say) -> None:
    """The start's single-shooting cost at its own point; ``dropped`` where the FMU refuses it."""
    start.z_start = problem.transform.z(list(start.initial.values()))
    start.z = start.z_start
    at_start = problem.runs([start.z_start])[0]
    refused = [r for r in at_start if r.status == "refused"]
    if refused:
        # Not a point of the model: the optimizer would only walk the penalty's plateau.
        problem.residual(at_start)  # the refusal counted in failed_runs, with the FMU's reason
        start.status = "dropped"
        start.message = f"the FMU refuses its parameters: {' '.join(refused[0].message.split())}"
        say(f"fit: start {start.origin!r} dropped: {start.message}")
        return
    start.start_cost = problem.cost_of(at_start)


def _multiple_stage(problem: Problem, start: StartResult, length: float, options: dict, say) -> None:
    res, hist = local_fit(problem, start.z, length, options)
    start.z, start.nfev, start.se = res.x, start.nfev + res.nfev, res.se
    start.ms_cost = float(res.cost)
    start.history += [(f"multiple {length:g} s", *h) for h in hist]
    say(
        f"fit: start {start.origin!r}: multiple shooting, {length:g} s segments: cost {res.cost:.6g} "
        f"({res.nfev} iterations, {problem.evaluator.runs} FMU runs so far, {time.perf_counter() - start.t0:.0f} s)"
    )


def _continued(problem: Problem, start: StartResult) -> None:
    """The single-shooting cost where the continuation ended; single shooting goes on from the
    start point instead where that is lower."""
    start.continuation_cost = problem.cost(start.z)
    start.from_continuation = start.continuation_cost <= start.start_cost
    if not start.from_continuation:
        start.z = start.z_start  # the continuation made the simulation error worse


def single_factors(start: StartResult) -> tuple:
    """The Jacobian steps (fractions of ``diff_step``) single shooting goes through from
    ``start``: all of STEP_FACTORS from a start point, from the second on from where the
    continuation ended. The coarsest step smooths the roughness of a cost far from its minimum;
    the continuation's end lies in the minimum's basin already, where that step's secant is
    hundreds of standard errors wide. Measured on the identification benchmark (seeds 100 and
    200, 30 fits): the same answers (every cost to 0.01 but one, both below the truth's), the
    same fits at the truth's minimum, 7993 runs against 8941; the calibration example 708 runs
    against 772."""
    return STEP_FACTORS[1:] if start.from_continuation else STEP_FACTORS


def _single_stage(problem: Problem, start: StartResult, options: dict, say) -> None:
    res, start.nfev = refine(problem, start.z, options, start, start.nfev, single_factors(start))
    start.z, start.cost = res.x, float(res.cost)
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
        f"{start.status}, {problem.evaluator.runs} FMU runs so far, {time.perf_counter() - start.t0:.0f} s"
    )


def _guarded(start: StartResult, stage, say) -> None:
    """``stage()``, whose failure (an exception anywhere inside it) ends this start only: it
    comes back ``failed`` with the reason, without a cost, and the other starts go on."""
    try:
        stage()
    except Exception as e:  # noqa: BLE001 -- one start's failure must not end the fit
        start.z, start.cost, start.status = None, math.inf, "failed"
        start.message = f"{type(e).__name__}: {' '.join(str(e).split())}"
        say(f"fit: start {start.origin!r} failed: {start.message}")


class _Meeting:
    """Where the starts meet after each multiple-shooting stage. The starts are ranked by their
    single-shooting cost at their start points (then by their order); after stage i a start
    waits for the starts ranked before it to end stage i (or to end), and is ``merged`` into the
    first of them that went on from stage i within MEET standard errors of it. A start never
    waits for one ranked after it, so the best start runs ahead, and which start merges into
    which does not depend on which thread or worker was faster: fit.json is the same at any
    load (tests/python/test_fit_reproducible.py)."""

    def __init__(self, starts: list):
        self.cv = threading.Condition()
        live = [s for s in starts if not s.status]
        order = sorted(range(len(live)), key=lambda k: (live[k].start_cost, k))
        self.ahead = {id(live[k]): [live[j] for j in order[:r]] for r, k in enumerate(order)}
        self.progress = {id(s): -1 for s in live}  # the last stage it ended and went on from
        self.points = {}  # (id, stage) -> (z, se) where it went on from the stage
        self.costs = {}  # (id, stage) -> its multiple-shooting cost there

    def after_stage(self, s: StartResult, stage: int, length: float, say) -> bool:
        """True where ``s`` goes on; False where it merged (then see :meth:`revive`), or where its
        stage cost is more than BEHIND times the lowest of the starts ranked before it at the same
        stage (``abandoned``)."""
        with self.cv:
            ahead = self.ahead[id(s)]
            self.cv.wait_for(lambda: all(self.progress[id(a)] >= stage for a in ahead))
            for a in ahead:
                point = self.points.get((id(a), stage))
                if point is not None and _meet(s.z, s.se, *point):
                    s.status, s.cost, s.merged_into = "merged", math.inf, a
                    s.message = (
                        f"ended the {length:g} s multiple-shooting stage within {MEET:g} standard errors of "
                        f"start {a.origin!r}: not followed further"
                    )
                    say(f"fit: start {s.origin!r} {s.message}")
                    self._end(s)
                    return False
            costs = [(self.costs[(id(a), stage)], a) for a in ahead if self.costs.get((id(a), stage)) is not None]
            if costs and s.ms_cost is not None and s.ms_cost > BEHIND * min(costs, key=lambda c: c[0])[0]:
                lowest, a = min(costs, key=lambda c: c[0])
                s.status, s.cost = "abandoned", math.inf
                times = s.ms_cost / lowest
                s.message = (
                    f"its {length:g} s multiple-shooting cost {s.ms_cost:.6g} is {times:.3g} times that of "
                    f"start {a.origin!r} ({lowest:.6g}) at the same stage: not followed further"
                )
                say(f"fit: start {s.origin!r} abandoned: {s.message}")
                self._end(s)
                return False
            self.points[(id(s), stage)] = (np.array(s.z), None if s.se is None else np.array(s.se))
            self.costs[(id(s), stage)] = s.ms_cost
            self.progress[id(s)] = stage
            self.cv.notify_all()
            return True

    def continued(self, s: StartResult) -> None:
        """``s`` has its continuation cost: the starts merged into it may decide (:meth:`revive`)."""
        with self.cv:
            self.cv.notify_all()

    def revive(self, s: StartResult, say) -> bool:
        """Whether the merged ``s`` goes on alone after all: from its start point where that has
        a lower single-shooting cost than where the start it joined ended the continuation (as
        it would have alone: :func:`_continued`), or from where it merged where that start
        failed; never where that start was abandoned (the basin they share was)."""

        def root():
            r = s.merged_into
            while r.status == "merged":
                r = r.merged_into
            return r

        with self.cv:
            self.cv.wait_for(lambda: root().continuation_cost is not None or self.progress[id(root())] == math.inf)
            r = root()
            if r.status == "abandoned":
                return False  # its basin is the one abandoned: so is it
            if r.continuation_cost is not None and s.start_cost < r.continuation_cost:
                s.z, s.continuation_cost = s.z_start, r.continuation_cost
                where = "its start point, whose cost is lower than where the continuation ended"
            elif r.continuation_cost is None:
                s.continuation_cost = None
                where = f"where it merged, since start {r.origin!r} ended without a continuation ({r.status})"
            else:
                return False
            s.status, s.message = "", ""
            say(f"fit: start {s.origin!r} goes on alone from {where}")
            return True

    def end(self, s: StartResult) -> None:
        with self.cv:
            self._end(s)

    def _end(self, s: StartResult) -> None:
        if id(s) in self.progress:
            self.progress[id(s)] = math.inf
        self.cv.notify_all()


def _meet(z, se, z_other, se_other) -> bool:
    if se is None or se_other is None or z is None:
        return False
    scale = np.maximum(se, se_other)
    return bool(np.all(np.isfinite(scale)) and np.all(np.abs(z - z_other) <= MEET * scale))


def run_starts(problem: Problem, starts: list, multiple: bool, options: dict, threads: int, say=None) -> list:
    """Every start through the continuation and single shooting, results in the same order.
    With ``threads`` > 1 each start runs in a thread of its own (sharing the evaluator); after
    each multiple-shooting stage a start that ended it in the same basin as a better-ranked one
    is ``merged`` and not followed further (:class:`_Meeting`). A start that fails is returned
    ``failed`` with its reason, and the others go on. ``say(line)`` reports each stage."""
    say = say or (lambda line: None)
    parallel = threads > 1 and len(starts) > 1
    lengths = segment_lengths(problem, options["segment"]) if multiple else []

    def each(work, items) -> None:
        if parallel:
            with ThreadPoolExecutor(max_workers=len(items)) as pool:
                list(pool.map(work, items))
        else:
            for s in items:
                work(s)

    t0 = time.perf_counter()
    for s in starts:
        s.t0 = t0
    # Each piece of work starts with its thread's recent runs forgotten (Problem.runs), and so
    # does the caller after them: which runs are found again then depends on neither the
    # threads' interleaving nor whether the starts ran in threads at all.
    each(lambda s: _guarded(s, lambda: (problem.forget(), _begin(problem, s, say)), say), starts)
    meeting = _Meeting(starts)

    def follow(s: StartResult) -> None:
        if s.status:
            return
        # Its runs wait behind those of the starts ranked before it.
        problem.evaluator.priority.value = -len(meeting.ahead[id(s)])
        problem.forget()
        try:
            alone = False
            for stage, length in enumerate(lengths):
                _multiple_stage(problem, s, length, options, say)
                if not meeting.after_stage(s, stage, length, say):
                    if s.status != "merged" or not meeting.revive(s, say):
                        return
                    alone = True
                    break
            if multiple and not alone:
                _continued(problem, s)
                meeting.continued(s)
            _single_stage(problem, s, options, say)
        except Exception as e:  # noqa: BLE001 -- one start's failure must not end the fit
            s.z, s.cost, s.status = None, math.inf, "failed"
            s.message = f"{type(e).__name__}: {' '.join(str(e).split())}"
            say(f"fit: start {s.origin!r} failed: {s.message}")
        finally:
            meeting.end(s)

    if parallel:
        each(follow, starts)
    else:
        # One at a time, best-ranked first, so that a later start can meet an earlier one.
        for s in _ranked(starts, meeting):
            follow(s)
    problem.forget()
    problem.evaluator.priority.value = 0
    return starts


def _ranked(starts: list, meeting: _Meeting) -> list:
    live = [s for s in starts if not s.status]
    return sorted(live, key=lambda s: len(meeting.ahead[id(s)]))


def guarded_start(problem: Problem, start: StartResult, multiple: bool, options: dict, say=None) -> StartResult:
    """One start through the continuation and single shooting (:func:`run_starts`); its failure
    comes back ``failed`` with the reason."""
    return run_starts(problem, [start], multiple, options, 1, say)[0]


def latin_hypercube(p: int, n: int, seed: int) -> np.ndarray:
    """n points in [0, 1]^p, a seeded Latin hypercube (scipy.stats.qmc)."""
    from scipy.stats import qmc

    if n <= 0:
        return np.empty((0, p))
    return qmc.LatinHypercube(d=p, seed=seed).random(n)
