"""The fit as a least-squares problem: parameters in a normalized space, residuals of every
sample of every experiment, runs on Dask or in this process.

* :class:`Transform`: each estimated parameter θ_j maps to z_j in [0, 1] over its bounds,
  linearly or (``scale = "log"``) in log θ. Where μ_k[i] and μ_s[i] of one joint are both
  estimated, z of μ_s is the fraction of the way from max(μ_k, low_s) to high_s:
  μ_s = b + z (high_s − b), b = max(μ_k, low_s), so every point the optimizer tries satisfies
  the FMU's μ_s ≥ μ_k and stays in μ_s's bounds, and none is refused for it.
* :class:`Evaluator`: runs (:func:`stickslip.fit.runner.run`) on a Dask cluster, the FMU's
  bytes sent to every worker by the sweep's worker plugin, the experiments' data scattered
  once; or in this process (``client=None``).
* :class:`Problem`: residuals (model − measured)/σ over all samples; a sample the run did not
  reach (the FMU refused the point or discarded a step) counts as :data:`PENALTY`, so the
  optimizer's trust region shrinks away from it instead of the fit ending.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict

import numpy as np

from .runner import Payload, RunResult, run
from .start import segment_starts, start_states

PENALTY = 1e3  # normalized residual of a sample a run did not reach
RECENT = 32  # points whose runs each thread keeps (Problem.runs)


class Transform:
    """θ (the FMU's values) <-> z in [0, 1]^p (the optimizer's variables)."""

    def __init__(self, estimates):
        self.estimates = list(estimates)
        names = [e.name for e in self.estimates]
        self.excess = {}  # index of mu_s[i] -> index of mu_k[i]
        for j, name in enumerate(names):
            if name.startswith("mu_s[") and name.replace("mu_s[", "mu_k[") in names:
                self.excess[j] = names.index(name.replace("mu_s[", "mu_k["))
        self.log = np.array([e.scale == "log" and j not in self.excess for j, e in enumerate(self.estimates)])
        self.low = np.array([math.log(e.low) if lg else e.low for e, lg in zip(self.estimates, self.log, strict=True)])
        high = np.array([math.log(e.high) if lg else e.high for e, lg in zip(self.estimates, self.log, strict=True)])
        self.span = high - self.low

    def _base(self, theta, j: int) -> tuple:
        """(b, top) of a μ_s reached from its μ_k: μ_s = b + z (top − b)."""
        e = self.estimates[j]
        base = max(theta[self.excess[j]], e.low)
        return base, max(e.high, base)

    def theta(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=np.float64)
        u = self.low + z * self.span
        theta = np.where(self.log, np.exp(np.where(self.log, u, 0.0)), u)
        for j in self.excess:
            base, top = self._base(theta, j)
            theta[j] = base + z[j] * (top - base)
        return theta

    def z(self, theta) -> np.ndarray:
        theta = np.asarray(theta, dtype=np.float64)
        u = np.where(self.log, np.log(np.where(self.log, theta, 1.0)), theta)
        z = (u - self.low) / self.span
        for j in self.excess:
            base, top = self._base(theta, j)
            z[j] = (theta[j] - base) / (top - base) if top > base else 0.0
        return np.clip(z, 0.0, 1.0)

    def jacobian(self, z) -> np.ndarray:
        """dθ/dz at z (p × p)."""
        z = np.asarray(z, dtype=np.float64)
        theta = self.theta(z)
        d = np.diag(np.where(self.log, theta, 1.0) * self.span)
        for j, k in self.excess.items():
            base, top = self._base(theta, j)
            d[j, j] = top - base
            if theta[k] > self.estimates[j].low:  # b = μ_k: μ_s moves with μ_k
                d[j, :] += (1.0 - z[j]) * d[k, :]
            if top > self.estimates[j].high:  # μ_k above high_s: μ_s = μ_k
                d[j, :] = d[k, :]
        return d

    def named(self, theta) -> dict:
        return {e.name: float(v) for e, v in zip(self.estimates, theta, strict=True)}


class Evaluator:
    """Runs experiments for parameter sets, on a Dask client or in this process."""

    def __init__(self, fmu_data: bytes, digest: str, payloads: list, client=None, fmu_sent: bool = False):
        """``fmu_sent``: :meth:`send_fmu` has already run on ``client``."""
        self.digest = digest
        self.client = client
        self.fmu_data = fmu_data
        self.payloads = payloads
        self.runs = 0  # experiments run (each of them with sensitivities counts once, in jacobians too)
        self.jacobians = 0
        self._lock = threading.Lock()
        # The Dask priority of the calling thread's runs (higher first): the fit's best-ranked
        # start runs ahead of the others (stickslip.fit.solve.run_starts).
        self.priority = threading.local()
        if client is not None:
            if not fmu_sent:
                Evaluator.send_fmu(client, fmu_data, digest)
            self.remote = client.scatter(payloads, broadcast=True)

    @staticmethod
    def send_fmu(client, fmu_data: bytes, digest: str) -> None:
        """The FMU to every worker of ``client`` (and those that join later), unpacked there."""
        from ..sweep import FmuPlugin

        client.register_plugin(FmuPlugin(fmu_data, digest))

    def map(self, jobs: list, sensitivities: list | None = None) -> list:
        """jobs: (experiment index, parameters, Segments or None) -> RunResults, in order; with
        ``sensitivities`` (per experiment {parameter: step}), their derivatives too (one native
        call a job)."""
        with self._lock:
            self.runs += len(jobs)
            if sensitivities:
                self.jacobians += len(jobs)

        def wrt(i):
            return sensitivities[i] if sensitivities else None

        if self.client is None:
            return [
                run(self.digest, self.payloads[i], p, s, fmu_data=self.fmu_data, sensitivities=wrt(i))
                for i, p, s in jobs
            ]
        futures = [
            self.client.submit(
                run,
                self.digest,
                self.remote[i],
                p,
                s,
                sensitivities=wrt(i),
                pure=False,
                priority=getattr(self.priority, "value", 0),
            )
            for i, p, s in jobs
        ]
        return self.client.gather(futures)


class Problem:
    """Residuals of a fit for points z, in single shooting (``segment=None``) or in multiple
    shooting with segments of ``segment`` seconds."""

    def __init__(self, spec, evaluator: Evaluator, error_tolerance: float | None = None):
        self.spec = spec
        self.transform = Transform(spec.estimates)
        self.evaluator = evaluator
        self.error_tolerance = spec.options["error_tolerance"] if error_tolerance is None else error_tolerance
        # The final cost: the whole run's simulation (None), or the prediction over a horizon
        # from each measured state ([options] horizon, s: multiple shooting to the end).
        self.horizon = spec.options.get("horizon")
        self.measured = [np.column_stack([c.values for c in e.channels]) for e in spec.experiments]
        self.sigma = [np.array([c.std for c in e.channels]) for e in spec.experiments]
        self.m = sum(x.size for x in self.measured)
        self.failures = []  # (parameters, experiment, status, message) of runs that did not finish
        self._lock = threading.Lock()
        self._segments = {}
        # Jacobian columns from the FMU's sensitivities, and by differences where their event
        # pattern changed (shared with the problems of other tolerances: with_tolerance).
        self.columns = {"sensitivities": 0, "differences": 0}
        # Per thread, the RunResults of the last RECENT points (runs are deterministic, so a
        # point asked for again is not run again): a stage's last Jacobian is the one the
        # uncertainty takes at its answer, and the tolerance check's the refit's first. Per
        # thread, so that which points are found does not depend on how the starts' threads
        # interleave (fit.json's run count is the same at any load).
        self._recent = threading.local()

    def with_tolerance(self, error_tolerance: float) -> Problem:
        """The same problem with the FMU's error_tolerance set to ``error_tolerance``."""
        other = Problem.__new__(Problem)
        other.__dict__.update(self.__dict__)
        other.error_tolerance = error_tolerance
        return other

    def segments(self, segment: float) -> list | None:
        """Per experiment the multiple-shooting Segments of about ``segment`` s, or None
        where an experiment cannot be restarted from its measurements."""
        with self._lock:
            if segment not in self._segments:
                from ..fmu import unpacked

                where = unpacked(self.evaluator.fmu_data, self.evaluator.digest)
                known = {e.name: e.initial for e in self.spec.estimates}
                self._segments[segment] = [
                    start_states(e, segment_starts(e.time, segment), self.spec.model_description, where, known, True)
                    for e in self.spec.experiments
                ]
            return self._segments[segment]

    def blocks(self) -> list:
        """(first row, end row) of each channel's time series in a residual vector."""
        out, offset = [], 0
        for meas in self.measured:
            n, k = meas.shape
            out += [(offset + j * n, offset + (j + 1) * n) for j in range(k)]
            offset += n * k
        return out

    def clusters(self, segment: float | None = None) -> list | None:
        """Row indices of a residual vector per multiple-shooting segment (all channels of its
        samples): the residuals that share the segment's start error. None in single shooting."""
        segment = self.horizon if segment is None else segment
        if segment is None:
            return None
        out, offset = [], 0
        for meas, seg in zip(self.measured, self.segments(segment), strict=True):
            n, k = meas.shape
            ends = [*seg.starts[1:], n]
            for a, b in zip(seg.starts, ends, strict=True):
                out.append(np.concatenate([offset + j * n + np.arange(a, b) for j in range(k)]))
            offset += n * k
        return out

    def channel_names(self) -> list:
        many = len(self.spec.experiments) > 1
        return [f"{e.name}:{c.output}" if many else c.output for e in self.spec.experiments for c in e.channels]

    def model_columns(self) -> np.ndarray:
        """Indices of the model's parameters among the estimates (not the start unknowns)."""
        return np.array([j for j, e in enumerate(self.spec.estimates) if e.start_of is None], dtype=int)

    def own(self, i: int) -> list:
        """Indices of the estimates a run of experiment i takes: the model's parameters and its
        own start unknowns (:func:`stickslip.fit.start.start_unknowns`)."""
        name = self.spec.experiments[i].name
        return [j for j, e in enumerate(self.spec.estimates) if e.start_of in (None, name)]

    def parameters(self, z, i: int) -> dict:
        """The FMU's parameters of a run of experiment i at z (a start unknown by the variable
        it sets)."""
        theta = self.transform.theta(z)
        values = {self.spec.estimates[j].variable: float(theta[j]) for j in self.own(i)}
        if self.error_tolerance is not None:
            values["error_tolerance"] = self.error_tolerance
        return values

    def runs(self, points: list, segment: float | None = None, sensitivities: list | None = None) -> list:
        """For each z in points: the RunResults of every experiment (with ``sensitivities``, per
        experiment {parameter: step}, their derivatives too)."""
        segment = self.horizon if segment is None else segment  # the final cost's shooting
        segments = self.segments(segment) if segment is not None else [None] * len(self.spec.experiments)
        n = len(self.spec.experiments)
        if sensitivities:
            jobs = [(i, self.parameters(z, i), segments[i]) for z in points for i in range(n)]
            results = self.evaluator.map(jobs, sensitivities)
            return [results[k * n : (k + 1) * n] for k in range(len(points))]
        recent = getattr(self._recent, "runs", None)
        if recent is None:
            recent = self._recent.runs = OrderedDict()
        keys = [(np.asarray(z, dtype=np.float64).tobytes(), self.error_tolerance, segment) for z in points]
        new = list(dict.fromkeys(k for k in keys if k not in recent))
        fresh = {}
        if new:
            at = {k: z for k, z in zip(keys, points, strict=True)}
            jobs = [(i, self.parameters(at[k], i), segments[i]) for k in new for i in range(n)]
            results = self.evaluator.map(jobs)
            for m, k in enumerate(new):
                fresh[k] = results[m * n : (m + 1) * n]
                # Kept only where the run's end is the FMU's own answer (ok, refused, discarded),
                # not an error that may be the worker's (a crash, a lost connection).
                if all(r.status in ("ok", "refused", "discard") for r in fresh[k]):
                    recent[k] = fresh[k]
        out = []
        for k in keys:
            if k in recent:
                recent.move_to_end(k)
                out.append(recent[k])
            else:
                out.append(fresh[k])
        while len(recent) > RECENT:
            recent.popitem(last=False)
        return out

    def forget(self) -> None:
        """Forgets this thread's recent runs: the next ask runs every point again."""
        self._recent.runs = OrderedDict()

    def residual(self, results: list) -> np.ndarray:
        """(model − measured)/σ of every sample, PENALTY where the run did not reach it."""
        parts = []
        for res, meas, sigma, e in zip(results, self.measured, self.sigma, self.spec.experiments, strict=True):
            r = (res.values - meas) / sigma
            r[~np.isfinite(r)] = PENALTY
            parts.append(r.ravel(order="F"))
            if res.status != "ok":
                with self._lock:
                    self.failures.append({"experiment": e.name, "status": res.status, "message": res.message})
        return np.concatenate(parts)

    @property
    def exact_jacobians(self) -> bool:
        """Whether Jacobians come from the FMU's sensitivities (``[options] jacobian``)."""
        return self.spec.options.get("jacobian", "differences") == "sensitivities"

    def count_columns(self, exact) -> None:
        with self._lock:
            self.columns["sensitivities"] += int(np.sum(exact))
            self.columns["differences"] += int(np.sum(~exact))

    def sensitivity_steps(self, z) -> list:
        """Per experiment {parameter: step} of the FMU's internal numerical differentiation at z
        (its own estimates, :meth:`own`): 1e-6 of the value (1e-6 of its bound range where the
        value is 0; a start unknown's always, its value being a position or a rate that may
        pass 0). With the sub-steps and events of the run frozen, the differences are the
        scheme's derivative up to rounding and to the Newmark iteration's 1e-12 over this step
        (1e-6 of the column, measured in src/fmi/tests.rs), not the error control's noise."""
        theta = self.transform.theta(z)

        def step(e, t):
            if e.start_of is not None:
                return 1e-6 * (e.high - e.low)
            return float(max(1e-6 * abs(t), 1e-6 * (e.high - e.low) if t == 0.0 else 0.0, 1e-300))

        estimates = self.spec.estimates
        return [
            {estimates[j].variable: step(estimates[j], theta[j]) for j in self.own(i)}
            for i in range(len(self.spec.experiments))
        ]

    def residual_jacobian(self, results: list, z) -> tuple:
        """(J, exact): the residuals' Jacobian in z from the runs' sensitivities, and per estimate
        whether its column is exact (no run's replays left their event pattern, every value
        finite); (None, None) where a run has no sensitivities. Rows of samples the residual
        penalizes are zero."""
        p = len(self.spec.estimates)
        parts = []
        exact = np.ones(p, dtype=bool)
        for i, (res, meas, sigma) in enumerate(zip(results, self.measured, self.sigma, strict=True)):
            if res.jacobian is None:
                return None, None
            n, k = meas.shape
            own = self.own(i)  # the run's columns; another experiment's start does not move it
            jac = np.zeros((n, k, p))
            jac[:, :, own] = res.jacobian / sigma[None, :, None]
            jac[~np.isfinite((res.values - meas) / sigma)] = 0.0
            exact[own] &= res.exact & np.all(np.isfinite(jac[:, :, own]), axis=(0, 1))
            parts.append(jac.transpose(1, 0, 2).reshape(k * n, p))
        return np.vstack(parts) @ self.transform.jacobian(z), exact

    def residuals(self, points: list, segment: float | None = None) -> list:
        return [self.residual(r) for r in self.runs(points, segment)]

    def cost(self, z) -> float:
        """The final cost ½Σr² at z (single shooting, or over the horizon; inf where a run failed)."""
        return self.cost_of(self.runs([z])[0])

    def cost_of(self, results: list) -> float:
        """½Σr² of one point's RunResults (inf where a run failed)."""
        if Problem.failed(results):
            return float("inf")
        r = self.residual(results)
        return 0.5 * float(r @ r)

    @staticmethod
    def failed(results: list) -> bool:
        return any(r.status != "ok" for r in results)


def payload_of(experiment, md=None, unzipdir=None, known: dict | None = None, outputs=None) -> Payload:
    """The Payload of an experiment: its inputs, known parameters, the outputs ``outputs``
    (default: its measured channels), and its start state (:mod:`stickslip.fit.start`) where
    it starts from its data (``md``: the FMU's model description, ``unzipdir``: the unpacked
    FMU, for the rotors' start)."""
    start = None
    if experiment.start == "data" and md is not None:
        start = start_states(experiment, [0], md, unzipdir, known)
    return Payload(
        experiment.name,
        experiment.time,
        experiment.motion,
        experiment.torques,
        list(outputs) if outputs is not None else [c.output for c in experiment.channels],
        dict(experiment.parameters),
        start,
    )


__all__ = ["PENALTY", "Evaluator", "Problem", "RunResult", "Transform", "payload_of"]
