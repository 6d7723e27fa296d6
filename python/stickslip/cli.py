"""The ``stickslip`` command: ``simulate``, ``study``, ``sweep``, ``bench``, ``fit``."""

from __future__ import annotations

import argparse
import sys

from .cluster import cluster_arguments
from .convergence import DEFAULT_THRESHOLD


def _sweep_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("spec", help="the SPEC (TOML): stop_time, communication_step, motion, fmu, [grid], [sample]")
    p.add_argument("--out", required=True, help="result directory (results.parquet, parts/, summary.png, summary.md)")
    cluster_arguments(p)
    p.add_argument(
        "--timeout", type=float, metavar="SECONDS", help="stop a variant after this much wall time (status timeout)"
    )
    p.add_argument("--retries", type=int, default=2, help="runs of a task again after its worker died (default 2)")
    p.add_argument("--samples", type=int, metavar="N", help="override [sample] n (the first N draws of the SPEC)")
    p.add_argument("--stop-time", type=float, metavar="SECONDS", help="override stop_time")
    p.add_argument(
        "--motion",
        metavar="MOTION.toml",
        help="override the SPEC's motion with this motion file (docs/motion.md), checked against the FMU's joints",
    )
    c = p.add_argument_group("convergence check (docs/convergence.md)")
    c.add_argument(
        "--check-convergence",
        action="store_true",
        help="run each variant (or --convergence-fraction of them) again with a tenfold tighter "
        "error_tolerance (fixed sub-steps: halved) and record the relative spread of every "
        "metric in a column <metric>_spread (n_stick_spread[i] for a joint's)",
    )
    c.add_argument(
        "--convergence-fraction",
        type=float,
        metavar="F",
        help="check this fraction of the variants, chosen by the SPEC's seed (default 1.0)",
    )
    c.add_argument(
        "--convergence-threshold",
        type=float,
        default=DEFAULT_THRESHOLD,
        metavar="T",
        help=f"a metric whose spread exceeds T is marked not converged in the summary (default {DEFAULT_THRESHOLD:g})",
    )


def sweep_main(a: argparse.Namespace) -> int:
    """``stickslip sweep``: exit 0 when every variant has a row, 1 on a refused SPEC or a lost
    cluster, 130 when interrupted."""
    from . import spec as spec_module
    from . import summary
    from .sweep import Check, SweepError, run_sweep

    if a.workers is not None and a.workers < 1:
        print(f"stickslip sweep: --workers {a.workers}: must be at least 1", file=sys.stderr)
        return 1
    if a.convergence_fraction is not None and not a.check_convergence:
        print("stickslip sweep: --convergence-fraction needs --check-convergence", file=sys.stderr)
        return 1
    if not a.convergence_threshold > 0:
        print(
            f"stickslip sweep: --convergence-threshold {a.convergence_threshold:g}: must be positive", file=sys.stderr
        )
        return 1
    try:
        check = None
        if a.check_convergence:
            check = Check(1.0 if a.convergence_fraction is None else a.convergence_fraction)
        spec = spec_module.load(a.spec, {"stop_time": a.stop_time, "n": a.samples, "motion": a.motion})
        stats = run_sweep(spec, a.out, a.scheduler, a.workers, a.timeout, a.retries, check=check)
    except (spec_module.SpecError, SweepError) as e:
        print(f"stickslip sweep: {e}", file=sys.stderr)
        return 1
    rows = stats["rows"]
    columns = list(rows.columns)
    metrics = columns[columns.index("t_end") + 1 : columns.index("worker")]
    if len(rows):
        summary.write(
            rows, spec, metrics, a.out, stats["seconds"] or None, a.convergence_threshold, stats["convergence"]
        )
    counts = ", ".join(f"{n} {s}" for s, n in rows["status"].value_counts().items())
    rate = (
        f"; {stats['ran'] / stats['seconds']:.2f} variants/s on {stats['workers']} workers" if stats["seconds"] else ""
    )
    print(
        f"sweep: {len(rows)} of {len(spec)} variants in {a.out}/results.parquet ({counts or 'none'}){rate}", flush=True
    )
    if summary.checked(rows):
        _convergence_line(rows, stats["metrics"], a.convergence_threshold, a.out)
    return 130 if stats["interrupted"] else 0


def _convergence_line(rows, metrics, threshold: float, out) -> None:
    """How many checked variants are not converged, on the terminal."""
    from .convergence import CHECKED
    from .summary import not_converged_metrics

    done = rows[rows["convergence_status"] == CHECKED]
    bad = [int(r["run"]) for _, r in done.iterrows() if not_converged_metrics(r, metrics, threshold)]
    failed = int((~rows["convergence_status"].fillna("not run").isin([CHECKED, "not selected", "not run"])).sum())
    print(
        f"convergence: {len(done)} variants checked, {len(bad)} with a metric not converged "
        f"(spread > {threshold:g})"
        + (f", {failed} check runs failed" if failed else "")
        + (f"; see {out}/summary.md" if bad or failed else ""),
        file=sys.stderr if bad else sys.stdout,
        flush=True,
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="stickslip", description="The stick-slip manipulator FMU from Python.")
    sub = p.add_subparsers(dest="command", required=True)
    from . import bench, simulate, study

    s = sub.add_parser("simulate", help="the reference motion (or a motion file) through the FMU, as CSV")
    simulate.add_arguments(s)
    s.set_defaults(main=simulate.main)
    s = sub.add_parser("study", help="the source study's five cases through the FMU")
    study.add_arguments(s)
    s.set_defaults(main=study.main)
    s = sub.add_parser("sweep", help="a parameter grid / Monte Carlo sample on a Dask cluster")
    _sweep_arguments(s)
    s.set_defaults(main=sweep_main)
    s = sub.add_parser("bench", help="variants per second of `sweep` on 1 and 2 workers")
    bench.add_arguments(s)
    s.set_defaults(main=bench.main)
    from .fit import cli as fit_cli

    s = sub.add_parser("fit", help="the FMU's parameters from measured runs, with standard errors")
    fit_cli.add_arguments(s)
    s.set_defaults(main=fit_cli.main)
    from .identify import cli as identify_cli

    s = sub.add_parser("identify", help="a real arm's links, friction and drives from its torque logs")
    identify_cli.add_arguments(s)
    s.set_defaults(main=identify_cli.main)
    from .identify import excitation

    s = sub.add_parser("excite", help="a periodic excitation trajectory for identification, as a motion file")
    excitation.add_arguments(s)
    s.set_defaults(main=excitation.main)
    a = p.parse_args(argv)
    return a.main(a)


if __name__ == "__main__":
    sys.exit(main())
