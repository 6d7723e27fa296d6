"""Run the stick-slip manipulator FMU with fmpy, the way a user does.

* the reference motion of shared/reference-manipulator.md: cycloidal
  point-to-point profiles over T = 1.5 s, evaluated with the same
  floating-point operations as ``src/motion.rs`` (bit-identical inputs);
* :func:`run`: instantiate the FMU with fmpy's FMU2Slave, set parameters,
  step it over the reference motion (inputs q*, q*', q*'' set at every
  communication point) and collect every output by name;
* :func:`write_csv`: the outputs as CSV, one column per FMU variable.

Command line (the main job uses it)::

    python python/fmu_runner.py [--fmu FILE] [--out results/reference.csv]
        [--end 2.0] [--interval 1e-3] [--set NAME=VALUE ...]
"""

from __future__ import annotations

import argparse
import csv
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FMU = ROOT / "target" / "fmu" / "StickSlipManipulator.fmu"

MOTION_TIME = 1.5  # T of the cycloidal profiles, s
RUN_TIME = 2.0  # the reference run, s
REFERENCE_PROFILES = (  # (start, end) of q1*, q2, q3*, q4
    (0.0, math.pi / 3.0),
    (0.0, math.pi / 12.0),
    (0.8, 1.0),
    (0.0, math.pi / 2.0),
)


def cycloidal(start: float, end: float, t: float, duration: float = MOTION_TIME):
    """(q, q', q'') of the cycloidal profile s(tau) = tau - sin(2 pi tau)/(2 pi) at time t.

    The same operations, in the same order, as ``Cycloidal::eval`` in
    src/motion.rs, so the values are bit-identical to the engine's.
    """
    tau2 = math.tau
    d = end - start
    if t <= 0.0:
        return start, 0.0, 0.0
    if t >= duration:
        return end, 0.0, 0.0
    tau = t / duration
    s = tau - math.sin(tau2 * tau) / tau2
    sd = (1.0 - math.cos(tau2 * tau)) / duration
    sdd = tau2 * math.sin(tau2 * tau) / (duration * duration)
    return start + d * s, d * sd, d * sdd


def reference_inputs(t: float):
    """(q*, q*', q*'') lists of the 4 joints of the reference motion at time t."""
    q, qd, qdd = [], [], []
    for start, end in REFERENCE_PROFILES:
        a, b, c = cycloidal(start, end, t)
        q.append(a)
        qd.append(b)
        qdd.append(c)
    return q, qd, qdd


def run(fmu=DEFAULT_FMU, end: float = RUN_TIME, interval: float = 1e-3, parameters: dict | None = None,
        inputs=reference_inputs, progress: str | None = None) -> dict:
    """Simulates ``end`` seconds in communication steps of ``interval``.

    ``parameters`` maps FMU variable names (``mu_k[3]``, ``h_max``, ...) to
    values set before initialization; ``inputs(t)`` returns (q*, q*', q*'')
    per joint at t. Returns a dict: ``time`` and every output by name, as
    lists (Booleans as 0/1).
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    fmu = str(fmu)
    md = read_model_description(fmu)
    by_name = {v.name: v for v in md.modelVariables}
    n = sum(1 for v in md.modelVariables if v.name.startswith("q_star["))
    in_vrs = [by_name[f"{g}[{i}]"].valueReference for g in ("q_star", "qd_star", "qdd_star") for i in range(1, n + 1)]
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    real_out = [v for v in outputs if v.type == "Real"]
    bool_out = [v for v in outputs if v.type == "Boolean"]
    unzipdir = extract(fmu, tempfile.mkdtemp(prefix="stickslip_"))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName="run")
    real_vrs = [v.valueReference for v in real_out]
    bool_vrs = [v.valueReference for v in bool_out]
    rows = []

    def record(t):
        # One tuple per communication point; split into columns at the end.
        rows.append((t, *slave.getReal(real_vrs), *(1 if x else 0 for x in slave.getBoolean(bool_vrs))))

    def set_inputs(t):
        q, qd, qdd = inputs(t)
        slave.setReal(in_vrs, [float(x) for x in (*q, *qd, *qdd)])

    try:
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        for name, value in (parameters or {}).items():
            v = by_name[name]
            if v.type == "Boolean":
                slave.setBoolean([v.valueReference], [bool(value)])
            else:
                slave.setReal([v.valueReference], [float(value)])
        slave.enterInitializationMode()
        set_inputs(0.0)
        slave.exitInitializationMode()
        record(0.0)
        steps = round(end / interval)
        wall = time.perf_counter()
        for k in range(steps):
            t = k * interval
            set_inputs(t)
            slave.doStep(currentCommunicationPoint=t, communicationStepSize=interval)
            record((k + 1) * interval)
            if progress and (k + 1) % max(1, steps // 10) == 0:
                print(f"\r{progress}: t = {(k + 1) * interval:.3f} s of {end} s "
                      f"({time.perf_counter() - wall:.1f} s wall)", end="", file=sys.stderr, flush=True)
        if progress:
            print(file=sys.stderr)
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(unzipdir, ignore_errors=True)
    names = ["time"] + [v.name for v in real_out + bool_out]
    return {name: list(column) for name, column in zip(names, zip(*rows))} if rows else {name: [] for name in names}


def write_csv(result: dict, path) -> None:
    """Writes a :func:`run` result, one column per variable (RFC 4180 quoting)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = list(result)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for row in zip(*(result[k] for k in names)):
            w.writerow([repr(float(x)) for x in row])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Simulate the reference motion through the FMU (fmpy).")
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    p.add_argument("--out", default=str(ROOT / "results" / "reference.csv"))
    p.add_argument("--end", type=float, default=RUN_TIME)
    p.add_argument("--interval", type=float, default=1e-3)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="parameter value, repeatable")
    a = p.parse_args(argv)
    parameters = {}
    for item in a.set:
        name, _, value = item.partition("=")
        parameters[name] = value.lower() == "true" if value.lower() in ("true", "false") else float(value)
    wall = time.perf_counter()
    result = run(a.fmu, a.end, a.interval, parameters, progress="reference motion")
    simulated = time.perf_counter()
    write_csv(result, a.out)
    print(f"simulated {a.end} s through {a.fmu} in {simulated - wall:.2f} s wall "
          f"(unpacking and instantiation included); wrote {a.out} in {time.perf_counter() - simulated:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
