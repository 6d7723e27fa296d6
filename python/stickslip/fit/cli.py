"""``stickslip fit SPEC.toml --out DIR [--workers N | --scheduler ADDRESS]``.

Exit status: 0 the fit ran (its warnings are in fit.json and printed), 2 a SPEC or data file
that cannot be used (one line naming the field; nothing written), 1 a fit that could not run
(no start reached a finite cost, an unreachable scheduler).
"""

from __future__ import annotations

import argparse
import sys


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("spec", help="the fit SPEC (TOML): fmu, [[experiment]], [estimate], [options] (docs/calibration.md)")
    p.add_argument("--out", required=True, help="result directory: fit.json, report.md, fitted.toml, plots")
    from ..cluster import cluster_arguments

    cluster_arguments(p, in_process=True)


def main(a: argparse.Namespace) -> int:
    from ..cluster import ClusterError
    from . import FitError, fit
    from .spec import FitSpecError, load

    if a.workers is not None and a.workers < 0:
        print(f"stickslip fit: --workers {a.workers}: must be at least 0", file=sys.stderr)
        return 2
    try:
        spec = load(a.spec)
    except FitSpecError as e:
        print(f"stickslip fit: {e}", file=sys.stderr)
        return 2
    names = ", ".join(spec.names)
    print(f"fit: {names} from {len(spec.experiments)} experiment(s) of {spec.fmu.name}", flush=True)
    try:
        result = fit(spec, out=a.out, workers=a.workers, scheduler=a.scheduler, progress=_say)
    except FitSpecError as e:
        print(f"stickslip fit: {e}", file=sys.stderr)
        return 2
    except (FitError, ClusterError) as e:
        print(f"stickslip fit: {e}", file=sys.stderr)
        return 1
    for name, p in result["parameters"].items():
        flag = " (at a bound)" if p["at_bound"] else ""
        print(f"  {name} = {p['value']:.8g} ± {p['std_error']:.3g}{flag}")
    print(
        f"fit: cost {result['cost']:.6g}, rms normalized residual {result['rms_normalized_residual']:.3g}, "
        f"{result['n_evaluations']} FMU runs, {result['wall_s']:.1f} s -> {a.out}/fit.json"
    )
    print(f"fit: {result['verdict']}")
    for w in result["warnings"]:
        print(f"warning: {w}")
    return 0


def _say(line: str) -> None:
    print(line, flush=True)
