"""The FMU as fmpy sees it: unpacked once per process, variables by name, log captured.

* :func:`unpacked`: an FMU's bytes extracted into a per-process temporary directory, once
  per content (sha256), removed at exit; a Dask worker unpacks the bytes sent to it here.
* :class:`LogCapture`: fmi2CallbackFunctions whose logger keeps the FMU's messages, so a
  discarded or refused step can report the FMU's reason.
* :func:`set_value`: a parameter set by its modelDescription name;
* :func:`initialize` and :func:`communication_points`: an instance set up with its parameters
  and stepped over a motion, the same way by every command (inputs set at t_k = k * step,
  a motion file's motor torques with their first two derivatives, then ``doStep(t_k, step)``).
"""

from __future__ import annotations

import atexit
import hashlib
import io
import shutil
import tempfile
from ctypes import byref
from pathlib import Path

from .motion import input_names

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_FMU = ROOT / "target" / "fmu" / "StickSlipManipulator.fmu"

_UNPACKED = {}  # sha256 of the FMU's bytes -> directory


def content_hash(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def unpacked(data: bytes, digest: str | None = None) -> str:
    """The directory into which the FMU ``data`` is extracted in this process (once per content)."""
    from fmpy import extract

    digest = digest or content_hash(data)
    if digest not in _UNPACKED:
        target = tempfile.mkdtemp(prefix=f"stickslip-fmu-{digest[:12]}-")
        atexit.register(shutil.rmtree, target, True)
        _UNPACKED[digest] = extract(io.BytesIO(data), unzipdir=target)
    return _UNPACKED[digest]


def model_description(data: bytes):
    """fmpy's ModelDescription of the FMU ``data``."""
    from fmpy import read_model_description

    return read_model_description(io.BytesIO(data))


def set_value(slave, variable, value) -> None:
    """Sets one Real, Integer or Boolean variable (fmpy ScalarVariable) of an FMU2Slave."""
    vr = [variable.valueReference]
    if variable.type == "Boolean":
        slave.setBoolean(vr, [bool(value)])
    elif variable.type in ("Integer", "Enumeration"):
        slave.setInteger(vr, [int(value)])
    else:
        slave.setReal(vr, [float(value)])


def input_references(md) -> list:
    """Value references of q_star[1..n], qd_star[1..n], qdd_star[1..n]: the order of a motion's values."""
    by_name = {v.name: v for v in md.modelVariables}
    n = sum(1 for v in md.modelVariables if v.causality == "input" and v.name.startswith("q_star["))
    return [by_name[name].valueReference for name in input_names(n)]


def _input_values(inputs) -> list:
    q, qd, qdd = inputs
    return [float(x) for x in (*q, *qd, *qdd)]


def _set_torques(slave, motion, t: float) -> None:
    """The motor torques of ``motion`` at t (its ``torques``, a :class:`stickslip.motion.TorqueSpline`
    bound to the FMU by :func:`stickslip.motion.load_motion_for`; none for most motions): the
    values by fmi2SetReal, their first and second derivatives by fmi2SetRealInputDerivatives."""
    torques = getattr(motion, "torques", None)
    if torques is None:
        return
    if torques.references is None:
        raise ValueError(f"{torques.source}: motor torques not bound to an FMU: load the motion with load_motion_for")
    value, rate, accel = torques(t)
    n = len(torques.references)
    slave.setReal(torques.references, [float(x) for x in value])
    slave.setRealInputDerivatives(torques.references, [1] * n, [float(x) for x in rate])
    slave.setRealInputDerivatives(torques.references, [2] * n, [float(x) for x in accel])


def initialize(slave, md, parameters: dict, input_vrs: list, motion, step: float) -> None:
    """setupExperiment at t = 0, the parameters set by name, initialization with the motion's
    inputs at t = 0 (and its motor torques, if it gives any). An unknown name raises ValueError;
    what the FMU refuses raises fmpy's FMICallException."""
    by_name = {v.name: v for v in md.modelVariables}
    slave.setupExperiment(startTime=0.0)
    for name, value in parameters.items():
        if name not in by_name:
            raise ValueError(f"{name!r} is not a variable of the FMU")
        set_value(slave, by_name[name], value)
    slave.enterInitializationMode()
    slave.setReal(input_vrs, _input_values(motion(0.0, step)))
    _set_torques(slave, motion, 0.0)
    slave.exitInitializationMode()


def communication_points(slave, input_vrs: list, motion, end: float, step: float):
    """Steps an initialized instance from 0 to ``end``: at t_k = k * step the motion's inputs
    (and its motor torques with their first two derivatives, if it gives any), then
    ``doStep(t_k, step)``; yields (k + 1, t_{k+1}) after each step."""
    for k in range(round(end / step)):
        t = k * step
        slave.setReal(input_vrs, _input_values(motion(t, step)))
        _set_torques(slave, motion, t)
        slave.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        yield k + 1, (k + 1) * step


_LOG_SINKS = {}  # componentEnvironment id -> LogCapture
_GLOBAL_LOGGER = None


def _dispatch_log(env, instance, status, category, message):
    dec = lambda b: b.decode("utf-8", "replace") if b is not None else ""  # noqa: E731
    sink = _LOG_SINKS.get(env or 0)
    if sink is not None:
        sink.records.append((dec(instance), int(status), dec(category), dec(message)))


class LogCapture:
    """fmi2CallbackFunctions whose logger appends (instance, status, category, message) to ``records``.

    fmpy formats the FMU's variadic message in a native proxy (fmpy.logging.addLoggerProxy)
    that keeps ONE Python logger for the whole process (a C global): every capture therefore
    uses the same Python function, which dispatches on the componentEnvironment pointer, a
    distinct small integer per capture. :meth:`close` drops the capture from that table.
    """

    _next_id = 1

    def __init__(self, logger=True):
        global _GLOBAL_LOGGER
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )

        self.records = []
        self.id = LogCapture._next_id
        LogCapture._next_id += 1
        _LOG_SINKS[self.id] = self
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.callbacks.componentEnvironment = self.id
        if logger:
            if _GLOBAL_LOGGER is None:
                _GLOBAL_LOGGER = fmi2CallbackLoggerTYPE(_dispatch_log)
            self.callbacks.logger = _GLOBAL_LOGGER
            from fmpy.logging import addLoggerProxy

            addLoggerProxy(byref(self.callbacks))

    def messages(self, category: str | None = None):
        return [m for (_, _, c, m) in self.records if category is None or c == category]

    def text(self) -> str:
        return "\n".join(f"[{s}] {c}: {m}" for (_, s, c, m) in self.records)

    def clear(self):
        self.records.clear()

    def close(self):
        _LOG_SINKS.pop(self.id, None)
