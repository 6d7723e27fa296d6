"""Soak of the FMU in one host process: resident memory stays flat.

1. `cycles` instantiate / initialize / step / free cycles through fmpy's FMU2Slave
   (each loads and unloads the shared library, as masters that create instances per
   run do);
2. one instance running `seconds` of simulated time at 1 ms communication steps under
   a smooth periodic motion of all four drives (the arm keeps moving, sticking and
   slipping), reading every output after each step.

The resident set size (VmRSS of /proc/self/status) is sampled along the way; a leak of
even one small allocation per step or per cycle would add megabytes. The long version
of docs/verification.md (10^4 cycles, 600 s simulated):

    python tests/python/soak.py --cycles 10000 --seconds 600
"""

import argparse
import json
import math
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
DEFAULT_FMU = ROOT / "target" / "fmu" / "StickSlipManipulator.fmu"


def rss_kib() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS in /proc/self/status")


def periodic_inputs(t: float):
    """A smooth motion of all drives with periods 4, 5, 3 and 6 s (q*, q*', q*'')."""
    spec = [(0.3, 4.0, 0.0), (0.1, 5.0, 0.0), (0.05, 3.0, 0.9), (0.5, 6.0, 0.0)]
    q, qd, qdd = [], [], []
    for amplitude, period, offset in spec:
        w = 2.0 * math.pi / period
        q.append(offset + amplitude * math.sin(w * t))
        qd.append(amplitude * w * math.cos(w * t))
        qdd.append(-amplitude * w * w * math.sin(w * t))
    return q, qd, qdd


def soak(fmu: str, cycles: int, seconds: float, interval: float = 1e-3) -> dict:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(fmu)
    unzipdir = extract(fmu)
    by_name = {v.name: v for v in md.modelVariables}
    in_vrs = [by_name[f"{g}[{i}]"].valueReference for g in ("q_star", "qd_star", "qdd_star") for i in range(1, 5)]
    out_vrs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"]

    def start(name):
        s = FMU2Slave(
            guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name
        )
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        q, qd, qdd = periodic_inputs(0.0)
        s.setReal(in_vrs, [*q, *qd, *qdd])
        s.exitInitializationMode()
        return s

    samples = {"cycles": [], "run": []}
    wall = time.perf_counter()
    for c in range(cycles):
        s = start(f"cycle{c}")
        s.doStep(currentCommunicationPoint=0.0, communicationStepSize=interval)
        s.getReal(out_vrs)
        s.terminate()
        s.freeInstance()
        if c % max(1, cycles // 10) == 0 or c == cycles - 1:
            samples["cycles"].append((c + 1, rss_kib()))
    cycles_wall = time.perf_counter() - wall

    s = start("run")
    steps = round(seconds / interval)
    finite = True
    wall = time.perf_counter()
    for k in range(steps):
        t = k * interval
        q, qd, qdd = periodic_inputs(t)
        s.setReal(in_vrs, [*q, *qd, *qdd])
        s.doStep(currentCommunicationPoint=t, communicationStepSize=interval)
        values = s.getReal(out_vrs)
        if k % max(1, steps // 20) == 0 or k == steps - 1:
            finite = finite and all(math.isfinite(x) for x in values)
            samples["run"].append((round((k + 1) * interval, 6), rss_kib()))
    run_wall = time.perf_counter() - wall
    n_stick = [s.getReal([by_name[f"n_stick[{j}]"].valueReference])[0] for j in (1, 3)]
    substeps = s.getReal([by_name["n_substeps"].valueReference])[0]
    s.terminate()
    s.freeInstance()
    return {
        "samples": samples,
        "cycles_wall_s": cycles_wall,
        "run_wall_s": run_wall,
        "finite": finite,
        "n_stick": n_stick,
        "n_substeps": substeps,
    }


def growth_kib(samples) -> int:
    """RSS growth over the second half of the samples: the first half warms up the
    allocator's arenas and Python's caches (RSS rises for a few hundred cycles, then
    stays put)."""
    return samples[-1][1] - samples[len(samples) // 2][1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu", default=str(DEFAULT_FMU))
    ap.add_argument("--cycles", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=60.0)
    a = ap.parse_args(argv)
    r = soak(a.fmu, a.cycles, a.seconds)
    print(json.dumps(r))
    c, run = r["samples"]["cycles"], r["samples"]["run"]
    print(
        f"{a.cycles} cycles in {r['cycles_wall_s']:.1f} s: RSS {c[0][1]} -> {c[len(c) // 2][1]} -> {c[-1][1]} KiB "
        f"(second half {growth_kib(c):+d} KiB); {a.seconds} s simulated in {r['run_wall_s']:.1f} s: RSS "
        f"{run[0][1]} -> {run[len(run) // 2][1]} -> {run[-1][1]} KiB (second half {growth_kib(run):+d} KiB); "
        f"stiction phases {r['n_stick']}, {r['n_substeps']:.0f} sub-steps, outputs finite: {r['finite']}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
