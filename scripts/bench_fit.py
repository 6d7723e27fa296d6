"""The fit's speed benchmark (docs/calibration.md, "Speed"): a 4-parameter fit of a 2 s
experiment of the reference arm on a local Dask cluster, its wall time and FMU runs.

The measured run is made by the FMU (stickslip.fit.synthetic, the reference motion, link
encoders with 2e-6 rad and 1e-6 m of noise, seed 1) at mu_k[1] = 0.17, mu_s[1] = 0.22,
mu_k[3] = 0.2, k[3] = 8e5; the fit starts 30-40 % away (0.12, 0.3, 0.14, 5e5) with
`starts` starts (default 1: the initial point; the equation-error estimate adds one).

    python scripts/bench_fit.py [--workers 2] [--starts 1] [--repeat 3] [--fmu FMU] [--jacobian differences]

``--suite``: the identification benchmark (stickslip.fit.benchmark): per arm and draw a seeded
fit problem (2-4 of mu_k, mu_s, k, b_v of one or two joints, true values drawn, a motion with
reversals, dwells and slips, data measured at fixed 2e-6 s sub-steps with noise and encoder
counts, starts 20-50 % off), fitted, and each estimate compared with the truth; DIR/suite.json
(every fit and parameter) and DIR/suite.md (coverage within 3 and 2 SE, median |z|, cost at the
answer over cost at the truth, fits that warned; per parameter kind, per arm, in total).

    python scripts/bench_fit.py --suite [--arms reference,kuka_iiwa,xarm6,motor] [--draws N] [--seed S]
        [--workers 2] [--out DIR] [--duration 2.0] [--parameters P] [--starts K]

Arms by name (reference, motor, kuka_iiwa, xarm6: target/fmu/<name>.fmu, built by
scripts/build_fmu.sh) or as FMU paths.
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
    p.add_argument("--starts", type=int, default=None, help="the fit's starts (default 1; --suite: drawn, 2-4)")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument(
        "--jacobian",
        choices=("sensitivities", "differences"),
        default="differences",
        help="[options] jacobian: differences of free runs (the default) or the FMU's sensitivities",
    )
    suite = p.add_argument_group("the identification benchmark (--suite)")
    suite.add_argument("--suite", action="store_true", help="run the identification benchmark instead")
    suite.add_argument("--arms", default="reference,kuka_iiwa,xarm6", help="comma-separated arm names or FMU paths")
    suite.add_argument("--draws", type=int, default=2, help="problems per arm (seeds S, S+1, ...)")
    suite.add_argument("--seed", type=int, default=1)
    suite.add_argument("--out", default="results/bench_fit", help="the suite's directory")
    suite.add_argument("--duration", type=float, default=2.0, help="s of measured data per problem")
    suite.add_argument("--parameters", type=int, default=None, help="parameters per problem (default: drawn, 2-4)")
    a = p.parse_args()
    if a.suite:
        run_suite(a)
        return
    a.starts = a.starts or 1
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
        "options": {"starts": a.starts, "seed": 1, "jacobian": a.jacobian},
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


def run_suite(a) -> None:
    from stickslip.fit.benchmark import run_suite

    t0 = time.perf_counter()
    arms = [x.strip() for x in a.arms.split(",") if x.strip()]
    doc = run_suite(
        arms,
        a.draws,
        a.seed,
        a.out,
        workers=a.workers,
        duration=a.duration,
        n_parameters=a.parameters,
        starts=a.starts,
        progress=lambda line: print(line, flush=True),
    )
    total = doc["summary"]["total"]
    share = "-" if total["within_3se"] is None else f"{100 * total['within_3se']:.0f} %"
    print(
        f"bench_fit --suite: {total['n']} estimates in {total['fits']} fits, truth within 3 SE: {share}; "
        f"{time.perf_counter() - t0:.0f} s; {Path(a.out) / 'suite.md'}"
    )


if __name__ == "__main__":
    main()
