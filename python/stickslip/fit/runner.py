"""One experiment through the FMU for one parameter set: the model's outputs at every sample.

Runs wherever the task lands (a Dask worker, or the caller). Each process keeps one FMU
instance per FMU content and resets it between runs (fmi2Reset), so a fit's hundreds of
runs pay for one instantiation per worker. A run never raises: what the FMU refuses or
discards becomes the result's ``status`` with the FMU's reason, the samples not reached are
NaN.

Single shooting runs the whole experiment from its start (the flexible joints at rest,
q = q*, as the FMU starts by default). Multiple shooting runs it in segments, each started
from the measured state at its first sample (``use_start_values``, ``q_start[i]`` and
``qd_start[i]`` of every flexible joint): the simulated motion cannot drift from the
measured one for longer than a segment, so a stick-slip pattern that differs early does
not decide the cost of everything after it.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

STATUS = {1: "warning", 2: "discard", 3: "error", 4: "fatal"}


@dataclass
class Payload:
    """What a worker needs of an experiment (sent once per fit, picklable)."""

    name: str
    time: np.ndarray
    motion: object
    torques: object
    outputs: list
    fixed: dict  # known parameters and settings, set in every run


@dataclass
class Segments:
    """Multiple shooting: segment k covers samples starts[k] .. starts[k+1] (the last one to
    the end); q_start / qd_start: (segments, flexible joints) at each segment's first sample."""

    starts: np.ndarray
    joints: list
    q_start: np.ndarray
    qd_start: np.ndarray


@dataclass
class RunResult:
    values: np.ndarray  # (samples, outputs), NaN where not reached
    status: str  # "ok", "refused", "discard", "error"
    message: str
    reached: int  # samples reached


class _Instance:
    """An FMU2Slave of one unpacked FMU with its value references, reused across runs."""

    def __init__(self, unzipdir: str):
        from fmpy import read_model_description

        from ..fmu import LogCapture

        self.unzipdir = unzipdir
        self.md = read_model_description(unzipdir)
        self.by_name = {v.name: v for v in self.md.modelVariables}
        self.log = LogCapture()
        self.slave = None
        self.fresh = False

    def vr(self, name: str) -> int:
        return self.by_name[name].valueReference

    def ready(self):
        """The slave, instantiated or reset to its instantiated state."""
        from fmpy.fmi2 import FMU2Slave

        self.log.clear()
        if self.slave is not None and not self.fresh:
            try:
                self.slave.reset()
                self.fresh = True
            except Exception:  # noqa: BLE001 -- a slave that cannot reset is made anew
                self.drop()
        if self.slave is None:
            self.slave = FMU2Slave(
                guid=self.md.guid,
                unzipDirectory=self.unzipdir,
                modelIdentifier=self.md.coSimulation.modelIdentifier,
                instanceName="fit",
            )
            self.slave.instantiate(callbacks=self.log.callbacks)
            self.fresh = True
        self.fresh = False
        return self.slave

    def drop(self):
        if self.slave is not None:
            try:
                self.slave.freeInstance()
            except Exception:  # noqa: BLE001 -- nothing more to free
                pass
        self.slave = None

    def reason(self, fallback: str) -> str:
        text = "; ".join(m for (_, s, _, m) in self.log.records if s >= 1)
        return text or fallback


@functools.cache
def _instance(unzipdir: str) -> _Instance:
    return _Instance(unzipdir)


def _unzipdir(digest: str, fmu_data: bytes | None) -> str:
    from ..fmu import unpacked
    from ..variant import _unpacked_here

    return unpacked(fmu_data, digest) if fmu_data is not None else _unpacked_here(digest)


def run(
    digest: str, payload: Payload, parameters: dict, segments: Segments | None = None, fmu_data: bytes | None = None
) -> RunResult:
    """The outputs ``payload.outputs`` at every sample of the experiment, with ``parameters``
    (and the payload's fixed ones) set; in segments when ``segments`` is given."""
    from fmpy.fmi1 import FMICallException

    n = len(payload.time)
    values = np.full((n, len(payload.outputs)), np.nan)
    try:
        inst = _instance(_unzipdir(digest, fmu_data))
    except Exception as e:  # noqa: BLE001 -- a result, never a crash
        return RunResult(values, "error", f"FMU not available here: {type(e).__name__}: {e}", 0)
    bounds = [(0, n - 1)] if segments is None else _bounds(segments.starts, n)
    reached = 0
    for k, (first, last) in enumerate(bounds):
        start = None if segments is None else (segments.joints, segments.q_start[k], segments.qd_start[k])
        try:
            reached += _run_span(inst, payload, parameters, first, last, start, values)
        except _Refused as e:
            inst.drop()
            return RunResult(values, "refused", str(e), reached)
        except FMICallException as e:
            status = "discard" if getattr(e, "status", None) == 2 else "error"
            message = inst.reason(str(e))
            inst.drop()
            return RunResult(values, status, message, int(np.isfinite(values[:, 0]).sum()))
        except Exception as e:  # noqa: BLE001 -- a result, never a crash
            inst.drop()
            return RunResult(values, "error", f"{type(e).__name__}: {e}", reached)
    return RunResult(values, "ok", "", reached)


class _Refused(Exception):
    """The FMU refused the parameters (when set or at initialization)."""


def _bounds(starts, n: int) -> list:
    ends = [*starts[1:], n - 1]
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def _run_span(inst: _Instance, payload: Payload, parameters: dict, first: int, last: int, start, values) -> int:
    """Simulates samples first..last into ``values``; returns how many samples it filled."""
    from fmpy.fmi1 import FMICallException

    from ..fmu import set_value

    slave = inst.ready()
    t = payload.time
    slave.setupExperiment(startTime=float(t[first]))
    for name, value in {**payload.fixed, **parameters}.items():
        try:
            set_value(slave, inst.by_name[name], value)
        except FMICallException as e:
            raise _Refused(f"{name} = {value!r}: {inst.reason(str(e))}") from None
    if start is not None:
        joints, q0, qd0 = start
        set_value(slave, inst.by_name["use_start_values"], True)
        slave.setReal([inst.vr(f"q_start[{i}]") for i in joints], [float(x) for x in q0])
        slave.setReal([inst.vr(f"qd_start[{i}]") for i in joints], [float(x) for x in qd0])
    try:
        slave.enterInitializationMode()
        _set_inputs(slave, inst, payload, float(t[first]), float(t[min(first + 1, last)] - t[first]))
        slave.exitInitializationMode()
    except FMICallException as e:
        raise _Refused(f"at initialization: {inst.reason(str(e))}") from None
    read = _reader(inst, tuple(payload.outputs))
    values[first] = read(slave)
    filled = 1
    for k in range(first, last):
        h = float(t[k + 1] - t[k])
        _set_inputs(slave, inst, payload, float(t[k]), h)
        slave.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=h)
        values[k + 1] = read(slave)
        filled += 1
    slave.terminate()
    # A span ends where the next begins: its last sample is the next span's first.
    return filled - (0 if last == len(t) - 1 else 1)


@functools.cache
def _input_vrs(inst: _Instance, joints: int) -> list:
    from ..motion import input_names

    return [inst.vr(name) for name in input_names(joints)]


@functools.cache
def _reader(inst: _Instance, outputs: tuple):
    """slave -> the outputs' values as floats (Real outputs by one getReal, Integer and
    Boolean ones, such as stick[i], by theirs)."""
    kinds = [inst.by_name[name].type for name in outputs]
    if all(k == "Real" for k in kinds):
        vrs = [inst.vr(name) for name in outputs]
        return lambda slave: slave.getReal(vrs)
    groups = {}
    for j, (name, kind) in enumerate(zip(outputs, kinds, strict=True)):
        groups.setdefault(kind, ([], []))
        groups[kind][0].append(j)
        groups[kind][1].append(inst.vr(name))
    getters = {"Real": "getReal", "Integer": "getInteger", "Boolean": "getBoolean", "Enumeration": "getInteger"}

    def read(slave):
        row = np.empty(len(outputs))
        for kind, (index, vrs) in groups.items():
            row[index] = np.asarray(getattr(slave, getters[kind])(vrs), dtype=np.float64)
        return row

    return read


def _set_inputs(slave, inst: _Instance, payload: Payload, t: float, step: float) -> None:
    q, qd, qdd = payload.motion(t, step)
    slave.setReal(_input_vrs(inst, len(q)), [float(x) for x in (*q, *qd, *qdd)])
    if payload.torques is not None:
        value, rate, acc = payload.torques(t)
        vrs = [inst.vr(n) for n in payload.torques.names]
        slave.setReal(vrs, [float(x) for x in value])
        slave.setRealInputDerivatives(vrs, [1] * len(vrs), [float(x) for x in rate])
        slave.setRealInputDerivatives(vrs, [2] * len(vrs), [float(x) for x in acc])
