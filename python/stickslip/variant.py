"""One variant of a sweep: a fresh FMU instance, its parameters, the motion, the metrics.

Runs wherever the task lands (a Dask worker process, or the caller): the FMU comes as its
content hash, unpacked in this process by :func:`stickslip.fmu.unpacked` (the sweep's worker
plugin does it when a worker starts). The metrics are taken at the communication points
t_k = k * step, k = 0..steps (inputs set at t_k, then ``doStep(t_k, step)``), exactly like a
hand-driven fmpy run of the same parameters:

* ``max_eps``: max of ``eps`` over the points reached; ``final_eps``: ``eps`` at the last one;
* per joint i: ``n_stick[i]``, ``t_stick[i]`` at the last point, ``max_N_normal[i]``: max of
  ``N_normal[i]`` over the points;
* ``Q_friction``, ``W_drive`` at the last point.

A variant never raises: what the FMU refuses or discards, and any other failure, becomes
the row's ``status`` with the FMU's logged messages in ``message``:

* ``ok``: the run reached stop_time;
* ``refused``: the FMU refused the parameters, when they were set or at initialization
  (e.g. mu_k > mu_s, a value out of range);
* ``discard``: a step returned fmi2Discard (the engine could not complete it);
* ``error``: a step returned fmi2Error, or anything else went wrong in the variant;
* ``timeout``: stopped after ``timeout`` seconds of wall time;

and ``t_end`` is the last communication point reached (the metrics
cover [0, t_end]).

The points are run inside the FMU's library when it has ``stickslip_run_experiment``
(:mod:`stickslip.experiment`): the same FMI calls as the per-point loop, with the inputs of
every point computed beforehand (once per motion in a process), the outputs the same bit
for bit; with a ``timeout``, in parts of about :data:`CHUNK_WALL` s of wall time, checked
between them. Older FMUs, fixed sub-steps (see :func:`_native_exact`), a timeout with a
library that cannot go on from step mode (:func:`_goes_on`) and ``STICKSLIP_PER_POINT=1``
take the per-point loop through fmpy.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
import re
import socket
import threading
import time

import numpy as np

from . import experiment
from .fmu import LogCapture, _input_values, communication_points, initialize, input_references, set_value, unpacked

STATUS_NAMES = {1: "warning", 2: "discard", 3: "error", 4: "fatal"}
# With a timeout, the native calls' parts: each aims at CHUNK_WALL s of wall time at the last
# part's speed (a call costs about 60 us more: 0.3 %), and has at most GROWTH times the last
# one's points, the first FIRST_CHUNK: a variant that slows down (an arm at rest at first,
# sticking later) overshoots its timeout by about one part, not by a speed misjudged manyfold.
CHUNK_WALL = 0.02
FIRST_CHUNK = 8
GROWTH = 4


@functools.cache
def _joints(names: tuple) -> tuple:
    """The joint numbers i of the FMU's ``n_stick[i]`` outputs."""
    return tuple(int(m.group(1)) for n in names if (m := re.fullmatch(r"n_stick\[(\d+)\]", n)))


def metric_names(output_names) -> list:
    """The metric columns for an FMU with these outputs (from its modelDescription)."""
    joints = _joints(tuple(output_names))
    return (
        ["max_eps", "final_eps"]
        + [f"n_stick[{i}]" for i in joints]
        + [f"t_stick[{i}]" for i in joints]
        + [f"max_N_normal[{i}]" for i in joints]
        + ["Q_friction", "W_drive"]
    )


class _Prepared:
    """Value references of one FMU, looked up once per process."""

    def __init__(self, unzipdir: str):
        from fmpy import read_model_description

        self.unzipdir = unzipdir
        self.md = read_model_description(unzipdir)
        self.by_name = {v.name: v for v in self.md.modelVariables}
        outputs = [v.name for v in self.md.modelVariables if v.causality == "output"]
        self.joints = _joints(tuple(outputs))
        self.inputs = input_references(self.md)
        self.sampled = [self.vr("eps")] + [self.vr(f"N_normal[{i}]") for i in self.joints]
        self.final_names = (
            [f"n_stick[{i}]" for i in self.joints] + [f"t_stick[{i}]" for i in self.joints] + ["Q_friction", "W_drive"]
        )
        self.final = [self.vr(n) for n in self.final_names]
        self.metrics = metric_names(outputs)
        self.goes_on = None  # whether stickslip_run_experiment goes on from step mode (_goes_on)

    def vr(self, name: str) -> int:
        return self.by_name[name].valueReference


@functools.cache
def _prepared(unzipdir: str) -> _Prepared:
    return _Prepared(unzipdir)


def run_variant(
    fmu_digest: str,
    run: int,
    parameters: dict,
    stop_time: float,
    step: float,
    motion,
    timeout: float | None = None,
    fmu_data: bytes | None = None,
) -> dict:
    """The row of one variant: ``run``, the parameters, ``status``, ``message``, ``wall_s``,
    ``cpu_s`` (the worker process's CPU time during the variant), ``t_end``, ``worker`` and
    the metrics. ``motion(t, step)`` gives the inputs; ``fmu_data``
    (the FMU's bytes) is needed only where the FMU has not been unpacked in this process."""
    wall, cpu = time.perf_counter(), time.process_time()
    row = {
        "run": run,
        **parameters,
        "status": "ok",
        "message": "",
        "t_end": 0.0,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }
    try:
        p = _prepared(unpacked(fmu_data, fmu_digest) if fmu_data is not None else _unpacked_here(fmu_digest))
    except Exception as e:  # noqa: BLE001 -- a row, never a crash
        return row | {
            "status": "error",
            "message": f"FMU not available here: {type(e).__name__}: {e}",
            "wall_s": time.perf_counter() - wall,
            "cpu_s": time.process_time() - cpu,
        }
    row.update(dict.fromkeys(p.metrics, float("nan")))
    log = LogCapture()
    slave = _slave(p, f"run{run}")
    sampled = None
    try:
        slave.instantiate(callbacks=log.callbacks)
        if (
            native_runs()
            and experiment.function(slave) is not None
            and _native_exact(p, parameters)
            and (timeout is None or _goes_on(p))
        ):
            sampled = _native_points(slave, p, parameters, motion, stop_time, step, timeout, wall, row, log)
        else:
            sampled = _per_point(slave, p, parameters, motion, stop_time, step, timeout, wall, row, log)
        if sampled is not None and len(sampled):
            _metrics(row, p, sampled, slave.getReal(p.final))
        if row["status"] in ("ok", "timeout"):
            slave.terminate()
    except _Refused:
        pass
    except Exception as e:  # noqa: BLE001 -- a row, never a crash
        row["status"] = "error"
        row["message"] = _reason(log, f"{type(e).__name__}: {e}")
    finally:
        _free(p, slave)
        log.close()
    if row["status"] == "ok" and log.records:
        row["message"] = _reason(log, "")
    row["wall_s"] = time.perf_counter() - wall
    row["cpu_s"] = time.process_time() - cpu
    return row


def native_runs() -> bool:
    """Whether the points go through the FMU's ``stickslip_run_experiment``: yes, unless
    ``STICKSLIP_PER_POINT=1`` (the switch of :func:`stickslip.fit.runner.native_runs`)."""
    return os.environ.get("STICKSLIP_PER_POINT", "") != "1"


def _native_exact(p: _Prepared, parameters: dict) -> bool:
    """Whether the native run gives the per-point loop's numbers bit for bit: not with fixed
    sub-steps (h_min >= h_max). The per-point loop steps by ``doStep(k * step, step)``, the
    library by the differences of its time points, and no float times t_k make every
    t_{k+1} - t_k equal to ``step``: the points given are the FMU's own times (each the last
    plus ``step``, rounded), so every step ends where the per-point one does, but its length
    differs from ``step`` by a rounding, and fixed sub-steps are that length divided evenly.
    With error control the length sets only the step's work budget (4 max_iterations per
    h_min of it, rounded up), which can come out one h_min's worth smaller: a step that needs
    all of the larger budget is discarded here and not per point (examples/monte_carlo.toml's
    1000 variants gave the same rows both ways)."""

    def value(name: str) -> float:
        v = parameters.get(name, p.by_name[name].start if name in p.by_name else None)
        return float(v) if v is not None else float("nan")

    return not value("h_min") >= value("h_max")


def _goes_on(p: _Prepared) -> bool:
    """Whether the FMU's ``stickslip_run_experiment`` goes on from step mode (an experiment
    in parts, which checking a timeout between them needs; a library that allows it in the
    instantiated state only refuses the second part): tried once per process on an instance
    of its own at the FMU's defaults, initialized by one call and gone on from by a second."""
    if p.goes_on is None:
        log = LogCapture()
        slave = _slave(p, "probe")
        try:
            slave.instantiate(callbacks=log.callbacks)
            slave.setupExperiment(startTime=0.0)
            p.goes_on = experiment.run(slave, [0.0]).status < 2 and experiment.run(slave, [0.0]).status < 2
        except Exception:  # noqa: BLE001 -- then not: the per-point loop
            p.goes_on = False
        finally:
            _free(p, slave)
            log.close()
    return p.goes_on


_SLAVES = {}  # unzipdir -> this process's FMU2Slaves whose instance was freed, their library loaded


def _slave(p: _Prepared, name: str):
    """An fmpy FMU2Slave for a new instance called ``name``: one of this process's whose
    instance was freed, or a new one (which loads the library and looks its functions up,
    about 2 ms: 2 % of a 2 s variant's time)."""
    from fmpy.fmi2 import FMU2Slave

    try:
        slave = _SLAVES.setdefault(p.unzipdir, []).pop()
    except IndexError:
        slave = FMU2Slave(
            guid=p.md.guid,
            unzipDirectory=p.unzipdir,
            modelIdentifier=p.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
    slave.instanceName = name
    slave.component = None
    return slave


def _free(p: _Prepared, slave) -> None:
    """Frees the slave's instance, if instantiation made one, and keeps the slave (its library
    loaded) for the next variant; one whose freeing failed is dropped."""
    try:
        if slave.component is not None:
            slave.fmi2FreeInstance(slave.component)
            slave.component = None
    except Exception:  # noqa: BLE001 -- not used again
        return
    _SLAVES[p.unzipdir].append(slave)


def _per_point(slave, p: _Prepared, parameters, motion, stop_time, step, timeout, wall, row, log) -> list | None:
    """The points through fmpy, one set of calls each: the rows of the sampled outputs."""
    from fmpy.fmi1 import FMICallException

    try:
        initialize(slave, p.md, parameters, p.inputs, motion, step)
    except FMICallException as e:
        row["status"] = "refused"
        row["message"] = _reason(log, str(e))
        raise _Refused from None
    sampled = None
    try:
        sampled = [list(slave.getReal(p.sampled))]
        steps = round(stop_time / step)
        for k, t in communication_points(slave, p.inputs, motion, stop_time, step):
            sampled.append(list(slave.getReal(p.sampled)))
            row["t_end"] = t
            if timeout is not None and k < steps and time.perf_counter() - wall > timeout:
                _timed_out(row, t, timeout)
                break
    except FMICallException as e:
        row["status"] = "discard" if e.status == 2 else "error"
        row["message"] = _reason(log, f"{e} at t = {row['t_end']:g} s")
    return sampled


def _native_points(slave, p: _Prepared, parameters, motion, stop_time, step, timeout, wall, row, log) -> np.ndarray:
    """The points by ``stickslip_run_experiment``: one call, or with a ``timeout`` calls of
    about :data:`CHUNK_WALL` s each (the next sized by the last one's speed, at most
    :data:`GROWTH` times its points), the timeout checked between them. The rows of the
    sampled outputs (points x outputs), as the per-point loop's."""
    from fmpy.fmi1 import FMICallException

    try:
        _set_up(slave, p, parameters)
    except FMICallException as e:
        row["status"] = "refused"
        row["message"] = _reason(log, str(e))
        raise _Refused from None
    steps = round(stop_time / step)
    times, drive, torque_vrs, torques = _inputs(motion, steps, step)
    out = np.full((steps + 1, len(p.sampled)), np.nan)
    first, chunk, done = 0, steps if timeout is None else min(FIRST_CHUNK, steps), 0
    while True:
        last = first + max(1, min(chunk, steps - first)) if steps else 0
        span = slice(first, last + 1)
        began = time.perf_counter()
        result = experiment.run(
            slave,
            times[span],
            drive_vrs=p.inputs,
            drive=drive[span],
            torque_vrs=torque_vrs,
            torques=None if torques is None else tuple(a[span] for a in torques),
            output_vrs=p.sampled,
            out=out[span],
        )
        # points 0..done-1 have their outputs (a later call first reads again the point it goes on from)
        done = max(done, first + result.reached)
        if result.status >= 2:
            failed = FMICallException(function=experiment.NAME, status=result.status)
            if done == 0:
                row["status"] = "refused"
                row["message"] = _reason(log, str(failed))
                raise _Refused
            row["t_end"] = (done - 1) * step
            row["status"] = "discard" if result.status == 2 else "error"
            row["message"] = _reason(log, f"{failed} at t = {row['t_end']:g} s")
            break
        row["t_end"] = last * step
        if last >= steps:
            break
        now = time.perf_counter()
        if now - wall > timeout:
            _timed_out(row, row["t_end"], timeout)
            break
        rate = (last - first) / max(now - began, 1e-6)  # points per second
        chunk = min(int(rate * min(CHUNK_WALL, timeout - (now - wall))) + 1, GROWTH * (last - first))
        first = last
    return out[:done]


def _timed_out(row: dict, t: float, timeout: float) -> None:
    row["status"] = "timeout"
    row["message"] = f"stopped at t = {t:g} s after {timeout:g} s wall (--timeout)"


def _set_up(slave, p: _Prepared, parameters: dict) -> None:
    """What :func:`stickslip.fmu.initialize` does before initialization: setupExperiment at
    t = 0 and the parameters set by name (an unknown name raises ValueError, a refused value
    fmpy's FMICallException)."""
    slave.setupExperiment(startTime=0.0)
    for name, value in parameters.items():
        if name not in p.by_name:
            raise ValueError(f"{name!r} is not a variable of the FMU")
        set_value(slave, p.by_name[name], value)


_INPUTS = {}  # (the motion's pickle's sha256, steps, step) -> _inputs' tables, the last few
_INPUTS_LOCK = threading.Lock()  # a worker may run variants in several threads


def _inputs(motion, steps: int, step: float):
    """The experiment's tables for the points k = 0..steps: the times (each the last plus
    ``step``: the FMU's own times, see :func:`_native_exact`), the drive inputs (points x
    inputs) and the motor torques' ``(torque vrs, (value, rate, acceleration))`` or ``([],
    None)``, the values at point k those :func:`stickslip.fmu.communication_points` sets at
    t_k = k * step: ``motion(t_k, step)``, its ``torques(t_k)``. The last point's inputs are
    never set (no step starts there): its row repeats the one before. Kept per process for
    the last few motions (a sweep's variants share theirs), by the motion's pickle."""
    try:
        key = (hashlib.sha256(pickle.dumps(motion)).hexdigest(), steps, step)
    except Exception:  # noqa: BLE001 -- a motion that does not pickle is computed every time
        key = None
    with _INPUTS_LOCK:
        if key is not None and key in _INPUTS:
            return _INPUTS[key]
    times = np.empty(steps + 1)
    t = 0.0
    for k in range(steps + 1):
        times[k] = t
        t += step
    ks = range(max(steps, 1))  # the points a step starts from (the first alone when there is no step)
    rows = [_input_values(motion(k * step, step)) for k in ks]
    drive = np.array(rows + rows[-1:] if steps else rows, dtype=np.float64)
    torque_vrs, torques = [], None
    spline = getattr(motion, "torques", None)
    if spline is not None:
        if spline.references is None:
            raise ValueError(
                f"{spline.source}: motor torques not bound to an FMU: load the motion with load_motion_for"
            )
        torque_vrs = list(spline.references)
        values = [spline(k * step) for k in ks]
        values += values[-1:] if steps else []
        torques = tuple(
            np.array([[float(x) for x in v[order]] for v in values], dtype=np.float64) for order in range(3)
        )
    tables = (times, drive, torque_vrs, torques)
    for a in (times, drive, *(torques or ())):
        a.flags.writeable = False
    if key is not None:
        with _INPUTS_LOCK:
            while len(_INPUTS) >= 4:
                _INPUTS.pop(next(iter(_INPUTS)))
            _INPUTS[key] = tables
    return tables


class _Refused(Exception):
    """The FMU refused the parameters (setting them or initializing with them)."""


def _metrics(row: dict, p: _Prepared, sampled, final: list) -> None:
    """The metrics of the sampled rows (a list of rows, or an array: the native run's, whose
    maxima numpy takes, the same numbers where no value is NaN) and the final values."""
    if isinstance(sampled, np.ndarray):
        if not np.isnan(sampled).any():
            row["max_eps"] = float(sampled[:, 0].max())
            row["final_eps"] = float(sampled[-1, 0])
            for j, i in enumerate(p.joints, 1):
                row[f"max_N_normal[{i}]"] = float(sampled[:, j].max())
            row.update(zip(p.final_names, final, strict=True))
            return
        sampled = sampled.tolist()
    eps = [s[0] for s in sampled]
    row["max_eps"] = max(eps)
    row["final_eps"] = eps[-1]
    for j, i in enumerate(p.joints, 1):
        row[f"max_N_normal[{i}]"] = max(s[j] for s in sampled)
    row.update(zip(p.final_names, final, strict=True))


def _reason(log: LogCapture, fallback: str) -> str:
    """The FMU's warnings and errors (its reason for a discard or an error), then ``fallback``."""
    said = [f"{STATUS_NAMES.get(s, s)}: {m}" for (_, s, _, m) in log.records if s >= 1]
    return "; ".join(said + ([fallback] if fallback else []))


def _unpacked_here(digest: str) -> str:
    """The FMU unpacked by the sweep's worker plugin in this process; if the plugin has not
    run here yet, its bytes are taken from the plugin and unpacked now."""
    from .fmu import _UNPACKED

    if digest in _UNPACKED:
        return _UNPACKED[digest]
    from distributed import get_worker

    plugin = get_worker().plugins.get(plugin_name(digest))
    if plugin is None:
        raise RuntimeError(f"the FMU {digest[:12]} was not sent to this worker")
    return unpacked(plugin.data, digest)


def plugin_name(digest: str) -> str:
    return f"stickslip-fmu-{digest[:16]}"
