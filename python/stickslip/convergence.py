"""Is a number converged? The same run again with a tenfold tighter error tolerance, and the
relative spread of every metric between the two runs.

Some outputs of this model have no converged value: a joint that comes to rest inside a
wide drive clearance after dozens of impacts stops wherever friction catches it in the
gap, and which point that is depends on every impact before (docs/convergence.md). Such a
number changes by any amount when the integration is refined; a converged one changes by
about what the error control promises (0.1 % on max eps). The check makes the difference
visible:

* :func:`tightened`: the parameters of the check run: the run's own ``error_tolerance``
  (its value in ``parameters``, else the FMU's start value, 5e-4 in the reference model)
  divided by :data:`FACTOR`; with fixed sub-steps (``h_min == h_max``) the sub-step
  halved instead (a fixed sub-step has no tolerance; the Newmark rule's error falls by 4
  per halving);
* :func:`spread`: the relative spread of one metric, |x_tight - x| / max(|x_tight|, |x|,
  :data:`SPREAD_FLOOR`); the same formula for the integer counts (one stiction phase more
  out of 5 is 0.2). The one home of the formula: ``stickslip sweep --check-convergence``,
  ``stickslip simulate --check-convergence`` and :func:`check_convergence` use it;
* :func:`check_convergence`: the Python API for one run;
* :func:`run_checked`: one variant of a sweep with its check (a Dask task), whose row
  keeps the main run's metrics whatever the check run does;
* :func:`selected_runs`: the seeded fraction of a sweep's variants that is checked.

A metric is *not converged* when its spread exceeds the threshold (default
:data:`DEFAULT_THRESHOLD`, 0.3 %, the error control's promise on final eps).
"""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass, field

import numpy as np

FACTOR = 10.0  # the check run's error_tolerance is the run's own divided by this
# A spread above this marks a metric as not converged: the error control's promise on
# final eps (0.3 %; 0.1 % on max eps), so that an unmarked number is one the promise covers
# (docs/convergence.md, "The threshold").
DEFAULT_THRESHOLD = 0.003
SPREAD_FLOOR = 1e-15  # |differences| of quantities below this (SI units) count as agreement
SPREAD_SUFFIX = "_spread"
# convergence_status of a sweep row: the check run's status, or why there was none
CHECKED = "checked"  # both runs reached the end: the spreads are set
NOT_SELECTED = "not selected"  # outside the checked fraction
NOT_RUN = "not run"  # the main run was not ok: nothing to compare
# ... and the check run's own status when it was not ok: refused, discard, error, timeout
COLUMNS = ["convergence_status", "convergence_message", "convergence_wall_s"]


def spread(x, x_tight, floor: float = SPREAD_FLOOR):
    """The relative spread |x_tight - x| / max(|x_tight|, |x|, floor) of a metric between the
    run (``x``) and its check run (``x_tight``); NaN where either is NaN or None. Scalars
    give a float, arrays (numpy broadcasting) an array.

    >>> spread(5, 6)            # one stiction phase more out of 5 ... 6
    0.16666666666666666
    >>> round(spread(1.01e-4, 1e-4), 6)   # max eps 1 % smaller in the check run
    0.009901
    >>> spread(0.0, 0.0)
    0.0
    """
    if x is None or x_tight is None:
        return math.nan
    a = np.asarray(x, dtype=np.float64)
    b = np.asarray(x_tight, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        out = np.abs(b - a) / np.maximum(np.maximum(np.abs(a), np.abs(b)), floor)
    return float(out) if out.ndim == 0 else out


def spread_name(metric: str) -> str:
    """The column of a metric's spread, the suffix before a joint index: ``final_eps`` ->
    ``final_eps_spread``, ``n_stick[3]`` -> ``n_stick_spread[3]`` (as the FMU names its
    per-joint variables)."""
    base, bracket, index = metric.partition("[")
    return base + SPREAD_SUFFIX + bracket + index


def spread_columns(metrics) -> list:
    return [spread_name(m) for m in metrics]


def spreads(metrics_main: dict, metrics_tight: dict, metrics) -> dict:
    """{metric: spread} of the named metrics between two runs' values (dicts by name)."""
    return {m: spread(metrics_main.get(m), metrics_tight.get(m)) for m in metrics}


def not_converged(spread_by_metric: dict, threshold: float = DEFAULT_THRESHOLD) -> list:
    """The metrics whose spread exceeds ``threshold`` (NaN: not checked, never listed)."""
    return [m for m, s in spread_by_metric.items() if s is not None and not math.isnan(s) and s > threshold]


def _start_value(md, name: str):
    v = next((v for v in md.modelVariables if v.name == name), None)
    if v is None or v.start is None:
        return None
    return float(v.start)


def tightened(parameters: dict, md) -> tuple:
    """(the parameter values that make a run's check run, a description): ``error_tolerance``
    divided by :data:`FACTOR`, or with fixed sub-steps (h_min = h_max) the sub-step halved.
    A run's own value is its entry in ``parameters``, else the FMU's start value
    (``md``: fmpy's ModelDescription). Raises ValueError if the FMU has no such parameter."""
    parameters = parameters or {}

    def own(name):
        value = parameters.get(name, _start_value(md, name))
        if value is None:
            raise ValueError(
                f"the FMU has no parameter `{name}` with a start value: the convergence check "
                "tightens the error tolerance (or halves fixed sub-steps)"
            )
        return float(value)

    h_min, h_max = own("h_min"), own("h_max")
    if h_min == h_max:
        return {"h_min": h_min / 2, "h_max": h_max / 2}, f"fixed sub-steps halved: {h_max:g} -> {h_max / 2:g} s"
    tol = own("error_tolerance")
    return {"error_tolerance": tol / FACTOR}, f"error_tolerance / {FACTOR:g}: {tol:g} -> {tol / FACTOR:g}"


def describe(rerun: dict) -> str:
    """The check run's settings as text, e.g. ``error_tolerance = 5e-05``."""
    return ", ".join(f"{k} = {v:g}" for k, v in rerun.items())


def selected_runs(n: int, fraction: float, seed: int) -> set:
    """The run ids (of 0..n-1) that a sweep checks: round(fraction * n) of them, at least one
    when fraction > 0, chosen by a random stream seeded by (seed, crc32("convergence")), so
    the same variants are chosen on every run and on resume; fraction 1 checks every one."""
    if not 0 < fraction <= 1:
        raise ValueError(f"--convergence-fraction {fraction:g}: must be in (0, 1]")
    if fraction >= 1:
        return set(range(n))
    k = min(n, max(1, round(fraction * n)))
    u = np.random.default_rng([seed, zlib.crc32(b"convergence")]).random(n)
    return set(int(i) for i in np.argsort(u, kind="stable")[:k])


def check_columns(
    row: dict, metrics, check_row: dict | None, status: str | None = None, wall: float = math.nan
) -> dict:
    """The convergence columns of a sweep row: ``convergence_status``, ``convergence_message``,
    ``convergence_wall_s`` and ``<metric>_spread`` for every metric (NaN unless checked)."""
    nan = dict.fromkeys(spread_columns(metrics), math.nan)
    if check_row is None:
        return {"convergence_status": status, "convergence_message": "", "convergence_wall_s": wall} | nan
    if check_row.get("status") != "ok":
        return {
            "convergence_status": check_row.get("status", "error"),
            "convergence_message": check_row.get("message", ""),
            "convergence_wall_s": wall,
        } | nan
    return {
        "convergence_status": CHECKED,
        "convergence_message": check_row.get("message", ""),
        "convergence_wall_s": wall,
    } | {spread_name(m): s for m, s in spreads(row, check_row, metrics).items()}


def run_checked(
    fmu_digest: str,
    run: int,
    parameters: dict,
    stop_time: float,
    step: float,
    motion,
    metrics,
    rerun: dict | None,
    timeout: float | None = None,
    fmu_data: bytes | None = None,
) -> dict:
    """One variant of a checked sweep (a Dask task): the row of
    :func:`stickslip.variant.run_variant`, and, when ``rerun`` (the check run's parameter
    values, e.g. ``{"error_tolerance": 5e-5}``) is given and the run is ok, the same variant
    again with them on top, and the :func:`check_columns`. Never raises, never loses the
    main row: a check run that fails is recorded in ``convergence_status`` (its status)
    and ``convergence_message``."""
    from .variant import run_variant

    row = run_variant(fmu_digest, run, parameters, stop_time, step, motion, timeout, fmu_data)
    if rerun is None:
        return row | check_columns(row, metrics, None, NOT_SELECTED)
    if row["status"] != "ok":
        return row | check_columns(row, metrics, None, NOT_RUN)
    wall = time.perf_counter()
    try:
        check = run_variant(fmu_digest, run, {**parameters, **rerun}, stop_time, step, motion, timeout, fmu_data)
    except Exception as e:  # noqa: BLE001 -- the main row is kept whatever happens here
        check = {"status": "error", "message": f"{type(e).__name__}: {e}"}
    return row | check_columns(row, metrics, check, wall=time.perf_counter() - wall)


def metrics_of_series(result: dict) -> dict:
    """The sweep's metrics (:func:`stickslip.variant.metric_names`) from a
    :func:`stickslip.simulate.run` result (every output at every communication point, t = 0
    included): the same definitions as a sweep row."""
    from .variant import metric_names

    out = {}
    for m in metric_names(list(result)):
        if m == "max_eps":
            out[m] = float(max(result["eps"]))
        elif m == "final_eps":
            out[m] = float(result["eps"][-1])
        elif m.startswith("max_N_normal["):
            out[m] = float(max(result[m[len("max_") :]]))
        else:
            out[m] = float(result[m][-1])
    return out


@dataclass
class Convergence:
    """The outcome of :func:`check_convergence`: both runs' metrics and their spreads."""

    status: str  # CHECKED, or the check run's status (refused, discard, error, timeout), or NOT_RUN
    rerun: dict  # the check run's parameter values on top of the run's, e.g. {"error_tolerance": 5e-5}
    method: str  # how they were chosen, e.g. "error_tolerance / 10: 0.0005 -> 5e-05"
    threshold: float
    metrics: dict = field(default_factory=dict)  # the run's metrics, by name
    tight: dict = field(default_factory=dict)  # the check run's metrics
    spreads: dict = field(default_factory=dict)  # metric -> spread (NaN unless CHECKED)
    message: str = ""  # the main run's or the check run's message when not ok
    seconds: tuple = (math.nan, math.nan)  # wall time of the run and of the check run

    @property
    def not_converged(self) -> list:
        """The metrics whose spread exceeds the threshold."""
        return not_converged(self.spreads, self.threshold)

    def report(self) -> str:
        """A table: metric, value, value of the check run, spread, and a mark where above the
        threshold (metrics that are 0 in both runs left out)."""
        lines = [
            f"convergence check ({self.method}; threshold {self.threshold:g}): {self.status}"
            + (f": {self.message}" if self.status != CHECKED and self.message else "")
        ]
        if self.status == CHECKED:
            width = max(len(m) for m in self.spreads)
            lines.append(f"  {'metric':<{width}}  {'run':>13}  {'check run':>13}  {'spread':>9}")
            for m, s in self.spreads.items():
                if self.metrics[m] == 0 and self.tight[m] == 0:
                    continue  # e.g. the stick count of a rigid joint
                mark = "  NOT CONVERGED" if m in self.not_converged else ""
                lines.append(f"  {m:<{width}}  {self.metrics[m]:>13.6g}  {self.tight[m]:>13.6g}  {s:>9.2e}{mark}")
        return "\n".join(lines)

    def warning(self) -> str | None:
        """A warning naming the metrics above the threshold, or None."""
        bad = self.not_converged
        if not bad:
            return None
        worst = ", ".join(f"{m} ({self.spreads[m]:.1%})" for m in bad)
        return (
            f"WARNING: not converged: {worst} changed by more than {self.threshold:.3g} "
            f"({self.threshold:.1%}) with {self.method}; these numbers depend on the integration, "
            "read them as one sample of a distribution, not as a value (docs/convergence.md)"
        )


def check_convergence(
    parameters: dict | None = None,
    fmu=None,
    stop_time: float | None = None,
    step: float = 1e-3,
    motion=None,
    threshold: float = DEFAULT_THRESHOLD,
    timeout: float | None = None,
    rerun: dict | None = None,
) -> Convergence:
    """Runs the FMU twice, as a sweep variant (:func:`stickslip.variant.run_variant`), and
    compares the metrics.

    ``parameters``: FMU variable values (any parameter, fixed ones included); ``fmu``: the
    FMU file (default ``target/fmu/StickSlipManipulator.fmu``); ``stop_time`` (default
    2 s), ``step`` the communication step; ``motion(t, step)`` the inputs (default the
    reference motion); ``rerun``: the check run's parameter values, by default
    :func:`tightened` (error_tolerance / 10, or fixed sub-steps halved).

    Returns a :class:`Convergence`: ``spreads`` per metric, ``not_converged`` the metrics
    above ``threshold``; ``report()`` and ``warning()`` as text. Example::

        c = check_convergence({"Delta[1]": 0.0349, "Delta[3]": 0.002}, stop_time=0.5)
        print(c.report())
        if c.not_converged: ...
    """
    from pathlib import Path

    from .fmu import DEFAULT_FMU, content_hash, model_description
    from .motion import RUN_TIME, reference_inputs
    from .variant import metric_names, run_variant

    data = Path(fmu or DEFAULT_FMU).read_bytes()
    digest = content_hash(data)
    md = model_description(data)
    parameters = dict(parameters or {})
    stop_time = RUN_TIME if stop_time is None else stop_time
    motion = motion or reference_inputs
    method = "given"
    if rerun is None:
        rerun, method = tightened(parameters, md)
    else:
        method = f"given: {describe(rerun)}"
    metrics = metric_names([v.name for v in md.modelVariables if v.causality == "output"])
    main = run_variant(digest, 0, parameters, stop_time, step, motion, timeout, data)
    result = Convergence(
        NOT_RUN,
        dict(rerun),
        method,
        threshold,
        {m: main.get(m, math.nan) for m in metrics},
        message=main.get("message", ""),
        seconds=(main.get("wall_s", math.nan), math.nan),
    )
    result.spreads = dict.fromkeys(metrics, math.nan)
    if main["status"] != "ok":
        result.message = f"the run ended {main['status']}: {main.get('message', '')}"
        return result
    tight = run_variant(digest, 1, {**parameters, **rerun}, stop_time, step, motion, timeout, data)
    result.tight = {m: tight.get(m, math.nan) for m in metrics}
    result.seconds = (main.get("wall_s", math.nan), tight.get("wall_s", math.nan))
    result.status = CHECKED if tight["status"] == "ok" else tight["status"]
    result.message = tight.get("message", "")
    if result.status == CHECKED:
        result.spreads = spreads(result.metrics, result.tight, metrics)
    return result
