"""The FMU of the reference arm with motor drives for the FMU tests: models/reference_rrpr_motor.toml
(the reference RRPR arm whose joints 1 and 3 have motor drives: a rotor of inertia J_m behind
the gear spring, turned by the input ``tau_m[i]``; joints 2 and 4 rigid, prescribed), built once
per process with ``bash scripts/build_fmu.sh --model models/reference_rrpr_motor.toml --out
<scratch>/motor.fmu`` for the platforms of the FMU under test (linux64, and win64 when it
carries one), as urdf_fmus.py builds the URDF arm's. After scripts/test.sh's own build_fmu.sh
stage the cargo builds in it do nothing and the build takes a few seconds.
``$STICKSLIP_MOTOR_FMU`` names a prebuilt one instead.

Also the motor FMU's standard drive, shared by test_motor_fmu.py, test_state.py (also in its
child process) and test_ranges.py: the reference motion's 12 inputs at every communication
point (for the motor joints 1 and 3 q_star, qd_star, qdd_star are ignored while stepping) and
the motor torques of :data:`TORQUE_SEGMENTS`, whose derivatives are set through
fmi2SetRealInputDerivatives where a segment starts (and the rate of a parabola at every point):
they persist until set again, so an FMU state taken inside a segment must carry them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from helpers import INTERVAL, ROOT, Slave, input_vector, require_fmu
from urdf_fmus import model_fmu

MOTOR_MODEL = ROOT / "models" / "reference_rrpr_motor.toml"
MOTOR_JOINTS = (1, 3)  # 1-based joints with a motor drive
RIGID_JOINTS = (2, 4)
# The model file's motor data (gear ratio N, rotor inertia J_m, viscous b_m, Coulomb tau_c).
GEAR_RATIO = {1: 100.0, 3: 628.3185307179587}
ROTOR_INERTIA = {1: 3.0e-4, 3: 1.2e-4}
MOTOR_VISCOUS = {1: 2.0e-4, 3: 1.0e-4}
MOTOR_COULOMB = {1: 0.03, 3: 0.02}
# The energy account of a motor FMU: constant over a run.
BALANCE = {
    "E_kin": 1,
    "E_pot": 1,
    "E_spring": 1,
    "E_rotor": 1,
    "W_drive": -1,
    "Q_friction": 1,
    "Q_damping": 1,
    "Q_motor": 1,
}

# Per motor joint, segments (t_start, tau_m, tau_m', tau_m'') in time order: from t_start on,
# tau_m(t) = tau_m + tau_m' (t - t_start) + tau_m'' (t - t_start)^2 / 2 (N.m, N.m/s, N.m/s2).
# Joint 1: held below tau_c (the rotor stays stuck), a ramp up past tau_c (it slips), a ramp
# down through zero (it reverses), a parabola. Joint 3: a torque ramp from 0.28 s on, set
# before the snapshot of test_state.py (t = 0.3 s) and active through its continuation.
TORQUE_SEGMENTS = {
    1: ((0.0, 0.02, 0.0, 0.0), (0.05, 0.02, 4.0, 0.0), (0.2, 0.62, -10.0, 0.0), (0.32, -0.58, 0.0, 40.0)),
    3: ((0.0, 0.0, 0.0, 0.0), (0.28, 0.0, 0.5, 0.0)),
}


def motor_fmu() -> Path:
    """The motor FMU's path, built on first use (`$STICKSLIP_MOTOR_FMU` may name a prebuilt one)."""
    return model_fmu("motor", MOTOR_MODEL, "STICKSLIP_MOTOR_FMU")


def require_motor_fmu() -> Path:
    """The motor FMU; skips the calling test when the FMU under test is not built (as
    helpers.require_fmu does), builds it otherwise."""
    require_fmu()
    return motor_fmu()


# ---------------------------------------------------------------------------
# the standard drive


def segment_index(joint: int, t: float) -> int:
    """The index of the segment of ``joint`` that holds at t."""
    segs = TORQUE_SEGMENTS[joint]
    return max(m for m, s in enumerate(segs) if t >= s[0])


def torque(joint: int, t: float):
    """(tau_m, tau_m', tau_m'') of ``joint`` at t."""
    ts, a, b, c = TORQUE_SEGMENTS[joint][segment_index(joint, t)]
    x = t - ts
    return a + b * x + c * x * x / 2.0, b + c * x, c


def segment_starts(joint: int, k: int, interval: float = INTERVAL) -> bool:
    """True if the step k (from t_k = k * interval) is the first of a segment of ``joint``."""
    t = k * interval
    return k == 0 or segment_index(joint, t) != segment_index(joint, (k - 1) * interval)


def motor_slave(name: str = "motor", static_start: bool = True, start_values: dict | None = None, **kw) -> Slave:
    """A Slave of the motor FMU initialized at t = 0 with the reference motion's inputs and
    tau_m of :func:`torque` at 0 (with ``static_start``: the rotors turned so that the gear
    springs hold the links)."""
    s = Slave(name, path=str(kw.pop("path", None) or motor_fmu()), **kw)
    s.fmu.setupExperiment(startTime=0.0)
    s.set("static_start", static_start)
    for n, v in (start_values or {}).items():
        s.set(n, v)
    s.fmu.enterInitializationMode()
    s.set_inputs(input_vector(0.0))
    for j in MOTOR_JOINTS:
        s.set(f"tau_m[{j}]", torque(j, 0.0)[0])
    s.fmu.exitInitializationMode()
    return s


def set_motor_inputs(s: Slave, k: int, interval: float = INTERVAL):
    """The inputs of step k: the reference motion's 12, tau_m of every motor joint, and its
    derivatives where a segment starts."""
    t = k * interval
    s.set_inputs(input_vector(t))
    for j in MOTOR_JOINTS:
        value, rate, accel = torque(j, t)
        s.set(f"tau_m[{j}]", value)
        vr = s.vars.vr(f"tau_m[{j}]")
        if segment_starts(j, k, interval):
            s.fmu.setRealInputDerivatives([vr, vr], [1, 2], [rate, accel])
        elif accel != 0.0:  # the rate of a parabola changes at every point
            s.fmu.setRealInputDerivatives([vr], [1], [rate])


def run_motor(s: Slave, k0: int, steps: int, interval: float = INTERVAL) -> np.ndarray:
    """Steps k0 .. k0+steps-1 of the standard drive; the outputs after each step, one row per step."""
    rows = []
    for k in range(k0, k0 + steps):
        set_motor_inputs(s, k, interval)
        s.fmu.doStep(currentCommunicationPoint=k * interval, communicationStepSize=interval)
        rows.append(s.outputs())
    return np.array(rows)


def balance(s: Slave) -> float:
    """E_kin + E_pot + E_spring + E_rotor - W_drive + Q_friction + Q_damping + Q_motor now."""
    return sum(sign * s.get(name) for name, sign in BALANCE.items())
