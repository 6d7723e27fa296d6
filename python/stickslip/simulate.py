"""Run the stick-slip manipulator FMU with fmpy, the way a user does.

* :func:`run`: instantiate the FMU with fmpy's FMU2Slave (an FMI 3.0 FMU, ``X-fmi3.fmu``:
  FMU3Slave through the FMI 2.0 scalar names, :mod:`stickslip.fmi3`), set parameters,
  step it over a motion, by default the reference motion of
  :mod:`stickslip.motion`, or a motion file (docs/motion.md; inputs q*, q*', q*''
  set at every communication point) and collect every output by name;
* :func:`write_csv`: the outputs as CSV, one column per FMU variable.

Command line (the main job uses it)::

    stickslip simulate [--fmu FILE] [--out results/reference.csv] [--motion MOTION.toml]
        [--end 2.0] [--interval 1e-3] [--set NAME=VALUE ...]

``--motion`` drives the FMU with a motion file (docs/motion.md) instead of the reference
arm's cycloids; its number of joints is checked against the FMU's. Without ``--end`` such a
run lasts the file's ``end``, else until the motion is at rest plus its ``settle`` (0.5 s).
        [--check-convergence [--convergence-threshold 0.003]]

Without ``--motion`` the reference arm's cycloids drive the FMU, which must then have the
reference arm's joints (:func:`stickslip.motion.reference_motion_refusal`: the reference FMU
and its motor variant); any other FMU needs ``--motion``.

An FMU with motor drives (inputs ``tau_m[i]``, e.g. one of models/reference_rrpr_motor.toml)
runs with the motor torques of the motion file's CSV (columns ``tau_m[i]``, a cubic spline
whose value and first two derivatives are set at every communication point), the others held
at their ``--set tau_m[i]=VALUE`` (default 0), and ``--set static_start=true`` if wanted; the
motion's q* of a motor joint is its start position only, and a motion file that moves a motor
joint is refused, as is a ``--set tau_m[i]`` for a torque the motion gives. A ``--set`` the FMU
refuses or does not know, a motion file that does not fit the FMU, an FMU without the reference
arm's joints and no ``--motion``, and a step the FMU refuses end the command with one line on
stderr (exit status 2).

``--check-convergence`` runs the motion a second time with a tenfold tighter
``error_tolerance`` (fixed sub-steps: halved), prints the relative spread of every
metric of a sweep row between the two runs (:mod:`stickslip.convergence`), warns on
the terminal when one exceeds the threshold, and writes them to OUT with the suffix
``.convergence.json``.
"""

from __future__ import annotations

import argparse
import csv
import shutil
import sys
import tempfile
import time
from pathlib import Path

from .convergence import DEFAULT_THRESHOLD
from .fmu import DEFAULT_FMU, ROOT, LogCapture, communication_points, initialize, input_references
from .motion import (
    RUN_TIME,
    MotionError,
    load_motion_for,
    motion_torques,
    motor_joints,
    reference_inputs,
    reference_motion_refusal,
)
from .progress import Progress


def run(
    fmu=DEFAULT_FMU,
    end: float | None = RUN_TIME,
    interval: float = 1e-3,
    parameters: dict | None = None,
    inputs=reference_inputs,
    progress: str | None = None,
    motion=None,
) -> dict:
    """Simulates ``end`` seconds in communication steps of ``interval``.

    ``parameters`` maps FMU variable names (``mu_k[3]``, ``h_max``, ...) to
    values set before initialization; ``inputs(t, interval)`` returns (q*, q*', q*'')
    per joint at t (:mod:`stickslip.motion`; a motion file's ``torques`` too, for the motor
    drives). The default, the reference arm's cycloids, is refused with ValueError for an FMU
    without the reference arm's joints (:func:`stickslip.motion.reference_motion_refusal`).
    ``motion``: the path of a motion file (docs/motion.md), checked against this FMU's joints,
    used instead of ``inputs``; with it ``end = None`` means the file's stop time. ``progress``:
    a label for the progress on stderr (:class:`stickslip.progress.Progress`: a bar on a
    terminal, else a line per 10 % of the steps), None for none. Returns a dict: ``time`` and
    every output by name, as lists (Booleans as 0/1). What the FMU refuses raises fmpy's FMICallException with
    the FMU's logged fmi2Error/fmi2Fatal messages in its attribute ``fmu_messages``.
    """
    from fmpy import extract, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave

    from .fmi3 import ScalarSlave, is_fmi3, scalar_view

    fmu = str(fmu)
    md = read_model_description(fmu)
    fmi3 = is_fmi3(md)
    if fmi3:  # the FMI 3.0 FMU through the FMI 2.0 FMU's scalar names (stickslip.fmi3)
        md = scalar_view(md)
    if motion is not None:
        inputs = load_motion_for(motion, md)
    elif inputs is reference_inputs:
        refusal = reference_motion_refusal(fmu)
        if refusal:
            raise ValueError(refusal)
    if fmi3 and motion_torques(inputs):
        raise ValueError(f"{fmu}: motor torques from a motion file are set on the FMI 2.0 FMU only")
    if end is None:
        end = getattr(inputs, "stop_time", RUN_TIME)
    in_vrs = input_references(md)
    outputs = [v for v in md.modelVariables if v.causality == "output"]
    real_out = [v for v in outputs if v.type == "Real"]
    bool_out = [v for v in outputs if v.type == "Boolean"]
    unzipdir = extract(fmu, tempfile.mkdtemp(prefix="stickslip_"))
    if fmi3:
        slave = ScalarSlave(md, unzipDirectory=unzipdir, instanceName="run")
    else:
        slave = FMU2Slave(
            guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="run"
        )
    real_vrs = [v.valueReference for v in real_out]
    bool_vrs = [v.valueReference for v in bool_out]
    rows = []
    log = LogCapture()

    def record(t):
        # One tuple per communication point; split into columns at the end.
        rows.append((t, *slave.getReal(real_vrs), *(1 if x else 0 for x in slave.getBoolean(bool_vrs))))

    running = None
    try:
        if fmi3:
            slave.instantiate(log=log)
        else:
            slave.instantiate(callbacks=log.callbacks)
        initialize(slave, md, parameters or {}, in_vrs, inputs, interval)
        record(0.0)
        if progress:
            # "{desc}": the label goes in as a value, so braces in it (a path) are no format fields
            line = "{desc}: {percent:3d} % (t = {t:.3f} s of " + f"{end:g}" + " s, {elapsed:.1f} s wall)"
            running = Progress(round(end / interval), line, unit="step", desc=progress)
        for _, t in communication_points(slave, in_vrs, inputs, end, interval):
            record(t)
            if running is not None:
                running.advance(t=t)
        slave.terminate()
    except FMICallException as e:
        e.fmu_messages = [m for (_, status, _, m) in log.records if status >= 3]
        raise
    finally:
        if running is not None:
            running.close()
        slave.freeInstance()
        log.close()
        shutil.rmtree(unzipdir, ignore_errors=True)
    names = ["time"] + [v.name for v in real_out + bool_out]
    columns = zip(*rows, strict=True) if rows else ([] for _ in names)
    return {name: list(column) for name, column in zip(names, columns, strict=True)}


def write_csv(result: dict, path) -> None:
    """Writes a :func:`run` result, one column per variable (RFC 4180 quoting)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    names = list(result)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        for row in zip(*(result[k] for k in names), strict=True):
            w.writerow([repr(float(x)) for x in row])


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--fmu", default=str(DEFAULT_FMU))
    p.add_argument("--out", default=str(ROOT / "results" / "reference.csv"))
    p.add_argument(
        "--motion",
        metavar="MOTION.toml",
        help="drive the FMU with this motion file (docs/motion.md: per joint a cycloid or a hold, or a CSV of "
        "t, q_star[1..n] and the motor drives' tau_m[i]); default: the reference arm's cycloids, for an FMU "
        "with the reference arm's joints only (any other FMU needs --motion)",
    )
    p.add_argument(
        "--end",
        type=float,
        default=None,
        help=f"stop time, s (default {RUN_TIME:g}; with --motion the file's `end`, else when it is at "
        f"rest plus its `settle`)",
    )
    p.add_argument("--interval", type=float, default=1e-3)
    r = p.add_argument_group("replay of measured experiments (docs/calibration.md)")
    r.add_argument(
        "--spec",
        metavar="SPEC.toml",
        help="replay the experiments of this fit SPEC exactly as the fit runs them (their inputs, known "
        "parameters and start state), writing OUT/<experiment>.csv and .png and printing the residuals",
    )
    r.add_argument("--experiment", action="append", default=[], metavar="NAME", help="only this experiment, repeatable")
    r.add_argument(
        "--fitted", metavar="fitted.toml", help="the values a fit wrote ([parameters], [settings]) to replay with"
    )
    r.add_argument(
        "--horizon",
        type=float,
        metavar="SECONDS",
        help="predict over this horizon: restart every SECONDS from the measured state (default: one run)",
    )
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE", help="parameter value, repeatable")
    p.add_argument(
        "--check-convergence",
        action="store_true",
        help="run again with a tenfold tighter error_tolerance (fixed sub-steps: halved), print the "
        "relative spread of each metric, warn above --convergence-threshold (docs/convergence.md)",
    )
    p.add_argument(
        "--convergence-threshold",
        type=float,
        default=DEFAULT_THRESHOLD,
        metavar="T",
        help=f"spread above which a metric is not converged (default {DEFAULT_THRESHOLD:g})",
    )


def main(a: argparse.Namespace) -> int:
    """``stickslip simulate``: the reference motion (or ``--motion``) through the FMU, written as CSV.
    What cannot run (a --set the FMU refuses or does not know, a motion file that does not fit
    the FMU, a step the FMU refuses) ends it with one line on stderr and exit status 2."""
    from fmpy.fmi1 import FMICallException

    parameters, given = {}, {}
    for item in a.set:
        name, eq, value = item.partition("=")
        try:
            if not eq or not name:
                raise ValueError
            parameters[name] = value.lower() == "true" if value.lower() in ("true", "false") else float(value)
            given[name] = item
        except ValueError:
            print(
                f"stickslip simulate: --set {item!r}: expected NAME=VALUE with a number, true or false", file=sys.stderr
            )
            return 2
    if a.spec is not None:
        return replay_main(a, parameters)
    if a.experiment or a.fitted or a.horizon is not None:
        print(
            "stickslip simulate: --experiment, --fitted and --horizon replay a fit SPEC: give --spec SPEC.toml",
            file=sys.stderr,
        )
        return 2
    inputs, label, end = reference_inputs, "reference motion", RUN_TIME if a.end is None else a.end
    if a.motion is None:
        refusal = reference_motion_refusal(a.fmu)
        if refusal:
            print(f"stickslip simulate: {refusal}", file=sys.stderr)
            return 2
    else:
        try:
            inputs = motion_of(a.motion, a.fmu)
        except MotionError as e:
            print(f"stickslip simulate: {e}", file=sys.stderr)
            return 2
        clash = [name for name in motion_torques(inputs) if name in parameters]
        if clash:
            print(
                f"stickslip simulate: --set {given[clash[0]]} and the motion file {a.motion} both give {clash[0]} "
                f"(a column of its CSV): give it once, drop the --set or the column",
                file=sys.stderr,
            )
            return 2
        label, end = f"motion {a.motion}", inputs.stop_time if a.end is None else a.end
        print(f"motion: {inputs.describe()}; simulating {end:g} s")
    note = motor_note(a.fmu, parameters, motion_torques(inputs))
    if note:
        print(note)
    wall = time.perf_counter()
    try:
        result = run(a.fmu, end, a.interval, parameters, inputs, progress=label)
    except ValueError as e:  # a --set name the FMU does not have
        print(f"stickslip simulate: {e}", file=sys.stderr)
        return 2
    except FMICallException as e:
        reason = " ".join("; ".join(getattr(e, "fmu_messages", [])).split()) or "(the FMU logged no message)"
        print(f"stickslip simulate: {e} {reason}", file=sys.stderr)
        return 2
    simulated = time.perf_counter()
    write_csv(result, a.out)
    print(
        f"simulated {end} s through {a.fmu} in {simulated - wall:.2f} s wall "
        f"(unpacking and instantiation included); wrote {a.out} in {time.perf_counter() - simulated:.2f} s"
    )
    if a.check_convergence:
        check = convergence_of(result, a.fmu, end, a.interval, parameters, a.convergence_threshold, inputs)
        path = Path(a.out).with_suffix(".convergence.json")
        write_convergence(check, path)
        print(check.report())
        print(f"wrote {path}")
        if check.status != "checked":
            print(f"WARNING: the convergence check run ended {check.status}: {check.message}", file=sys.stderr)
        elif check.warning():
            print(check.warning(), file=sys.stderr, flush=True)
    return 0


def replay_main(a: argparse.Namespace, overrides: dict) -> int:
    """``stickslip simulate --spec SPEC.toml [--experiment NAME] [--fitted fitted.toml] [--set ...]``:
    the SPEC's experiments replayed (:mod:`stickslip.fit.replay`) into ``--out`` (a directory;
    default results/replay). Exit 2 for a SPEC, fitted.toml or --set that cannot be used, 1
    when a run ends early (the FMU refused or discarded a step), else 0."""
    from .fit.replay import ReplayError, fitted_starts, fitted_values, replay
    from .fit.spec import FitSpecError, load

    if a.motion is not None or a.end is not None:
        print(
            "stickslip simulate: --spec replays the SPEC's own inputs and times: leave out --motion and --end",
            file=sys.stderr,
        )
        return 2
    out = Path(a.out) if a.out != str(ROOT / "results" / "reference.csv") else ROOT / "results" / "replay"
    if out.suffix.lower() == ".csv":
        print(
            f"stickslip simulate: --out {out}: with --spec, a directory (one CSV and plot per experiment)",
            file=sys.stderr,
        )
        return 2
    try:
        spec = load(a.spec, replay=True)
        fitted = fitted_values(a.fitted) if a.fitted else {}
        if a.horizon is not None and not a.horizon > 0:
            raise ReplayError(f"--horizon {a.horizon:g}: must be > 0 seconds")
        starts = fitted_starts(a.fitted) if a.fitted else {}
        report = replay(spec, a.experiment or None, fitted, overrides, out, horizon=a.horizon, starts=starts)
    except (FitSpecError, ReplayError) as e:
        print(f"stickslip simulate: {e}", file=sys.stderr)
        return 2
    failed = [name for name, r in report.items() if r["status"] != "ok"]
    for name in failed:
        print(
            f"stickslip simulate: experiment {name!r}: {report[name]['status']}: {report[name]['message']}",
            file=sys.stderr,
        )
    return 1 if failed else 0


def motor_note(fmu, parameters: dict, replayed=()) -> str | None:
    """For an FMU with motor drives, the line that says which joints they drive and the motor
    torques of the run: those the motion gives (``replayed``, names tau_m[i]), the others held
    (``--set tau_m[i]=VALUE``, else the FMU's start value); None for another FMU (or one fmpy
    cannot read: :func:`run` reports that)."""
    from fmpy import read_model_description

    try:
        md = read_model_description(str(fmu))
    except Exception:  # noqa: BLE001
        return None
    motors = motor_joints(md)
    if not motors:
        return None
    start = {v.name: v.start for v in md.modelVariables}
    held = [i for i in motors if f"tau_m[{i}]" not in replayed]
    torques = ", ".join(
        f"tau_m[{i}] = {float(parameters.get(f'tau_m[{i}]', start[f'tau_m[{i}]'] or 0.0)):g}" for i in held
    )
    line = f"motor drives on joints {', '.join(map(str, motors))}: the motion's q* is their start position only; "
    if replayed:
        line += f"the motors run on {', '.join(replayed)} of the motion's CSV (a cubic spline, with its derivatives)"
        return line + (f", and on {torques} N.m, held constant (--set tau_m[i]=VALUE)" if held else "")
    return line + f"the motors run on {torques} N.m, held constant (--set tau_m[i]=VALUE)"


def motion_of(path, fmu):
    """The motion file ``path`` checked against the FMU file ``fmu`` (:func:`stickslip.motion.load_motion`);
    raises :class:`stickslip.motion.MotionError`, also for an unreadable FMU."""
    from fmpy import read_model_description

    try:
        md = read_model_description(str(fmu))
    except Exception as e:  # noqa: BLE001 -- any unreadable FMU
        raise MotionError(f"fmu {fmu}: not a readable FMU ({e})") from None
    return load_motion_for(path, md)


def convergence_of(
    result: dict,
    fmu,
    end: float,
    interval: float,
    parameters: dict,
    threshold: float = DEFAULT_THRESHOLD,
    inputs=reference_inputs,
):
    """The convergence check of a :func:`run` result: the same run again with the tightened
    settings (:func:`stickslip.convergence.tightened`), the sweep's metrics of both and their
    spreads; a :class:`stickslip.convergence.Convergence`."""
    from fmpy import read_model_description

    from .convergence import CHECKED, Convergence, metrics_of_series, spreads, tightened

    rerun, method = tightened(parameters, read_model_description(str(fmu)))
    metrics = metrics_of_series(result)
    check = Convergence("error", rerun, method, threshold, metrics, spreads=dict.fromkeys(metrics, float("nan")))
    wall = time.perf_counter()
    try:
        tight = run(fmu, end, interval, {**parameters, **rerun}, inputs, progress="convergence check run")
    except Exception as e:  # noqa: BLE001 -- the main run's CSV is written; report the check's failure
        status = getattr(e, "status", None)
        check.status = "discard" if status == 2 else "error"
        check.message = f"{type(e).__name__}: {e}"
        return check
    check.seconds = (float("nan"), time.perf_counter() - wall)
    check.tight = metrics_of_series(tight)
    check.status = CHECKED
    check.spreads = spreads(check.metrics, check.tight, list(metrics))
    return check


def write_convergence(check, path) -> None:
    """A :class:`stickslip.convergence.Convergence` as JSON: settings, both runs' metrics,
    spreads, and the metrics above the threshold."""
    import json
    import math

    clean = lambda d: {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in d.items()}  # noqa: E731
    Path(path).write_text(
        json.dumps(
            {
                "status": check.status,
                "message": check.message,
                "rerun": check.rerun,
                "method": check.method,
                "threshold": check.threshold,
                "not_converged": check.not_converged,
                "metrics": clean(check.metrics),
                "check_run_metrics": clean(check.tight),
                "spreads": clean(check.spreads),
            },
            indent=1,
        ),
        encoding="utf-8",
    )
