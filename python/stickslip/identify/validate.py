"""Validation as robotics identification does it: held-out runs' torques predicted from their
measured motion (through the same derivative filter), per joint the relative rms error
rms(τ̂ − τ)/rms(τ), for three models side by side:

* **identified**: the physically consistent model (links, friction, armature);
* **catalogue**: the FMU's own model (the URDF's or model file's links), no friction;
* **per joint**: each joint alone, τ_i = a q̈_i + b q̇_i + c sgn q̇_i + d (a reflected inertia,
  viscous and Coulomb friction and a constant for the joint's mean gravity load), fitted by
  least squares on the identification's runs: what a model without the arm's coupling gets.
"""

from __future__ import annotations

import math

import numpy as np

from .equations import Equations, equations


def per_joint_columns(motion, i: int, rows) -> np.ndarray:
    return np.column_stack(
        [motion.qdd[rows, i - 1], motion.qd[rows, i - 1], motion.sign[rows, i - 1], np.ones(int(np.sum(rows)))]
    )


def per_joint_fit(motions: list) -> dict:
    """Joint -> the four coefficients of the per-joint model, least squares over ``motions``'
    kept rows."""
    out = {}
    joints = sorted({i for m in motions for i in m.tau})
    for i in joints:
        A = np.vstack([per_joint_columns(m, i, m.keep[i]) for m in motions if i in m.tau])
        b = np.concatenate([m.tau[i][m.keep[i]] for m in motions if i in m.tau])
        out[i] = np.linalg.lstsq(A, b, rcond=None)[0]
    return out


def relative_rms(predicted, measured) -> float:
    scale = math.sqrt(float(np.mean(measured**2)))
    return math.sqrt(float(np.mean((predicted - measured) ** 2))) / scale if scale > 0 else math.inf


def predictions(motion, regressor, friction: str, armature: bool, models: dict, per_joint: dict, loaded=()) -> dict:
    """Per joint of the held-out ``motion``: time series of the measured torque and of each
    model's prediction ("identified", "catalogue": θ vectors of the equations' columns; "per
    joint": :func:`per_joint_fit`), at the samples the motion keeps (where the friction law
    holds: the joint moves for certain); ``loaded``: the joints whose dry friction is μ_k·L."""
    eq: Equations = equations([motion], regressor, friction, armature, loaded=loaded)
    out = {}
    for i in sorted(motion.tau):
        rows = eq.joint == i
        keep = motion.keep[i]
        series = {"measured": eq.b[rows]}
        for name, theta in models.items():
            series[name] = eq.A[rows] @ theta
        if i in per_joint:
            series["per joint"] = per_joint_columns(motion, i, keep) @ per_joint[i]
        series["index"] = np.flatnonzero(keep)
        out[i] = series
    return out


def table(predicted: dict) -> dict:
    """Joint -> model -> relative rms of :func:`predictions`."""
    return {
        i: {name: relative_rms(v, s["measured"]) for name, v in s.items() if name not in ("measured", "index")}
        for i, s in predicted.items()
    }
