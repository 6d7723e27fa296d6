"""``stickslip fit SPEC.toml --out DIR [--workers N | --scheduler ADDRESS]``.

Exit status, each failure one line on stderr, never a traceback:

* 0 the fit ran to its answer (trusted or not: the verdict and warnings are in fit.json and printed);
* 1 the fit could not finish (no start reached a finite cost, the uncertainty at the best start
  failed, an unreachable scheduler): DIR/fit.json and DIR/report.md say what finished and why the
  rest did not (no fitted.toml);
* 2 a SPEC or data file that cannot be used (one line naming the field; nothing written);
* 3 an internal error (a bug: the line names it, the traceback is in DIR/error.log).
"""

from __future__ import annotations

import argparse
import sys
import warnings


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
    # numpy's RuntimeWarnings (a log of a negative value, ...) are the fit's to turn into a
    # reason; the console gets the reasons, not numpy's lines.
    warnings.simplefilter("ignore", RuntimeWarning)
    try:
        result = fit(spec, out=a.out, workers=a.workers, scheduler=a.scheduler, progress=_say)
    except FitSpecError as e:
        print(f"stickslip fit: {e}", file=sys.stderr)
        return 2
    except (FitError, ClusterError) as e:
        print(f"stickslip fit: {e}", file=sys.stderr)
        return 1
    except Exception as e:  # noqa: BLE001 -- one line and the traceback in a file, never on the console
        log = _error_log(a.out)
        print(
            f"stickslip fit: internal error: {type(e).__name__}: {' '.join(str(e).split())}"
            + (f" (traceback in {log})" if log else ""),
            file=sys.stderr,
        )
        return 3
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


def _error_log(out) -> str | None:
    """DIR/error.log with the current exception's traceback (its path), or None where it cannot be written."""
    import traceback
    from pathlib import Path

    try:
        path = Path(out) / "error.log"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(traceback.format_exc())
        return str(path)
    except OSError:
        return None


def _say(line: str) -> None:
    print(line, flush=True)
