"""``stickslip identify SPEC.toml --out DIR``: a real arm's physically valid model from its torque logs.

Exit status, each failure one line on stderr, never a traceback:

* 0 the identification ran (trusted or not: the warnings are in identify.json and printed);
  DIR holds identify.json, report.md, the identified model file (and URDF) and the figures;
* 1 it could not finish (no torque samples left, the engine refused a state): nothing written;
* 2 a SPEC or log that cannot be used (one line naming the field; nothing written);
* 3 an internal error (a bug: the line names it, the traceback is in DIR/error.log).
"""

from __future__ import annotations

import argparse
import sys
import warnings


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("spec", help="the SPEC (TOML): fmu, [[experiment]], [[heldout]], [identify] (docs/calibration.md)")
    p.add_argument("--out", required=True, help="result directory: identify.json, report.md, identified.toml, figures")


def main(a: argparse.Namespace) -> int:
    from ..fit.cli import _error_log
    from ..fit.idim import InverseDynamicsError, StageUnavailable
    from .identification import IdentifyError, identify
    from .spec import IdentifySpecError, load

    try:
        spec = load(a.spec)
    except IdentifySpecError as e:
        print(f"stickslip identify: {e}", file=sys.stderr)
        return 2
    print(
        f"identify: {len(spec.experiments)} run(s), {len(spec.heldout)} held out, {spec.n} joints of {spec.fmu.name}",
        flush=True,
    )
    warnings.simplefilter("ignore", RuntimeWarning)
    try:
        result = identify(spec, out=a.out, progress=lambda line: print(line, flush=True))
    except (IdentifyError, InverseDynamicsError, StageUnavailable, ValueError) as e:
        print(f"stickslip identify: {' '.join(str(e).split())}", file=sys.stderr)
        return 1
    except Exception as e:  # noqa: BLE001 -- one line and the traceback in a file, never on the console
        log = _error_log(a.out)
        print(
            f"stickslip identify: internal error: {type(e).__name__}: {' '.join(str(e).split())}"
            + (f" (traceback in {log})" if log else ""),
            file=sys.stderr,
        )
        return 3
    for run, rows in result["validation"].items():
        for i, row in rows.items():
            print(f"  held-out {run} joint {i}: " + ", ".join(f"{k} {v:.4f}" for k, v in row.items()))
    print(
        f"identify: {len(result['base_parameters'])} base parameters -> {a.out}/identify.json, {result['model_file']}"
    )
    print(f"identify: {'trusted' if result['trusted'] else 'NOT TRUSTED: see the warnings'}")
    for w in result["warnings"]:
        print(f"warning: {w}")
    return 0
