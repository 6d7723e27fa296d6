#!/usr/bin/env python3
"""Axis control of the motor-driven arm: a cascaded position/velocity controller at 1 kHz.

The controller is what a servo drive runs, written in Python and closed around the FMU of
``models/reference_rrpr_motor.toml`` (the reference RRPR arm whose joints 1 and 3 are turned
by motors through a gear spring) through fmpy's FMU2Slave. Every millisecond it reads the
encoders, computes a motor torque, sets ``tau_m[i]`` and calls ``fmi2DoStep``:

    r, r', r''  (the path)                                   torque   tau_m, saturated
        |                                                    feed-forward J r'' (+ F_c tanh(r'/v_eps))
        v              v_cmd = r' + Kv (r - y)                  |
    (+)--> Kv --(+)--> [ v_cmd - v ] --> Kp (1 + wi/s) --(+)--> 1/N --> [FMU] --+--> theta_m
     ^ -            ^ -   velocity PI (integral optional)                    |      (motor encoder)
     |              |                                                        +--> q
     |              +-- v = (theta_m,k - theta_m,k-1) / (N T): the motor encoder's difference
     +-- y = theta_m / N (motor encoder, the default) or q (a link-side encoder)

All gains are in link units (rad or m at the joint): Kv in 1/s, the velocity loop's
proportional gain Kp = J wv (J the axis' inertia seen at the link, wv the velocity loop's
bandwidth) and its integral corner wi. The encoders are quantized (20 bit per motor
revolution, 20 bit per link revolution for the link encoder of joint 1); the velocity is the
backward difference of the motor encoder (the mean speed over the last period, half a sample
late), not the FMU's omega_m (``--velocity tacho`` uses omega_m, a tachometer). The torque is
held over the step (zero-order hold, no input derivatives), limited to the motor's peak torque
with conditional integration (anti-windup).

Three experiments (docs/control.md shows and explains the figures):

(a) ``tracking``: the reference motion (q1 0 -> pi/3 and q3 0.8 -> 1.0 m on cycloids over
    1.5 s, held to 2 s; joints 2 and 4 prescribed as in the reference run) on the arm as its
    model file gives it, both axes on their motor encoders: the link-side error, the gear's
    wind-up theta_m/N - q, the stick flags of link and rotor, the motor torques.
(b) ``hunting``: a slow positioning move of joint 1 (10 mrad in 1 s, held to 5 s) with a
    harmonic-drive gear (k = 2.5e4 N.m/rad, lost motion +-0.5 arcmin) and bearing friction
    with a decreasing (Stribeck) characteristic, the position loop closed on a link-side
    encoder: with integral action the axis hunts (stick, wind up, slip past, reverse), without
    it (P position, P velocity: a PD) it stops with a steady-state error and no cycle; with a
    Coulomb friction feed-forward (and no integrator) it stops nearer the target, no cycle;
    the same PI on the motor encoder does not hunt (the friction is outside that loop).
(c) ``encoders``: the same move with the arm's own friction (mu_s = mu_k = 0.2), motor
    encoder against link encoder: the motor loop is in position to a few counts while the
    link is off by the gear's wind-up and lost motion; the link loop puts the link
    on the target but goes unstable at a position gain the motor loop takes easily (a sweep
    of Kv, and the linearized loop's stability limit).

Run it (about 20 s, --quick 12 s; writes PNGs, one CSV per run and summary.json into --out;
``--docs-figures docs/figures`` also writes the figures, in 64 colours, for docs/control.md):

    python examples/axis_control.py [--fmu target/fmu/reference_rrpr_motor.fmu] \
        [--out results/axis_control] [--docs-figures docs/figures] [--quick] [--velocity tacho]

The FMU: ``bash scripts/build_fmu.sh --platforms linux64 --model models/reference_rrpr_motor.toml
--out target/fmu/reference_rrpr_motor.fmu``. Or import it: :func:`run` steps one
:class:`Scenario` and returns a dict of arrays; :func:`hunting_metrics` measures a run.
"""

from __future__ import annotations

import argparse
import csv
import functools
import json
import math
import shutil
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FMU = ROOT / "target" / "fmu" / "reference_rrpr_motor.fmu"
DEFAULT_OUT = ROOT / "results" / "axis_control"
DOCS_FIGURES = ROOT / "docs" / "figures"

STEP = 1e-3  # the controller's period: 1 kHz
MOTOR_JOINTS = (1, 3)
RIGID_JOINTS = (2, 4)
UNIT = {1: "rad", 3: "m"}

# ---------------------------------------------------------------------------
# the plant as the controller knows it (nameplate and commissioning data)

# Link-side inertia of each axis without the rotor: what a torque-step identification
# (a drive's auto-tuning) measures at the start pose q = (0, 0, 0.8 m, 0): 0.1 N.m on the
# frictionless joint-1 motor gives q1'' = 1.238 rad/s2, i.e. 100 * 0.1 / 1.238 = 8.08 kg.m2 in
# all, of which N^2 J_m = 3.0 is the rotor: 5.08 kg.m2 of links (column, slideway at the axis,
# slider 0.4 m and wrist 0.9 m out). Joint 3 moves links 3 and 4: 8 + 4 = 12 kg (11.9 measured).
# The controller keeps these constants: as q3 grows to 1.0 m and q2 tilts, joint 1's true
# inertia grows by about a fifth, which the feedback absorbs.
LINK_INERTIA = {1: 5.08, 3: 11.9}
# Peak torques of the motors: joint 1 a 400 W AC servo (rated 1.27 N.m, peak 3.8 N.m),
# joint 3 a 200 W one on the ball screw (rated 0.64 N.m, peak 1.9 N.m). The reference
# motion needs at most 0.25 and 0.3 N.m.
TORQUE_LIMIT = {1: 3.8, 3: 1.9}
# Encoders: a 20-bit single-turn motor encoder (2^20 counts per motor revolution; 6.0e-8 rad at
# joint 1 behind N = 100, 9.5e-9 m at joint 3 behind the 10 mm ball screw); joint 1's link-side
# encoder (experiments (b), (c)) a 20-bit absolute encoder on the output flange: 6.0e-6 rad.
MOTOR_COUNTS = 2**20
LINK_RESOLUTION = {1: 2.0 * math.pi / 2**20, 3: 1e-7}  # rad; m (a 0.1 um linear scale)

# ---------------------------------------------------------------------------
# the plant variants of the experiments (FMU parameters set before initialization)

# (b), (c): joint 1's gear as a real harmonic drive of this size (a CSF-25-100 class gear):
# torsional stiffness 2.5e4 N.m/rad (catalogue K3, the stiffness above a quarter of the rated
# torque; the model file's k = 1e6 N.m/rad is the source study's, forty times stiffer than
# such a gear), and a lost motion of 1 arcmin, +-0.5 arcmin about the centre: the clearance of
# eq. (2.1) is one-sided, Delta = 1.45e-4 rad. The locked-rotor mode of the link on this
# spring is at sqrt(k/I) = sqrt(2.5e4/5.08) = 70 rad/s (11 Hz), the free-free mode with the
# rotor (N^2 J_m = 3 kg.m2) at 115 rad/s (18 Hz): the first modes of a real arm.
HARMONIC_DRIVE = {"k[1]": 2.5e4, "Delta[1]": 1.45e-4}
# (b): joint 1's bearing friction with a decreasing characteristic: static mu_s = 0.2 (the
# study's coefficient), kinetic mu_k = 0.1 once sliding, mu(v) = mu_k + (mu_s - mu_k)
# exp(-|q'|/v_s) with v_s = 0.005 rad/s, i.e. 0.25 mm/s of sliding at the bearing surfaces
# (d/2 = 0.05 m): boundary-lubricated contacts lose their static excess within 0.1 to 1 mm/s
# (Armstrong-Helouvry, Dupont and Canudas de Wit, Automatica 30 (1994) 1083, sec. 2.1). The
# bearing load of the arm's weight (N_normal[1] = 1834 N at the start pose) makes the lever
# load 83.2 N.m per unit coefficient: 16.6 N.m of static and 8.3 N.m of kinetic friction at
# the link, plus the rotor's 0.03 N.m (3 N.m at the link).
STRIBECK = {"mu_s[1]": 0.2, "mu_k[1]": 0.1, "v_s[1]": 0.005}
# Joint 1's friction per unit coefficient at the start pose (eq. 3.14): the weight on the
# thrust bearing |f_z| = 510.1 N and the overturning moment 79.46 N.m of the arm's overhang on
# the radial bearings 0.12 m apart, R_A = R_B = 662.2 N (the FMU's f[1,3], n[1,2] and
# N_normal[1] = 1834.5 N): R_A d_A/2 + R_B d_B/2 + 2/3 |f_z| d_C/2 = 66.2 + 17.0 N.m.
BEARING_LEVER = 83.2  # N.m
# (b): the feed-forward's friction estimate, link side: what a constant-speed run measures,
# 8.3 N.m of kinetic bearing friction + 3 N.m of rotor friction behind the gear.
FRICTION_ESTIMATE = 11.0
# (c): the arm's own joint friction (mu_s = mu_k = 0.2, no Stribeck drop: the study's).
OWN_FRICTION = {"mu_s[1]": 0.2, "mu_k[1]": 0.2, "v_s[1]": 0.0}


@dataclass(frozen=True)
class Gains:
    """One axis' cascade, in link units (rad or m at the joint)."""

    kv: float  # position loop gain, 1/s: v_cmd = r' + kv (r - y)
    wv: float  # velocity loop bandwidth, rad/s: Kp = J wv
    wi: float  # integral corner of the velocity PI, rad/s: Ki = Kp wi
    integral: bool = True
    feedback: str = "motor"  # position from the motor encoder (theta_m / N) or "link" (q)
    velocity_ff: bool = True  # v_cmd gets r'
    torque_ff: bool = True  # tau gets J r''
    friction_ff: float = 0.0  # Coulomb friction feed-forward F_c tanh(r'/v_eps), link side (N.m or N)
    friction_ff_speed: float = 1e-3  # v_eps: the feed-forward's smoothing of sgn r', rad/s or m/s


# (a) on the model file's stiff gears (k = 1e6: the locked-link mode at sqrt(k/I) = 440 rad/s,
# the free mode at 730 rad/s for joint 1; joint 3's at 290 and 320 rad/s): velocity loops of
# 250 rad/s (40 Hz) bandwidth, the integral corner a quarter below it (wi = 60 rad/s), the
# position loop another quarter below (Kv = 60 1/s): the usual cascade spacing, each loop
# seeing the inner one as a unit gain. Motor encoders on both axes; the sampled linear loop
# (linear_loop_radius with k = 1e6) is stable beyond Kv = 400/s.
TRACKING_GAINS = {1: Gains(kv=60.0, wv=250.0, wi=60.0), 3: Gains(kv=60.0, wv=250.0, wi=60.0)}
# (b), (c) joint 1 on the harmonic drive: the velocity loop lowered to 80 rad/s (13 Hz, between
# the gear's link mode at 70 and its free mode at 115 rad/s), wi = 20 rad/s, Kv = 20 1/s, the
# same spacing. A link-side encoder needs the low velocity loop: the stiffer the motor is held,
# the less the motor loop damps the link mode (its sampled linear loop is unstable from
# Kv = 32/s at wv = 80 rad/s, from 13/s at 150 rad/s; the motor encoder's from 178/s).
POSITIONING_GAINS = Gains(kv=20.0, wv=80.0, wi=20.0)
# Joint 3 holds its position (0.8 m) meanwhile, on its motor encoder.
HOLD_GAINS = Gains(kv=60.0, wv=250.0, wi=60.0)


def stiffness(gains: Gains, joint: int = 1, gear_ratio: float = 100.0, rotor_inertia: float = 3e-4) -> float:
    """The static stiffness of the P position / P velocity cascade at rest: a position error e
    gives the torque Kp Kv e = J wv Kv e (link side), N.m/rad."""
    return (LINK_INERTIA[joint] + gear_ratio**2 * rotor_inertia) * gains.wv * gains.kv


def dead_band(gains: Gains, static_friction: float, rotor_coulomb: float = 0.03, gear_ratio: float = 100.0) -> float:
    """The largest error at which a P cascade (no integrator) leaves the axis stuck: the loop's
    torque J wv Kv |e| below the static friction of the link plus the rotor's N tau_c."""
    return (static_friction + gear_ratio * rotor_coulomb) / stiffness(gains)


# ---------------------------------------------------------------------------
# paths


def cycloid(start: float, end: float, duration: float, t0: float = 0.0):
    """The cycloidal point-to-point path start -> end over [t0, t0 + duration]: t -> (r, r', r'')."""
    from stickslip.motion import cycloidal

    def path(t: float):
        return cycloidal(start, end, t - t0, duration)

    return path


def hold(value: float):
    return lambda t: (value, 0.0, 0.0)


def reference_paths():
    """The reference motion (src/motion.rs): every joint on its cycloid over 1.5 s."""
    from stickslip.motion import MOTION_TIME, REFERENCE_PROFILES

    return {j: cycloid(a, b, MOTION_TIME) for j, (a, b) in enumerate(REFERENCE_PROFILES, start=1)}


# The positioning move of (b) and (c): joint 1 by 10 mrad (10 mm at the gripper 1 m out) in
# 1 s, a peak speed of 0.02 rad/s, 4 v_s: the move itself crosses the Stribeck region.
MOVE = (0.0, 0.01, 1.0)  # start, end (rad), duration (s)


def positioning_paths(move=MOVE):
    start, end, duration = move
    return {1: cycloid(start, end, duration), 2: hold(0.0), 3: hold(0.8), 4: hold(0.0)}


@dataclass
class Scenario:
    """One closed-loop run: the FMU's start values, the paths of all joints (the rigid
    joints' are their prescribed motion) and the gains of the motor axes."""

    name: str
    title: str
    end: float
    paths: dict
    gains: dict
    parameters: dict = field(default_factory=dict)
    move_end: float = 1.0  # when the path comes to rest (for the metrics)


def tracking_scenario(end: float = 2.0) -> Scenario:
    return Scenario(
        "a_tracking", "reference motion, motor encoders", end, reference_paths(), dict(TRACKING_GAINS), move_end=1.5
    )


def hunting_scenarios(end: float = 5.0, move=MOVE) -> list:
    """(b): link-encoder loop of joint 1 on the harmonic drive with Stribeck friction; with
    integral action (PI), without (P: a PD on the position), P with a friction feed-forward;
    and the PI on the motor encoder, for comparison."""
    p = {**HARMONIC_DRIVE, **STRIBECK}
    link = replace(POSITIONING_GAINS, feedback="link")
    variants = (
        ("b_PI", "PI velocity loop (integral action)", link),
        ("b_P", "P velocity loop (no integral: a PD)", replace(link, integral=False)),
        ("b_P_friction_ff", "P + friction feed-forward", replace(link, integral=False, friction_ff=FRICTION_ESTIMATE)),
        ("b_PI_motor_encoder", "PI on the motor encoder instead", replace(link, feedback="motor")),
    )
    return [
        Scenario(n, t, end, positioning_paths(move), {1: g, 3: HOLD_GAINS}, p, move_end=move[2]) for n, t, g in variants
    ]


def encoder_scenarios(end: float = 4.0, move=MOVE, unstable_kv: float = 120.0) -> list:
    """(c): motor encoder against link encoder, PI, the arm's own friction on the harmonic
    drive; and the link loop at a gain the motor loop takes (``unstable_kv``)."""
    p = {**HARMONIC_DRIVE, **OWN_FRICTION}
    g = POSITIONING_GAINS
    variants = (
        ("c_motor", f"motor encoder, Kv = {g.kv:g}/s", g),
        ("c_link", f"link encoder, Kv = {g.kv:g}/s", replace(g, feedback="link")),
        ("c_link_fast", f"link encoder, Kv = {unstable_kv:g}/s", replace(g, feedback="link", kv=unstable_kv)),
    )
    return [
        Scenario(n, t, end, positioning_paths(move), {1: gg, 3: HOLD_GAINS}, p, move_end=move[2])
        for n, t, gg in variants
    ]


# ---------------------------------------------------------------------------
# the controller


def quantize(x: float, resolution: float) -> float:
    """An encoder's reading: x rounded to whole counts."""
    return round(x / resolution) * resolution if resolution > 0.0 else x


class AxisController:
    """The cascade of one motor axis: P position loop, PI (or P) velocity loop, feed-forward,
    torque limit; link units inside, motor torque out."""

    def __init__(
        self,
        gains: Gains,
        gear_ratio: float,
        rotor_inertia: float,
        link_inertia: float,
        torque_limit: float,
        link_resolution: float,
        velocity: str = "encoder",
        quantized: bool = True,
    ):
        self.g = gains
        self.n = gear_ratio
        self.inertia = link_inertia + gear_ratio**2 * rotor_inertia  # J seen at the link
        self.kp = self.inertia * gains.wv
        self.ki = self.kp * gains.wi if gains.integral else 0.0
        self.limit = torque_limit
        self.motor_resolution = 2.0 * math.pi / MOTOR_COUNTS if quantized else 0.0
        self.link_resolution = link_resolution if quantized else 0.0
        self.velocity = velocity
        self.integrator = 0.0  # link-side torque (N.m or N)
        self.previous = None  # last motor encoder reading, rad

    def start(self, theta_m: float, holding_torque: float):
        """Bumpless start: the integrator holds the motor torque the gear carries at rest
        (tau_load of a static start), the encoder difference starts from the first reading."""
        self.integrator = holding_torque * self.n if self.g.integral else 0.0
        self.previous = quantize(theta_m, self.motor_resolution)

    def update(self, r: float, rd: float, rdd: float, theta_m: float, q: float, omega_m: float, dt: float):
        """The motor torque for the next period, from the path and the sensors; and what the
        controller saw: (tau_m, y, v, torque feed-forward)."""
        g = self.g
        encoder = quantize(theta_m, self.motor_resolution)
        if g.feedback == "motor":
            y = encoder / self.n
        elif g.feedback == "link":
            y = quantize(q, self.link_resolution)
        else:
            raise ValueError(f"feedback {g.feedback!r}: 'motor' or 'link'")
        if self.velocity == "tacho":
            v = omega_m / self.n
        else:
            v = (encoder - self.previous) / (dt * self.n)
        self.previous = encoder
        v_cmd = g.kv * (r - y) + (rd if g.velocity_ff else 0.0)
        ev = v_cmd - v
        ff = self.inertia * rdd if g.torque_ff else 0.0
        if g.friction_ff:
            ff += g.friction_ff * math.tanh(rd / g.friction_ff_speed)
        demand = (self.kp * ev + self.integrator + ff) / self.n
        tau = min(self.limit, max(-self.limit, demand))
        # conditional integration: no integration while the demand is cut by the limit
        if self.ki and tau == demand:
            self.integrator += self.ki * ev * dt
        return tau, y, v, ff / self.n


# ---------------------------------------------------------------------------
# the closed loop


LOGGED = (
    "r",
    "rd",
    "q",
    "qd",
    "x",
    "xd",
    "y",
    "v",
    "tau_m",
    "tau_ff",
    "tau_load",
    "windup",
    "F_drive",
    "F_friction",
    "stick",
    "stick_m",
)


def run(
    scenario: Scenario,
    fmu: str | Path | None = None,
    step: float = STEP,
    velocity: str = "encoder",
    quantized: bool = True,
) -> dict:
    """Steps the closed loop of ``scenario`` from t = 0 to its end. Returns a dict: ``time``
    (n+1 points) and per logged quantity a dict {joint: array} for the motor joints:
    r, rd (path), q, qd (link), x = theta_m/N, xd = omega_m/N (motor, link units), y, v (what
    the controller measured), tau_m (its output), tau_ff (its feed-forward part), tau_load
    (F/N), windup (eps_joint = theta_m/N - q), F_drive, F_friction, stick, stick_m (0/1);
    ``quantized=False``: ideal encoders (no counts);
    ``wall`` the wall time, ``n_substeps`` the FMU's Newmark sub-steps."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    fmu = str(fmu or DEFAULT_FMU)
    md = read_model_description(fmu)
    variables = {v.name: v for v in md.modelVariables}
    vr = {name: v.valueReference for name, v in variables.items()}
    joints = tuple(j for j in MOTOR_JOINTS if f"tau_m[{j}]" in vr)
    if joints != MOTOR_JOINTS:
        raise ValueError(f"{fmu}: expected motor drives on joints {MOTOR_JOINTS} (models/reference_rrpr_motor.toml)")
    unzipdir = extract(fmu, unzipdir=tempfile.mkdtemp(prefix="axis_control_"))
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName=scenario.name,
    )
    n = round(scenario.end / step)
    log = {k: {j: np.zeros(n + 1) for j in joints} for k in LOGGED}
    log["time"] = np.array([k * step for k in range(n + 1)])
    reals = ("q", "qd", "theta_m", "omega_m", "tau_load", "eps_joint", "F_drive", "F_friction")
    read_vrs = [vr[f"{name}[{j}]"] for j in joints for name in reals]
    bool_vrs = [vr[f"{name}[{j}]"] for j in joints for name in ("stick", "stick_m")]
    tau_vrs = [vr[f"tau_m[{j}]"] for j in joints]
    rigid_vrs = [vr[f"{g}[{j}]"] for j in RIGID_JOINTS for g in ("q_star", "qd_star", "qdd_star")]
    started = time.perf_counter()
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        # static start: each rotor turned so that its gear spring holds the link at rest
        # against gravity (tau_load then reads the holding torque)
        slave.setBoolean([vr["static_start"]], [True])
        for name, value in scenario.parameters.items():
            slave.setReal([vr[name]], [float(value)])
        slave.enterInitializationMode()
        # the start pose: q_star of every joint (the motor joints' start position)
        for j in range(1, 5):
            r, rd, rdd = scenario.paths[j](0.0)
            slave.setReal([vr[f"q_star[{j}]"], vr[f"qd_star[{j}]"], vr[f"qdd_star[{j}]"]], [r, rd, rdd])
        slave.exitInitializationMode()
        param = lambda name: slave.getReal([vr[name]])[0]  # noqa: E731
        controllers = {
            j: AxisController(
                scenario.gains[j],
                param(f"gear_ratio[{j}]"),
                param(f"J_m[{j}]"),
                LINK_INERTIA[j],
                TORQUE_LIMIT[j],
                LINK_RESOLUTION[j],
                velocity,
                quantized,
            )
            for j in joints
        }
        for j in joints:
            controllers[j].start(param(f"theta_m[{j}]"), param(f"tau_load[{j}]"))
        for k in range(n + 1):
            t = k * step
            values = slave.getReal(read_vrs)
            flags = slave.getBoolean(bool_vrs)
            taus = []
            for m, j in enumerate(joints):
                q, qd, theta, omega, tau_load, windup, f_drive, f_friction = values[
                    m * len(reals) : (m + 1) * len(reals)
                ]
                r, rd, rdd = scenario.paths[j](t)
                c = controllers[j]
                tau, y, v, ff = c.update(r, rd, rdd, theta, q, omega, step)
                taus.append(tau)
                row = {
                    "r": r,
                    "rd": rd,
                    "q": q,
                    "qd": qd,
                    "x": theta / c.n,
                    "xd": omega / c.n,
                    "y": y,
                    "v": v,
                    "tau_m": tau,
                    "tau_ff": ff,
                    "tau_load": tau_load,
                    "windup": windup,
                    "F_drive": f_drive,
                    "F_friction": f_friction,
                    "stick": float(flags[2 * m] != 0),
                    "stick_m": float(flags[2 * m + 1] != 0),
                }
                for key, value in row.items():
                    log[key][j][k] = value
            if k == n:
                break
            slave.setReal(tau_vrs, taus)
            rigid = []
            for j in RIGID_JOINTS:
                rigid.extend(scenario.paths[j](t))
            slave.setReal(rigid_vrs, rigid)
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        log["n_substeps"] = slave.getReal([vr["n_substeps"]])[0]
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)
    log["wall"] = time.perf_counter() - started
    log["scenario"] = scenario
    return log


# ---------------------------------------------------------------------------
# measuring hunting


def crossings(e: np.ndarray, band: float) -> np.ndarray:
    """Indices where e changes sign, counted with a hysteresis of +-band (a crossing is from
    above +band to below -band or back): numerical zeros and encoder counts are no cycles."""
    state, found = 0, []
    for k, value in enumerate(e):
        s = 1 if value > band else (-1 if value < -band else 0)
        if s and s != state:
            if state:
                found.append(k)
            state = s
    return np.array(found, dtype=int)


def rising_edges(flag: np.ndarray) -> int:
    return int(np.sum((flag[1:] > 0.5) & (flag[:-1] < 0.5)))


def hunting_metrics(log: dict, joint: int = 1, settle: float = 1.0, band: float = 1e-6) -> dict:
    """The motion of ``joint`` from ``settle`` seconds after its path came to rest to the end
    (the window), measured as a servo engineer would:

    * ``sign_changes``: sign changes of the link error e = r - q (hysteresis ``band``);
    * ``stick_phases``: stiction phases of the link entered in the window; ``stick_phases_rotor``
      those of the rotor; ``stuck_fraction``: share of the window the link is stuck;
    * ``amplitude``: (max e - min e)/2, ``mean_error`` and ``error_end`` (e at the end),
      ``max_abs_error``;
    * ``period``: the mean time between every second crossing (a full cycle), NaN with fewer
      than 3 crossings;
    * ``motor_error_end``: r - theta_m/N at the end (what a motor encoder reports),
      ``windup_end``: theta_m/N - q at the end;
    * ``torque_peak``: the largest |tau_m| in the window, ``saturated``: the torque hit its limit
      in the window.
    """
    t = log["time"]
    s = log["scenario"]
    t0 = s.move_end + settle
    w = t >= t0 - 1e-12
    e = log["r"][joint][w] - log["q"][joint][w]
    cross = crossings(e, band)
    times = t[w][cross]
    period = float(np.mean(np.diff(times[::2]))) if len(times) >= 3 else float("nan")
    tau = log["tau_m"][joint][w]
    return {
        "window": [float(t0), float(t[-1])],
        "sign_changes": len(cross),
        "stick_phases": rising_edges(log["stick"][joint][w]),
        "stick_phases_rotor": rising_edges(log["stick_m"][joint][w]),
        "stuck_fraction": float(np.mean(log["stick"][joint][w])),
        "amplitude": float((e.max() - e.min()) / 2.0),
        "mean_error": float(e.mean()),
        "max_abs_error": float(np.abs(e).max()),
        "error_end": float(e[-1]),
        "period": period,
        "motor_error_end": float(log["r"][joint][-1] - log["x"][joint][-1]),
        "windup_end": float(log["windup"][joint][-1]),
        "torque_peak": float(np.abs(tau).max()),
        "saturated": bool(np.abs(tau).max() >= TORQUE_LIMIT[joint] * (1 - 1e-12)),
    }


def tracking_metrics(log: dict) -> dict:
    """Per motor joint: the largest link error |r - q| while moving and after, the largest
    wind-up, the motor error and link error at the end, the peak torque, stiction phases of
    link and rotor."""
    t = log["time"]
    s = log["scenario"]
    out = {}
    for j in MOTOR_JOINTS:
        e = log["r"][j] - log["q"][j]
        out[str(j)] = {
            "unit": UNIT[j],
            "max_link_error": float(np.abs(e).max()),
            "max_link_error_moving": float(np.abs(e[t <= s.move_end]).max()),
            "link_error_end": float(e[-1]),
            "motor_error_end": float(log["r"][j][-1] - log["x"][j][-1]),
            "max_motor_error": float(np.abs(log["r"][j] - log["x"][j]).max()),
            "max_windup": float(np.abs(log["windup"][j]).max()),
            "windup_end": float(log["windup"][j][-1]),
            "torque_peak": float(np.abs(log["tau_m"][j]).max()),
            "stick_phases": rising_edges(log["stick"][j]) + int(log["stick"][j][0] > 0.5),
            "stick_phases_rotor": rising_edges(log["stick_m"][j]) + int(log["stick_m"][j][0] > 0.5),
            "stuck_at_end": bool(log["stick"][j][-1] > 0.5),
        }
    return out


# ---------------------------------------------------------------------------
# the position loop's stability: gain sweep and linearized loop


def gain_sweep(fmu=None, kvs=(10, 20, 30, 40, 60, 80, 100, 120, 160, 240, 320), end: float = 3.0, move=MOVE) -> dict:
    """(c)'s plant and move run with each position gain Kv on each encoder (PI). A run is
    unstable when its torque hits the limit after the move or its link error in the hold
    exceeds 5e-3 rad (six times the motor loop's offset). Returns per encoder the runs' metrics
    and the largest stable Kv below the first unstable one."""
    out = {}
    for fb in ("motor", "link"):
        rows = []
        for kv in kvs:
            g = replace(POSITIONING_GAINS, feedback=fb, kv=float(kv))
            sc = Scenario(
                f"sweep_{fb}_{kv}",
                "",
                end,
                positioning_paths(move),
                {1: g, 3: HOLD_GAINS},
                {**HARMONIC_DRIVE, **OWN_FRICTION},
                move_end=move[2],
            )
            m = hunting_metrics(run(sc, fmu), settle=0.0)
            m["kv"] = float(kv)
            m["stable"] = not m["saturated"] and m["max_abs_error"] < 5e-3
            rows.append(m)
        unstable = [r["kv"] for r in rows if not r["stable"]]
        stable = [r["kv"] for r in rows if r["stable"] and (not unstable or r["kv"] < min(unstable))]
        out[fb] = {
            "runs": rows,
            "largest_stable_kv": max(stable) if stable else None,
            "smallest_unstable_kv": min(unstable) if unstable else None,
        }
    return out


@functools.cache
def _two_mass_sampled(k: float, link_inertia: float, rotor: float, step: float):
    """The two masses (rotor and link, link units) on the gear spring k, state (x, x', q, q'),
    input the link-side motor torque held over a period: (A_d, B_d) of the sampled plant."""
    from scipy.linalg import expm

    a = np.array(
        [[0, 1, 0, 0], [-k / rotor, 0, k / rotor, 0], [0, 0, 0, 1], [k / link_inertia, 0, -k / link_inertia, 0]],
        dtype=float,
    )
    b = np.array([[0.0], [1.0 / rotor], [0.0], [0.0]])
    m = expm(np.block([[a, b], [np.zeros((1, 5))]]) * step)
    return m[:4, :4], m[:4, 4:]


def linear_loop_radius(
    kv: float,
    feedback: str,
    gains: Gains = POSITIONING_GAINS,
    k: float = HARMONIC_DRIVE["k[1]"],
    link_inertia: float = LINK_INERTIA[1],
    gear_ratio: float = 100.0,
    rotor_inertia: float = 3e-4,
    step: float = STEP,
) -> float:
    """The spectral radius of the sampled closed loop of joint 1 without friction and
    backlash: the two masses (rotor N^2 J_m and link I on the gear spring k, link units) under
    a zero-order-held torque, the controller above with the encoder difference as velocity.
    Below 1: stable. The pure linear loop: what friction adds (damping while sliding, a dead
    band while stuck) is left out."""
    jr = gear_ratio**2 * rotor_inertia
    ad, bd = _two_mass_sampled(k, link_inertia, jr, step)
    kp = (link_inertia + jr) * gains.wv
    ki = kp * gains.wi if gains.integral else 0.0
    # discrete state: plant (4), previous motor position p = x_{k-1}, integrator z (with integral action)
    #   ev_k = kv (r - y_k) - (x_k - p_k)/T   (r = 0),   tau_k = kp ev_k + z_k,   z_{k+1} = z_k + ki T ev_k
    cy = np.array([1.0, 0, 0, 0]) if feedback == "motor" else np.array([0, 0, 1.0, 0])
    cx = np.array([1.0, 0, 0, 0])
    size = 6 if ki else 5
    ev = np.zeros(size)
    ev[:4] = -kv * cy - cx / step
    ev[4] = 1.0 / step
    tau = kp * ev
    if ki:
        tau[5] += 1.0
    big = np.zeros((size, size))
    big[:4, :4] = ad
    big[:4, :] += bd @ tau[None, :]
    big[4, :4] = cx
    if ki:
        big[5, :] = ki * step * ev
        big[5, 5] += 1.0
    return float(max(abs(np.linalg.eigvals(big))))


def linear_stability_limit(feedback: str, gains: Gains = POSITIONING_GAINS, kv_max: float = 2000.0) -> float:
    """The smallest Kv at which the linearized sampled loop (:func:`linear_loop_radius`) is
    unstable, to 0.1 %; inf if it is stable up to ``kv_max``."""
    kvs = np.geomspace(0.1, kv_max, 300)
    radius = [linear_loop_radius(kv, feedback, gains) for kv in kvs]
    first = next((i for i, rho in enumerate(radius) if rho >= 1.0), None)
    if first is None:
        return math.inf
    if first == 0:
        return float(kvs[0])
    lo, hi = kvs[first - 1], kvs[first]
    while hi - lo > 1e-3 * hi:
        mid = 0.5 * (lo + hi)
        if linear_loop_radius(mid, feedback, gains) >= 1.0:
            hi = mid
        else:
            lo = mid
    return float(hi)


FRICTIONLESS = {
    "k[1]": HARMONIC_DRIVE["k[1]"],
    "Delta[1]": 0.0,
    "mu_s[1]": 0.0,
    "mu_k[1]": 0.0,
    "tau_c[1]": 0.0,
    "b_m[1]": 0.0,
}


def linear_check(fmu=None, factors=(0.8, 1.2), end: float = 4.0) -> dict:
    """The linearized loop's limits checked on the FMU: joint 1 on the harmonic drive without
    friction, backlash and motor friction (the plant of :func:`linear_loop_radius`) and ideal
    encoders, the move of (b) with each encoder at ``factors`` times its predicted limit. Returns per encoder and
    factor the growth of the link error's peak-to-peak from [1.5 s, 2 s] to [end - 0.5 s, end]:
    below 1 the oscillation left by the move dies out, above 1 it grows."""
    out = {}
    for fb in ("motor", "link"):
        limit = linear_stability_limit(fb)
        out[fb] = {"limit_kv": limit, "runs": []}
        for f in factors:
            g = replace(POSITIONING_GAINS, feedback=fb, kv=f * limit)
            log = run(
                Scenario(f"linear_{fb}_{f:g}", "", end, positioning_paths(), {1: g, 3: HOLD_GAINS}, FRICTIONLESS),
                fmu,
                quantized=False,
            )
            t = log["time"]
            e = log["r"][1] - log["q"][1]
            early = np.ptp(e[(t >= 1.5) & (t <= 2.0)])
            late = np.ptp(e[t >= end - 0.5])
            out[fb]["runs"].append(
                {
                    "factor": f,
                    "kv": f * limit,
                    "ptp_early": float(early),
                    "ptp_late": float(late),
                    "growth": float(late / early) if early > 0 else float("nan"),
                }
            )
    return out


# ---------------------------------------------------------------------------
# output: CSV, figures, summary


def write_csv(log: dict, path: Path):
    cols = ["time"] + [f"{k}[{j}]" for j in MOTOR_JOINTS for k in LOGGED]
    data = [log["time"]] + [log[k][j] for j in MOTOR_JOINTS for k in LOGGED]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for row in zip(*data, strict=True):
            w.writerow([f"{x:.10g}" for x in row])


def _stick_bars(ax, t, flag, y, height, color, label):
    """Stiction phases as horizontal bars at height y."""
    on = flag > 0.5
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        ax.broken_barh(
            [(t[a], t[min(b, len(t) - 1)] - t[a] + 1e-9)], (y - height / 2, height), color=color, label=label
        )
        label = None
    if label:  # never stuck: the legend entry all the same
        ax.broken_barh([], (y - height / 2, height), color=color, label=label)


def _scale(values, unit):
    """A display scale for an error: (factor, unit label) so that the numbers read as mrad or mm."""
    peak = max(float(np.max(np.abs(v))) for v in values) if values else 0.0
    if unit == "rad":
        return (1e3, "mrad") if peak >= 1e-4 else (1e6, "µrad")
    return (1e3, "mm") if peak >= 1e-4 else (1e6, "µm")


def figure_tracking(log: dict, path: Path):
    import matplotlib.pyplot as plt

    t = log["time"]
    fig, axes = plt.subplots(5, 2, figsize=(12, 11), sharex=True)
    for c, j in enumerate(MOTOR_JOINTS):
        u = UNIT[j]
        ax = axes[:, c]
        ax[0].plot(t, log["r"][j], "k--", lw=1, label="path r")
        ax[0].plot(t, log["q"][j], lw=1.2, label="link q")
        ax[0].set_ylabel(f"q{j} ({u})")
        ax[0].set_title(
            f"joint {j}: "
            + (
                "revolute, gear N = 100, k = 1e6 N·m/rad"
                if j == 1
                else "prismatic, ball screw of 10 mm lead, k = 1e6 N/m"
            )
        )
        ax[0].legend(loc="lower right", fontsize=8)
        e = log["r"][j] - log["q"][j]
        me = log["r"][j] - log["x"][j]
        f, lab = _scale([e, me], u)
        ax[1].plot(t, f * e, lw=1.2, label="link error r − q")
        ax[1].plot(t, f * me, lw=0.9, label="motor error r − θm/N")
        ax[1].axhline(0, color="k", lw=0.5)
        ax[1].set_ylabel(f"error ({lab})")
        ax[1].legend(loc="upper right", fontsize=8)
        w = log["windup"][j]
        f, lab = _scale([w], u)
        ax[2].plot(t, f * w, color="tab:green", lw=1.2)
        ax[2].axhline(0, color="k", lw=0.5)
        ax[2].set_ylabel(f"wind-up θm/N − q ({lab})")
        _stick_bars(ax[3], t, log["stick"][j], 1.0, 0.6, "tab:red", "link stuck")
        _stick_bars(ax[3], t, log["stick_m"][j], 0.0, 0.6, "tab:purple", "rotor stuck")
        ax[3].set_yticks([0, 1])
        ax[3].set_yticklabels(["rotor", "link"])
        ax[3].set_ylim(-0.6, 1.6)
        ax[3].set_ylabel("stuck")
        ax[4].plot(t, log["tau_m"][j], lw=1.0, label="τm (controller)")
        ax[4].plot(t, log["tau_ff"][j], lw=0.8, ls="--", label="feed-forward part")
        ax[4].plot(t, log["tau_load"][j], lw=0.8, label="gear load F/N")
        ax[4].set_ylabel("motor torque (N·m)")
        ax[4].set_xlabel("t (s)")
        ax[4].legend(loc="upper right", fontsize=8)
    fig.suptitle("(a) Reference motion on the motor encoders: cascaded P / PI + feed-forward at 1 kHz")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_hunting(logs: list, metrics: list, path: Path, joint: int = 1):
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(5, len(logs), figsize=(5.0 * len(logs), 11), sharex=True, sharey="row")
    axes = np.atleast_2d(axes).reshape(5, len(logs))
    for c, (log, m) in enumerate(zip(logs, metrics, strict=True)):
        t = log["time"]
        s = log["scenario"]
        ax = axes[:, c]
        ax[0].plot(t, 1e3 * log["r"][joint], "k--", lw=1, label="path r")
        ax[0].plot(t, 1e3 * log["q"][joint], lw=1.2, label="link q")
        ax[0].plot(t, 1e3 * log["x"][joint], lw=0.8, label="motor θm/N")
        ax[0].set_title(s.title, fontsize=10)
        e = log["r"][joint] - log["q"][joint]
        ax[1].plot(t, 1e3 * e, lw=1.2, label="link error r − q")
        ax[1].axhline(0, color="k", lw=0.5)
        ax[1].axvspan(m["window"][0], m["window"][1], color="0.92", zorder=0)
        period = f", period {m['period']:.2f} s" if math.isfinite(m["period"]) else ""
        ax[1].text(
            0.02,
            0.04,
            f"after {m['window'][0]:g} s: {m['sign_changes']} sign changes, "
            f"{m['stick_phases']} stick phases\n±{1e3 * m['amplitude']:.3f} mrad{period}, "
            f"mean {1e3 * m['mean_error']:+.3f} mrad",
            transform=ax[1].transAxes,
            fontsize=8,
            va="bottom",
            bbox=dict(facecolor="white", alpha=0.85, edgecolor="none"),
        )
        ax[2].plot(t, 1e3 * log["windup"][joint], color="tab:green", lw=1.2)
        ax[2].axhline(0, color="k", lw=0.5)
        for sgn in (-1, 1):
            ax[2].axhline(sgn * 1e3 * HARMONIC_DRIVE["Delta[1]"], color="tab:green", lw=0.5, ls=":")
        _stick_bars(ax[3], t, log["stick"][joint], 1.0, 0.6, "tab:red", "link stuck")
        _stick_bars(ax[3], t, log["stick_m"][joint], 0.0, 0.6, "tab:purple", "rotor stuck")
        ax[3].set_yticks([0, 1])
        ax[3].set_yticklabels(["rotor", "link"])
        ax[3].set_ylim(-0.6, 1.6)
        ax[4].plot(t, log["tau_m"][joint], lw=1.0, label="τm")
        ax[4].plot(t, log["tau_load"][joint], lw=0.8, label="gear load F/N")
        ax[4].set_xlabel("t (s)")
        if c == 0:
            ax[0].set_ylabel("q1 (mrad)")
            ax[0].legend(loc="lower right", fontsize=8)
            ax[1].set_ylabel("link error (mrad)")
            ax[2].set_ylabel("wind-up θm/N − q (mrad)\n(dotted: lost motion ±Δ)")
            ax[3].set_ylabel("stuck")
            ax[4].set_ylabel("motor torque (N·m)")
            ax[4].legend(loc="lower right", fontsize=8)
    # room below the error curves for the numbers
    errors = np.concatenate([1e3 * (log["r"][joint] - log["q"][joint]) for log in logs])
    lo, hi = errors.min(), errors.max()
    axes[1, 0].set_ylim(lo - 0.45 * (hi - lo), hi + 0.05 * (hi - lo))
    fig.suptitle(
        "(b) Slow positioning move of joint 1 (harmonic drive, bearing friction with a Stribeck drop "
        "μs 0.2 → μk 0.1): link encoder, and on the right the motor encoder",
        fontsize=11,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_encoders(logs: list, metrics: list, sweep: dict | None, limits: dict | None, path: Path, joint: int = 1):
    import matplotlib.pyplot as plt

    ncol = len(logs)
    rows = 4 + (1 if sweep else 0)
    fig = plt.figure(figsize=(5.0 * ncol, 2.3 * rows + 1))
    gs = fig.add_gridspec(rows, ncol)
    first = None
    for c, (log, m) in enumerate(zip(logs, metrics, strict=True)):
        t = log["time"]
        ax = [fig.add_subplot(gs[r, c], sharex=first) for r in range(4)]
        first = first or ax[0]
        e = log["r"][joint] - log["q"][joint]
        me = log["r"][joint] - log["x"][joint]
        ax[0].plot(t, 1e3 * e, lw=1.2, label="link error r − q (true)")
        ax[0].plot(t, 1e3 * me, lw=1.0, label="motor error r − θm/N")
        ax[0].axhline(0, color="k", lw=0.5)
        ax[0].set_title(log["scenario"].title, fontsize=10)
        lim = (-1.2, 1.8)  # mrad: the stable runs on one scale; an unstable one on its own
        if max(np.abs(e).max(), np.abs(me).max()) * 1e3 < lim[1] - 0.1:
            ax[0].set_ylim(*lim)
        if m["saturated"]:
            ax[0].set_title(log["scenario"].title + ": unstable", fontsize=10, color="tab:red")
        ax[0].text(
            0.98,
            0.96,
            f"at the end: link {1e3 * m['error_end']:+.4f} mrad, motor {1e3 * m['motor_error_end']:+.5f} mrad",
            transform=ax[0].transAxes,
            fontsize=8,
            ha="right",
            va="top",
            bbox=dict(facecolor="white", alpha=0.85, edgecolor="none"),
        )
        ax[1].plot(t, 1e3 * log["windup"][joint], color="tab:green", lw=1.2)
        ax[1].axhline(0, color="k", lw=0.5)
        if np.abs(log["windup"][joint]).max() * 1e3 < lim[1] - 0.1:
            ax[1].set_ylim(*lim)
        _stick_bars(ax[2], t, log["stick"][joint], 1.0, 0.6, "tab:red", "link stuck")
        _stick_bars(ax[2], t, log["stick_m"][joint], 0.0, 0.6, "tab:purple", "rotor stuck")
        ax[2].set_yticks([0, 1])
        ax[2].set_yticklabels(["rotor", "link"])
        ax[2].set_ylim(-0.6, 1.6)
        ax[3].plot(t, log["tau_m"][joint], lw=1.0)
        ax[3].set_xlabel("t (s)")
        if c == 0:
            ax[0].set_ylabel("error (mrad)")
            ax[0].legend(loc="lower right", fontsize=8)
            ax[1].set_ylabel("wind-up θm/N − q (mrad)")
            ax[2].set_ylabel("stuck")
            ax[3].set_ylabel("motor torque (N·m)")
    if sweep:
        ax = fig.add_subplot(gs[4, :])
        for fb, marker in (("motor", "o"), ("link", "s")):
            runs = sweep[fb]["runs"]
            kv = [r["kv"] for r in runs]
            err = [1e3 * r["max_abs_error"] for r in runs]
            ax.semilogy(kv, err, marker=marker, label=f"{fb} encoder: largest |r − q| in the hold")
            bad = [(r["kv"], 1e3 * r["max_abs_error"]) for r in runs if not r["stable"]]
            if bad:
                ax.semilogy(*zip(*bad, strict=True), "x", color="tab:red", ms=10, mew=2)
        if limits:
            for fb, ls in (("motor", "--"), ("link", ":")):
                if math.isfinite(limits[fb]):
                    ax.axvline(
                        limits[fb],
                        color="k",
                        ls=ls,
                        lw=0.8,
                        label=f"linearized loop unstable from Kv = {limits[fb]:.0f}/s ({fb})",
                    )
        ax.set_xlabel("position gain Kv (1/s)")
        ax.set_ylabel("mrad")
        ax.set_title("gain sweep (PI, same move; red x: unstable, the torque saturates)", fontsize=10)
        ax.legend(fontsize=8, loc="lower right")
    fig.suptitle(
        "(c) Motor encoder against link encoder: joint 1 on the harmonic drive, the arm's own friction (μs = μk = 0.2)",
        fontsize=11,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def docs_copy(src: Path, dst: Path, colours: int = 64):
    """The figure for the docs page: the same image in a palette of ``colours`` (a third of
    the bytes; line plots lose nothing visible), as the other docs figures."""
    from PIL import Image

    with Image.open(src) as im:
        im.convert("RGB").quantize(colours).save(dst, optimize=True)


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, (np.floating, np.integer)):
        return _jsonable(x.item())
    return x


def _positioning(scenarios, a, out: Path, line) -> tuple:
    """Runs the positioning scenarios of (b) or (c): each one's CSV, its metrics printed with
    ``line(metrics)``; returns the logs, the metrics and the summary's entries by name."""
    logs, metrics, runs = [], [], {}
    for sc in scenarios:
        log = run(sc, a.fmu, velocity=a.velocity)
        m = hunting_metrics(log)
        write_csv(log, out / f"{sc.name}.csv")
        logs.append(log)
        metrics.append(m)
        runs[sc.name] = {"title": sc.title, "gains": asdict(sc.gains[1]), "wall_s": log["wall"], **m}
        print(f"    {sc.title:36s} {line(m)}  ({log['wall']:.2f} s)")
    return logs, metrics, runs


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fmu", default=str(DEFAULT_FMU), help="the motor arm's FMU (models/reference_rrpr_motor.toml)")
    p.add_argument("--out", default=str(DEFAULT_OUT), help="directory for PNGs, CSVs and summary.json")
    p.add_argument(
        "--docs-figures",
        default="",
        help=f"also write the figures here ({DOCS_FIGURES.relative_to(ROOT)} for docs/control.md); default: not",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help="(c) held to 3 s, no gain sweep, no frictionless check: the CI's reduced form",
    )
    p.add_argument(
        "--velocity",
        choices=("encoder", "tacho"),
        default="encoder",
        help="velocity from the motor encoder's difference (default) or omega_m (a tachometer)",
    )
    a = p.parse_args(argv)
    if not Path(a.fmu).is_file():
        sys.exit(
            f"axis_control.py: {a.fmu} not found: build it with `bash scripts/build_fmu.sh --platforms linux64 "
            f"--model models/reference_rrpr_motor.toml --out {a.fmu}`"
        )
    import matplotlib

    matplotlib.use("Agg")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    summary = {
        "fmu": str(a.fmu),
        "controller_period_s": STEP,
        "velocity_estimate": a.velocity,
        "motor_encoder_counts_per_rev": MOTOR_COUNTS,
        "link_encoder_resolution_joint1_rad": LINK_RESOLUTION[1],
        "torque_limit_Nm": {str(j): v for j, v in TORQUE_LIMIT.items()},
        "link_inertia_nominal": {str(j): v for j, v in LINK_INERTIA.items()},
    }
    figures = []

    # (a) the reference motion
    log = run(tracking_scenario(), a.fmu, velocity=a.velocity)
    write_csv(log, out / "a_tracking.csv")
    summary["a_tracking"] = {
        "gains": {str(j): asdict(g) for j, g in TRACKING_GAINS.items()},
        "parameters": {},
        "wall_s": log["wall"],
        "n_substeps": log["n_substeps"],
        "joints": tracking_metrics(log),
    }
    figure_tracking(log, out / "axis_control_tracking.png")
    figures.append("axis_control_tracking.png")
    print(f"(a) reference motion, motor encoders ({log['wall']:.2f} s):")
    for j, m in summary["a_tracking"]["joints"].items():
        u = m["unit"]
        print(
            f"    joint {j}: max |r - q| {m['max_link_error']:.3e} {u}, max wind-up {m['max_windup']:.3e} {u}, "
            f"at 2 s: link error {m['link_error_end']:+.3e} {u}, motor error {m['motor_error_end']:+.1e} {u}, "
            f"peak torque {m['torque_peak']:.3f} N.m"
        )

    # (b) hunting
    end_b = 5.0
    summary["b_hunting"] = {
        "parameters": {**HARMONIC_DRIVE, **STRIBECK},
        "move": dict(zip(("q0", "q1", "T"), MOVE, strict=True)),
        "friction_estimate_link_Nm": FRICTION_ESTIMATE,
    }
    print(f"(b) slow positioning move of joint 1, hunting counted from {MOVE[2] + 1:g} s to {end_b:g} s:")
    logs_b, metrics_b, summary["b_hunting"]["runs"] = _positioning(
        hunting_scenarios(end_b),
        a,
        out,
        lambda m: (
            f"{m['sign_changes']:3d} sign changes, {m['stick_phases']:3d} stick phases, "
            f"amplitude {m['amplitude']:.3e} rad, period {m['period']:.3f} s, mean error {m['mean_error']:+.3e} rad"
        ),
    )
    figure_hunting(logs_b, metrics_b, out / "axis_control_hunting.png")
    figures.append("axis_control_hunting.png")

    # (c) encoders
    end_c = 3.0 if a.quick else 4.0
    summary["c_encoders"] = {
        "parameters": {**HARMONIC_DRIVE, **OWN_FRICTION},
        "move": dict(zip(("q0", "q1", "T"), MOVE, strict=True)),
    }
    print("(c) motor encoder against link encoder, the arm's own friction:")
    logs_c, metrics_c, summary["c_encoders"]["runs"] = _positioning(
        encoder_scenarios(end_c),
        a,
        out,
        lambda m: (
            f"link error at the end {m['error_end']:+.3e} rad, motor error {m['motor_error_end']:+.3e} rad, wind-up "
            f"{m['windup_end']:+.3e} rad, hold amplitude {m['amplitude']:.2e} rad"
            f"{', SATURATED' if m['saturated'] else ''}"
        ),
    )
    sweep = None
    limits = {fb: linear_stability_limit(fb) for fb in ("motor", "link")}
    summary["c_encoders"]["linear_stability_limit_kv"] = limits
    print(
        f"    linearized sampled loop (no friction, no backlash): unstable from Kv = {limits['motor']:.1f}/s on the "
        f"motor encoder, {limits['link']:.1f}/s on the link encoder"
    )
    if not a.quick:
        t0 = time.perf_counter()
        check = linear_check(a.fmu)
        summary["c_encoders"]["linear_check"] = check
        for fb, c in check.items():
            growth = ", ".join(f"x{r['growth']:.2g} at {r['factor']:g} Kv_lim" for r in c["runs"])
            print(f"    frictionless FMU, {fb} encoder: oscillation after the move grows {growth}")
        sweep = gain_sweep(a.fmu)
        summary["c_encoders"]["gain_sweep"] = {
            fb: {
                "largest_stable_kv": s["largest_stable_kv"],
                "smallest_unstable_kv": s["smallest_unstable_kv"],
                "runs": [
                    {
                        k: r[k]
                        for k in (
                            "kv",
                            "stable",
                            "max_abs_error",
                            "error_end",
                            "motor_error_end",
                            "sign_changes",
                            "saturated",
                        )
                    }
                    for r in s["runs"]
                ],
            }
            for fb, s in sweep.items()
        }
        fmt = lambda x: "none in the sweep" if x is None else f"{x:g}/s"  # noqa: E731
        motor, link = sweep["motor"], sweep["link"]
        print(
            f"    gain sweep with friction: motor encoder stable up to Kv = {fmt(motor['largest_stable_kv'])} "
            f"(unstable from {fmt(motor['smallest_unstable_kv'])}), link encoder up to "
            f"{fmt(link['largest_stable_kv'])} (unstable from {fmt(link['smallest_unstable_kv'])})"
            f"  ({time.perf_counter() - t0:.1f} s with the check)"
        )
    figure_encoders(logs_c, metrics_c, sweep, limits, out / "axis_control_encoders.png")
    figures.append("axis_control_encoders.png")

    summary["wall_s"] = time.perf_counter() - started
    (out / "summary.json").write_text(json.dumps(_jsonable(summary), indent=2) + "\n")
    if a.docs_figures:
        docs = Path(a.docs_figures)
        docs.mkdir(parents=True, exist_ok=True)
        for name in figures:
            docs_copy(out / name, docs / name)
        print(f"figures copied to {docs} (64 colours)")
    print(f"wrote {out}/ (figures {', '.join(figures)}, CSVs, summary.json) in {summary['wall_s']:.1f} s")
    return summary


if __name__ == "__main__":
    main()
