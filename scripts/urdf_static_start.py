#!/usr/bin/env python3
"""Start values that put an arm's flexible joints in static equilibrium at a motion's start.

Usage:  python scripts/urdf_static_start.py --fmu ARM.fmu --motion MOTION.toml

Without start values the FMU starts every flexible joint at q = q* with its drive spring
relaxed (`use_start_values = false`); an arm whose start pose loads a joint with gravity
then drops into its spring at t = 0 and rings at the drive's natural frequency, which
would be mistaken for the motion's own dynamics. This script computes, for the motion
file's q*(0), the coordinates where each flexible drive's spring holds the gravity load,
k_i (q*_i - q_i) = tau_i(q) (tau = the generalized gravity force at rest, from the
engine's inverse dynamics in the FMU's own binary, on the model it carries), by fixed-point iteration
(converged to 1e-15 rad in a few rounds: the lag is ~1e-3 rad), and prints them as
`stickslip simulate` options, one per line:

    --set use_start_values=true
    --set q_start[2]=0.60054...

(qd_start stays 0: at rest, stuck where friction holds the joint.) Clearance is taken
into account: the spring of a drive with clearance Delta_i transmits k_i (|q* - q| - Delta_i), so
the lag grows by Delta_i (a joint without gravity load, |tau_i| < 1e-9, starts at q* within it).
"""

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "python"))
from stickslip.motion import MotionError, fmu_joints, load_motion_for  # noqa: E402


def fmu_parameters(md):
    """{name: start value} of the real variables of the FMU whose modelDescription (fmpy) is
    ``md``, and its number of joints."""
    values = {v.name: float(v.start) for v in md.modelVariables if v.type == "Real" and v.start is not None}
    return values, fmu_joints(md)[0]


def gravity_torques(unzipdir, q):
    """tau(q) at rest, by the engine in the unpacked FMU's binary (stickslip.fit.idim)."""
    from stickslip.fit.idim import InverseDynamicsError, StageUnavailable, inverse_dynamics

    n = len(q)
    try:
        tau, _ = inverse_dynamics(unzipdir, [list(q) + [0.0] * 2 * n])
    except (InverseDynamicsError, StageUnavailable) as e:
        raise SystemExit(f"urdf_static_start: {e}") from None
    return [float(x) for x in tau[0]]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmu", required=True, type=Path, help="the arm's FMU (its model, drive parameters, joints)")
    ap.add_argument("--motion", required=True, type=Path, help="the motion file whose q*(0) is the start pose")
    args = ap.parse_args(argv)

    from fmpy import read_model_description

    from stickslip.fmu import content_hash, unpacked

    data = args.fmu.read_bytes()
    unzipdir = unpacked(data, content_hash(data))
    md = read_model_description(str(args.fmu))
    params, n = fmu_parameters(md)
    flexible = [i for i in range(1, n + 1) if f"k[{i}]" in params]
    try:
        q_star = list(load_motion_for(args.motion, md)(0.0)[0])
    except MotionError as e:
        print(f"urdf_static_start: {e}", file=sys.stderr)
        return 2
    q = list(q_star)
    for _ in range(50):
        tau = gravity_torques(unzipdir, q)
        new = list(q_star)
        for i in flexible:
            if abs(tau[i - 1]) < 1e-9:
                continue  # no load (a vertical axis): q = q* is an equilibrium, inside any clearance
            lag = tau[i - 1] / params[f"k[{i}]"]
            gap = params.get(f"Delta[{i}]", 0.0)
            new[i - 1] = q_star[i - 1] - (lag + (gap if lag > 0 else -gap))
        change = max(abs(a - b) for a, b in zip(new, q, strict=True))
        q = new
        if change < 1e-15:
            break
    else:
        raise SystemExit(f"urdf_static_start: no static equilibrium found for {args.fmu} (last change {change:.1e})")
    print("--set use_start_values=true")
    for i in flexible:
        print(f"--set q_start[{i}]={q[i - 1]!r}")
    lags = ", ".join(f"joint {i}: {q_star[i - 1] - q[i - 1]:.3e} rad" for i in flexible)
    print(f"urdf_static_start: static lags q* - q at the start pose: {lags}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
