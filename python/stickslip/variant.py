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
"""

from __future__ import annotations

import functools
import os
import re
import socket
import time

from .fmu import LogCapture, communication_points, initialize, input_references, unpacked

STATUS_NAMES = {1: "warning", 2: "discard", 3: "error", 4: "fatal"}


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
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

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
    slave = FMU2Slave(
        guid=p.md.guid,
        unzipDirectory=p.unzipdir,
        modelIdentifier=p.md.coSimulation.modelIdentifier,
        instanceName=f"run{run}",
    )
    sampled = None
    try:
        slave.instantiate(callbacks=log.callbacks)
        try:
            initialize(slave, p.md, parameters, p.inputs, motion, step)
        except FMICallException as e:
            row["status"] = "refused"
            row["message"] = _reason(log, str(e))
            raise _Refused from None
        try:
            sampled = [list(slave.getReal(p.sampled))]
            steps = round(stop_time / step)
            for k, t in communication_points(slave, p.inputs, motion, stop_time, step):
                sampled.append(list(slave.getReal(p.sampled)))
                row["t_end"] = t
                if timeout is not None and k < steps and time.perf_counter() - wall > timeout:
                    row["status"] = "timeout"
                    row["message"] = f"stopped at t = {t:g} s after {timeout:g} s wall (--timeout)"
                    break
        except FMICallException as e:
            row["status"] = "discard" if e.status == 2 else "error"
            row["message"] = _reason(log, f"{e} at t = {row['t_end']:g} s")
        if sampled:
            _metrics(row, p, sampled, slave.getReal(p.final))
        if row["status"] in ("ok", "timeout"):
            slave.terminate()
    except _Refused:
        pass
    except Exception as e:  # noqa: BLE001 -- a row, never a crash
        row["status"] = "error"
        row["message"] = _reason(log, f"{type(e).__name__}: {e}")
    finally:
        try:
            slave.freeInstance()
        except Exception:  # noqa: BLE001 -- instantiation failed: nothing to free
            pass
        log.close()
    if row["status"] == "ok" and log.records:
        row["message"] = _reason(log, "")
    row["wall_s"] = time.perf_counter() - wall
    row["cpu_s"] = time.process_time() - cpu
    return row


class _Refused(Exception):
    """The FMU refused the parameters (setting them or initializing with them)."""


def _metrics(row: dict, p: _Prepared, sampled: list, final: list) -> None:
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
