"""A whole experiment in one native call: the FMU's ``stickslip_run_experiment`` (src/fmi/experiment.rs).

A master that steps an FMU from Python pays for every communication point: the inputs' fmi2SetReal,
fmi2DoStep and fmi2GetReal through ctypes. This calls the FMU's own library once per experiment,
with the inputs of every point as arrays, on an instance fmpy instantiated and set up; the
library makes the same FMI calls inside (the outputs are the per-point path's bit for bit, a
test). With ``sensitivities``, it also returns ∂output/∂value for Real parameters and start
values, by internal numerical differentiation: replays of the run's sub-step schedule with one
value moved by its step (exact derivatives of the discrete scheme, up to rounding; a column whose
replays changed the event pattern is flagged in ``departures``).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np

NAME = "stickslip_run_experiment"

_double_p = ctypes.POINTER(ctypes.c_double)
_uint_p = ctypes.POINTER(ctypes.c_uint)
_size = ctypes.c_size_t
ARGTYPES = [
    ctypes.c_void_p,  # fmi2Component
    _size,
    _double_p,  # n_points, time
    _size,
    _uint_p,
    _double_p,  # n_drive, drive_vr, drive
    _size,
    _uint_p,
    _double_p,
    _double_p,
    _double_p,  # n_torques, torque_vr, torque, torque_rate, torque_accel
    _size,
    _uint_p,
    _double_p,  # n_outputs, output_vr, outputs
    _size,
    _uint_p,
    _double_p,
    ctypes.c_int,
    _size,  # n_sensitivities, sensitivity_vr, sensitivity_step, central, threads
    _double_p,
    ctypes.POINTER(ctypes.c_uint64),  # sensitivities, departures
    ctypes.POINTER(_size),  # reached
]


@dataclass
class Result:
    status: int  # the fmi2Status: 0 ok, 1 warning, 2 discard, 3 error, 4 fatal
    reached: int  # points whose outputs were written
    outputs: np.ndarray  # (points, outputs)
    sensitivities: np.ndarray | None = None  # (points, outputs, values)
    departures: np.ndarray | None = None  # (values,): 0 where the column is exact, 2**64 - 1 where a replay failed


def function(slave):
    """The library's ``stickslip_run_experiment`` for an fmpy ``FMU2Slave``, or None for an FMU
    built before it existed."""
    dll = getattr(slave, "dll", None)
    f = getattr(dll, NAME, None) if dll is not None else None
    if f is not None and f.argtypes is None:
        f.argtypes = ARGTYPES
        f.restype = ctypes.c_int
    return f


def _vrs(values) -> ctypes.Array:
    values = list(values)
    return (ctypes.c_uint * max(1, len(values)))(*values)


def _array(a, rows: int, columns: int, name: str) -> np.ndarray:
    a = np.require(a if a is not None else np.empty((rows, 0)), np.float64, ["C", "A"])
    if a.size != rows * columns:
        raise ValueError(f"{name} has {a.size} values, not {rows} points x {columns}")
    return a


def run(
    slave,
    time,
    drive_vrs=(),
    drive=None,
    torque_vrs=(),
    torques=None,
    output_vrs=(),
    sensitivity_vrs=(),
    steps=(),
    central: bool = False,
    threads: int = 0,
    out: np.ndarray | None = None,
) -> Result:
    """Runs the experiment on ``slave`` (instantiated and set up, not initialized): the inputs
    ``drive`` (points x drive_vrs) and ``torques`` ((value, rate, acceleration), each points x
    torque_vrs) at the points ``time``; the outputs ``output_vrs`` at every point (into ``out``
    when given), and their sensitivities to ``sensitivity_vrs`` with ``steps``."""
    f = function(slave)
    if f is None:
        raise RuntimeError(f"this FMU's library has no {NAME}: build it again with scripts/build_fmu.sh")
    t = np.require(time, np.float64, ["C", "A"])  # data columns may be unaligned views
    n = len(t)
    drive = _array(drive, n, len(drive_vrs), "drive")
    if torques is None:
        torques = (None, None, None)
    value, rate, acc = (_array(x, n, len(torque_vrs), "torques") for x in torques)
    values = np.full((n, len(output_vrs)), np.nan) if out is None else out
    flags = values.flags
    if values.shape != (n, len(output_vrs)) or not (flags.c_contiguous and flags.aligned) or values.dtype != np.float64:
        raise ValueError(f"out must be a C-contiguous, aligned float64 array of shape {(n, len(output_vrs))}")
    p = len(sensitivity_vrs)
    sens = np.full((n, len(output_vrs), p), np.nan) if p else np.empty(1)
    departures = np.zeros(max(p, 1), dtype=np.uint64)
    step = np.require(steps if p else [1.0], np.float64, ["C", "A"])
    if p and len(step) != p:
        raise ValueError(f"{p} sensitivity values need {p} steps, not {len(step)}")
    reached = _size(0)

    def ptr(a):
        return a.ctypes.data_as(_double_p)

    status = f(
        slave.component,
        n,
        ptr(t),
        len(drive_vrs),
        _vrs(drive_vrs),
        ptr(drive),
        len(torque_vrs),
        _vrs(torque_vrs),
        ptr(value),
        ptr(rate),
        ptr(acc),
        len(output_vrs),
        _vrs(output_vrs),
        ptr(values),
        p,
        _vrs(sensitivity_vrs),
        ptr(step),
        int(bool(central)),
        int(threads),
        ptr(sens),
        departures.ctypes.data_as(ctypes.POINTER(ctypes.c_uint64)),
        ctypes.byref(reached),
    )
    return Result(
        status=int(status),
        reached=int(reached.value),
        outputs=values,
        sensitivities=sens if p else None,
        departures=departures if p else None,
    )
