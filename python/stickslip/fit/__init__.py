"""``stickslip fit SPEC --out DIR``: the FMU's parameters from measured runs, with uncertainties.

Two stages, as robot identification does it (docs/calibration.md):

1. the equation-error stage (:mod:`stickslip.fit.idim`, IDIM-LS): friction and drive
   parameters from the measured motion and the engine's inverse dynamics, no simulation;
2. the output-error stage (:mod:`stickslip.fit.solve`, as DIDIM refines IDIM): weighted
   nonlinear least squares of (model − measured)/σ over every sample, from the user's
   initial point, the first stage's estimate and a seeded Latin hypercube; multiple
   shooting first where every flexible joint's q is measured, then the simulation-error
   cost itself.

The result: each parameter's value and standard error, the correlation matrix, warnings
where the data cannot tell parameters apart, a bound is active or the starts disagree
(:mod:`stickslip.fit.report` writes fit.json, report.md, plots and fitted.toml).

The runs go to a Dask cluster (a LocalCluster of ``workers`` processes by default, or the
scheduler at ``scheduler``, or a ``client`` given; ``workers=0`` runs them in this process).
"""

from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..motion import motor_joints
from .problem import Evaluator, Problem, payload_of
from .solve import (
    StartResult,
    guarded_start,
    jacobian,
    latin_hypercube,
    refine,
    run_starts,
    segment_lengths,
)
from .spec import FitSpec, FitSpecError, load
from .start import START_SIGMAS, start_unknowns

CORRELATED = 0.95  # |correlation| above which two parameters are reported as not separable
# |correlation| at or above which the fit is not trusted: the data fix one combination of the two
# and next to nothing across it, a valley so narrow that its curvature, not the linearization,
# sets where along it the estimate lies (measured: reference draw 104 of the identification
# benchmark, mu_k[1] and b_v[1] at -1.000, b_v[1] 5.5 standard errors from the truth).
UNIDENTIFIABLE = 0.999
SAME_COST = 0.95  # starts whose cost the data cannot reject at this level are "of similar cost"
# The FMU's own numerical error: the answer is redone at a tenfold tighter error_tolerance
# while the standard errors move by more than SE_STEP_CHANGE with a 3x Jacobian step, or a
# Gauss-Newton step at the tighter tolerance moves an estimate by more than SHIFT_LIMIT
# standard errors; at most TIGHTENINGS times, never below TOLERANCE_FLOOR.
SE_STEP_CHANGE = 0.10
SHIFT_LIMIT = 0.3
TIGHTENINGS = 2
TOLERANCE_FLOOR = 1e-8
# An answer is not a minimum when a point its profiles evaluated lies lower by more than
# NOT_A_MINIMUM σ̂² in the cost ½Σr² (one standard error from a parabola's bottom costs ½σ̂²: this
# is a fifth of that); the fit then goes on from that point, at most FROM_LOWER times.
NOT_A_MINIMUM = 0.1
FROM_LOWER = 2


class FitError(RuntimeError):
    """A fit that could not run to the end (no start gave a finite cost)."""


def fit(
    spec, out=None, workers: int | None = None, scheduler: str | None = None, client=None, base_dir=None, progress=None
) -> dict:
    """Fits the SPEC (a TOML path or a dict); writes DIR ``out`` when given; returns the
    content of fit.json (plus ``"_internal"``, the arrays the report uses). ``progress``:
    a function of one line of text, called per stage and start (the CLI prints them)."""
    t0 = time.perf_counter()
    say = progress or (lambda line: None)
    spec = spec if isinstance(spec, FitSpec) else load(spec, base_dir)
    fmu_data = Path(spec.fmu).read_bytes()
    from ..fmu import content_hash, unpacked

    digest = content_hash(fmu_data)
    # The cluster starts, and its workers unpack the FMU, while the experiments' start states
    # are read here (a SPEC that does not load has started nothing).
    connecting = None
    if client is None and workers != 0:
        from ..cluster import Connecting

        connecting = Connecting(scheduler, workers, lambda c: Evaluator.send_fmu(c, fmu_data, digest))
    try:
        md = spec.model_description
        flexible = sorted(int(v.name[8:-1]) for v in md.modelVariables if v.name.startswith("q_start["))
        known = {e.name: e.initial for e in spec.estimates}
        payloads = [payload_of(e, md, unpacked(fmu_data, digest), known) for e in spec.experiments]
    except BaseException:
        if connecting is not None:
            connecting.close()
        raise
    for e, p in zip(spec.experiments, payloads, strict=True):
        say(f"fit: experiment {e.name!r} starts " + _start_text(e, p))
        say(f"fit: experiment {e.name!r}: derivative filter: {_filter_text(e)}")
    own_cluster = None
    if connecting is not None:
        client, own_cluster = connecting.result()
    model = spec  # the SPEC's own estimates: the model's parameters, without the start unknowns
    if spec.options["fit_start"] and spec.options["stage"] != "equation-error":
        unknowns = [u for e, p in zip(spec.experiments, payloads, strict=True) for u in start_unknowns(e, p.start)]
        if unknowns:
            spec = replace(spec, estimates=[*spec.estimates, *unknowns])
            say(f"fit: the start state of the joints moving at the first sample is fitted too: {_names(unknowns)}")
    try:
        _probe(model, payloads, fmu_data, digest)
        evaluator = Evaluator(fmu_data, digest, payloads, client, fmu_sent=connecting is not None)
        problem = Problem(spec, evaluator)
        # Multiple shooting restarts each segment from the measured q, q' of every flexible and
        # motor joint (a rotor turned to carry its link's load: stickslip.fit.start).
        segments = problem.segments(spec.options["segment"])
        shooting = spec.options["shooting"]
        if spec.options["horizon"] is not None and any(s is None for s in segments):
            raise FitSpecError(
                f"{spec.source}: [options] horizon needs every flexible and motor joint's q measured "
                f"(q[{'], q['.join(map(str, flexible))}]) in every experiment, to restart the runs from it"
            )
        if shooting == "multiple" and any(s is None for s in segments):
            motors = motor_joints(md)
            raise FitSpecError(
                f'{spec.source}: [options] shooting = "multiple" needs every flexible and motor joint\'s q measured '
                f"(q[{'], q['.join(map(str, flexible))}]) in every experiment"
                + (f" (motor drives on joints {motors}: their rotors start from the link's)" if motors else "")
            )
        multiple = shooting == "multiple" or (shooting == "auto" and all(s is not None for s in segments))
        initial = {e.name: e.initial for e in spec.estimates}
        starts = [StartResult(dict(initial), "initial")]
        tunable = {
            v.name: float(v.start)
            for v in md.modelVariables
            if v.causality == "parameter" and v.type == "Real" and v.start is not None
        }
        from . import idim

        errors = {}
        try:
            idim_theta, notes = idim.estimate(model, unpacked(fmu_data, digest), flexible, initial, tunable, errors)
        except (RuntimeError, OSError, KeyError, ValueError) as e:
            idim_theta, notes = {}, [f"equation-error stage failed, its start left out: {e}"]
        for note in notes:
            say(f"fit: {note}")
        if spec.options["stage"] == "equation-error":
            result = _equation_error_result(spec, problem, idim_theta, errors, notes, evaluator, t0, say)
            result["method"]["start"] = {
                e.name: _start_text(e, p) for e, p in zip(spec.experiments, payloads, strict=True)
            }
            result["method"]["derivatives"] = {e.name: _filter_text(e) for e in spec.experiments}
            result["_internal"]["payloads"] = payloads
            if problem.horizon is not None:
                result["_internal"]["segments"] = problem.segments(problem.horizon)
            if out is not None:
                from .report import write

                write(result, spec, Path(out))
            return result
        dropped = []
        if idim_theta:
            at = {n: idim_theta.get(n, initial[n]) for n in initial}
            reason = _impossible(spec.estimates, at)
            if reason is None:
                z = problem.transform.z(list(at.values()))
                starts.append(StartResult(problem.transform.named(problem.transform.theta(z)), "equation-error"))
            else:
                dropped.append(StartResult(at, "equation-error", status="dropped", message=reason))
                say(f"fit: start 'equation-error' dropped: {reason}")
        # The hypercube spans the model's parameters; the start unknowns start as read.
        read = problem.transform.z(list(initial.values()))
        tied = np.array([e.start_of is not None for e in spec.estimates])
        for k, z in enumerate(latin_hypercube(len(initial), spec.options["starts"] - 1, spec.options["seed"])):
            z = np.where(tied, read, z)
            starts.append(StartResult(problem.transform.named(problem.transform.theta(z)), f"latin hypercube {k + 1}"))
        threads = max(1, min(len(starts), _cores(client)))
        say(
            f"fit: {len(starts)} start(s), "
            + ("multiple shooting in a continuation of segment lengths, then " if multiple else "")
            + (
                f"the prediction over a {spec.options['horizon']:g} s horizon"
                if spec.options["horizon"]
                else "single shooting"
            )
        )

        results = run_starts(problem, starts, multiple, spec.options, threads, say) + dropped
        finite = [s for s in results if math.isfinite(s.cost) and s.z is not None]
        if not finite:
            why = "no start reached a finite cost: " + "; ".join(f"{s.origin}: {s.message}" for s in results)
            _give_up(spec, out, why, results, problem, notes, evaluator, t0)
        best = min(finite, key=lambda s: s.cost)
        moved = []
        for attempt in range(FROM_LOWER + 1):
            try:
                result = _summarize(spec, problem, best, results, multiple, notes, evaluator, t0, say, moved)
            except Exception as e:  # noqa: BLE001 -- what finished is written, with why the rest did not
                why = f"the uncertainty of the best start failed: {type(e).__name__}: {' '.join(str(e).split())}"
                _give_up(spec, out, why, results, problem, notes, evaluator, t0, best, traceback.format_exc())
            lower = result["_internal"]["lower"]
            # A start the evaluation budget stopped ([options] max_evaluations) is not gone on from:
            # the user's budget holds; its answer is reported as not a minimum.
            if lower is None or attempt == FROM_LOWER or best.status != "converged":
                break
            # Not a minimum along a profile: single shooting goes on from the lower point, at the
            # answer's error tolerance.
            at = result["_internal"]["problem"]
            origin = f"the lower point on a profile of {best.origin!r}"
            say(
                f"fit: the answer of start {best.origin!r} (cost {best.cost:.6g}) is not a minimum: "
                f"going on from {origin} (cost {lower[0]:.6g})"
            )
            again = guarded_start(at, StartResult(at.transform.named(lower[1]), origin), False, spec.options, say)
            results.append(again)
            if not (math.isfinite(again.cost) and again.z is not None and again.cost < best.cost):
                break
            moved.append(
                f"start {best.origin!r} ended at cost {best.cost:.6g}, which is not a minimum along its profiles; "
                f"the fit went on from a lower point on them to cost {again.cost:.6g}"
            )
            best = again
        result["method"]["start"] = {e.name: _start_text(e, p) for e, p in zip(spec.experiments, payloads, strict=True)}
        result["method"]["derivatives"] = {e.name: _filter_text(e) for e in spec.experiments}
        result["_internal"]["payloads"] = payloads
        if problem.horizon is not None:
            result["_internal"]["segments"] = problem.segments(problem.horizon)
    finally:
        if own_cluster is not None:
            client.close()
            own_cluster.close()
    if out is not None:
        from .report import write

        write(result, spec, Path(out))
    return result


def _names(estimates) -> str:
    return ", ".join(e.name for e in estimates)


def _impossible(estimates, theta: dict) -> str | None:
    """Why θ cannot be a start (a value that is not a number, or outside its bounds), or None."""
    for e in estimates:
        v = theta[e.name]
        if not math.isfinite(v):
            return f"{e.name} = {v} is not a number"
        if not e.low <= v <= e.high:
            return f"{e.name} = {v:.6g} lies outside its bounds [{e.low:g}, {e.high:g}]"
    return None


def _give_up(spec, out, why: str, results: list, problem, notes, evaluator, t0, best=None, trace=None):
    """Writes what finished (fit.json, report.md; no fitted.toml: there is no answer to replay)
    into ``out`` and raises :class:`FitError` with ``why``: the starts, each with its cost or the
    reason it ended without one, and the best start's parameters without standard errors."""
    transform = problem.transform
    record = {
        "trusted": False,
        "verdict": f"FAILED: {why}",
        "error": why,
        "parameters": (
            {
                n: {"value": v, "std_error": None, "initial": e.initial, "bounds": [e.low, e.high]}
                for (n, v), e in zip(transform.named(transform.theta(best.z)).items(), spec.estimates, strict=True)
            }
            if best is not None
            else {}
        ),
        "n_evaluations": evaluator.runs,
        "wall_s": time.perf_counter() - t0,
        "warnings": [f"the fit did not finish: {why}"],
        "starts": [_start_json(s, transform) for s in results],
        "method": {"equation_error_stage": notes},
        "failed_runs": _failed_runs(problem.failures),
    }
    if out is not None:
        from .report import write_failure

        write_failure(record, spec, Path(out), trace)
    raise FitError(why + (f" (what finished: {Path(out) / 'fit.json'})" if out is not None else ""))


def _start_json(s, transform) -> dict:
    return {
        "origin": s.origin,
        "initial": s.initial,
        "cost": s.cost if math.isfinite(s.cost) else None,
        "multiple_shooting_cost": s.ms_cost,
        "cost_at_start": s.start_cost if math.isfinite(s.start_cost) else None,
        "cost_after_continuation": s.continuation_cost,
        "parameters": transform.named(transform.theta(s.z)) if s.z is not None else None,
        "status": s.status,
        "message": s.message,
        "iterations": s.nfev,
    }


def _failed_runs(failures: list) -> dict:
    """The runs the FMU refused or discarded, in an order that does not depend on which thread
    or worker met them first."""
    ordered = sorted(failures, key=lambda f: (f["experiment"], f["status"], f["message"]))
    return {
        "count": len(ordered),
        "by_status": {st: sum(f["status"] == st for f in ordered) for st in sorted({f["status"] for f in ordered})},
        "first": ordered[:5],
    }


def _equation_error_result(spec, problem, theta: dict, errors: dict, notes: list, evaluator, t0: float, say) -> dict:
    """The fit's result where ``[options] stage = "equation-error"``: the equation-error
    stage's estimates (:mod:`stickslip.fit.idim`: the torques' or slip equations' linear least
    squares) and standard errors are the answer; the FMU runs once at them (over the horizon
    where one is set) for the residuals, the goodness of fit and the plots, which show how the
    model with these values follows the measured motion, but do not decide the estimate."""
    from .uncertainty import goodness_of_fit

    names = [e.name for e in spec.estimates]
    missing = [n for n in names if not math.isfinite(theta.get(n, math.nan))]
    if len(missing) == len(names):
        raise FitError(
            "stage = 'equation-error': the equation-error stage estimated none of the parameters: "
            + "; ".join(n for n in notes)
        )
    # What is reported is what the replay runs and fitted.toml holds: an estimate outside its
    # physical bounds is taken at the bound it crossed, and says so.
    raw = {e.name: theta[e.name] if e.name not in missing else e.initial for e in spec.estimates}
    values = np.array([min(max(raw[e.name], e.low), e.high) for e in spec.estimates])
    z = problem.transform.z(values)
    values = problem.transform.theta(z)
    runs = problem.runs([z])[0]
    r = problem.residual(runs)
    cost = 0.5 * float(r @ r)
    channels = [(c.sigma, c.resolution) for e in spec.experiments for c in e.channels]
    gof = goodness_of_fit(
        r, problem.blocks(), [(n, *c) for n, c in zip(problem.channel_names(), channels, strict=True)], 0
    )
    warnings = [
        f"{n} was not estimated by the equation-error stage (see its notes): reported at its initial value"
        for n in missing
    ]
    params = {}
    for e, v in zip(spec.estimates, values, strict=True):
        se = errors.get(e.name, math.inf) if e.name not in missing else math.inf
        at_bound = bool(min(v - e.low, e.high - v) <= 1e-6 * (e.high - e.low))
        params[e.name] = {
            "value": float(v),
            "std_error": float(se),
            "std_error_classical": float(se),
            "std_error_sandwich": math.nan,
            "initial": e.initial,
            "bounds": [e.low, e.high],
            "at_bound": at_bound,
            "scale": e.scale,
        }
        if not e.low <= raw[e.name] <= e.high:
            warnings.append(
                f"{e.name}: the equation-error estimate {raw[e.name]:.6g} lies outside its bounds [{e.low:g}, "
                f"{e.high:g}]; reported, replayed and written to fitted.toml at {v:.6g}, where its standard error "
                "does not describe it (a model error the least squares absorbed: docs/calibration.md)"
            )
    residual_rms = _residual_rms(spec, runs)
    trusted = not warnings
    level = math.sqrt(gof["reduced_chi_square"]) if gof["reduced_chi_square"] > 0 else math.nan
    shooting = f"over a {problem.horizon:g} s horizon" if problem.horizon is not None else "as one run"
    verdict = (
        "equation-error estimate (the measured torques' or slip equations' linear least squares)"
        + ("" if trusted else ", NOT COMPLETE: see the warnings")
        + f"; replayed {shooting}, the residuals are {level:.3g}× the stated noise"
    )
    say(f"fit: equation-error stage is the answer; its replay's cost {cost:.6g} ({evaluator.runs} FMU runs)")
    correlation = np.eye(len(names))
    for a, x in enumerate(names):
        for b, y in enumerate(names):
            if (x, y) in errors and x not in missing and y not in missing:
                correlation[a, b] = errors[(x, y)]
    return {
        "trusted": trusted,
        "verdict": verdict,
        "parameters": params,
        "correlation": {"names": names, "matrix": correlation.tolist()},
        "cost": cost,
        "goodness_of_fit": _goodness_json(gof),
        "rms_normalized_residual": float(np.sqrt(np.mean(r**2))),
        "residual_rms": residual_rms,
        "n_evaluations": evaluator.runs,
        "wall_s": time.perf_counter() - t0,
        "converged": True,
        "warnings": warnings,
        "starts": [],
        "method": {
            "stage": "equation-error",
            "shooting": f"equation-error; replayed {shooting}",
            "horizon_s": problem.horizon,
            "segment_s": None,
            "loss": "linear",
            "absolute_sigma": True,
            "sigma_scale": 1.0,
            "error_tolerance": problem.error_tolerance,
            "error_tolerance_checks": [],
            "segment_lengths_s": None,
            "diff_step": None,
            "sandwich_lag_windows": {},
            "noise": _noise(problem, spec),
            "std_error_change_with_3x_step": None,
            "condition_number": None,
            "samples": len(r),
            "equation_error_stage": notes,
            "jacobian_notes": [],
        },
        "dropped_rows": {e.name: e.dropped_rows for e in spec.experiments if e.dropped_rows},
        "failed_runs": _failed_runs(problem.failures),
        "_internal": {
            "z": z,
            "theta": values,
            "runs": runs,
            "covariance": np.diag([p["std_error"] ** 2 for p in params.values()]),
        },
    }


def _residual_rms(spec, runs) -> dict:
    """The rms of model − measured per channel ("experiment:output" with several experiments)."""
    out = {}
    for ex, res in zip(spec.experiments, runs, strict=True):
        for k, c in enumerate(ex.channels):
            key = c.output if len(spec.experiments) == 1 else f"{ex.name}:{c.output}"
            out[key] = float(np.sqrt(np.mean((res.values[:, k] - c.values) ** 2)))
    return out


def _noise(problem, spec) -> dict:
    """Each channel's noise model: its sigma and the encoder's count (given or detected)."""
    channels = [c for e in spec.experiments for c in e.channels]
    return {
        name: {"sigma": c.sigma, "resolution": c.resolution, "resolution_detected": c.resolution_detected}
        for name, c in zip(problem.channel_names(), channels, strict=True)
    }


def _goodness_json(gof: dict) -> dict:
    """:func:`stickslip.fit.uncertainty.goodness_of_fit`'s result as fit.json holds it."""
    return {
        **{k: v for k, v in gof.items() if k != "channels"},
        "channels": {c.name: {k: v for k, v in c.__dict__.items() if k != "name"} for c in gof["channels"]},
    }


def _filter_text(experiment) -> str:
    """The experiment's derivative filter, for the console and the report."""
    from .filtering import describe

    t = experiment.time
    text = describe(experiment.derivatives, float(np.median(np.diff(t))), len(t))
    if experiment.filtered_inputs:
        text += f"; through it also the measured inputs {', '.join(experiment.filtered_inputs)}"
    return text


def _start_text(experiment, payload) -> str:
    """How a run of the experiment starts, for the console and the report."""
    if experiment.start == "rest":
        return "at the FMU's own start (start = 'rest': spring-driven joints at rest at q = q*)"
    if experiment.start == "parameters":
        return "from the start values in its parameters"
    if payload.start is None:
        return "at the FMU's own start (no spring-driven joint)"
    return "from its first samples: " + payload.start.describe()


def _probe(spec, payloads: list, fmu_data: bytes, digest: str) -> None:
    """Each experiment's first step with its known parameters and settings, and the estimated
    ones at their initial values or else the FMU's own: what the FMU refuses with both is
    the SPEC's problem, not a point of the fit, and is reported as such."""
    from dataclasses import replace

    from .runner import run

    settings = {} if spec.options["error_tolerance"] is None else {"error_tolerance": spec.options["error_tolerance"]}
    initial = {e.name: e.initial for e in spec.estimates}
    for e, payload in zip(spec.experiments, payloads, strict=True):
        short = replace(payload, time=payload.time[:2])
        result = run(digest, short, {**initial, **settings}, fmu_data=fmu_data)
        if result.status != "ok":  # the initial point may be refused; the known values may not
            result = run(digest, short, settings, fmu_data=fmu_data)
        if result.status != "ok":
            raise FitSpecError(
                f"{spec.source}: experiment {e.name!r}: the FMU {result.status} its first step with the known "
                f"parameters and settings: {' '.join(result.message.split())}"
            )


def _cores(client) -> int:
    if client is None:
        return 1
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001 -- an unreachable scheduler answers later, with a clear error
        return 1


@dataclass
class Optimum:
    """What the fit knows at its answer z: residuals, J in θ's units, the uncertainty, and how
    much the standard errors move with a 3x Jacobian step."""

    z: np.ndarray
    r: np.ndarray
    J: np.ndarray
    unc: object
    se_change: float
    notes: list


def _at_optimum(problem: Problem, z, options: dict) -> Optimum:
    from .uncertainty import rho_prime, uncertainty

    names = [e.name for e in problem.spec.estimates]
    r = problem.residuals([z])[0]
    to_theta = np.linalg.inv(problem.transform.jacobian(z))
    Jz, notes = jacobian(problem, z, r, None, options["diff_step"])
    # The Jacobian again with a 3x larger step: standard errors that depend on the step
    # would mean the integration's noise, not the data, set them.
    J3z, _ = jacobian(problem, z, r, None, 3.0 * options["diff_step"])
    weights = None if options["loss"] == "linear" else np.sqrt(rho_prime(r, options["loss"], options["f_scale"]))
    J, J3 = Jz @ to_theta, J3z @ to_theta
    clusters = problem.clusters()
    unc = uncertainty(J, r, problem.blocks(), names, options["absolute_sigma"], weights, clusters)
    unc3 = uncertainty(J3, r, problem.blocks(), names, options["absolute_sigma"], weights, clusters)
    with np.errstate(invalid="ignore", divide="ignore"):
        change = np.abs(unc3.std_error_classical / unc.std_error_classical - 1.0)
    finite = change[np.isfinite(change)]
    return Optimum(z, r, J, unc, float(finite.max()) if len(finite) else math.nan, notes)


def _numerically_converged(problem: Problem, opt: Optimum, options: dict, say) -> tuple:
    """(problem, optimum, record): the answer at an error_tolerance the estimates no longer
    notice. A tenfold tighter tolerance gets one Gauss-Newton step from the answer; where it
    moves an estimate by more than SHIFT_LIMIT standard errors from where the step at this
    tolerance would, or the standard errors move
    by more than SE_STEP_CHANGE with a 3x Jacobian step, the fit goes on from the answer at
    the tighter tolerance, and the check is repeated there."""
    default = _fmu_tolerance(problem.spec)
    record = []
    for _ in range(TIGHTENINGS):
        tol = problem.error_tolerance if problem.error_tolerance is not None else default
        if tol is None or tol / 10.0 < TOLERANCE_FLOOR:
            break
        tighter = problem.with_tolerance(tol / 10.0)
        r = tighter.residuals([opt.z])[0]
        Jz, _ = jacobian(tighter, opt.z, r, None, options["diff_step"])
        J = Jz @ np.linalg.inv(problem.transform.jacobian(opt.z))
        # Where the answer would go at the tighter tolerance, against where it would go at this
        # one: a trust region stops short of the exact minimum of a cost this rough, so the
        # Gauss-Newton step at the same tolerance is not zero, and only the difference is the
        # FMU's numerical error.
        step = np.linalg.lstsq(opt.J, opt.r, rcond=None)[0] - np.linalg.lstsq(J, r, rcond=None)[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            shift = np.abs(step) / opt.unc.std_error
        shift = float(np.nanmax(np.where(np.isfinite(shift), shift, np.nan))) if np.any(np.isfinite(shift)) else 0.0
        entry = {
            "error_tolerance": tol,
            "std_error_change_with_3x_step": opt.se_change,
            "shift_at_tenfold_tighter_se": shift,
            "shift_at_tenfold_tighter": [float(x) for x in np.abs(step)],
        }
        previous = record[-1]["std_error_change_with_3x_step"] if record else None
        refit, not_reduced = _tighten(opt.se_change, previous, shift)
        if not_reduced:
            entry["step_change_not_reduced"] = True
        record.append(entry)
        if not refit:
            break
        say(
            f"fit: at error_tolerance {tol:g} the estimates move by {shift:.2g} standard errors at a tenfold tighter "
            f"one (standard errors {100 * opt.se_change:.0f} % with a 3x Jacobian step): refitting at {tol / 10:g}"
        )
        # From the answer, with the Jacobian step its single shooting settled on (``diff_step``
        # here): the finer steps were tried there and lowered the cost by less than ½, and at
        # the tighter tolerance they would again (measured on the calibration example: 0.003
        # for 14 runs at 5e-5, bench_fit 0.002 for 8).
        res, _ = refine(tighter, opt.z, options, factors=(1.0,))
        problem = tighter
        opt = _at_optimum(problem, res.x, options)
        entry["refitted"] = True
    return problem, opt, record


def _moving_start_warnings(spec, payloads: list) -> list:
    """Where the model does not follow the data and an experiment starts with a joint in motion:
    that joint's start state is read off its first samples by the derivative filter, and its
    error alone can make the run drift from the data (docs/calibration.md, "The start")."""
    out = []
    for e, payload in zip(spec.experiments, payloads, strict=True):
        start = payload.start
        moving = [i for i, how in (start.how if start is not None else {}).items() if how.startswith("moving")]
        if moving:
            said = "; ".join(f"joint {i} {start.how[i]}" for i in moving)
            out.append(
                f"experiment {e.name!r} starts with joint(s) {', '.join(map(str, moving))} in motion ({said}): "
                "a start state read off filtered samples is uncertain, and its error alone can make the run drift "
                "from the data and end the fit away from the truth. Fit it with the parameters ([options] fit_start = "
                "true, the default); where the run starts from the FMU's own start (at rest, the springs relaxed) "
                'set start = "rest" in its [[experiment]]; else begin the data where the arm stands still'
            )
    return out


def _tighten(se_change: float, previous: float | None, shift: float) -> tuple:
    """(refit, not_reduced) of a tolerance check: refit at the tenfold tighter tolerance where a
    Gauss-Newton step there moves an estimate by more than SHIFT_LIMIT standard errors, or where
    the standard errors move by more than SE_STEP_CHANGE with a 3x Jacobian step and that comes
    from the FMU's noise. It does only where the last tightening shrank it to half or less
    (``previous``: the change at the tolerance before, None at the first check): where it did
    not (``not_reduced``), the cost is simply not a parabola over the step, and tightening again
    buys nothing (measured on the identification benchmark's reference arm: 50 % at 5e-4 and at
    5e-5, the refit at 5e-6 moving the estimates by 0.004 standard errors)."""
    dependent = se_change > SE_STEP_CHANGE
    noise = dependent and (previous is None or se_change <= 0.5 * previous)
    return bool(noise or shift > SHIFT_LIMIT), bool(dependent and not noise)


def _fmu_tolerance(spec) -> float | None:
    for v in spec.model_description.modelVariables:
        if v.name == "error_tolerance" and v.start is not None:
            return float(v.start)
    return None


def _numerical_part(tightening: list, std_error) -> np.ndarray:
    """Per parameter, the FMU's numerical error of the estimate where it exceeds the statistical
    standard error, else 0: the move of the estimate between the last two error tolerances
    tried (a Gauss-Newton step at each, :func:`_numerically_converged`). The error at the
    tighter tolerance is at most that move where halving it at least halves the error
    (any convergent error control), so the move stands for it, as a standard uncertainty of
    its own, independent of the noise: the reported standard error is their root sum of squares."""
    out = np.zeros(len(std_error))
    if not tightening:
        return out
    shift = np.asarray(tightening[-1]["shift_at_tenfold_tighter"], dtype=np.float64)
    with np.errstate(invalid="ignore"):
        over = np.isfinite(std_error) & (shift > std_error)
    out[over] = shift[over]
    return out


def _summarize(
    spec,
    problem: Problem,
    best: StartResult,
    results: list,
    multiple: bool,
    notes: list,
    evaluator,
    t0: float,
    say,
    moved=(),
) -> dict:
    from .profile import Lowest, profiles
    from .uncertainty import LEVEL, goodness_of_fit, misfit_warnings

    # The Jacobian of the uncertainty takes the step single shooting ended with.
    options = dict(spec.options, diff_step=best.step or spec.options["diff_step"])
    transform = problem.transform
    opt = _at_optimum(problem, best.z, options)
    problem, opt, tightening = _numerically_converged(problem, opt, options, say)
    z, r, unc, se_change, jac_notes = opt.z, opt.r, opt.unc, opt.se_change, opt.notes
    cost = 0.5 * float(r @ r)
    channels = [(c.sigma, c.resolution) for e in spec.experiments for c in e.channels]
    gof = goodness_of_fit(
        r, problem.blocks(), [(n, *c) for n, c in zip(problem.channel_names(), channels, strict=True)], len(z)
    )
    say(f"fit: best cost {cost:.6g}; profiles and goodness of fit ({evaluator.runs} FMU runs so far)")
    lowest = Lowest(cost)
    linear = options["loss"] == "linear"
    profile = profiles(problem, transform.theta(z), cost, opt.J, unc, unc.scale, lowest) if linear else {}
    theta = transform.theta(z)
    names = [e.name for e in spec.estimates]
    warnings = list(moved)
    params, start_state = {}, {}
    numerical = _numerical_part(tightening, unc.std_error)
    for j, e in enumerate(spec.estimates):
        span = e.high - e.low
        at_bound = bool(min(theta[j] - e.low, e.high - theta[j]) <= 1e-6 * span)
        prof = profile.get(e.name)
        se = float(unc.std_error[j])
        if prof is not None and math.isfinite(se):
            se = max(se, prof["std_error_profile"])
        statistical = se
        se = math.hypot(se, numerical[j])
        if e.start_of is not None:  # an unknown of the fit, not a parameter of the model
            start_state[e.name] = {
                "value": float(theta[j]),
                "std_error": se,
                "read": e.initial,
                "bounds": [e.low, e.high],
                "at_bound": at_bound,
                "experiment": e.start_of,
                "variable": e.variable,
            }
            if at_bound:
                warnings.append(
                    f"{e.name} = {theta[j]:.6g} sits on a bound of the start state, {START_SIGMAS:g} noise standard "
                    f"deviations of its reading ({e.initial:.8g}) away: the model does not follow the run's first "
                    "samples from any start near them"
                )
            continue
        params[e.name] = {
            "value": float(theta[j]),
            "std_error": se,
            "std_error_statistical": statistical,
            "std_error_numerical": float(numerical[j]),
            "std_error_classical": float(unc.std_error_classical[j]),
            "std_error_sandwich": float(unc.std_error_sandwich[j]),
            "initial": e.initial,
            "bounds": [e.low, e.high],
            "at_bound": at_bound,
            "scale": e.scale,
        }
        if prof is not None:
            params[e.name]["profile"] = {k: v for k, v in prof.items() if k != "runs"}
        if at_bound:
            side = "lower" if theta[j] - e.low <= e.high - theta[j] else "upper"
            warnings.append(
                f"{e.name} = {theta[j]:.6g} sits on its {side} bound: the data may want it beyond "
                f"[{e.low:g}, {e.high:g}], and its standard error does not describe that"
            )
    unidentifiable = []
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            c = unc.correlation[a, b]
            if math.isfinite(c) and abs(c) >= UNIDENTIFIABLE:
                unidentifiable.append((names[a], names[b], float(c)))
            if math.isfinite(c) and abs(c) > CORRELATED:
                warnings.append(
                    f"{names[a]} and {names[b]} are not separately identifiable from these measurements "
                    f"(correlation {c:+.3f}): the data fix a combination of the two"
                )
    for rel, direction in unc.singular:
        combo = " ".join(f"{v:+.2f}·{n}" for n, v in direction.items())
        warnings.append(
            f"J'J is near-singular (relative singular value {rel:.1e}): the direction {combo} "
            "(column-scaled) is not determined by the data"
        )
    last = tightening[-1] if tightening else None
    numerically_limited = [n for n, x in zip(names, numerical, strict=True) if x > 0 and n in params]
    if numerically_limited:
        warnings.append(
            f"the FMU's numerical error moves {', '.join(numerically_limited)} by more than its statistical standard "
            f"error (the estimates moved by {last['shift_at_tenfold_tighter_se']:.2g} standard errors between "
            f"error_tolerance {last['error_tolerance']:g} and {last['error_tolerance'] / 10:g}, the tightest tried): "
            "that move is added to their standard errors (std_error_numerical); set [options] error_tolerance "
            "lower to shrink it"
        )
    elif last is not None and last.get("refitted") and last["shift_at_tenfold_tighter_se"] > SHIFT_LIMIT:
        warnings.append(
            f"the FMU's numerical error still moved the estimates at error_tolerance {last['error_tolerance'] / 10:g} "
            f"(the last check: {last['shift_at_tenfold_tighter_se']:.2g} standard errors); the answer is the fit at "
            "that tolerance, tighter ones were not tried: set [options] error_tolerance lower to check"
        )
    elif last is not None and last.get("step_change_not_reduced"):
        first = tightening[0]
        warnings.append(
            f"the standard errors change by {100 * se_change:.0f} % when the Jacobian's step is tripled, and a tenfold "
            f"tighter error_tolerance did not reduce that ({100 * first['std_error_change_with_3x_step']:.0f} % at "
            f"{first['error_tolerance']:g}, {100 * last['std_error_change_with_3x_step']:.0f} % at "
            f"{last['error_tolerance']:g}): the cost is not a parabola over the step, not the FMU's noise; the "
            "standard errors are uncertain by about that much (a profile gives an interval that does not assume one)"
        )
    elif math.isfinite(se_change) and se_change > SE_STEP_CHANGE:
        warnings.append(
            f"the standard errors change by {100 * se_change:.0f} % when the Jacobian's step is tripled: the "
            "integration noise is not far below the step; tighten error_tolerance"
        )
    misfit = misfit_warnings(gof, options["absolute_sigma"])
    if misfit and not any(e.start_of is not None for e in spec.estimates):
        misfit += _moving_start_warnings(spec, problem.evaluator.payloads)
    warnings = misfit + warnings
    for name, prof in profile.items():
        for side, is_open in zip(("lower", "upper"), prof["open"], strict=True):
            if is_open:
                end = prof["interval_95"][0 if side == "lower" else 1]
                warnings.append(
                    f"{name}: the profile cost stays within the 95 % threshold as far as the walk went on the {side} "
                    f"side ({end:.6g}): the data bound it only weakly there"
                )
    # Another minimum is "of similar cost" when the data cannot reject it: its cost exceeds
    # the best by less than half the chi-square quantile of p degrees of freedom, in units of
    # the noise scale (a likelihood-ratio test at the level SAME_COST).
    from scipy.stats import chi2

    margin = 0.5 * float(chi2.ppf(SAME_COST, len(names))) * unc.scale
    similar = []
    for s in results:
        if s is best or s.z is None or not math.isfinite(s.cost):
            continue
        if s.cost <= best.cost + margin:
            other = transform.theta(s.z)
            apart = [n for j, n in enumerate(names) if abs(other[j] - theta[j]) > 3.0 * max(unc.std_error[j], 1e-300)]
            if apart:
                similar.append((s, apart))
    for s, apart in similar:
        warnings.append(
            f"start {s.origin!r} ended in a different minimum of similar cost ({s.cost:.6g} vs {best.cost:.6g}), "
            f"differing in {', '.join(apart)}: the data do not single out one solution"
        )
    # Minima the data cannot tell apart are part of the answer's uncertainty: each parameter's
    # distance to the farthest of them joins its standard error (root sum of squares).
    spread = np.zeros(len(names))
    for s, _ in similar:
        spread = np.maximum(spread, np.abs(transform.theta(s.z) - theta))
    for j, name in enumerate(names):
        entry = params.get(name) or start_state[name]
        entry["std_error_minima"] = float(spread[j])
        entry["std_error"] = math.hypot(entry["std_error"], spread[j])
    lower = None
    if lowest.theta is not None and lowest.cost < cost - NOT_A_MINIMUM * unc.scale:
        lower = (lowest.cost, lowest.theta)
        warnings.append(
            f"the answer is not a minimum of its own cost: a point its profiles evaluated has cost {lowest.cost:.6g} "
            f"against {cost:.6g} ("
            + ", ".join(f"{n} = {v:.6g}" for n, v in zip(names, lowest.theta, strict=True))
            + ")"
        )
    runs = problem.runs([z])[0]
    residual_rms = _residual_rms(spec, runs)
    m = len(r)
    failures = problem.failures
    trusted = not misfit and not similar and not numerically_limited and lower is None and not unidentifiable
    if misfit:
        verdict = "NOT TRUSTED: " + misfit[0].split(":")[0] + " — the model does not follow the data (see the warnings)"
    elif similar:
        verdict = "NOT UNIQUE: another start ended in a different minimum the data cannot reject"
    elif lower is not None:
        verdict = "NOT A MINIMUM: a point along a profile has a lower cost (see the warnings)"
    elif unidentifiable:
        a, b, c = max(unidentifiable, key=lambda x: abs(x[2]))
        verdict = (
            f"NOT IDENTIFIABLE: {a} and {b} have correlation {c:+.4f}, the data fix only a combination of the "
            "two; their standard errors, taken from a valley that narrow, are not reliable (fix one of them, or "
            "measure a motion that separates them)"
        )
    elif numerically_limited:
        verdict = (
            "NOT TRUSTED: the FMU's numerical error, not the data, limits "
            + ", ".join(numerically_limited)
            + " (their standard errors include it)"
        )
    elif gof["p_value"] >= LEVEL:
        verdict = f"the residuals are what the noise model says (chi-square p = {gof['p_value']:.2g})"
    else:
        level = math.sqrt(gof["reduced_chi_square"])
        verdict = (
            f"no structure in the residuals beyond the noise, whose level is {level:.3g}× the stated one"
            f" (reduced chi-square {gof['reduced_chi_square']:.4g}, p = {gof['p_value']:.2g})"
        )
    return {
        "trusted": trusted,
        "verdict": verdict,
        "parameters": params,
        "start_state": start_state,
        "correlation": {"names": names, "matrix": np.round(unc.correlation, 12).tolist()},
        "cost": cost,
        "goodness_of_fit": _goodness_json(gof),
        "rms_normalized_residual": float(np.sqrt(np.mean(r**2))),
        "residual_rms": residual_rms,
        "n_evaluations": evaluator.runs,
        "jacobian_columns": {"runs with sensitivities": evaluator.jacobians, **problem.columns},
        "wall_s": time.perf_counter() - t0,
        "converged": best.status == "converged",
        "warnings": warnings,
        "starts": [_start_json(s, transform) for s in results],
        "method": {
            "shooting": (
                f"multiple, then over a {problem.horizon:g} s horizon"
                if problem.horizon is not None
                else "multiple, then single"
                if multiple
                else "single"
            ),
            "horizon_s": problem.horizon,
            "segment_s": options["segment"] if multiple else None,
            "loss": options["loss"],
            "absolute_sigma": options["absolute_sigma"],
            "sigma_scale": unc.scale,
            "error_tolerance": problem.error_tolerance,
            "error_tolerance_checks": tightening,
            "segment_lengths_s": segment_lengths(problem, options["segment"]) if multiple else None,
            "diff_step": options["diff_step"],
            "sandwich_lag_windows": dict(zip(problem.channel_names(), unc.lags, strict=False)),
            "noise": _noise(problem, spec),
            "std_error_change_with_3x_step": se_change,
            "condition_number": unc.condition,
            "samples": m,
            "equation_error_stage": notes,
            "jacobian_notes": jac_notes,
        },
        "dropped_rows": {e.name: e.dropped_rows for e in spec.experiments if e.dropped_rows},
        "failed_runs": _failed_runs(failures),
        "_internal": {
            "z": z,
            "theta": theta,
            "runs": runs,
            # the numerical part is independent of the statistical one: added on the diagonal
            "covariance": unc.covariance + np.diag(numerical**2 + spread**2),
            "lower": lower,
            "problem": problem,
        },
    }


__all__ = ["FitError", "FitSpecError", "fit", "load"]
