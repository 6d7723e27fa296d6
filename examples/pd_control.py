#!/usr/bin/env python3
"""Closed loop with the stick-slip manipulator FMU: a PD controller in Python.

The controller runs at 1 kHz and steps the FMU (FMI 2.0 co-simulation) through fmpy's
FMU2Slave. It moves the flexible joints 1 (revolute) and 3 (prismatic) of the reference
manipulator from (0 rad, 0.8 m) to a target, by default (0.3 rad, 0.9 m), and holds it;
the rigid joints 2 and 4 are held at 0.

Each millisecond the controller reads the measured q and qd of the flexible joints and
sets their drive inputs (the motor-side position q* of the elastic drive, eq. 2.1):

    q*_i = r_i + Kp_i (r_i - q_i) + Kd_i (rd_i - qd_i)

where r_i(t) is a cycloidal path from the start to the target over ``move_time`` (1 s)
and rd_i its rate. q* is held over the step (qd_star = qdd_star = 0: zero-order hold, as a
digital controller does). Kp adds stiffness to the drive (the drive spring k sees the
error magnified by 1 + Kp, which also shrinks the dead band that static friction leaves
around the target), Kd adds damping (k*Kd in N.s/m or N.m.s/rad) to the undamped drive.

Run it as a script (writes a CSV and, with --plot, a PNG):

    python examples/pd_control.py [--fmu target/fmu/StickSlipManipulator.fmu] \
        [--target 0.3 0.9] [--end 2.0] [--csv results/pd_control.csv] [--plot results/pd_control.png]

or import it: ``run(...)`` returns a dict of numpy arrays (time, q, qd, q_star, stick, ...).
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FMU = ROOT / "target" / "fmu" / "StickSlipManipulator.fmu"

START = (0.0, 0.8)  # q1 (rad), q3 (m) at rest at t = 0
TARGET = (0.3, 0.9)
KP = (1.0, 1.0)  # dimensionless
KD = (0.002, 0.004)  # s
STEP = 1e-3  # 1 kHz
FLEXIBLE = (1, 3)


def cycloidal(start: float, end: float, t: float, duration: float):
    """Position and rate of the cycloidal path from start to end over [0, duration]."""
    if t <= 0.0:
        return start, 0.0
    if t >= duration:
        return end, 0.0
    tau = t / duration
    d = end - start
    return (
        start + d * (tau - math.sin(2 * math.pi * tau) / (2 * math.pi)),
        d * (1.0 - math.cos(2 * math.pi * tau)) / duration,
    )


class PD:
    """The PD law on the drive input of one flexible joint."""

    def __init__(self, kp: float, kd: float):
        self.kp, self.kd = kp, kd

    def __call__(self, r: float, rd: float, q: float, qd: float) -> float:
        return r + self.kp * (r - q) + self.kd * (rd - qd)


def run(
    fmu: str | Path | None = None,
    target=TARGET,
    end: float = 2.0,
    move_time: float = 1.0,
    kp=KP,
    kd=KD,
    step: float = STEP,
    parameters: dict | None = None,
):
    """Runs the closed loop from t = 0 to ``end``; returns a dict of arrays, one row per
    communication point: time, r (path), q, qd, q_star (the controller's outputs), stick."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    fmu = str(fmu or DEFAULT_FMU)
    md = read_model_description(fmu)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    unzipdir = extract(fmu, unzipdir=tempfile.mkdtemp(prefix="pd_control_"))
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=unzipdir,
        modelIdentifier=md.coSimulation.modelIdentifier,
        instanceName="pd_control",
    )
    laws = [PD(kp[0], kd[0]), PD(kp[1], kd[1])]
    q_star_vr = [vr[f"q_star[{i}]"] for i in range(1, 5)]
    rate_vr = [vr[f"{g}[{i}]"] for g in ("qd_star", "qdd_star") for i in range(1, 5)]
    q_vr = [vr[f"q[{i}]"] for i in FLEXIBLE]
    qd_vr = [vr[f"qd[{i}]"] for i in FLEXIBLE]
    stick_vr = [vr[f"stick[{i}]"] for i in FLEXIBLE]

    n = round(end / step)
    log = {k: np.zeros((n + 1, 2)) for k in ("r", "q", "qd", "q_star")}
    log["stick"] = np.zeros((n + 1, 2), dtype=bool)
    log["time"] = np.array([k * step for k in range(n + 1)])
    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        for name, value in (parameters or {}).items():
            slave.setReal([vr[name]], [value])
        slave.enterInitializationMode()
        # at rest at the start: q* = q, rigid joints 2 and 4 held at 0
        slave.setReal(q_star_vr, [START[0], 0.0, START[1], 0.0])
        slave.setReal(rate_vr, [0.0] * 8)
        slave.exitInitializationMode()
        for k in range(n + 1):
            t = k * step
            q = slave.getReal(q_vr)
            qd = slave.getReal(qd_vr)
            paths = [cycloidal(START[j], target[j], t, move_time) for j in range(2)]
            u = [laws[j](paths[j][0], paths[j][1], q[j], qd[j]) for j in range(2)]
            log["time"][k] = t
            log["r"][k] = [p[0] for p in paths]
            log["q"][k] = q
            log["qd"][k] = qd
            log["q_star"][k] = u
            log["stick"][k] = [b != 0 for b in slave.getBoolean(stick_vr)]
            if k == n:
                break
            # zero-order hold of the controller output over the next millisecond
            slave.setReal(q_star_vr, [u[0], 0.0, u[1], 0.0])
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)
    return log


def summary(log, target=TARGET, settle_time: float = 1.5, hold: float = 0.3) -> dict:
    """Largest |q - target| after settle_time, largest |qd| and |q - target| over the last
    ``hold`` seconds, per flexible joint."""
    t = log["time"]
    err = np.abs(log["q"] - np.asarray(target))
    after = t >= settle_time - 1e-12
    last = t >= t[-1] - hold - 1e-12
    return {
        "max_error_after_settle": err[after].max(axis=0) if after.any() else np.full(2, np.nan),
        "max_error_last": err[last].max(axis=0),
        "max_rate_last": np.abs(log["qd"][last]).max(axis=0),
        "error_end": err[-1],
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    p.add_argument("--target", type=float, nargs=2, default=TARGET, metavar=("Q1", "Q3"))
    p.add_argument("--end", type=float, default=2.0)
    p.add_argument("--csv", default=None, help="write time, r, q, qd, q_star, stick of joints 1 and 3")
    p.add_argument("--plot", default=None, help="write a PNG of q, q* and the stick phases")
    a = p.parse_args(argv)
    if not Path(a.fmu).is_file():
        sys.exit(f"{a.fmu} not found: build it with `bash scripts/build_fmu.sh`")
    log = run(a.fmu, tuple(a.target), a.end)
    s = summary(log, tuple(a.target))
    for key, value in s.items():
        print(f"{key:24s} joint 1: {value[0]:.3e} rad   joint 3: {value[1]:.3e} m")
    print("(after settle = from t = 1.5 s; last = the last 0.3 s)")
    if a.csv:
        Path(a.csv).parent.mkdir(parents=True, exist_ok=True)
        cols = ["time"] + [f"{k}[{i}]" for k in ("r", "q", "qd", "q_star", "stick") for i in FLEXIBLE]
        data = np.column_stack([log["time"]] + [log[k].astype(float) for k in ("r", "q", "qd", "q_star", "stick")])
        np.savetxt(a.csv, data, delimiter=",", header=",".join(cols), comments="", fmt="%.17g")
        print("wrote", a.csv)
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
        for j, (i, unit) in enumerate(zip(FLEXIBLE, ("rad", "m"), strict=True)):
            ax[j].plot(log["time"], log["q"][:, j], label=f"q{i}")
            ax[j].plot(log["time"], log["q_star"][:, j], lw=0.8, label=f"q{i}* (controller)")
            ax[j].plot(log["time"], log["r"][:, j], "--", lw=0.8, label="path")
            ax[j].set_ylabel(unit)
            ax[j].legend(loc="lower right")
            ax[2].plot(
                log["time"], log["stick"][:, j] * (1 + 0.1 * j), drawstyle="steps-post", label=f"joint {i} stuck"
            )
        ax[2].set_xlabel("t (s)")
        ax[2].legend()
        Path(a.plot).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(a.plot, dpi=120)
        print("wrote", a.plot)


if __name__ == "__main__":
    main()
