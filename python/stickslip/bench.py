"""``stickslip bench``: variants per second of ``stickslip sweep`` on 1, 2, ... local workers.

Every variant is the reference motion with the reference arm, its drive stiffness k[3]
drawn within +-1 % (so that every variant costs about the same and no two are equal). For
each worker count a fresh sweep into a temporary directory; the rate counts from the first
task submitted to the last row received (cluster start-up, shown apart, excluded).
Parallel efficiency = rate(N workers) / (N * rate(1 worker)). More columns tell scheduling
overhead from CPU contention on a shared machine: the median wall and CPU time of a
variant inside its worker (the wall time rises above the CPU time when other jobs hold the
cores), and the workers' busy fraction, the summed variant wall times over (N x the
sweep's wall time) (falls when Dask leaves workers idle). The load average is printed
before and after.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from .fmu import DEFAULT_FMU


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--variants", type=int, default=40, help="variants per worker count (default 40)")
    p.add_argument("--workers", default="1,2", help="comma-separated worker counts (default 1,2)")
    p.add_argument("--stop-time", type=float, default=2.0, help="s (default 2.0, the reference run)")
    p.add_argument("--communication-step", type=float, default=1e-3)
    p.add_argument("--fmu", default=str(DEFAULT_FMU))


def main(a: argparse.Namespace) -> int:
    from . import spec as spec_module
    from .sweep import run_sweep

    text = (
        f'stop_time = {a.stop_time!r}\ncommunication_step = {a.communication_step!r}\nmotion = "reference"\n'
        f'fmu = "{a.fmu}"\n[sample]\nn = {a.variants}\nseed = 1\n"k[3]" = {{ uniform = [0.99e6, 1.01e6] }}\n'
    )
    spec = spec_module.parse(text, "bench")
    rates, lines = {}, []
    print(
        f"bench: {a.variants} variants of the {a.stop_time:g} s reference motion per worker count, "
        f"{os.cpu_count()} cores, load average {_load()}",
        flush=True,
    )
    for n in (int(x) for x in a.workers.split(",")):
        with tempfile.TemporaryDirectory(prefix="stickslip-bench-") as out:
            wall = time.perf_counter()
            stats = run_sweep(spec, Path(out), workers=n, progress_tty=False)
            total = time.perf_counter() - wall
        rows = stats["rows"]
        ok = int((rows["status"] == "ok").sum())
        rates[n] = stats["ran"] / stats["seconds"]
        per, cpu = rows["wall_s"].median(), rows["cpu_s"].median()
        busy = rows["wall_s"].sum() / (stats["workers"] * stats["seconds"])
        lines.append((n, rates[n], per, cpu, busy))
        print(
            f"bench: {n} worker(s): {rates[n]:.3f} variants/s ({ok} ok, median {per:.3f} s wall, {cpu:.3f} s CPU "
            f"per variant in the worker, workers busy {100 * busy:.0f} %, {total - stats['seconds']:.1f} s cluster "
            f"start-up and shut-down), load average {_load()}",
            flush=True,
        )
    one = rates.get(1)
    print(
        "\n| workers | variants/s | per variant in the worker: wall, CPU (median) | workers busy "
        "| parallel efficiency |\n|---|---|---|---|---|"
    )
    for n, r, per, cpu, busy in lines:
        print(
            f"| {n} | {r:.3f} | {per:.3f} s, {cpu:.3f} s | {100 * busy:.0f} % | "
            + (f"{r / (n * one):.2f} |" if one else "– |")
        )
    return 0


def _load() -> str:
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())
