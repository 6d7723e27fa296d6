"""The state an experiment (or a multiple-shooting segment) starts from, read off its samples.

A real run does not start where the FMU starts by default (every spring-driven joint at
q = q*, at rest, its spring unloaded): the arm stands deflected under gravity, or moves. So
by default (``start = "data"`` of an ``[[experiment]]``) every run of a fit and of a replay
starts from the measured state at its first sample:

* a flexible or motor joint whose link q is measured: where it stands still (its samples stay
  within three noise standard deviations of their median for REST_SAMPLES samples from there
  on, an outlier apart:
  :func:`resting`), at rest at the mean of those samples, so that an arm at rest starts at
  rest and its joints' stiction decides, as at a real start; where its samples stand within
  the same noise band of the command q*, at q* itself (the FMU's own start position: a
  sample cannot tell the two apart, and a start position off by a fraction of the noise,
  the mean's error or a creep within the band, would shift every breakaway by k·δq, a bias
  no standard error covers); else q and q̇ from the derivative
  filter (:mod:`stickslip.fit.filtering`) at that sample, a q̇ within three times the standard
  deviation the filter leaves of the channel's noise at that sample (:func:`reading_noise`: at
  a record's edge several times the middle's) taken as 0;
* such a joint whose q is not measured: the command q*, q̇* (the FMU's own start);
* a motor joint's rotor: turned so that its gear spring carries the joint's load at that
  state, θ_m = N·(q + F/k + sgn(F)·Δ), spinning at ω_m = N·q̇ (the gear's deflection rate is
  left out), with F the generalized force of the joint by the engine's inverse dynamics at the
  measured (q, q̇, q̈) (the other joints at their measurements or commands), the link's
  friction left out (it is what the fit estimates; at rest, stiction holds the difference).
  This is the FMU's ``static_start`` for an arm at rest, and its generalization to one in
  motion. k and Δ are the run's own values (they may be estimated), so θ_m is completed in
  :func:`stickslip.fit.runner.run` from the F stored here.

``start = "rest"`` keeps the FMU's own start; start values in the experiment's
``parameters`` (use_start_values, q_start[i], ...) are set as given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

NOISE_SIGMAS = 3.0  # a filtered q̇ within this many of its noise standard deviations is 0
START_SIGMAS = 10.0  # a start unknown's bounds: this many noise standard deviations of its reading
NOISE_DRAWS = 128  # noise records through the filter for a reading's noise (reading_noise)
REST_SAMPLES = 7  # a joint whose q stays within NOISE_SIGMAS noise for this many samples is at rest


@dataclass
class Segments:
    """Start states at samples ``starts`` (single shooting: [0]; multiple shooting: each
    segment's first sample; segment k runs to starts[k+1], the last to the end).

    ``joints``: the spring-driven joints (1-based) set through q_start / qd_start, with
    ``q_start`` / ``qd_start`` of shape (segments, joints); ``motors``: the motor joints among
    them, with ``gear_force`` (segments, motors), the joint's load F at the start, and
    ``gear_ratio`` (motors) their N."""

    starts: np.ndarray
    joints: list
    q_start: np.ndarray
    qd_start: np.ndarray
    motors: list = field(default_factory=list)
    gear_force: np.ndarray | None = None
    gear_ratio: list = field(default_factory=list)
    how: dict = field(default_factory=dict)  # joint -> how it starts at the first segment, for the report
    # joint -> (σ of q, σ of q̇) the noise leaves in the reading of a joint moving at the first
    # sample (the bounds of its start unknowns: start_unknowns)
    moving: dict = field(default_factory=dict)

    def state(self, k: int, values=None) -> tuple:
        """(q, q̇) of the joints at the start of segment k: as read, but for the experiment's
        first sample where ``values`` ({FMU variable: value}, the run's parameters) holds a
        fitted start (``q_start[i]``, ``qd_start[i]``: :func:`start_unknowns`). Later segments
        start from their own reading."""
        q, qd = self.q_start[k].copy(), self.qd_start[k].copy()
        if k == 0 and values:
            for j, i in enumerate(self.joints):
                q[j] = float(values.get(f"q_start[{i}]", q[j]))
                qd[j] = float(values.get(f"qd_start[{i}]", qd[j]))
        return q, qd

    def rotor(self, k: int, values, state=None) -> dict:
        """theta_m_start[i], omega_m_start[i] of segment k, with the gear's k[i] and Delta[i]
        from ``values(name)`` (the run's parameter values), the joints at ``state`` ((q, q̇)
        rows; default: as read)."""
        out = {}
        qs, qds = state if state is not None else (self.q_start[k], self.qd_start[k])
        for m, i in enumerate(self.motors):
            j = self.joints.index(i)
            q, qd, force, ratio = qs[j], qds[j], self.gear_force[k, m], self.gear_ratio[m]
            stiffness, clearance = float(values(f"k[{i}]")), float(values(f"Delta[{i}]") or 0.0)
            deflection = force / stiffness + math.copysign(clearance, force) if force != 0.0 else 0.0
            out[f"theta_m_start[{i}]"] = ratio * (q + deflection)
            out[f"omega_m_start[{i}]"] = ratio * qd
        return out

    def describe(self) -> str:
        """How the first segment starts, joint by joint (the report's line)."""
        parts = [f"joint {i} {self.how.get(i, 'at its command (q not measured)')}" for i in self.joints]
        if self.motors:
            parts.append(f"rotors {self.motors} turned to carry the joints' load (inverse dynamics)")
        return "; ".join(parts)


def spring_joints(md) -> tuple:
    """(the joints with a q_start parameter: flexible and motor drives, the motor joints)."""
    from ..motion import motor_joints

    joints = sorted(int(v.name[8:-1]) for v in md.modelVariables if v.name.startswith("q_start["))
    return joints, [i for i in motor_joints(md) if i in joints]


def start_states(experiment, starts, md, unzipdir=None, known: dict | None = None, require_measured=False):
    """The :class:`Segments` of ``experiment`` at the samples ``starts``; None where
    ``require_measured`` and a spring-driven joint's q is not measured (multiple shooting
    needs every one), or where the FMU has no spring-driven joint. ``unzipdir``: the unpacked
    FMU, whose binary gives the inverse dynamics of a motor joint's load; ``known``: the
    parameter values the inverse dynamics take (masses, ...)."""
    from .filtering import derivatives

    joints, motors = spring_joints(md)
    if not joints:
        return None
    channels = {c.output: c for c in experiment.channels}
    measured = [i for i in joints if f"q[{i}]" in channels]
    if require_measured and len(measured) < len(joints):
        return None
    t = experiment.time
    starts = np.asarray(starts, dtype=int)
    cmd = np.array(
        [
            np.concatenate([np.asarray(x, dtype=np.float64) for x in experiment.motion(float(tk), 0.0)])
            for tk in t[starts]
        ]
    )
    n = cmd.shape[1] // 3
    q, qd, qdd = cmd[:, :n].copy(), cmd[:, n : 2 * n].copy(), cmd[:, 2 * n :].copy()
    for i in motors:  # the command of a motor joint is its start position only
        qd[:, i - 1] = 0.0
        qdd[:, i - 1] = 0.0
    rng = np.random.default_rng(0)
    how, moving = {}, {}
    for i in measured:
        c = channels[f"q[{i}]"]
        value, rate, accel = derivatives(t, c.values, experiment.derivatives)
        spread = reading_noise(t, c.std, starts, experiment.derivatives, rng)
        slow = np.abs(rate[starts]) <= NOISE_SIGMAS * spread[1]
        for row, k in enumerate(starts):
            # the band: three noise standard deviations, and a count more where the samples are
            # rounded (the median the band is taken around lies on the count's grid itself)
            band = NOISE_SIGMAS * c.std + (c.resolution or 0.0)
            held = resting(c.values, int(k), band)
            if held is not None:  # the joint stands still from this sample on
                position, count = held
                if abs(position - q[row, i - 1]) <= band:
                    position = q[row, i - 1]  # where its command puts it: the data cannot tell them apart
                    said = f"at rest at its command q* = {position:.8g} (its {count} still samples within the noise)"
                else:
                    said = f"at rest at {position:.8g}, the mean of its {count} still samples"
                q[row, i - 1], qd[row, i - 1], qdd[row, i - 1] = position, 0.0, 0.0
            else:
                q[row, i - 1] = value[k]
                qd[row, i - 1] = 0.0 if slow[row] else rate[k]
                qdd[row, i - 1] = 0.0 if slow[row] else accel[k]
                said = f"moving: q = {q[row, i - 1]:.8g}, q' = {qd[row, i - 1]:.6g} from the derivative filter"
                if row == 0:
                    moving[i] = (float(spread[0][0]), float(spread[1][0]), c.resolution or 0.0)
            if row == 0:
                how[i] = said
    columns = [i - 1 for i in joints]
    force, ratios = None, []
    if motors:
        from .idim import RIGID_BODY, inverse_dynamics, joint_of

        if unzipdir is None:
            raise ValueError("the start of a motor joint needs the FMU's binary (its inverse dynamics)")
        start = {v.name: v.start for v in md.modelVariables}
        values = {**{k: v for k, v in start.items() if v is not None}, **(known or {}), **experiment.parameters}
        settings = [f"{k}={float(v)!r}" for k, v in values.items() if (joint_of(k) or ("",))[0] in RIGID_BODY]
        tau, _ = inverse_dynamics(unzipdir, np.hstack([q, qd, qdd]), settings)
        force = tau[:, [i - 1 for i in motors]]
        ratios = [float(values.get(f"gear_ratio[{i}]", 1.0)) for i in motors]
    return Segments(
        starts, list(joints), q[:, columns], qd[:, columns], list(motors), force, ratios, how, _spans(moving)
    )


def _spans(moving: dict) -> dict:
    """joint -> (half-width of q_start's bounds, of qd_start's) of the joints read moving at
    the first sample: START_SIGMAS times the noise the reading carries there, and two counts of
    the encoder for q. (The benchmark's joints that sag from rest were read 2-3.3 of those
    standard deviations off, q̇ = 0 well within.)"""
    return {i: (START_SIGMAS * sq + 2.0 * count, START_SIGMAS * sv) for i, (sq, sv, count) in moving.items()}


def start_unknowns(experiment, segments) -> list:
    """The start state of ``experiment`` as unknowns of the fit (:class:`stickslip.fit.spec.Estimate`
    with ``start_of`` its name): ``q_start[i]`` and ``qd_start[i]`` of every joint its first
    sample reads as moving, each within START_SIGMAS of the reading's noise of the reading.

    Why: a joint moving at the first sample is read through the derivative filter at the
    record's edge, where the filter extrapolates and where a drive ringing faster than its
    window is not followed. Single shooting then starts a few μrad and mrad/s off, every run of
    the fit from the same wrong state, and that error alone moves the answer: on the
    benchmark's KUKA iiwa and xArm 6, whose joints sag from relaxed springs at t = 0, it kept 7
    of 10 fits away from the truth's minimum; each reached it once started from the true state.
    As unknowns, the state is fitted with the parameters, and the parameters' standard errors
    carry its uncertainty (the covariance's marginal). A joint at rest is not one: its state is
    the mean of its still samples, at rest."""
    if segments is None or not segments.moving:
        return []
    from .spec import Estimate

    out = []
    for j, i in enumerate(segments.joints):
        if i not in segments.moving:
            continue
        wq, wv = segments.moving[i]
        for name, value, width in (("q_start", segments.q_start[0, j], wq), ("qd_start", segments.qd_start[0, j], wv)):
            value = float(value)
            out.append(
                Estimate(
                    f"{experiment.name}:{name}[{i}]", value, value - width, value + width, start_of=experiment.name
                )
            )
    return out


def reading_noise(t, std: float, at, flt, rng, draws: int = NOISE_DRAWS) -> tuple:
    """(σ of the filtered value, σ of the filtered rate) at the samples ``at`` that white noise
    of ``std`` on the samples leaves, sample by sample: ``draws`` noise records through the
    filter (one call, a matrix of them), the spread over the draws at each sample (its own
    error 1/sqrt(2·draws), 6 % for 128).

    Per sample, not one figure for the record: at a record's edge a filter extrapolates (the
    default quintic Savitzky-Golay's rate at the first sample has 6.1 times the noise of its
    rate in the middle, the coefficients' root sum of squares 1.14 against 0.188 per sample
    interval). A joint at rest at t = 0 and sagging from there read through the middle's band
    came out moving at 2 σ of the edge's noise (−0.011 to +0.009 rad/s on the benchmark's
    KUKA iiwa and xArm 6), and that start alone kept 7 of their 10 fits from the truth's
    minimum."""
    from .filtering import derivatives

    at = np.asarray(at, dtype=int)
    value, rate, _ = derivatives(t, rng.normal(0.0, std, (len(t), draws)), flt)
    return np.std(value[at], axis=1), np.std(rate[at], axis=1)


def resting(values, k: int, tolerance: float, samples: int = REST_SAMPLES):
    """(position, samples averaged) of a joint that stands still at sample k, or None.

    Still: of the ``samples`` samples from k on, all but a fifth (an outlier of the encoder,
    at least one) lie within ``tolerance`` of their median. The position is the mean of the
    samples within that band over the still run around k, which ends (either way) where
    fewer than half of ``samples`` consecutive samples stay in the band: a joint that creeps
    away within the noise pulls the mean by a fraction of the noise, an outlier not at all."""
    y = np.asarray(values)
    if k + samples > len(y):
        return None
    anchor = float(np.median(y[k : k + samples]))  # not sample k alone: its own noise
    near = np.abs(y - anchor) <= tolerance
    if near[k : k + samples].sum() < samples - max(1, samples // 5):
        return None
    end = k + samples
    while end < len(y) and near[end : end + samples].mean() >= 0.5:
        end += 1
    begin = k
    while begin > 0 and near[max(0, begin - samples) : begin].mean() >= 0.5:
        begin -= 1
    run = y[begin:end][near[begin:end]]
    return float(np.mean(run)), len(run)


def segment_starts(time, segment: float) -> np.ndarray:
    """The first samples of multiple-shooting segments of about ``segment`` seconds (at least
    two samples each; no stub of less than half a segment at the end)."""
    t = np.asarray(time)
    dt = float(np.median(np.diff(t)))
    per = max(2, round(segment / dt))
    starts = np.arange(0, len(t) - 1, per)
    if len(starts) > 1 and len(t) - 1 - starts[-1] < per // 2:
        starts = starts[:-1]
    return starts
