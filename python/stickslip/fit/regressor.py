"""The joint-torque regressor from the engine (issue 42): the rigid-body inverse dynamics
τ = M(q)·q̈ + C(q, q̇)·q̇ + g(q) of (3.9) are linear in each link's ten standard inertial
parameters, τ = Y(q, q̇, q̈)·π, and the FMU's own binary computes Y (its export
``stickslip_joint_torque_regressor``, called with ctypes on the FMU's ``resources/model.toml``,
as :mod:`stickslip.fit.idim` calls ``stickslip_inverse_dynamics``).

Per link i the ten parameters in Pinocchio's order, named as :func:`parameter_names` names them:
``m[i]``, ``mc_x[i]``, ``mc_y[i]``, ``mc_z[i]`` (the first moment m·c, c the centre of mass),
``I_xx[i]``, ``I_xy[i]``, ``I_yy[i]``, ``I_xz[i]``, ``I_yz[i]``, ``I_zz[i]`` (the inertia about the
origin of the link's frame, I = I_c + m·(cᵀc·1 − c·cᵀ)), all in the engine's link frame: for a
Denavit-Hartenberg model the frame just after joint i's motion (the study's frame i turned back by
Trans_x(a_i)·Rot_x(α_i)), for a URDF model the joint's child link frame turned so that z is the
joint axis (the child link frame itself for ``axis xyz="0 0 1"``); docs/method.md, "The
joint-torque regressor", says it in full.
"""

from __future__ import annotations

import ctypes
import functools

import numpy as np

from .idim import InverseDynamicsError, _model_source, export, library_path

EXPORT = "stickslip_joint_torque_regressor"  # the FMU library's function beyond FMI 2.0
# A link's standard parameters, in the engine's (and Pinocchio's) order.
PARAMETERS = ("m", "mc_x", "mc_y", "mc_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz")


def parameter_names(n: int) -> list:
    """The names of the 10n standard parameters of n links, in the order of π: "m[1]", "mc_x[1]",
    …, "I_zz[1]", "m[2]", …"""
    return [f"{p}[{i}]" for i in range(1, n + 1) for p in PARAMETERS]


@functools.cache
def _engine(path: str):
    """The export of the library at ``path``, with its C signature."""
    double_p = ctypes.POINTER(ctypes.c_double)
    size = ctypes.c_size_t
    argtypes = [
        ctypes.c_char_p,  # model: resources/model.toml
        ctypes.c_char_p,  # urdf: the URDF it names, or NULL
        ctypes.POINTER(ctypes.c_char_p),  # settings "m[3]=8.0", ...
        size,
        double_p,  # states, rows x [q(n), qd(n), qdd(n)]
        size,  # rows
        size,  # columns
        double_p,  # regressor, rows x n x 10n
        size,  # its size
        double_p,  # parameters, 10n
        size,  # their number
        ctypes.c_char_p,  # message buffer
        size,
    ]
    return export(path, EXPORT, argtypes, "the engine's joint-torque regressor was exported")


def joint_torque_regressor(unzipdir, states, settings=()) -> tuple:
    """(Y, π, names) at ``states`` (rows × [q(n), q̇(n), q̈(n)], SI units) by the engine in the
    unpacked FMU ``unzipdir``'s own binary, on the FMU's model with ``settings`` (tunable
    parameters by FMU name, "m[3]=8.0") applied: Y of shape rows × n × 10n with Y[r] @ π the
    inverse dynamics τ of row r (:func:`stickslip.fit.idim.inverse_dynamics`, gravity included) to
    rounding, π the model's 10n standard parameters and ``names`` theirs
    (:func:`parameter_names`). With no rows, Y is empty and π still the model's. Raises
    :class:`~stickslip.fit.idim.StageUnavailable` where the binary cannot do it and
    :class:`~stickslip.fit.idim.InverseDynamicsError` with the engine's reason where it refuses
    the input."""
    engine = _engine(str(library_path(unzipdir)))
    states = np.ascontiguousarray(states, dtype=np.float64)
    if states.ndim != 2:
        raise InverseDynamicsError(f"states must be rows of q, qd, qdd, not an array of shape {states.shape}")
    rows, columns = states.shape
    n = columns // 3
    regressor, parameters = np.full((rows, n, 10 * n), np.nan), np.full(10 * n, np.nan)
    text, urdf = _model_source(unzipdir)
    encoded = [str(s).encode() for s in settings]
    message = ctypes.create_string_buffer(1024)
    double_p = ctypes.POINTER(ctypes.c_double)
    status = engine(
        text.encode(),
        urdf.encode() if urdf is not None else None,
        (ctypes.c_char_p * max(1, len(encoded)))(*encoded),
        len(encoded),
        states.ctypes.data_as(double_p),
        rows,
        columns,
        regressor.ctypes.data_as(double_p),
        regressor.size,
        parameters.ctypes.data_as(double_p),
        parameters.size,
        message,
        len(message),
    )
    if status != 0:
        raise InverseDynamicsError(message.value.decode(errors="replace") or f"{EXPORT} returned {status}")
    return regressor, parameters, parameter_names(n)
