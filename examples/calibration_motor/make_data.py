"""Makes the motor-drive calibration example's measured runs (issue 36, item 7).

The arm is the reference arm with motor drives (models/reference_rrpr_motor.toml,
target/fmu/reference_rrpr_motor.fmu; docs/motor_drives.md): joint 1 revolute behind a
harmonic drive (N = 100), joint 3 prismatic behind a ball screw (N = 2π/0.01 m), joints 2 and
4 rigid (prescribed by q_star). Its FMU runs with the values in TRUTH (the FMU's defaults in
the comments; every other parameter at its default: gear stiffness k = 1e6, no gear damping or
clearance, v_s = 0, b_v = 0, μ_s[3] = 0.2). calibration.toml does not know them.

Six runs, each a CSV of 4 ms samples (250 Hz), 2.5–4 s: ``fit_1``, ``fit_2``, ``fit_3`` (the
fit's) and ``heldout_1``, ``heldout_2``, ``heldout_3`` (other motions, for prediction); RUNS
below lists each run's start and moves. Joints 1 and 3 make cycloidal point-to-point moves with
dwells, reversals after a dwell and direct reversals (fast moves up to 3 rad/s and 1 m/s, slow
ones, creep); joint 2 tilts the slideway during fit_2 and heldout_2 (the weight on the ball
screw and the friction loads change with it), joint 4 turns during fit_3 and heldout_2; the
rigid joints hold their start position in the other runs.

**The start.** Every run starts at rest in static equilibrium at its start position:
``use_start_values = true``, ``q_start[1]``, ``q_start[3]`` the start positions of RUNS,
``static_start = true`` (each rotor turned so that its gear spring holds its link at rest
against gravity); every joint's set point dwells at least 0.2 s before its first move, and
links and rotors do not move in the first 0.2 s (51 samples) of pass 2: a fit can start from
those samples as well as from the parameters above.

**Pass 1: the closed loop.** A PD controller at 250 Hz on the link encoders: at each sample
t_k it reads the link encoders (the encoder model below, its own noise draws), estimates each
speed by the backward difference of two readings, and commands

    tau_m[i] = (KP_i (r_i − y_i) + KD_i (r'_i − v_i) + g_i) / N_i

with r_i, r'_i the set point and its rate, y_i the reading, v_i the speed estimate, KP = 6000
N·m/rad, KD = 250 N·m·s/rad for joint 1 (about 4 Hz, damping ratio 0.5, for its 7.5–10.5 kg·m²:
links 3.7–6.4, rotor N²J_m 3.9), KP = 3e4 N/m, KD = 1200 N·s/m for joint 3 (about 3 Hz, damping
ratio 0.4, for its 71 kg: links 12, rotor 59), g_1 = 0 (joint 1's axis is vertical) and g_3 =
12 kg · 9.81 m/s² · sin q*_2 (the weight of links 3 and 4 along the slideway, what the static
start's holding torque N·tau_load[3] is). The torque is held over the 4 ms step (no derivatives);
the rigid joints get the not-a-knot cubic spline of their logged commands (as in pass 2).

**Pass 2: the truth.** The FMU again from the same start, open loop: tau_m is the not-a-knot
cubic spline (scipy's CubicSpline, default end conditions) through pass 1's torques at the
samples, its value and first two derivatives set at every communication point
(fmi2SetRealInputDerivatives, orders 1 and 2), and q_star[2], q_star[4] the spline of the logged
commands, with the calls of stickslip.fit.runner (checked: the runner, given the SPEC's
experiment with these torques, gives the same outputs bit for bit). Both passes use fixed
sub-steps h_min = h_max = 2e-6 s and communication steps of 4 ms. Pass 2's outputs are the
measured run's true values; the spline's torque leads the held one by about half a step, so
pass 2 differs from pass 1 by up to 6 mrad and 2 mm (printed per run as ``pass1-2``): the data
are exactly pass 2, and pass 1 is only where its torques came from.

**Columns** (written with 10 significant digits): ``t`` (s); ``q_star2``, ``q_star4`` (rad):
the commands of the rigid joints, exact; ``tau_m1``, ``tau_m3`` (N·m): the motor torques
(pass 1's, which pass 2 replays) with Gaussian white noise of standard deviation 0.015 N·m
(joint 1) and 0.012 N·m (joint 3), about 1 % of a run's range (0.5–3 %, printed), independent
between samples; ``link1`` (rad), ``link3`` (m): the link encoders of joints 1 and 3, pass 2's
q[1] and q[3] with Gaussian noise of 3e-6 rad and 5e-7 m added and the sum rounded to the
encoder's count (a 20-bit encoder: 2π/2^20 = 5.992e-6 rad; a 1 µm scale); ``rotor1``,
``rotor3`` (rad): the motor encoders, pass 2's theta_m[1] and theta_m[3] (motor side; the
encoder in joint units is theta_m/N) with noise of half a count rounded to a 17-bit count
(2π/2^17 rad). Noise draws: numpy's default_rng([seed, 1]) for the controller's readings in
pass 1, default_rng([seed, 2]) for the logged noise (tau_m1, tau_m3, link1, link3, rotor1,
rotor3 in this order), seed = 1..6 in the order of RUNS.

**The torque noise is an input error.** The fit replays the logged torques, noise included,
open loop: at the true parameters that replay leaves the true motion by millimetres and
milliradians within a run (printed per run as ``logged replay``: thousands of the
encoders' standard deviations), mostly where a dwell's held torque is near the breakaway
level and the noise decides whether and when the link breaks away. (With TORQUE_NOISE's values
0 the logged torques are pass 2's own, to 10 digits.)

The summary printed per run and joint: stiction phases after the start of the link (n_stick)
and of the rotor (n_stick_m) in pass 2, the fraction of samples stuck, the largest link
speed, the range of the motor torque, the largest |q| difference of pass 1 and pass 2, and of
the logged-torque replay and pass 2.

    python examples/calibration_motor/make_data.py [--fmu target/fmu/reference_rrpr_motor.fmu] [--runs fit_1 ...]

takes 20-40 s (two passes and the logged-torque replay per run, on one core).
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

HERE = Path(__file__).resolve().parent
FMU = HERE.parents[1] / "target" / "fmu" / "reference_rrpr_motor.fmu"

# The true values (the FMU's defaults in brackets); calibration.toml does not know them.
TRUTH = {
    "J_m[1]": 3.9e-4,  # kg.m2 (3e-4)
    "b_m[1]": 3.5e-4,  # N.m.s/rad (2e-4)
    "tau_c[1]": 0.045,  # N.m (0.03)
    "mu_k[1]": 0.12,  # (0.2)
    "mu_s[1]": 0.16,  # (0.2)
    "J_m[3]": 1.5e-4,  # kg.m2 (1.2e-4)
    "b_m[3]": 1.6e-4,  # N.m.s/rad (1e-4)
    "tau_c[3]": 0.028,  # N.m (0.02)
    "mu_k[3]": 0.15,  # (0.2; mu_s[3] stays at its default 0.2)
}
STEP = 0.004  # s: the controller's period and the log's sample interval (250 Hz)
SUBSTEP = 2e-6  # s: the FMU's fixed sub-step in both passes (h_min = h_max)
DIGITS = 10  # significant digits of the CSV
MOTORS = (1, 3)  # the motor-drive joints; 2 and 4 are rigid (prescribed by q_star)
RIGID = (2, 4)
RATIO = {1: 100.0, 3: 2.0 * math.pi / 0.01}  # gear ratios N (harmonic drive; ball screw of 10 mm lead)
# Link encoders, FMU output: (column, noise standard deviation, count). The noise is added to
# the true position and the sum rounded to the count, as an encoder reads a noisy position.
ENCODERS = {
    "q[1]": ("link1", 3e-6, 2.0 * math.pi / 2**20),  # rad: a 20-bit absolute encoder
    "q[3]": ("link3", 0.5e-6, 1e-6),  # m: a 1 um linear scale
}
# Motor encoders: 17 bits per motor turn, logged as the rotor angle theta_m (motor rad; the
# motor encoder in joint units is theta_m / N).
ROTOR_COUNT = 2.0 * math.pi / 2**17
ROTORS = {
    "theta_m[1]": ("rotor1", 0.5 * ROTOR_COUNT, ROTOR_COUNT),
    "theta_m[3]": ("rotor3", 0.5 * ROTOR_COUNT, ROTOR_COUNT),
}
TORQUE_NOISE = {1: 0.015, 3: 0.012}  # N.m: white noise of the logged motor torques
# The controller: per motor joint a PD loop on its link encoder in link units, its output
# divided by N; joint 3 with the feed-forward of the weight it lifts.
KP = {1: 6000.0, 3: 3.0e4}  # N.m/rad (joint 1), N/m (joint 3)
KD = {1: 250.0, 3: 1200.0}  # N.m.s/rad, N.s/m
LIFTED_MASS = 12.0  # kg: links 3 and 4 (8 + 4 kg), lifted by the ball screw
G = 9.81  # m/s2


@dataclass
class Run:
    duration: float  # s
    start: dict  # joint -> position at t = 0 (rad or m), at rest
    moves: dict  # joint -> [(t0, t1, target), ...]: cycloidal point-to-point moves, dwells between
    seed: int


RUNS = {
    "fit_1": Run(  # medium moves with dwells, reversals after a dwell
        3.0,
        {1: 0.0, 2: 0.2, 3: 0.8, 4: 0.0},
        {
            1: [(0.2, 0.9, 0.5), (1.3, 1.7, 0.3), (2.0, 2.8, 0.4)],
            3: [(0.3, 0.8, 0.7), (1.2, 1.6, 0.78), (2.0, 2.5, 0.74)],
        },
        1,
    ),
    "fit_2": Run(  # slow moves and direct reversals while joint 2 tilts the slideway
        3.0,
        {1: 0.2, 2: 0.1, 3: 0.85, 4: 0.0},
        {
            1: [(0.2, 1.2, -0.1), (1.2, 2.0, 0.1), (2.3, 2.7, 0.05)],
            2: [(0.4, 2.4, 0.45)],
            3: [(0.3, 1.3, 0.95), (1.3, 2.3, 0.8), (2.5, 2.8, 0.82)],
        },
        2,
    ),
    "fit_3": Run(  # fast large moves, small ones, joint 4 turning
        3.5,
        {1: -0.3, 2: 0.35, 3: 0.75, 4: 0.0},
        {
            1: [(0.2, 0.8, 0.6), (1.2, 1.8, 0.2), (2.2, 2.5, 0.25), (2.7, 3.3, 0.0)],
            3: [(0.25, 0.65, 0.9), (1.0, 1.6, 0.72), (2.0, 2.4, 0.76), (2.8, 3.2, 0.74)],
            4: [(0.5, 1.5, 1.2), (2.0, 3.0, 0.0)],
        },
        3,
    ),
    "heldout_1": Run(  # slideway level (no weight on the ball screw), joint 4 turned
        3.0,
        {1: 0.1, 2: 0.0, 3: 0.7, 4: 0.5},
        {
            1: [(0.2, 1.0, 0.7), (1.4, 1.9, 0.4), (2.3, 2.7, 0.45)],
            3: [(0.3, 1.0, 0.9), (1.5, 1.8, 0.85), (2.2, 2.6, 0.8)],
        },
        4,
    ),
    "heldout_2": Run(  # every joint moving, joint 2 lowering the slideway
        4.0,
        {1: 0.0, 2: 0.3, 3: 0.8, 4: 0.0},
        {
            1: [(0.2, 0.9, -0.4), (1.1, 1.5, -0.2), (1.8, 2.3, -0.35), (2.8, 3.6, 0.0)],
            2: [(0.5, 3.0, 0.05)],
            3: [(0.3, 0.9, 0.72), (1.2, 1.8, 0.86), (2.4, 3.0, 0.8)],
            4: [(1.0, 2.0, -0.8)],
        },
        5,
    ),
    "heldout_3": Run(  # creep: small slow moves
        2.5,
        {1: 0.0, 2: 0.2, 3: 0.8, 4: 0.0},
        {
            1: [(0.2, 1.0, 0.05), (1.2, 2.0, 0.0)],
            3: [(0.3, 1.2, 0.81), (1.4, 2.2, 0.795)],
        },
        6,
    ),
}


def cycloid(q0: float, q1: float, t0: float, t1: float, t: float) -> tuple:
    """(q, q', q'') of the cycloidal move from q0 at t0 to q1 at t1, at rest at both ends."""
    if t <= t0:
        return q0, 0.0, 0.0
    if t >= t1:
        return q1, 0.0, 0.0
    T = t1 - t0
    s = (t - t0) / T
    a = 2.0 * math.pi * s
    d = q1 - q0
    return (
        q0 + d * (s - math.sin(a) / (2.0 * math.pi)),
        d / T * (1.0 - math.cos(a)),
        d / T**2 * 2.0 * math.pi * math.sin(a),
    )


def path(start: float, moves: list):
    """The set point of a joint as a function of t: its moves one after the other."""

    def at(t: float) -> tuple:
        q = start
        for t0, t1, target in moves:
            if t < t1:
                return cycloid(q, target, t0, t1, t)
            q = target
        return q, 0.0, 0.0

    return at


def as_logged(x) -> np.ndarray:
    """The values as the fit reads them back from the CSV (DIGITS significant digits)."""
    return np.array([float(f"{v:.{DIGITS}g}") for v in np.asarray(x, dtype=np.float64)])


def read_out(rng, y, sigma: float, count: float) -> np.ndarray:
    """An encoder's reading of the true position y: noise added, the sum rounded to the count."""
    return np.round((y + sigma * rng.standard_normal(np.shape(y))) / count) * count


OUTPUTS = ["q[1]", "q[2]", "q[3]", "q[4]", "qd[1]", "qd[3]", "theta_m[1]", "theta_m[3]", "tau_load[1]", "tau_load[3]"]
OUTPUTS += ["n_stick[1]", "n_stick[3]", "n_stick_m[1]", "n_stick_m[3]"]
FLAGS = ["stick[1]", "stick[3]", "stick_m[1]", "stick_m[3]"]


class Arm:
    """The motor-drive FMU through fmpy, initialized and stepped with the calls of
    stickslip.fit.runner (``_run_span``, ``_input_setter``)."""

    def __init__(self, fmu: Path):
        from fmpy import extract, read_model_description

        self.md = read_model_description(str(fmu))
        self.dir = extract(str(fmu))
        self.var = {v.name: v for v in self.md.modelVariables}
        self.drive = self.vr([f"{g}[{i}]" for g in ("q_star", "qd_star", "qdd_star") for i in range(1, 5)])
        self.torque = self.vr([f"tau_m[{i}]" for i in MOTORS])
        self.outputs, self.flags = self.vr(OUTPUTS), self.vr(FLAGS)

    def vr(self, names) -> list:
        return [self.var[n].valueReference for n in names]

    def start(self, parameters: dict, drive0, torque0):
        """An instance at t = 0 with ``parameters``, initialized with the inputs of the first sample."""
        from fmpy.fmi2 import FMU2Slave

        s = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.dir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName="make_data",
        )
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        for name, value in parameters.items():
            if self.var[name].type == "Boolean":
                s.setBoolean(self.vr([name]), [bool(value)])
            else:
                s.setReal(self.vr([name]), [float(value)])
        s.enterInitializationMode()
        s.setReal(self.drive, [float(x) for x in drive0])
        self.set_torques(s, *torque0)
        s.exitInitializationMode()
        return s

    def set_torques(self, s, value, rate, accel) -> None:
        """tau_m and its first two derivatives (fmi2SetRealInputDerivatives, orders 1 and 2)."""
        n = len(MOTORS)
        s.setReal(self.torque, [float(x) for x in value])
        s.setRealInputDerivatives(self.torque, [1] * n, [float(x) for x in rate])
        s.setRealInputDerivatives(self.torque, [2] * n, [float(x) for x in accel])

    def read(self, s) -> np.ndarray:
        return np.array([*s.getReal(self.outputs), *(float(f) for f in s.getBoolean(self.flags))])


def drive_table(t, commands: dict) -> np.ndarray:
    """(samples, 12): q*, q*', q*'' of the four joints at the samples, as the fit sets them:
    the rigid joints' from the not-a-knot cubic spline of their logged commands, the motor
    joints' at the FMU's start value 0 (the FMU ignores them with use_start_values)."""
    table = np.zeros((len(t), 12))
    for i, q in commands.items():
        spline = CubicSpline(t, q)
        for order in range(3):
            table[:, 4 * order + i - 1] = spline(t, order)
    return table


def closed_loop(arm: Arm, run: Run, t, drive, parameters: dict, rng) -> tuple:
    """Pass 1: the PD loop at 250 Hz on the link encoders' readings, each torque held over its
    4 ms step. Returns the torques at the samples (samples, 2) and the outputs."""
    refs = {i: path(run.start[i], run.moves.get(i, [])) for i in MOTORS}
    zero = np.zeros(len(MOTORS))
    s = arm.start(parameters, drive[0], (zero, zero, zero))
    tau = np.zeros((len(t), len(MOTORS)))
    out = np.zeros((len(t), len(OUTPUTS) + len(FLAGS)))
    previous = None
    for k in range(len(t)):
        out[k] = arm.read(s)
        y = np.array([read_out(rng, out[k][OUTPUTS.index(o)], *ENCODERS[o][1:]) for o in ENCODERS])
        v = zero if previous is None else (y - previous) / STEP  # the encoders' backward difference
        previous = y
        for m, i in enumerate(MOTORS):
            r, rd, _ = refs[i](float(t[k]))
            u = KP[i] * (r - y[m]) + KD[i] * (rd - v[m])
            if i == 3:
                u += LIFTED_MASS * G * math.sin(drive[k][1])  # the weight along the slideway, tilted by q*_2
            tau[k, m] = u / RATIO[i]
        if k == len(t) - 1:
            break
        s.setReal(arm.drive, [float(x) for x in drive[k]])
        arm.set_torques(s, tau[k], zero, zero)
        s.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=float(t[k + 1] - t[k]))
    s.terminate()
    s.freeInstance()
    return tau, out


def replay(arm: Arm, t, drive, tau, parameters: dict) -> np.ndarray:
    """Open loop with the not-a-knot cubic spline of the torque samples: value and first two
    derivatives set at every sample, as the fit replays a torque column
    (stickslip.fit.spec.Torques, stickslip.fit.runner._input_setter)."""
    spline = CubicSpline(t, tau, axis=0)
    value, rate, accel = spline(t), spline(t, 1), spline(t, 2)
    s = arm.start(parameters, drive[0], (value[0], rate[0], accel[0]))
    out = np.zeros((len(t), len(OUTPUTS) + len(FLAGS)))
    out[0] = arm.read(s)
    for k in range(len(t) - 1):
        s.setReal(arm.drive, [float(x) for x in drive[k]])
        arm.set_torques(s, value[k], rate[k], accel[k])
        s.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=float(t[k + 1] - t[k]))
        out[k + 1] = arm.read(s)
    s.terminate()
    s.freeInstance()
    return out


def named(values: np.ndarray) -> dict:
    return {name: values[:, k] for k, name in enumerate(OUTPUTS + FLAGS)}


def start_parameters(run: Run) -> dict:
    """The start: at rest in static equilibrium at the run's start position."""
    return {"use_start_values": True, "static_start": True, "q_start[1]": run.start[1], "q_start[3]": run.start[3]}


def make(arm: Arm, name: str, run: Run) -> dict:
    """One measured run: its CSV columns and the numbers of the summary."""
    t = as_logged(np.round(np.arange(0.0, run.duration + 0.5 * STEP, STEP), 12))
    commands = {i: as_logged([path(run.start[i], run.moves.get(i, []))(float(x))[0] for x in t]) for i in RIGID}
    drive = drive_table(t, commands)
    parameters = {**TRUTH, "h_min": SUBSTEP, "h_max": SUBSTEP, **start_parameters(run)}
    rng = np.random.default_rng([run.seed, 1])  # the controller's encoder readings
    tau, first = closed_loop(arm, run, t, drive, parameters, rng)
    truth = named(replay(arm, t, drive, tau, parameters))
    first = named(first)
    rng = np.random.default_rng([run.seed, 2])  # the logged measurements
    columns = {"t": t}
    for i in RIGID:
        columns[f"q_star{i}"] = commands[i]
    for m, i in enumerate(MOTORS):
        columns[f"tau_m{i}"] = as_logged(tau[:, m] + TORQUE_NOISE[i] * rng.standard_normal(len(t)))
    for output, (column, sigma, count) in {**ENCODERS, **ROTORS}.items():
        columns[column] = as_logged(read_out(rng, truth[output], sigma, count))
    # what the fit gets at the truth: the logged (noisy) torques replayed
    logged = named(replay(arm, t, drive, np.column_stack([columns[f"tau_m{i}"] for i in MOTORS]), parameters))
    summary = {"samples": len(t)}
    for i in MOTORS:
        q = f"q[{i}]"
        summary[i] = {
            "link_stick_phases": round(float(truth[f"n_stick[{i}]"][-1] - truth[f"n_stick[{i}]"][0])),
            "rotor_stick_phases": round(float(truth[f"n_stick_m[{i}]"][-1] - truth[f"n_stick_m[{i}]"][0])),
            "stuck_at_start": bool(truth[f"stick[{i}]"][0]),
            "stuck_fraction": float(np.mean(truth[f"stick[{i}]"])),
            "max_speed": float(np.max(np.abs(truth[f"qd[{i}]"]))),
            "torque_range": (float(tau[:, MOTORS.index(i)].min()), float(tau[:, MOTORS.index(i)].max())),
            "pass_difference": float(np.max(np.abs(first[q] - truth[q]))),
            "noisy_replay": float(np.max(np.abs(logged[q] - truth[q]))),
            "noisy_replay_rms": float(np.sqrt(np.mean((logged[q] - truth[q]) ** 2))),
        }
    return {"columns": columns, "summary": summary, "truth": truth, "first": first, "tau": tau}


def write_csv(columns: dict, path: Path) -> None:
    names = list(columns)
    table = np.column_stack([columns[n] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt=f"%.{DIGITS}g")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fmu", default=str(FMU))
    p.add_argument("--runs", nargs="*", default=list(RUNS), help="default: all six")
    a = p.parse_args()
    wall = time.perf_counter()
    arm = Arm(Path(a.fmu))
    std = {i: math.hypot(ENCODERS[f"q[{i}]"][1], ENCODERS[f"q[{i}]"][2] / math.sqrt(12.0)) for i in MOTORS}
    print(
        "run        j  stick link/rotor  stuck  max|qd|  tau_m range N.m    noise  pass1-2   "
        "logged replay max (rms, /std)"
    )
    stuck = []
    for name in a.runs:
        result = make(arm, name, RUNS[name])
        stuck += [result["summary"][i]["stuck_at_start"] for i in MOTORS]
        write_csv(result["columns"], HERE / f"{name}.csv")
        for i in MOTORS:
            j = result["summary"][i]
            low, high = j["torque_range"]
            unit = "rad" if i == 1 else "m"
            print(
                f"{name:10s} {i}  {j['link_stick_phases']:5d} / {j['rotor_stick_phases']:3d}    "
                f"{100 * j['stuck_fraction']:4.0f} %  {j['max_speed']:5.3f}  {low:+7.4f}..{high:+7.4f}  "
                f"{100 * TORQUE_NOISE[i] / (high - low):4.2f} %  {j['pass_difference']:.2e}  "
                f"{j['noisy_replay']:.2e} {unit} ({j['noisy_replay_rms']:.1e}, {j['noisy_replay'] / std[i]:5.0f})"
            )
        print(f"{'':10s}    {result['summary']['samples']} samples, {RUNS[name].duration:g} s -> {name}.csv")
    print(
        f"stick: stiction phases after the start ({sum(stuck)} of {len(stuck)} links stuck at the start); "
        "stuck: samples with the link stuck; "
        "max|qd|: rad/s, m/s;\nnoise: the torque noise over the range; pass1-2: max |q| difference of the closed "
        "loop and the truth (rad, m);\nlogged replay: max |q| difference of the logged torques replayed and the truth "
        f"(rms; max over the encoder's std). {time.perf_counter() - wall:.1f} s"
    )


if __name__ == "__main__":
    main()
