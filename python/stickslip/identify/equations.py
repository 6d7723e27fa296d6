"""The identification's equations: each measured joint torque at each sample, linear in the
parameters.

Joint i at sample k (Gautier and Khalil's inverse dynamic identification model, IDIM):

    τ_i = Y_i(q, q̇, q̈) π + b_v,i q̇_i + τ_c,i sgn q̇_i + I_a,i q̈_i

with π the links' standard inertial parameters (the engine's regressor,
:mod:`stickslip.fit.regressor`: the study's rigid-body dynamics (3.9) written linear in them),
b_v the viscous and τ_c the Coulomb friction of the joint, I_a its reflected rotor inertia
(armature, N²·J_m of a motor behind a gear of ratio N). The positions go through the SPEC's
derivative filter (:mod:`stickslip.fit.filtering`) for q, q̇, q̈, and the torques through the
same filter's value, so that both sides see the same delay and passband (parallel filtering).
The Coulomb column is sgn q̇ through the same smoothing. A joint's rows leave out the samples
within the filter's reach of either end, and, where its
Coulomb column is estimated, the samples whose filtered q̇ does not have the sign of the true one
for certain (:func:`stickslip.fit.idim._certain`: |q̇| above the noise the filter leaves in it and
above |q̈| times its reach), as the equation-error stage of ``stickslip fit`` does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..fit.filtering import derivatives, noise_gains
from ..fit.idim import SLIP_SIGMAS, _certain
from ..fit.spec import detect_resolution

# The position noise assumed where the encoder's count cannot be detected: a 20-bit encoder's
# rounding, 2π/2^20/√12 rad.
DEFAULT_POSITION_NOISE = 2 * math.pi / 2**20 / math.sqrt(12.0)


@dataclass
class Equations:
    """Rows of A θ = b: ``names`` the columns (the regressor's standard parameters, then the
    joints' friction and armature), ``joint`` (1-based) of every row, ``blocks`` the (start,
    stop) rows of each (run, joint) time series."""

    names: list
    A: np.ndarray
    b: np.ndarray
    joint: np.ndarray
    blocks: list
    inertial: int  # the first ``inertial`` columns are the links' standard parameters


@dataclass
class Motion:
    """A log through the derivative filter: q, q̇, q̈ (samples × n) and the torques'
    filtered values (joint -> samples), and which samples each joint's rows keep."""

    name: str
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    sign: np.ndarray  # sgn q̇ through the filter's smoothing, as the torques went through it
    tau: dict
    keep: dict  # joint -> boolean mask


def filtered(log, flt, coulomb: bool) -> Motion:
    """The log ``log`` (:class:`stickslip.identify.spec.Log`) through the filter ``flt``."""
    t = log.time
    dt = float(np.median(np.diff(t)))
    n_samples = log.q.shape[0]
    q, qd, qdd = derivatives(t, log.q, flt)
    gains = noise_gains(flt, dt, n_samples)
    reach = flt.reach(dt, n_samples)
    edge = math.ceil(reach / dt) + 1
    inside = np.zeros(n_samples, dtype=bool)
    inside[edge : n_samples - edge] = True
    tau, keep = {}, {}
    for i, samples in log.tau.items():
        tau[i] = derivatives(t, samples, flt)[0]
        mask = inside.copy()
        if coulomb:
            resolution = detect_resolution(log.q[:, i - 1])
            sigma = resolution / math.sqrt(12.0) if resolution > 0 else DEFAULT_POSITION_NOISE
            mask &= _certain(qd[:, i - 1], qdd[:, i - 1], SLIP_SIGMAS * gains[1] * sigma, reach)
        keep[i] = mask
    # The Coulomb torque jumps where q̇ changes sign; the measured torque reaches the equations
    # through the filter's smoothing, and so does the column that explains that jump.
    sign = derivatives(t, np.sign(qd), flt)[0]
    return Motion(log.name, q, qd, qdd, sign, tau, keep)


def column_names(inertial_names, n: int, friction: str, armature: bool) -> list:
    """The columns' names: the regressor's, then per joint b_v[i], tau_c[i], I_a[i] as chosen."""
    extra = []
    for i in range(1, n + 1):
        if "viscous" in friction:
            extra.append(f"b_v[{i}]")
        if "coulomb" in friction:
            extra.append(f"tau_c[{i}]")
        if armature:
            extra.append(f"I_a[{i}]")
    return list(inertial_names) + extra


def equations(motions: list, regressor, friction: str, armature: bool, joints=None) -> Equations:
    """The rows of every motion (:func:`filtered`) and measured joint (``joints``: those to use,
    default all measured); ``regressor(states) -> (Y, π, names)`` the engine's regressor of the
    arm (:func:`stickslip.fit.regressor.joint_torque_regressor` bound to its FMU)."""
    rows_A, rows_b, joint_of, blocks = [], [], [], []
    names = None
    offset = 0
    for motion in motions:
        n = motion.q.shape[1]
        Y, _, inertial_names = regressor(np.hstack([motion.q, motion.qd, motion.qdd]))
        if names is None:
            names = column_names(inertial_names, n, friction, armature)
        for i, tau in motion.tau.items():
            if joints is not None and i not in joints:
                continue
            k = motion.keep[i]
            extra = np.zeros((int(k.sum()), len(names) - Y.shape[2]))
            for j, name in enumerate(names[Y.shape[2] :]):
                kind, _, rest = name.partition("[")
                if int(rest[:-1]) != i:
                    continue
                source = {"b_v": motion.qd[k, i - 1], "tau_c": motion.sign[k, i - 1], "I_a": motion.qdd[k, i - 1]}
                extra[:, j] = source[kind]
            rows_A.append(np.hstack([Y[k, i - 1, :], extra]))
            rows_b.append(tau[k])
            joint_of.append(np.full(int(k.sum()), i))
            blocks.append((offset, offset + int(k.sum())))
            offset += int(k.sum())
    if names is None or offset == 0:
        raise ValueError("no torque samples left to identify from (every joint's rows were dropped)")
    return Equations(names, np.vstack(rows_A), np.concatenate(rows_b), np.concatenate(joint_of), blocks, Y.shape[2])
