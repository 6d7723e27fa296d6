"""One experiment through the FMU for one parameter set: the model's outputs at every sample.

Runs wherever the task lands (a Dask worker, or the caller). Each process keeps one FMU
instance per FMU content and resets it between runs (fmi2Reset), so a fit's hundreds of
runs pay for one instantiation per worker. A run never raises: what the FMU refuses or
discards becomes the result's ``status`` with the FMU's reason, the samples not reached are
NaN.

Single shooting runs the whole experiment from its start: the measured state at its first
sample (``payload.start``, :mod:`stickslip.fit.start`), or the FMU's own start (every
spring-driven joint at rest at q = q*) where the experiment says ``start = "rest"``.
Multiple shooting runs it in segments, each started from the measured state at its first
sample (``use_start_values``, ``q_start[i]`` and ``qd_start[i]`` of every flexible and motor
joint, ``theta_m_start[i]`` and ``omega_m_start[i]`` of every rotor): the simulated motion
cannot drift from the measured one for longer than a segment, so a stick-slip pattern that
differs early does not decide the cost of everything after it.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass

import numpy as np

from .. import experiment
from .start import Segments

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
    start: Segments | None = None  # the start state from the data (single shooting), or None

    def inputs(self) -> tuple:
        """The drive inputs at every sample, computed once per process: (q*, q*', q*'') as one
        C-contiguous (samples, 3 joints) array, and the torques' (value, rate, acceleration)
        arrays (samples, torques) or None."""
        table = self.__dict__.get("_inputs")
        if table is None:
            t = self.time
            steps = np.append(np.diff(t), t[-1] - t[-2] if len(t) > 1 else 0.0)
            drive = np.ascontiguousarray(
                [
                    np.concatenate([np.asarray(x, dtype=np.float64) for x in self.motion(float(tk), float(h))])
                    for tk, h in zip(t, steps, strict=True)
                ]
            )
            torques = None
            if self.torques is not None:
                torques = tuple(np.ascontiguousarray(np.atleast_2d(x).reshape(len(t), -1)) for x in self.torques(t))
            table = self.__dict__["_inputs"] = (drive, torques)
        return table

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k != "_inputs"}


@dataclass
class RunResult:
    values: np.ndarray  # (samples, outputs), NaN where not reached
    status: str  # "ok", "refused", "discard", "error"
    message: str
    reached: int  # samples reached
    # With sensitivities requested: (samples, outputs, parameters) d(output)/d(parameter), and per
    # parameter whether its column is exact (no replay of any span left its event pattern).
    jacobian: np.ndarray | None = None
    exact: np.ndarray | None = None


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
    digest: str,
    payload: Payload,
    parameters: dict,
    segments: Segments | None = None,
    fmu_data: bytes | None = None,
    sensitivities: dict | None = None,
) -> RunResult:
    """The outputs ``payload.outputs`` at every sample of the experiment, with ``parameters``
    (and the payload's fixed ones) set; in segments when ``segments`` is given, else from the
    payload's start state (when it has one). With ``sensitivities`` ({parameter: step}), also
    their derivatives by the FMU's internal numerical differentiation
    (:mod:`stickslip.experiment`): ``jacobian`` and ``exact`` of the result, None where the FMU
    cannot give them (built before the export, or ``STICKSLIP_PER_POINT=1``)."""
    from fmpy.fmi1 import FMICallException

    n = len(payload.time)
    values = np.full((n, len(payload.outputs)), np.nan)
    wrt = None
    if sensitivities:
        wrt = _Sensitivities(list(sensitivities), np.array(list(sensitivities.values()), dtype=np.float64))
        wrt.jacobian = np.full((n, len(payload.outputs), len(wrt.names)), np.nan)
        wrt.exact = np.ones(len(wrt.names), dtype=bool)
    try:
        inst = _instance(_unzipdir(digest, fmu_data))
    except Exception as e:  # noqa: BLE001 -- a result, never a crash
        return RunResult(values, "error", f"FMU not available here: {type(e).__name__}: {e}", 0)
    segments = segments if segments is not None else payload.start
    bounds = [(0, n - 1)] if segments is None else _bounds(segments.starts, n)
    reached = 0
    for k, (first, last) in enumerate(bounds):
        start = None if segments is None else (segments, k)
        try:
            reached += _run_span(inst, payload, parameters, first, last, start, values, wrt)
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
    if wrt is not None and wrt.available:
        return RunResult(values, "ok", "", reached, wrt.jacobian, wrt.exact)
    return RunResult(values, "ok", "", reached)


@dataclass
class _Sensitivities:
    """What a run's sensitivities are taken to, and where they go (filled span by span)."""

    names: list
    steps: np.ndarray
    jacobian: np.ndarray = None
    exact: np.ndarray = None
    available: bool = True


class _Refused(Exception):
    """The FMU refused the parameters (when set or at initialization)."""


def _bounds(starts, n: int) -> list:
    ends = [*starts[1:], n - 1]
    return [(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def _run_span(
    inst: _Instance, payload: Payload, parameters: dict, first: int, last: int, start, values, wrt=None
) -> int:
    """Simulates samples first..last into ``values`` (and their sensitivities into ``wrt``);
    returns how many samples it filled."""
    from fmpy.fmi1 import FMICallException

    from ..fmu import set_value

    chain = {}  # start value -> {parameter: d(start value)/d(parameter)}: the rotors' start

    slave = inst.ready()
    t = payload.time
    slave.setupExperiment(startTime=float(t[first]))
    for name, value in {**payload.fixed, **parameters}.items():
        try:
            set_value(slave, inst.by_name[name], value)
        except FMICallException as e:
            raise _Refused(f"{name} = {value!r}: {inst.reason(str(e))}") from None
    held = ()  # the start unknowns (q_start[i], qd_start[i]) a later segment does not depend on
    if start is not None:
        segments, k = start
        joints = segments.joints
        # The first segment starts from the fitted start state where the parameters hold one
        # (stickslip.fit.start.start_unknowns), the others from their reading.
        q0, qd0 = segments.state(k, parameters)
        if k > 0:
            held = tuple(n for n in parameters if n.startswith(("q_start[", "qd_start[")))
        set_value(slave, inst.by_name["use_start_values"], True)
        slave.setReal([inst.vr(f"q_start[{i}]") for i in joints], [float(x) for x in q0])
        slave.setReal([inst.vr(f"qd_start[{i}]") for i in joints], [float(x) for x in qd0])
        if segments.motors:
            known = {**payload.fixed, **parameters}

            def value(name):
                return known[name] if name in known else float(inst.by_name[name].start or 0.0)

            rotor = segments.rotor(k, value, (q0, qd0))
            set_value(slave, inst.by_name["static_start"], False)  # the rotors start where the data put them
            slave.setReal([inst.vr(name) for name in rotor], [float(x) for x in rotor.values()])
            if wrt is not None:
                chain = _rotor_chain(segments, k, known, value, wrt, rotor)
    if native_runs() and experiment.function(slave) is not None:
        return _run_span_native(slave, inst, payload, first, last, values, wrt, chain, held)
    if wrt is not None:
        wrt.available = False
    set_drive, set_torques = _input_setter(slave, inst, payload)
    try:
        slave.enterInitializationMode()
        set_drive(first)
        if set_torques is not None:
            set_torques(first)
        slave.exitInitializationMode()
    except FMICallException as e:
        raise _Refused(f"at initialization: {inst.reason(str(e))}") from None
    read = _reader(inst, tuple(payload.outputs))
    read(slave, values, first)
    for k in range(first, last):
        set_drive(k)
        if set_torques is not None:
            set_torques(k)
        slave.doStep(currentCommunicationPoint=float(t[k]), communicationStepSize=float(t[k + 1] - t[k]))
        read(slave, values, k + 1)
    filled = last - first + 1
    slave.terminate()
    # A span ends where the next begins: its last sample is the next span's first.
    return filled - (0 if last == len(t) - 1 else 1)


def native_runs() -> bool:
    """Whether runs go through the FMU's ``stickslip_run_experiment`` (one call an experiment)
    rather than per communication point through fmpy: yes, unless ``STICKSLIP_PER_POINT=1`` (the
    test that both give the same numbers bit for bit sets it)."""
    return os.environ.get("STICKSLIP_PER_POINT", "") != "1"


def _rotor_chain(segments, k: int, known: dict, value, wrt, rotor: dict) -> dict:
    """{theta_m_start[i]: (its value, {parameter: derivative})}: how the rotors' start of segment k
    (:meth:`Segments.rotor`, from the gear's k[i] and Delta[i] and the fitted start state) moves
    with the parameters the sensitivities are taken to, by central differences of that closed
    form (its rounding ~1e-10 of the derivative)."""
    out = {}
    for name, step in zip(wrt.names, wrt.steps, strict=True):
        if not name.startswith(("k[", "Delta[", "q_start[", "qd_start[")) or name not in known:
            continue

        def moved(dx, name=name):
            shifted = {**known, name: known[name] + dx}
            return segments.rotor(k, lambda n: shifted[n] if n in shifted else value(n), segments.state(k, shifted))

        plus, minus = moved(step), moved(-step)
        for start in plus:
            d = (plus[start] - minus[start]) / (2.0 * step)
            if d != 0.0:
                out.setdefault(start, (rotor[start], {}))[1][name] = d
    return out


def _run_span_native(
    slave, inst: _Instance, payload: Payload, first: int, last: int, values, wrt=None, chain=None, held=()
) -> int:
    """Samples first..last into ``values`` by one native call: the same FMI calls as the
    per-point loop below, made inside the FMU's library; with ``wrt``, the sensitivities too
    (those to a rotor's start value folded into its parameters' by ``chain``; those to the
    parameters ``held``, which the span does not depend on, 0)."""
    from ..motion import input_names

    drive, torques = payload.inputs()
    joints = drive.shape[1] // 3
    span = slice(first, last + 1)
    torque_vrs = [] if torques is None else [inst.vr(name) for name in payload.torques.names]
    names, steps = [], []
    if wrt is not None:
        starts = sorted(chain or {})
        names = [n for n in wrt.names if n not in held] + starts
        # A start value's step: 1e-6 of its size, at least 1e-9 (rad).
        own = [s for n, s in zip(wrt.names, wrt.steps, strict=True) if n not in held]
        steps = [*own, *(max(1e-9, 1e-6 * abs(chain[n][0])) for n in starts)]
    result = experiment.run(
        slave,
        payload.time[span],
        drive_vrs=[inst.vr(name) for name in input_names(joints)],
        drive=drive[span],
        torque_vrs=torque_vrs,
        torques=None if torques is None else tuple(a[span] for a in torques),
        output_vrs=[inst.vr(name) for name in payload.outputs],
        sensitivity_vrs=[inst.vr(n) for n in names],
        steps=steps,
        out=values[span] if values[span].flags.c_contiguous else None,
    )
    if not values[span].flags.c_contiguous:
        values[span] = result.outputs
    if wrt is not None and result.sensitivities is not None:
        own = [j for j, n in enumerate(wrt.names) if n not in held]
        p = len(own)
        jac = np.zeros((result.sensitivities.shape[0], result.sensitivities.shape[1], len(wrt.names)))
        jac[:, :, own] = result.sensitivities[:, :, :p]
        exact = np.ones(len(wrt.names), dtype=bool)
        exact[own] = result.departures[:p] == 0
        for m, start in enumerate(starts):
            for name, d in chain[start][1].items():
                j = wrt.names.index(name)
                jac[:, :, j] += result.sensitivities[:, :, p + m] * d
                exact[j] &= result.departures[p + m] == 0
        wrt.jacobian[span] = jac
        wrt.exact &= exact
    if result.reached == 0 and result.status >= 2:
        raise _Refused(f"at initialization: {inst.reason('initialization failed')}")
    if result.status >= 2:
        from fmpy.fmi1 import FMICallException

        raise FMICallException(function="stickslip_run_experiment", status=result.status)
    filled = last - first + 1
    slave.terminate()
    return filled - (0 if last == len(payload.time) - 1 else 1)


@functools.cache
def _reader(inst: _Instance, outputs: tuple):
    """read(slave, values, k): the outputs into row k of ``values`` (C-contiguous float64):
    Real outputs by one fmi2GetReal straight into the row, Integer and Boolean ones (such as
    stick[i]) by their getters."""
    from ctypes import POINTER, c_double, c_uint, cast

    kinds = [inst.by_name[name].type for name in outputs]
    if all(k == "Real" for k in kinds):
        n = len(outputs)
        vrs = (c_uint * n)(*[inst.vr(name) for name in outputs])

        def read_real(slave, values, k):
            row = cast(values.ctypes.data + k * values.strides[0], POINTER(c_double))
            slave.fmi2GetReal(slave.component, vrs, n, row)

        return read_real
    groups = {}
    for j, (name, kind) in enumerate(zip(outputs, kinds, strict=True)):
        groups.setdefault(kind, ([], []))
        groups[kind][0].append(j)
        groups[kind][1].append(inst.vr(name))
    getters = {"Real": "getReal", "Integer": "getInteger", "Boolean": "getBoolean", "Enumeration": "getInteger"}

    def read(slave, values, k):
        for kind, (index, vrs) in groups.items():
            values[k, index] = np.asarray(getattr(slave, getters[kind])(vrs), dtype=np.float64)

    return read


def _input_setter(slave, inst: _Instance, payload: Payload) -> tuple:
    """(set_drive(k), set_torques(k) or None): the inputs of sample k set from the payload's
    precomputed table through the FMI functions directly (one call, no per-step lists)."""
    from ctypes import POINTER, c_double, c_int, c_uint, cast

    from ..motion import input_names

    drive, torques = payload.inputs()
    joints = drive.shape[1] // 3
    vrs = (c_uint * (3 * joints))(*[inst.vr(name) for name in input_names(joints)])
    row = drive.strides[0]
    base = drive.ctypes.data
    component = slave.component

    def set_drive(k):
        slave.fmi2SetReal(component, vrs, 3 * joints, cast(base + k * row, POINTER(c_double)))

    set_torques = None
    if torques is not None:
        n = len(payload.torques.names)
        tvrs = (c_uint * n)(*[inst.vr(name) for name in payload.torques.names])
        orders = [(c_int * n)(*([o] * n)) for o in (1, 2)]

        def set_torques(k):
            value, rate, acc = (cast(a.ctypes.data + k * a.strides[0], POINTER(c_double)) for a in torques)
            slave.fmi2SetReal(component, tvrs, n, value)
            slave.fmi2SetRealInputDerivatives(component, tvrs, n, orders[0], rate)
            slave.fmi2SetRealInputDerivatives(component, tvrs, n, orders[1], acc)

    return set_drive, set_torques
