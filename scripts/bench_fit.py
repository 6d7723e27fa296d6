"""The fit's speed benchmark (docs/calibration.md, "Speed"): a 4-parameter fit of a 2 s
experiment of the reference arm on a local Dask cluster, its wall time and FMU runs.

The measured run is made by the FMU (stickslip.fit.synthetic, the reference motion, link
encoders with 2e-6 rad and 1e-6 m of noise, seed 1) at mu_k[1] = 0.17, mu_s[1] = 0.22,
mu_k[3] = 0.2, k[3] = 8e5; the fit starts 30-40 % away (0.12, 0.3, 0.14, 5e5) with
`starts` starts (default 1: the initial point; the equation-error estimate adds one).

    python scripts/bench_fit.py [--workers 2] [--starts 1] [--repeat 3] [--fmu FMU]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from stickslip.fit import fit
from stickslip.fit.synthetic import measure, write_csv
from stickslip.fmu import DEFAULT_FMU

TRUTH = {"mu_k[1]": 0.17, "mu_s[1]": 0.22, "mu_k[3]": 0.2, "k[3]": 8e5}
INITIAL = {"mu_k[1]": 0.12, "mu_s[1]": 0.3, "mu_k[3]": 0.14, "k[3]": 5e5}
BOUNDS = {"mu_k[1]": [0.05, 0.4], "mu_s[1]": [0.05, 0.5], "mu_k[3]": [0.05, 0.2], "k[3]": [1e5, 5e6]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--starts", type=int, default=1)
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="stickslip-bench-fit-"))
    columns = measure(a.fmu, TRUTH, {"q[1]": ("link1", 2e-6, 0.0), "q[3]": ("link3", 1e-6, 0.0)}, seed=1)
    write_csv(columns, tmp / "run.csv")
    spec = {
        "fmu": str(Path(a.fmu).resolve()),
        "experiment": [
            {
                "data": str(tmp / "run.csv"),
                "time": "t",
                "inputs": {f"q_star[{i}]": f"motor{i}" for i in range(1, 5)},
                "parameters": {"mu_s[3]": 0.2},
                "measured": {"q[1]": {"column": "link1", "sigma": 2e-6}, "q[3]": {"column": "link3", "sigma": 1e-6}},
            }
        ],
        "estimate": {
            n: {"initial": INITIAL[n], "bounds": BOUNDS[n], **({"scale": "log"} if n.startswith("k[") else {})}
            for n in TRUTH
        },
        "options": {"starts": a.starts, "seed": 1},
    }
    walls = []
    for k in range(a.repeat):
        t0 = time.perf_counter()
        r = fit(spec, workers=a.workers)
        walls.append(time.perf_counter() - t0)
        err = max(
            abs(r["parameters"][n]["value"] / TRUTH[n] - 1) / (r["parameters"][n]["std_error"] / TRUTH[n])
            for n in TRUTH
        )
        print(
            f"run {k + 1}: {walls[-1]:.1f} s wall (cluster start included), {r['n_evaluations']} FMU runs, "
            f"cost {r['cost']:.1f}, largest |estimate - truth| {err:.2f} standard errors",
            flush=True,
        )
    print(f"bench_fit: {a.workers} workers, median {statistics.median(walls):.1f} s over {len(walls)} fits")


if __name__ == "__main__":
    main()
