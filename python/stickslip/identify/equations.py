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
    time: np.ndarray = None
    flt: object = None
    loaded: np.ndarray = None  # L·sgn q̇ through the smoothing (:func:`with_lever_load`)


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
    return Motion(log.name, q, qd, qdd, sign, tau, keep, t, flt)


def with_lever_load(motion: Motion, lever) -> Motion:
    """The motion with its dry-friction columns: ``lever(states)`` -> the lever load L of every
    joint's friction at each state (the engine's joint reactions through the contact geometry,
    (3.11)-(3.15); NaN for a joint without), L·sgn q̇ through the filter's smoothing."""
    L = lever(np.hstack([motion.q, motion.qd, motion.qdd]))
    motion.loaded = derivatives(motion.time, np.nan_to_num(L) * np.sign(motion.qd), motion.flt)[0]
    return motion


def column_names(inertial_names, n: int, friction: str, armature: bool, loaded=()) -> list:
    """The columns' names: the regressor's, then per joint b_v[i], the dry friction and I_a[i]
    as chosen; the dry friction of a joint in ``loaded`` (one with contact geometry) is the
    study's μ_k[i]·L (its column L·sgn q̇), of any other a constant tau_c[i]·sgn q̇."""
    extra = []
    for i in range(1, n + 1):
        if "viscous" in friction:
            extra.append(f"b_v[{i}]")
        if "coulomb" in friction:
            extra.append(f"mu_k[{i}]" if i in loaded else f"tau_c[{i}]")
        if armature:
            extra.append(f"I_a[{i}]")
    return list(inertial_names) + extra


def _extra(kind: str, qd, qdd, sign, loaded):
    """A friction or armature column of one joint."""
    return {"b_v": qd, "tau_c": sign, "mu_k": loaded, "I_a": qdd}[kind]


def equations(motions: list, regressor, friction: str, armature: bool, joints=None, loaded=()) -> Equations:
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
            names = column_names(inertial_names, n, friction, armature, loaded)
        for i, tau in motion.tau.items():
            if joints is not None and i not in joints:
                continue
            k = motion.keep[i]
            extra = np.zeros((int(k.sum()), len(names) - Y.shape[2]))
            for j, name in enumerate(names[Y.shape[2] :]):
                kind, _, rest = name.partition("[")
                if int(rest[:-1]) != i:
                    continue
                dry = motion.loaded[k, i - 1] if kind == "mu_k" else None
                extra[:, j] = _extra(kind, motion.qd[k, i - 1], motion.qdd[k, i - 1], motion.sign[k, i - 1], dry)
            rows_A.append(np.hstack([Y[k, i - 1, :], extra]))
            rows_b.append(tau[k])
            joint_of.append(np.full(int(k.sum()), i))
            blocks.append((offset, offset + int(k.sum())))
            offset += int(k.sum())
    if names is None or offset == 0:
        raise ValueError("no torque samples left to identify from (every joint's rows were dropped)")
    return Equations(names, np.vstack(rows_A), np.concatenate(rows_b), np.concatenate(joint_of), blocks, Y.shape[2])


def structural_base(regressor, n: int, friction: str, armature: bool, seed: int = 5, count: int = 300, lever=None):
    """The base parameters of the equations' columns (:mod:`stickslip.identify.base`): the
    regressor, friction and armature columns at ``count`` random states, each joint's row with
    its own q̇, sgn q̇, L·sgn q̇ (``lever(states)``, for the joints with contact geometry) and q̈
    in its friction and armature columns."""
    from .base import base_parameters, random_states

    states = random_states(n, count, seed)
    Y, _, inertial_names = regressor(states)
    L = lever(states) if lever is not None else np.full((count, n), np.nan)
    loaded = [i for i in range(1, n + 1) if np.all(np.isfinite(L[:, i - 1]))]
    names = column_names(inertial_names, n, friction, armature, loaded)
    qd, qdd = states[:, n : 2 * n], states[:, 2 * n :]
    rows = []
    for i in range(1, n + 1):
        extra = np.zeros((count, len(names) - Y.shape[2]))
        for j, name in enumerate(names[Y.shape[2] :]):
            kind, _, rest = name.partition("[")
            if int(rest[:-1]) == i:
                sign = np.sign(qd[:, i - 1])
                extra[:, j] = _extra(kind, qd[:, i - 1], qdd[:, i - 1], sign, L[:, i - 1] * sign)
        rows.append(np.hstack([Y[:, i - 1, :], extra]))
    return base_parameters(np.vstack(rows), names)
