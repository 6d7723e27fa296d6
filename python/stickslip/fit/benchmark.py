"""An identification benchmark for ``stickslip fit``: seeded fit problems with a known truth,
and a suite that measures how often the fit's standard errors cover that truth.

:func:`generate` draws one fit problem for an arm (any FMU whose joints have flexible or motor
drives with friction: the reference DH arm, its motor-drive variant, the URDF examples), from
a seed, deterministically:

* which parameters to estimate: 2 to 4 (or ``n_parameters``) of μ_k, μ_s, k and b_v (where the
  FMU has them) of one or two flexible joints with friction (a joint with ``k[i]`` and
  ``mu_k[i]`` among the FMU's tunable parameters);
* their true values: μ_k in [0.05, 0.3], μ_s in [1.1, 1.6] × μ_k, k log-uniform within a
  factor 2.5 of the FMU's start value, b_v (when estimated) such that the viscous force at the
  joint's fast speed is 10–50 % of its Coulomb friction (measured in a probe run). The drawn
  values of a joint that are not estimated are told to the fit as known parameters, as an
  engineer knows what is not fitted;
* a motion (:class:`PlannedMotion`): after a settling dwell, every flexible joint makes
  moves at a fast and a slow speed (steady slips at two speeds, creep), each ended by a stop
  and a dwell or by a direct reversal; rigid joints may make one cycloidal move. Motor-drive
  joints follow their planned motion through a PD loop on the motor angle in a first run;
  its logged torques (a cubic spline of them) are the measured run's input, as the fit gets
  them;
* the measured run, made by the FMU at fixed sub-steps (``h_min = h_max = 2e-6`` s, the
  study's converged step) with the true values, sampled every 1 ms: the commands exact, the
  link encoders (``q[i]`` of every flexible joint, and ``theta_m[i]`` of a motor drive) with
  Gaussian noise of a few µrad or µm, then quantized to the encoder's count (2π/2^20..2^22
  rad, 0.5–1 µm; :func:`stickslip.fit.synthetic.measure` with ``noise_first=True``);
* the draw is kept only when the true run succeeds both at fixed sub-steps and at the FMU's
  default error control, and when each joint with an estimated parameter sticks and slips
  (at least two stiction phases after the start, ``n_stick[i]``, and stuck between 5 % and
  90 % of the time, ``t_stick[i]``); otherwise everything is drawn again from the same
  generator (so the result stays a function of the seed);
* the fit SPEC (a dict for :func:`stickslip.fit.fit`): the starts 20–50 % away from the truth
  (random sign, turned where μ_s ≥ μ_k requires it), bounds that hold truth and start, the
  FMU's default error control, ``starts`` 2–4, every channel with its ``sigma`` and
  ``resolution``.

It writes the data CSV (``run.csv``), ``spec.json`` and ``problem.json`` (the truth, the
draw, the checks) into the directory it is given.

:func:`run_suite` (``python scripts/bench_fit.py --suite``) fits a problem per (arm, draw) and
compares each estimate with the truth: (estimate − truth)/SE, within 2 and 3 SE, the
simulation-error cost ½Σ((model − measured)/σ)² at the answer and at the truth (both at the
FMU's default error control, σ the channel's noise and count, sqrt(σ² + q²/12), as the fit
weighs them), wall time, FMU runs and warnings. It writes ``suite.json`` (every fit and every
parameter's row) and ``suite.md`` (coverage per parameter kind and per arm).
"""

from __future__ import annotations

import json
import math
import re
import statistics
import time
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..fmu import ROOT

SUBSTEP = 2e-6  # s, the fixed sub-step of the measured runs (the study's converged step)
INTERVAL = 1e-3  # s, the sampling interval
KINDS = ("mu_k", "mu_s", "k", "b_v")  # the parameter kinds a problem may estimate
ATTEMPTS = 12  # draws tried per seed before giving up


@dataclass(frozen=True)
class Arm:
    """A benchmark arm: its FMU and the pose its motions start from ({joint: q}, the
    other joints at their q_star start value)."""

    name: str
    fmu: Path
    pose: dict = field(default_factory=dict)


ARMS = {
    "reference": Arm("reference", ROOT / "target" / "fmu" / "StickSlipManipulator.fmu", {3: 0.8}),
    "motor": Arm("motor", ROOT / "target" / "fmu" / "reference_rrpr_motor.fmu", {3: 0.8}),
    # the start poses of examples/motions/<arm>.toml: gravity loads shoulder and elbow
    "kuka_iiwa": Arm("kuka_iiwa", ROOT / "target" / "fmu" / "kuka_iiwa.fmu", {2: 0.6, 4: -1.5, 6: 0.8}),
    "xarm6": Arm("xarm6", ROOT / "target" / "fmu" / "xarm6.fmu", {2: 0.2, 3: -0.8, 5: 0.5}),
}


class GenerationError(RuntimeError):
    """No physically sane problem could be drawn for this arm and seed."""


# ---------------------------------------------------------------------------
# the arm, from its modelDescription


@dataclass
class Joint:
    index: int
    kind: str  # "revolute" or "prismatic"
    drive: str  # "rigid", "flexible" or "motor"
    start: float  # q_star start value


def joints_of(md) -> list:
    """The FMU's joints (1..n, chain order) from the descriptions of its q_star[i] inputs."""
    out = []
    for v in md.modelVariables:
        m = re.fullmatch(r"q_star\[(\d+)\]", v.name)
        if v.causality != "input" or not m:
            continue
        text = v.description or ""
        kind = re.search(r"\b(revolute|prismatic)\b", text)
        drive = re.search(r"\b(rigid|flexible|motor) drive\b", text)
        out.append(
            Joint(
                int(m.group(1)),
                kind.group(1) if kind else "revolute",
                drive.group(1) if drive else "rigid",
                float(v.start or 0.0),
            )
        )
    return sorted(out, key=lambda j: j.index)


def _tunable(md) -> dict:
    return {
        v.name: v
        for v in md.modelVariables
        if v.causality == "parameter" and v.variability == "tunable" and v.type == "Real"
    }


def candidates(md) -> list:
    """The joints whose drive and friction a problem may estimate: flexible (or motor) drives
    with a tunable stiffness k[i] and a kinetic friction coefficient mu_k[i]."""
    tunable = _tunable(md)
    return [j.index for j in joints_of(md) if f"k[{j.index}]" in tunable and f"mu_k[{j.index}]" in tunable]


# ---------------------------------------------------------------------------
# the motion


def _ramp(tau: float):
    """(∫S, S, S') of the cycloidal step S(τ) = τ − sin(2πτ)/(2π) on [0, 1] (0 before, 1 after)."""
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau >= 1.0:
        return 0.5 + (tau - 1.0), 1.0, 0.0
    w = 2.0 * math.pi * tau
    integral = tau * tau / 2.0 + (math.cos(w) - 1.0) / (4.0 * math.pi**2)
    return integral, tau - math.sin(w) / (2.0 * math.pi), 1.0 - math.cos(w)


class PlannedMotion:
    """Per joint a start position and either velocity steps (t0, T, dv) — the velocity changes
    by dv over [t0, t0 + T] along a cycloidal step, so q, q', q'' are exact and q'' continuous —
    or one cycloid (q0, q1, t0, t1); a callable motion(t, step) -> (q*, q*', q*'') lists."""

    def __init__(self, pose: list, steps: dict, cycloids: dict):
        self.pose = [float(x) for x in pose]
        self.steps = {int(i): [tuple(map(float, s)) for s in v] for i, v in steps.items()}
        self.cycloids = {int(i): tuple(map(float, c)) for i, c in cycloids.items()}
        self.joints = len(self.pose)

    def __call__(self, t: float, step: float = 0.0):
        from ..motion import cycloidal

        q, qd, qdd = list(self.pose), [0.0] * self.joints, [0.0] * self.joints
        for i, steps in self.steps.items():
            for t0, length, dv in steps:
                p, s, a = _ramp((t - t0) / length)
                q[i - 1] += dv * length * p
                qd[i - 1] += dv * s
                qdd[i - 1] += dv * a / length
        for i, (q0, q1, t0, t1) in self.cycloids.items():
            q[i - 1], qd[i - 1], qdd[i - 1] = cycloidal(q0, q1, t - t0, t1 - t0)
        return q, qd, qdd

    def to_dict(self) -> dict:
        return {
            "pose": self.pose,
            "velocity_steps": {str(i): [list(s) for s in v] for i, v in self.steps.items()},
            "cycloids": {str(i): list(c) for i, c in self.cycloids.items()},
        }

    @classmethod
    def from_dict(cls, d: dict) -> PlannedMotion:
        return cls(d["pose"], d["velocity_steps"], d["cycloids"])


def _plan_joint(rng, kind: str, start: float, end: float) -> tuple:
    """Velocity steps of one flexible joint over [start, end]: moves at a fast and a slow
    speed (the first two one of each), alternating in sign and steered back towards the
    start when more than 0.3 rad (60 mm) away, each ended by a stop and a dwell or by a direct
    reversal (one of each among the first two). Returns (steps, {"fast": v, "slow": v, "moves": [...]})."""
    if kind == "prismatic":
        fast, slow, reach = rng.uniform(0.04, 0.12), rng.uniform(0.004, 0.015), 0.06
    else:
        fast, slow, reach = rng.uniform(0.2, 0.6), rng.uniform(0.02, 0.06), 0.3
    scale = min(1.0, (end - start) / 1.7)  # shorter phases in a short experiment
    speeds = list(rng.permutation([fast, slow]))
    stops = list(rng.permutation([True, False]))
    steps, moves = [], []
    t, v, q = start, 0.0, 0.0
    sign = float(rng.choice([-1.0, 1.0]))
    while True:
        speed = speeds.pop(0) if speeds else float(rng.choice([fast, slow]))
        stop = stops.pop(0) if stops else bool(rng.random() < 0.5)
        ramp = rng.uniform(0.03, 0.08) * max(scale, 0.5)
        cruise = rng.uniform(0.1, 0.3) * scale
        dwell = rng.uniform(0.05, 0.2) * scale if stop else 0.0
        if v != 0.0:  # a direct reversal: one step from the last move's speed to this one's
            ramp *= 2.0
        if t + ramp + cruise + 2 * ramp + dwell > end:
            break
        target = sign * speed
        steps.append((t, ramp, target - v))
        q += (v + target) / 2.0 * ramp + target * cruise
        t += ramp + cruise
        moves.append({"speed": target, "at": t, "then": "stop" if stop else "reversal"})
        v = target
        if stop:
            steps.append((t, ramp, -v))
            q += v * ramp / 2.0
            t += ramp + dwell
            v = 0.0
        sign = -math.copysign(1.0, q) if abs(q) > reach else -sign  # back and forth, never far
    if v != 0.0:  # come to rest before the end
        ramp = min(0.06, max(end - t, 1e-3))
        steps.append((t, ramp, -v))
    return steps, {"fast": fast, "slow": slow, "moves": moves}


def plan_motion(rng, joints: list, pose: dict, duration: float) -> tuple:
    """A :class:`PlannedMotion` of every joint over [0, duration] and its description: every
    flexible or motor-drive joint per :func:`_plan_joint` after a settling dwell (the arm
    starts with its drive springs relaxed and settles into them), rigid joints one cycloidal
    move of 0.05–0.3 rad (or 10–40 mm) each with probability ½."""
    settle = min(0.3, 0.15 * duration)
    tail = min(0.2, 0.1 * duration)
    start = [pose.get(j.index, j.start) for j in joints]
    steps, cycloids, plans = {}, {}, {}
    for j in joints:
        if j.drive == "rigid":
            if rng.random() < 0.5:
                size = rng.uniform(0.01, 0.04) if j.kind == "prismatic" else rng.uniform(0.05, 0.3)
                t0 = rng.uniform(0.0, 0.4) * duration
                t1 = t0 + rng.uniform(0.3, 0.55) * duration
                q0 = start[j.index - 1]
                cycloids[j.index] = (q0, q0 + float(rng.choice([-1.0, 1.0])) * size, t0, t1)
            continue
        steps[j.index], plans[j.index] = _plan_joint(rng, j.kind, settle, duration - tail)
    return PlannedMotion(start, steps, cycloids), plans


# ---------------------------------------------------------------------------
# motor drives: the torques of a PD loop on the motor angle


def _loop_torques(fmu: Path, md, motion, t, parameters: dict, motors: list) -> dict:
    """{joint: torque at every sample}: the FMU run at its default error control with
    ``parameters``, each motor-drive joint i held by a PD loop on its motor angle around
    N·q*_i(t) (N the gear ratio; 10 Hz bandwidth, critically damped, for twice the rotor's
    inertia) plus the holding torque of the static start and the planned acceleration's
    torque, sampled and held over each 1 ms step. The rigid joints follow ``motion``."""
    from fmpy.fmi2 import FMU2Slave

    from ..fmu import content_hash, input_references, set_value, unpacked

    data = fmu.read_bytes()
    var = {v.name: v for v in md.modelVariables}
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unpacked(data, content_hash(data)),
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="benchmark-loop",
    )
    slave.instantiate()
    try:
        slave.setupExperiment(startTime=float(t[0]))
        for name, value in parameters.items():
            set_value(slave, var[name], value)
        inputs = input_references(md)
        slave.enterInitializationMode()
        q, qd, qdd = motion(float(t[0]))
        slave.setReal(inputs, [float(x) for x in q + qd + qdd])
        slave.exitInitializationMode()
        vr = lambda names: [var[n].valueReference for n in names]  # noqa: E731
        hold = np.array(slave.getReal(vr([f"tau_load[{i}]" for i in motors])))
        ratio = np.array([float(var[f"gear_ratio[{i}]"].start) for i in motors])
        inertia = 2.0 * np.array([float(var[f"J_m[{i}]"].start) for i in motors])
        omega = 2.0 * math.pi * 10.0
        kp, kd = inertia * omega**2, 2.0 * inertia * omega
        state = vr([f"theta_m[{i}]" for i in motors] + [f"omega_m[{i}]" for i in motors])
        torque_refs = vr([f"tau_m[{i}]" for i in motors])
        log = np.empty((len(t), len(motors)))
        for k in range(len(t)):
            q, qd, qdd = motion(float(t[k]))
            y = np.array(slave.getReal(state))
            theta, omega_m = y[: len(motors)], y[len(motors) :]
            want = np.array([q[i - 1] for i in motors]) * ratio
            rate = np.array([qd[i - 1] for i in motors]) * ratio
            acc = np.array([qdd[i - 1] for i in motors]) * ratio
            tau = hold + inertia * acc + kp * (want - theta) + kd * (rate - omega_m)
            log[k] = tau
            if k == len(t) - 1:
                break
            slave.setReal(torque_refs, [float(x) for x in tau])
            slave.setReal(inputs, [float(x) for x in q + qd + qdd])
            slave.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=float(t[k + 1] - t[k]))
        slave.terminate()
    finally:
        slave.freeInstance()
    return {i: log[:, m] for m, i in enumerate(motors)}


# ---------------------------------------------------------------------------
# the problem


@dataclass
class FitProblem:
    """One drawn fit problem: the SPEC and everything needed to judge the fit's answer."""

    arm: str
    seed: int
    fmu: str
    duration: float
    attempts: int  # draws tried until this one passed
    joints: list  # the joints with an estimated parameter
    estimated: list  # parameter names, in the SPEC's order
    truth: dict  # the true value of every estimated parameter
    known: dict  # drawn (or set) values told to the fit
    initial: dict
    bounds: dict
    channels: dict  # FMU output: {"column", "sigma", "resolution"}
    motion: dict  # PlannedMotion.to_dict() and the per-joint plans
    checks: dict  # the true run's stiction counts and times per joint
    data: str  # the CSV path
    spec: dict

    def to_dict(self) -> dict:
        return asdict(self)


def _kind(name: str) -> str:
    return name.split("[", 1)[0]


def _joint(name: str) -> int:
    return int(name[name.index("[") + 1 : -1])


def _uniform_factor(rng) -> float:
    """1 ± U(0.2, 0.5): a start 20–50 % away from the truth, either side."""
    return 1.0 + float(rng.choice([-1.0, 1.0])) * rng.uniform(0.2, 0.5)


def _starts(rng, truth: dict, known: dict) -> dict:
    """Starts 20–50 % off with random sign, turned (deterministically) where the FMU's
    μ_s ≥ μ_k would refuse them: μ_k alone stays below the known μ_s, μ_s alone above the
    known μ_k, and an estimated pair starts with μ_s ≥ μ_k."""
    for _ in range(50):
        start = {n: v * _uniform_factor(rng) for n, v in truth.items()}
        ok = True
        for n in start:
            if _kind(n) == "mu_k":
                other = n.replace("mu_k[", "mu_s[")
                limit = start.get(other, known.get(other))
                if limit is not None and start[n] > limit:
                    ok = False
            if _kind(n) == "mu_s":
                other = n.replace("mu_s[", "mu_k[")
                limit = start.get(other, known.get(other))
                if limit is not None and start[n] < limit:
                    ok = False
        if ok:
            return start
    # fall back: every μ_k below, every μ_s above its truth (always consistent)
    out = {}
    for n, v in truth.items():
        f = rng.uniform(0.2, 0.5)
        out[n] = v * (1.0 - f if _kind(n) == "mu_k" else 1.0 + f if _kind(n) == "mu_s" else _uniform_factor(rng))
    return out


def _bounds(name: str, truth: float, start: float, known: dict, variable) -> tuple:
    """[low, high] (and the scale) holding truth and start with room on both sides, inside
    the FMU's range and on the right side of a known μ_s or μ_k."""
    lo, hi = min(truth, start), max(truth, start)
    top = float(variable.max) if variable.max is not None else math.inf
    kind = _kind(name)
    if kind == "k":
        return [max(lo / 4.0, 1e-9), min(hi * 4.0, top)], "log"
    if kind == "b_v":
        return [0.0, min(3.0 * hi, top)], "linear"
    low, high = 0.5 * lo, min(2.0 * hi, top)
    if kind == "mu_k" and name.replace("mu_k[", "mu_s[") in known:
        high = min(high, known[name.replace("mu_k[", "mu_s[")])
    if kind == "mu_s" and name.replace("mu_s[", "mu_k[") in known:
        low = max(low, known[name.replace("mu_s[", "mu_k[")])
    return [low, high], "linear"


def _encoder(rng, output: str, joint: Joint) -> dict:
    """A channel's noise and count: link encoders 1–4 µrad on a 20–22 bit count, linear scales
    0.5–2 µm on a 0.5 or 1 µm count; motor encoders 2–5 µrad on an 18–20 bit count."""
    if output.startswith("theta_m["):
        return {"sigma": rng.uniform(2e-6, 5e-6), "resolution": 2 * math.pi / 2 ** int(rng.integers(18, 21))}
    if joint.kind == "prismatic":
        return {"sigma": rng.uniform(0.5e-6, 2e-6), "resolution": float(rng.choice([0.5e-6, 1e-6]))}
    return {"sigma": rng.uniform(1e-6, 4e-6), "resolution": 2 * math.pi / 2 ** int(rng.integers(20, 23))}


def _run_outputs(fmu: Path, t, motion, torques, outputs: list, parameters: dict):
    """One run at the FMU's default error control (the fit's model): a RunResult."""
    from ..fmu import content_hash
    from .runner import Payload, run
    from .spec import Torques

    data = fmu.read_bytes()
    logged = None
    if torques:
        logged = Torques(t, list(torques), np.column_stack([v for v in torques.values()]))
    return run(content_hash(data), Payload("probe", t, motion, logged, outputs, {}), dict(parameters), fmu_data=data)


def _coulomb_level(fmu: Path, t, motion, torques, joint: int, parameters: dict) -> float:
    """The median |F_friction[i]| − b_v|q'| while joint i slips (with b_v as in ``parameters``)."""
    res = _run_outputs(fmu, t, motion, torques, [f"F_friction[{joint}]", f"qd[{joint}]", f"stick[{joint}]"], parameters)
    if res.status != "ok":
        return math.nan
    f, qd, stick = res.values.T
    slipping = (stick < 0.5) & (np.abs(qd) > 1e-6)
    return float(np.median(np.abs(f[slipping]))) if slipping.any() else math.nan


def _spec_takes_resolution() -> bool:
    from . import spec

    return "resolution" in getattr(spec, "CHANNEL_KEYS", ())


def generate(
    fmu,
    seed: int,
    out_dir,
    *,
    arm: str | None = None,
    duration: float = 2.0,
    n_parameters: int | None = None,
    starts: int | None = None,
    substep: float = SUBSTEP,
    attempts: int = ATTEMPTS,
) -> FitProblem:
    """Draws the fit problem of ``seed`` for the FMU at ``fmu`` (a path, or an arm name of
    :data:`ARMS`) and writes its data into ``out_dir``: ``run.csv`` (the measured run),
    ``spec.json`` (the fit SPEC) and ``problem.json`` (:class:`FitProblem`). ``arm`` names the
    arm (default: the ARMS entry of that FMU, else its file stem) and so its start pose;
    ``duration`` s of data; ``n_parameters`` estimated (default 2–4, drawn); ``starts`` of the
    fit (default 2–4, drawn); ``substep``: the measured run's fixed sub-step. Raises
    :class:`GenerationError` when no draw of ``attempts`` passes the checks."""
    from fmpy import read_model_description

    from ..motion import motor_joints
    from .synthetic import measure, write_csv

    if isinstance(fmu, str) and fmu in ARMS:
        arm, fmu = fmu, ARMS[fmu].fmu
    fmu = Path(fmu).resolve()
    if arm is None:
        arm = next((a.name for a in ARMS.values() if a.fmu.resolve() == fmu), fmu.stem)
    profile = ARMS.get(arm, Arm(arm, fmu))
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    md = read_model_description(str(fmu))
    tunable = _tunable(md)
    joints = joints_of(md)
    by_index = {j.index: j for j in joints}
    motors = motor_joints(md)
    pool_joints = candidates(md)
    if not pool_joints:
        raise GenerationError(f"{fmu}: no joint has a flexible drive with friction (k[i] and mu_k[i])")
    flexible = [j.index for j in joints if j.drive != "rigid"]
    rng = np.random.default_rng([int(seed), 35, zlib.crc32(arm.encode())])  # the arm's own draws
    t = np.round(np.arange(0.0, duration + 0.5 * INTERVAL, INTERVAL), 12)
    reasons = []
    for attempt in range(1, attempts + 1):
        # which parameters
        n_joints = int(rng.integers(1, 3)) if len(pool_joints) > 1 else 1
        chosen = sorted(int(i) for i in rng.choice(pool_joints, size=n_joints, replace=False))
        pool = [f"{kind}[{i}]" for i in chosen for kind in KINDS if f"{kind}[{i}]" in tunable]
        p = n_parameters or int(rng.integers(2, 5))
        picked = set(rng.permutation(pool)[: min(p, len(pool))].tolist())
        estimated = [n for n in pool if n in picked]  # joint, then KINDS order
        est_joints = sorted({_joint(n) for n in estimated})
        # their true values (b_v below, once the motion is known)
        drawn = {}
        for i in est_joints:
            mu_k = rng.uniform(0.05, 0.3)
            drawn[f"mu_k[{i}]"] = mu_k
            drawn[f"mu_s[{i}]"] = mu_k * rng.uniform(1.1, 1.6)
            drawn[f"k[{i}]"] = float(tunable[f"k[{i}]"].start) * math.exp(rng.uniform(-math.log(2.5), math.log(2.5)))
        ratios = {i: rng.uniform(0.1, 0.5) for i in est_joints}
        motion, plans = plan_motion(rng, joints, profile.pose, duration)
        settings = {"static_start": True} if motors else {}
        channels = {}
        for i in flexible:
            channels[f"q[{i}]"] = {"column": f"link{i}", **_encoder(rng, f"q[{i}]", by_index[i])}
            if i in motors:
                channels[f"theta_m[{i}]"] = {"column": f"rotor{i}", **_encoder(rng, f"theta_m[{i}]", by_index[i])}
        noise_seed = int(rng.integers(0, 2**31))
        n_starts = starts or int(rng.integers(2, 5))
        start_rng = np.random.default_rng([int(seed), 35, zlib.crc32(arm.encode()), attempt])
        # motor drives: the torques of a PD loop following the plan, with the drawn values
        torques = {}
        try:
            if motors:
                torques = _loop_torques(fmu, md, motion, t, {**settings, **drawn}, motors)
            for i in est_joints:
                if f"b_v[{i}]" in estimated:
                    level = _coulomb_level(
                        fmu, t, motion, {f"tau_m[{m}]": v for m, v in torques.items()}, i, {**settings, **drawn}
                    )
                    if not math.isfinite(level) or level <= 0:
                        raise RuntimeError(f"joint {i} never slips in the probe run")
                    drawn[f"b_v[{i}]"] = ratios[i] * level / plans[i]["fast"]
        except Exception as e:  # noqa: BLE001 -- an FMU that refuses the loop's run (fmpy's FMICallException too)
            reasons.append(f"attempt {attempt}: {type(e).__name__}: {e}")
            continue
        truth = {n: float(drawn[n]) for n in estimated}
        known = {**settings, **{n: float(v) for n, v in drawn.items() if n not in truth}}
        record = [f"{g}[{i}]" for i in est_joints for g in ("n_stick", "t_stick")]
        torque_logs = {f"tau_m[{m}]": (f"tau{m}", _held(t, v)) for m, v in torques.items()}
        try:
            columns = measure(
                fmu,
                {**known, **truth, "h_min": substep, "h_max": substep},
                {o: (c["column"], c["sigma"], c["resolution"]) for o, c in channels.items()},
                duration=duration,
                step=INTERVAL,
                motion=motion,
                inputs={f"q_star[{j.index}]": f"motor{j.index}" for j in joints},
                seed=noise_seed,
                torques=torque_logs or None,
                noise_first=True,
                record=record,
            )
        except RuntimeError as e:
            reasons.append(f"attempt {attempt}: at fixed sub-steps: {e}")
            continue
        for i in motors:  # the FMU ignores a motor joint's q_star while stepping: its start position
            columns[f"motor{i}"] = np.full(len(t), columns[f"motor{i}"][0])
        checks, bad = {}, []
        for i in est_joints:
            n = columns.pop(f"n_stick[{i}]")
            stuck = columns.pop(f"t_stick[{i}]")
            phases = int(np.rint(n[-1] - n[0]))
            fraction = float(stuck[-1] / duration)
            checks[str(i)] = {"stiction_phases": phases, "stuck_fraction": fraction}
            if phases < 2 or not 0.05 <= fraction <= 0.9:
                bad.append(
                    f"joint {i}: {phases} stiction phases after the start, stuck {100 * fraction:.0f} % of the time"
                )
        if bad:
            reasons.append(f"attempt {attempt}: " + "; ".join(bad))
            continue
        default = _run_outputs(
            fmu, t, motion, {k: v[1](t) for k, v in torque_logs.items()}, list(channels), {**known, **truth}
        )
        if default.status != "ok":
            reasons.append(f"attempt {attempt}: at the default error control: {default.status}: {default.message}")
            continue
        initial = _starts(start_rng, truth, known)
        bounds, scales = {}, {}
        for n in estimated:
            bounds[n], scales[n] = _bounds(n, truth[n], initial[n], known, tunable[n])
        break
    else:
        raise GenerationError(
            f"{arm} (seed {seed}): no draw of {attempts} ran and stuck and slipped: " + " | ".join(reasons[-3:])
        )
    data = out_dir / "run.csv"
    write_csv(columns, data)
    resolution = _spec_takes_resolution()
    inputs = {f"q_star[{j.index}]": f"motor{j.index}" for j in joints}
    inputs.update({name: column for name, (column, _) in torque_logs.items()})
    spec = {
        "fmu": str(fmu),
        "experiment": [
            {
                "name": "run",
                "data": str(data.resolve()),
                "time": "t",
                "inputs": inputs,
                "parameters": dict(known),
                "measured": {
                    o: {
                        "column": c["column"],
                        "sigma": c["sigma"],
                        **({"resolution": c["resolution"]} if resolution else {}),
                    }
                    for o, c in channels.items()
                },
            }
        ],
        "estimate": {
            n: {"initial": initial[n], "bounds": bounds[n], **({"scale": "log"} if scales[n] == "log" else {})}
            for n in estimated
        },
        "options": {"starts": n_starts, "seed": int(seed)},
    }
    problem = FitProblem(
        arm=arm,
        seed=int(seed),
        fmu=str(fmu),
        duration=float(duration),
        attempts=attempt,
        joints=est_joints,
        estimated=estimated,
        truth=truth,
        known=known,
        initial=initial,
        bounds=bounds,
        channels=channels,
        motion={**motion.to_dict(), "plans": {str(i): v for i, v in plans.items()}, "substep": substep},
        checks=checks,
        data=str(data.resolve()),
        spec=spec,
    )
    (out_dir / "spec.json").write_text(json.dumps(spec, indent=1, default=_json_default) + "\n")
    (out_dir / "problem.json").write_text(json.dumps(problem.to_dict(), indent=1, default=_json_default) + "\n")
    return problem


def _held(t, values):
    """The torque log as a function of time (its value at each sample; measure() and the fit
    join the samples by a cubic spline)."""
    t = np.asarray(t, dtype=np.float64)
    values = np.asarray(values, dtype=np.float64)

    def f(x):
        return np.interp(x, t, values)

    return f


def _json_default(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, Path):
        return str(x)
    return repr(x)


# ---------------------------------------------------------------------------
# judging a fit


def simulation_cost(spec, values: dict, sigma: dict | None = None, error_tolerance: float | None = None) -> dict:
    """The simulation-error cost ½Σ((model − measured)/σ)² of the SPEC's experiments with the
    estimated parameters at ``values`` (single shooting; the FMU's ``error_tolerance`` if
    given, else as the SPEC says): {"cost", "channels" (per output), "status", "message"}. σ of
    a channel: ``sigma`` [output] when given, else the channel's own (noise and count, as the
    fit weighs it)."""
    from ..fmu import content_hash
    from .runner import Payload, run
    from .spec import FitSpec, load

    fs = spec if isinstance(spec, FitSpec) else load(spec)
    data = Path(fs.fmu).read_bytes()
    digest = content_hash(data)
    tolerance = fs.options.get("error_tolerance") if error_tolerance is None else error_tolerance
    settings = {} if tolerance is None else {"error_tolerance": tolerance}
    total, per = 0.0, {}
    many = len(fs.experiments) > 1
    for e in fs.experiments:
        outputs = [c.output for c in e.channels]
        payload = Payload(e.name, e.time, e.motion, e.torques, outputs, dict(e.parameters))
        res = run(digest, payload, {**values, **settings}, fmu_data=data)
        if res.status != "ok":
            return {"cost": math.inf, "channels": per, "status": res.status, "message": res.message}
        for k, c in enumerate(e.channels):
            name = f"{e.name}:{c.output}" if many else c.output
            std = (sigma or {}).get(name) or getattr(c, "std", c.sigma)
            r = (res.values[:, k] - c.values) / std
            per[name] = 0.5 * float(r @ r)
            total += per[name]
    return {"cost": total, "channels": per, "status": "ok", "message": ""}


def _effective_sigma(result: dict) -> dict | None:
    """{channel: σ} the fit weighed the residuals with, where its result says (method.noise's
    sigma and resolution), else None (the SPEC's own)."""
    noise = (result.get("method") or {}).get("noise")
    if not isinstance(noise, dict):
        return None
    out = {}
    for name, n in noise.items():
        try:
            out[name] = math.sqrt(float(n["sigma"]) ** 2 + float(n.get("resolution") or 0.0) ** 2 / 12.0)
        except (KeyError, TypeError, ValueError):
            return None
    return out


def judge(problem: FitProblem, result: dict) -> dict:
    """The fit's answer against the truth: per parameter the estimate, SE, z = (estimate −
    truth)/SE, within 2 and 3 SE; the costs at the answer and at the truth, both with the σ
    and at the FMU error_tolerance the fit's answer was computed with (where its result says:
    method.noise, method.error_tolerance; else the SPEC's, i.e. the FMU's default)."""
    from .spec import load

    sigma = _effective_sigma(result)
    tolerance = (result.get("method") or {}).get("error_tolerance")
    tolerance = float(tolerance) if isinstance(tolerance, (int, float)) and tolerance > 0 else None
    params = result.get("parameters") or {}
    answer = {n: float(params[n]["value"]) for n in problem.estimated if n in params}
    spec = load(problem.spec)
    at_truth = simulation_cost(spec, problem.truth, sigma, tolerance)
    at_answer = simulation_cost(spec, answer, sigma, tolerance) if len(answer) == len(problem.estimated) else None
    rows = {}
    for n in problem.estimated:
        p = params.get(n) or {}
        value, se = p.get("value"), p.get("std_error")
        truth = problem.truth[n]
        z = (value - truth) / se if value is not None and se and math.isfinite(se) and se > 0 else math.nan
        rows[n] = {
            "kind": _kind(n),
            "joint": _joint(n),
            "truth": truth,
            "initial": problem.initial[n],
            "bounds": problem.bounds[n],
            "estimate": value,
            "std_error": se,
            "z": z,
            "within_3se": bool(math.isfinite(z) and abs(z) <= 3.0),
            "within_2se": bool(math.isfinite(z) and abs(z) <= 2.0),
            "relative_error": (value - truth) / truth if value is not None and truth else math.nan,
            "at_bound": p.get("at_bound"),
        }
    cost_answer = at_answer["cost"] if at_answer else math.nan
    return {
        "parameters": rows,
        "cost": result.get("cost"),
        "cost_answer": cost_answer,
        "cost_truth": at_truth["cost"],
        "cost_ratio": cost_answer / at_truth["cost"] if at_truth["cost"] and math.isfinite(at_truth["cost"]) else None,
        "cost_sigma": "the fit's (method.noise)" if sigma else "the SPEC's (sigma, resolution)",
        "cost_error_tolerance": tolerance,
        "truth_run": at_truth["status"],
    }


# ---------------------------------------------------------------------------
# the suite


def _clean(x):
    """JSON-safe: NaN and inf as None, numpy scalars as numbers, unknown objects as text."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items() if k != "_internal"}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, np.generic):
        return _clean(x.item())
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if x is None or isinstance(x, (bool, int, str)):
        return x
    return repr(x)


def run_suite(
    arms: list,
    draws: int,
    seed: int,
    out,
    workers: int = 2,
    duration: float = 2.0,
    n_parameters: int | None = None,
    starts: int | None = None,
    client=None,
    progress=print,
) -> dict:
    """Generates and fits draw 0..draws−1 (seeds ``seed`` + draw) of every arm (names of
    :data:`ARMS`, ``name=path`` or FMU paths), into DIR ``out``: per (arm, draw) a directory with the data,
    the SPEC, the problem and fit.json; ``suite.json`` (rewritten after every fit) and
    ``suite.md``. The fits' runs go to ``client``, else to a LocalCluster of ``workers``
    processes (``workers=0``: in this process). Returns the content of suite.json."""
    from . import fit

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    own = None
    if client is None and workers:
        client, own = _connect(workers)
    t0 = time.perf_counter()
    fits, rows = [], []
    settings = {
        "arms": list(arms),
        "draws": draws,
        "seed": seed,
        "workers": workers,
        "duration_s": duration,
        "n_parameters": n_parameters,
        "starts": starts,
        "substep_s": SUBSTEP,
    }
    try:
        for given in arms:
            arm, fmu = _arm(given)
            for draw in range(draws):
                s = seed + draw
                name = f"{arm}-{s}"
                where = out / name
                entry = {"arm": arm, "fmu": str(fmu), "draw": draw, "seed": s, "dir": name}
                started = time.perf_counter()
                try:
                    problem = generate(
                        fmu, s, where, arm=arm, duration=duration, n_parameters=n_parameters, starts=starts
                    )
                except GenerationError as e:
                    entry.update(error=f"generation: {e}")
                    fits.append(entry)
                    progress(f"bench: {name}: {entry['error']}")
                    continue
                entry.update(
                    estimated=problem.estimated,
                    truth=problem.truth,
                    attempts=problem.attempts,
                    generation_s=time.perf_counter() - started,
                )
                n_starts = problem.spec["options"]["starts"]
                progress(f"bench: {name}: fitting {', '.join(problem.estimated)} (starts {n_starts})")
                try:
                    kwargs = {"client": client} if client is not None else {"workers": 0}
                    result = fit(problem.spec, **kwargs)
                except Exception as e:  # noqa: BLE001 -- a fit that crashes is a result of the benchmark
                    entry.update(error=f"fit: {type(e).__name__}: {e}", fit_wall_s=time.perf_counter() - started)
                    fits.append(entry)
                    progress(f"bench: {name}: {entry['error']}")
                    _write(out, settings, fits, rows, t0)
                    continue
                (where / "fit.json").write_text(json.dumps(_clean(result), indent=1) + "\n")
                verdict = judge(problem, result)
                entry.update(
                    wall_s=result.get("wall_s"),
                    n_evaluations=result.get("n_evaluations"),
                    cost=result.get("cost"),
                    cost_answer=verdict["cost_answer"],
                    cost_truth=verdict["cost_truth"],
                    cost_ratio=verdict["cost_ratio"],
                    cost_sigma=verdict["cost_sigma"],
                    cost_error_tolerance=verdict["cost_error_tolerance"],
                    warnings=list(result.get("warnings") or []),
                    converged=result.get("converged"),
                    trusted=result.get("trusted"),
                    verdict=result.get("verdict"),
                    method=result.get("method"),
                    parameters=verdict["parameters"],
                )
                fits.append(entry)
                for n, r in verdict["parameters"].items():
                    rows.append(
                        {
                            "arm": entry["arm"],
                            "seed": s,
                            "parameter": n,
                            **r,
                            "cost_ratio": verdict["cost_ratio"],
                            "warned": bool(entry["warnings"]),
                        }
                    )
                zs = ", ".join(f"{n} {r['z']:+.2f}" for n, r in verdict["parameters"].items())
                progress(
                    f"bench: {name}: {result.get('wall_s', math.nan):.0f} s, {result.get('n_evaluations')} runs, "
                    f"cost {verdict['cost_answer']:.6g} (truth {verdict['cost_truth']:.6g}); z: {zs}"
                )
                _write(out, settings, fits, rows, t0)
    finally:
        if own is not None:
            client.close()
            own.close()
    return _write(out, settings, fits, rows, t0)


def _arm(given: str) -> tuple:
    """(name, FMU path) of an arm given as a name of :data:`ARMS`, ``name=path`` (an ARMS arm's
    pose with another build of its FMU) or a path (named by its file's stem)."""
    if "=" in given:
        name, path = given.split("=", 1)
        return name, Path(path).resolve()
    if given in ARMS:
        return given, ARMS[given].fmu
    return Path(given).stem, Path(given).resolve()


def _connect(workers: int):
    try:
        from ..cluster import connect
    except ImportError:  # an older package: the sweep's
        from ..sweep import _client as connect
    return connect(None, workers)


def summarize(rows: list, fits: list) -> dict:
    """Per parameter kind, per arm and in total: n, the fractions within 3 and 2 SE, the
    median |z|, the median cost ratio (answer/truth) and the fits that warned."""

    def group(select_rows, select_fits) -> dict:
        z = [abs(r["z"]) for r in select_rows if r["z"] is not None and math.isfinite(r["z"])]
        ratios = [f["cost_ratio"] for f in select_fits if f.get("cost_ratio") is not None]
        rel = [abs(r["relative_error"]) for r in select_rows if _finite(r.get("relative_error"))]
        n = len(select_rows)
        return {
            "n": n,
            "within_3se": sum(r["within_3se"] for r in select_rows) / n if n else None,
            "within_2se": sum(r["within_2se"] for r in select_rows) / n if n else None,
            "median_abs_z": statistics.median(z) if z else None,
            "median_abs_relative_error": statistics.median(rel) if rel else None,
            "median_cost_ratio": statistics.median(ratios) if ratios else None,
            "fits": len(select_fits),
            "fits_warned": sum(1 for f in select_fits if f.get("warnings")),
            "fits_failed": sum(1 for f in select_fits if "error" in f),
        }

    done = [f for f in fits if "parameters" in f]
    kinds = sorted({r["kind"] for r in rows}, key=lambda k: (*KINDS, k).index(k))
    arms = list(dict.fromkeys(f["arm"] for f in fits))
    return {
        "by_kind": {
            k: group(
                [r for r in rows if r["kind"] == k],
                [f for f in done if any(_kind(n) == k for n in f["parameters"])],
            )
            for k in kinds
        },
        "by_arm": {a: group([r for r in rows if r["arm"] == a], [f for f in fits if f["arm"] == a]) for a in arms},
        "total": group(rows, fits),
    }


def _finite(x) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def _write(out: Path, settings: dict, fits: list, rows: list, t0: float) -> dict:
    summary = summarize(rows, fits)
    doc = _clean(
        {
            "settings": settings,
            "wall_s": time.perf_counter() - t0,
            "summary": summary,
            "fits": fits,
            "rows": rows,
        }
    )
    tmp = out / "suite.json.tmp"
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    tmp.replace(out / "suite.json")
    (out / "suite.md").write_text(markdown(doc))
    return doc


def _fmt(x, spec: str = ".2f") -> str:
    return "–" if x is None else format(x, spec)


def markdown(doc: dict) -> str:
    """suite.md: the coverage tables per parameter kind and per arm, totals, and every fit."""
    s = doc["settings"]
    lines = [
        "# Identification benchmark of `stickslip fit`",
        "",
        f"Arms {', '.join(s['arms'])}; {s['draws']} draw(s) each from seed {s['seed']}; {s['duration_s']:g} s of data "
        f"at 1 ms, measured at fixed {s['substep_s']:g} s sub-steps; the SPECs leave the FMU's error control at its "
        f"default (the fit may tighten it itself); {s['workers']} worker(s); wall {doc['wall_s']:.0f} s.",
        "",
        "Coverage: the fraction of estimates whose truth lies within 3 (2) reported standard errors; "
        "|z| = |estimate − truth|/SE; cost ratio: the simulation-error cost at the answer over that at the "
        "truth, both at the error tolerance of the fit's answer (≤ 1: the truth's basin or better; ≫ 1: a wrong "
        "minimum). A fit warned: its result has warnings; failed: generation or fit raised.",
        "",
    ]
    header = (
        "| {} | n | within 3 SE | within 2 SE | median \\|z\\| | median \\|estimate/truth − 1\\| "
        "| median cost ratio | fits warned | fits failed |"
    )
    rule = "|---|---|---|---|---|---|---|---|---|"

    def row(name, g):
        return (
            f"| {name} | {g['n']} | {_fmt(g['within_3se'])} | {_fmt(g['within_2se'])} | {_fmt(g['median_abs_z'])} | "
            f"{_fmt(g['median_abs_relative_error'], '.2g')} | {_fmt(g['median_cost_ratio'], '.4g')} | "
            f"{g['fits_warned']} of {g['fits']} | {g['fits_failed']} |"
        )

    summary = doc["summary"]
    for title, key, col in (("Per parameter kind", "by_kind", "kind"), ("Per arm", "by_arm", "arm")):
        lines += [f"## {title}", "", header.format(col), rule]
        lines += [row(f"`{k}`" if key == "by_kind" else k, g) for k, g in summary[key].items()]
        lines += [row("**total**", summary["total"]), ""]
    lines += [
        "## Every fit",
        "",
        "| fit | parameter | truth | initial | estimate ± SE | z | cost answer / truth | wall s | FMU runs "
        "| warnings |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for f in doc["fits"]:
        if "error" in f:
            lines.append(f"| {f['dir']} | – | – | – | {f['error'][:160]} | – | – | – | – | – |")
            continue
        for n, r in f["parameters"].items():
            lines.append(
                f"| {f['dir']} | `{n}` | {r['truth']:.6g} | {r['initial']:.6g} | "
                f"{_fmt(r['estimate'], '.6g')} ± {_fmt(r['std_error'], '.2g')} | {_fmt(r['z'], '+.2f')} | "
                f"{_fmt(f.get('cost_answer'), '.6g')} / {_fmt(f.get('cost_truth'), '.6g')} | "
                f"{_fmt(f.get('wall_s'), '.0f')} | {f.get('n_evaluations')} | {len(f.get('warnings') or [])} |"
            )
    return "\n".join(lines) + "\n"


__all__ = [
    "ARMS",
    "Arm",
    "FitProblem",
    "GenerationError",
    "PlannedMotion",
    "candidates",
    "generate",
    "joints_of",
    "judge",
    "markdown",
    "run_suite",
    "simulation_cost",
    "summarize",
]
