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
from pathlib import Path

import numpy as np

from ..motion import motor_joints
from .problem import Evaluator, Problem, measured_segments, payload_of
from .solve import StartResult, jacobian, latin_hypercube, run_starts, uncertainty
from .spec import FitSpec, FitSpecError, load

CORRELATED = 0.95  # |correlation| above which two parameters are reported as not separable
SAME_COST = 0.95  # starts whose cost the data cannot reject at this level are "of similar cost"


class FitError(RuntimeError):
    """A fit that could not run to the end (no start gave a finite cost)."""


def fit(spec, out=None, workers: int | None = None, scheduler: str | None = None, client=None, base_dir=None) -> dict:
    """Fits the SPEC (a TOML path or a dict); writes DIR ``out`` when given; returns the
    content of fit.json (plus ``"_internal"``, the arrays the report uses)."""
    t0 = time.perf_counter()
    spec = spec if isinstance(spec, FitSpec) else load(spec, base_dir)
    fmu_data = Path(spec.fmu).read_bytes()
    from ..fmu import content_hash, unpacked

    digest = content_hash(fmu_data)
    md = spec.model_description
    flexible = sorted(int(v.name[8:-1]) for v in md.modelVariables if v.name.startswith("q_start["))
    payloads = [payload_of(e) for e in spec.experiments]
    own_cluster = None
    if client is None and workers != 0:
        from ..cluster import connect

        client, own_cluster = connect(scheduler, workers)
    try:
        _probe(spec, payloads, fmu_data, digest)
        evaluator = Evaluator(fmu_data, digest, payloads, client)
        # Multiple shooting restarts each segment from the measured q, q' of every flexible
        # joint; a motor drive's rotor state (theta_m, omega_m) is not measured that way.
        motors = motor_joints(md)
        segments = [
            None if motors else measured_segments(e, spec.options["segment"], flexible) for e in spec.experiments
        ]
        shooting = spec.options["shooting"]
        if shooting == "multiple" and any(s is None for s in segments):
            raise FitSpecError(
                f'{spec.source}: [options] shooting = "multiple" needs every flexible joint\'s q measured '
                f"(q[{'], q['.join(map(str, flexible))}]) in every experiment, and no motor drives"
                + (f" (this FMU has them on joints {motors})" if motors else "")
            )
        multiple = shooting == "multiple" or (shooting == "auto" and all(s is not None for s in segments))
        problem = Problem(spec, evaluator, segments)
        initial = {e.name: e.initial for e in spec.estimates}
        starts = [StartResult(dict(initial), "initial")]
        tunable = {
            v.name: float(v.start)
            for v in md.modelVariables
            if v.causality == "parameter" and v.type == "Real" and v.start is not None
        }
        from . import idim

        try:
            idim_theta, notes = idim.estimate(spec, unpacked(fmu_data, digest), flexible, initial, tunable)
        except (RuntimeError, OSError, KeyError, ValueError) as e:
            idim_theta, notes = {}, [f"equation-error stage failed, its start left out: {e}"]
        if idim_theta:
            z = problem.transform.z([idim_theta.get(n, initial[n]) for n in initial])
            starts.append(StartResult(problem.transform.named(problem.transform.theta(z)), "equation-error"))
        for k, z in enumerate(latin_hypercube(len(initial), spec.options["starts"] - 1, spec.options["seed"])):
            starts.append(StartResult(problem.transform.named(problem.transform.theta(z)), f"latin hypercube {k + 1}"))
        threads = max(1, min(len(starts), _cores(client)))
        results = run_starts(problem, starts, multiple, spec.options, threads)
        finite = [s for s in results if math.isfinite(s.cost) and s.z is not None]
        if not finite:
            raise FitError("no start reached a finite cost: " + "; ".join(s.message for s in results))
        best = min(finite, key=lambda s: s.cost)
        result = _summarize(spec, problem, best, results, multiple, notes, evaluator, t0)
    finally:
        if own_cluster is not None:
            client.close()
            own_cluster.close()
    if out is not None:
        from .report import write

        write(result, spec, Path(out))
    return result


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


def _summarize(
    spec, problem: Problem, best: StartResult, results: list, multiple: bool, notes: list, evaluator, t0: float
) -> dict:
    options = spec.options
    transform = problem.transform
    z = best.z
    r = problem.residuals([z], "single")[0]
    J, jac_notes = jacobian(problem, z, r, "single", options["diff_step"])
    unc = uncertainty(problem, z, r, J, options)
    # The Jacobian again with a 3x larger step: standard errors that depend on the step
    # would mean the integration's noise, not the data, set them.
    J3, _ = jacobian(problem, z, r, "single", 3.0 * options["diff_step"])
    unc3 = uncertainty(problem, z, r, J3, options)
    with np.errstate(invalid="ignore", divide="ignore"):
        change = np.abs(unc3.std_error / unc.std_error - 1.0)
    finite = change[np.isfinite(change)]
    se_change = float(finite.max()) if len(finite) else math.nan
    theta = transform.theta(z)
    names = [e.name for e in spec.estimates]
    warnings = []
    params = {}
    for j, e in enumerate(spec.estimates):
        span = e.high - e.low
        at_bound = bool(min(theta[j] - e.low, e.high - theta[j]) <= 1e-6 * span)
        params[e.name] = {
            "value": float(theta[j]),
            "std_error": float(unc.std_error[j]),
            "initial": e.initial,
            "bounds": [e.low, e.high],
            "at_bound": at_bound,
            "scale": e.scale,
        }
        if at_bound:
            side = "lower" if theta[j] - e.low <= e.high - theta[j] else "upper"
            warnings.append(
                f"{e.name} = {theta[j]:.6g} sits on its {side} bound: the data may want it beyond "
                f"[{e.low:g}, {e.high:g}], and its standard error does not describe that"
            )
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            c = unc.correlation[a, b]
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
    if math.isfinite(se_change) and se_change > 0.25:
        warnings.append(
            f"the standard errors change by {100 * se_change:.0f} % when the Jacobian's step is tripled: the "
            "integration noise is not far below the step; tighten error_tolerance"
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
    runs = problem.runs([z], "single")[0]
    residual_rms = {}
    for ex, res in zip(spec.experiments, runs, strict=True):
        for k, c in enumerate(ex.channels):
            key = c.output if len(spec.experiments) == 1 else f"{ex.name}:{c.output}"
            d = res.values[:, k] - c.values
            residual_rms[key] = float(np.sqrt(np.mean(d**2)))
    m = len(r)
    failures = problem.failures
    return {
        "parameters": params,
        "correlation": {"names": names, "matrix": np.round(unc.correlation, 12).tolist()},
        "cost": float(best.cost),
        "rms_normalized_residual": float(np.sqrt(np.mean(r**2))),
        "residual_rms": residual_rms,
        "n_evaluations": evaluator.runs,
        "wall_s": time.perf_counter() - t0,
        "converged": best.status == "converged",
        "warnings": warnings,
        "starts": [
            {
                "origin": s.origin,
                "initial": s.initial,
                "cost": s.cost if math.isfinite(s.cost) else None,
                "multiple_shooting_cost": s.ms_cost,
                "parameters": transform.named(transform.theta(s.z)) if s.z is not None else None,
                "status": s.status,
                "iterations": s.nfev,
            }
            for s in results
        ],
        "method": {
            "shooting": "multiple, then single" if multiple else "single",
            "segment_s": options["segment"] if multiple else None,
            "loss": options["loss"],
            "absolute_sigma": options["absolute_sigma"],
            "sigma_scale": unc.scale,
            "error_tolerance": options["error_tolerance"],
            "diff_step": options["diff_step"],
            "std_error_change_with_3x_step": se_change,
            "condition_number": unc.condition,
            "samples": m,
            "equation_error_stage": notes,
            "jacobian_notes": jac_notes,
        },
        "dropped_rows": {e.name: e.dropped_rows for e in spec.experiments if e.dropped_rows},
        "failed_runs": {
            "count": len(failures),
            "by_status": {st: sum(1 for f in failures if f["status"] == st) for st in {f["status"] for f in failures}},
            "first": failures[:5],
        },
        "_internal": {"z": z, "theta": theta, "runs": runs, "covariance": unc.covariance},
    }


__all__ = ["FitError", "FitSpecError", "fit", "load"]
