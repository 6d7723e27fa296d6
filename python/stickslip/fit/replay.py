"""Replay of measured experiments: ``stickslip simulate --spec SPEC.toml [--experiment NAME]
[--fitted fitted.toml] [--set NAME=VALUE ...] [--out DIR]``.

Each experiment of a fit SPEC runs through the FMU exactly as the fit runs it
(:func:`stickslip.fit.runner.run`): the same inputs (the columns' splines, the torques'
value and rates at each sample, the derivative filter where a column is a measurement), the
same known parameters, the same start state (:mod:`stickslip.fit.start`), stepped from
sample to sample. The values it runs with: the FMU's start values, then those of
``fitted.toml`` ([parameters] and [settings]: the estimates and the fit's error_tolerance),
then the experiment's own known ones, then ``--set``. A SPEC for replay alone (held-out runs)
needs no ``[estimate]``.

For each experiment it writes ``DIR/<experiment>.csv`` (time and every output of the FMU at
the samples), ``DIR/<experiment>.png`` (measured against simulated, the residuals; motor
joints' wind-up and torque; stiction shaded), and prints per measured channel the residual's
rms and its rms in units of the channel's σ, and the cost ½Σ((model − measured)/σ)²: for an
experiment of the fit and its fitted.toml, the fit's own numbers (fit.json ``residual_rms``).

``--horizon SECONDS``: a prediction over that horizon instead of one simulation of the whole
run: the run restarts every ``horizon`` seconds from the measured state there (as the fit's
multiple shooting does, :mod:`stickslip.fit.start`). An arm driven by logged torques drifts
open loop (the torque log's noise is an input error the simulation integrates); its
prediction over a horizon shows how well the model follows the arm without that drift.
"""

from __future__ import annotations

import csv
import math
import re
import tomllib
from pathlib import Path

import numpy as np


class ReplayError(ValueError):
    """What keeps a replay from running: an unknown experiment, an unreadable fitted.toml."""


def fitted_values(path) -> dict:
    """The [parameters] and [settings] of a fitted.toml, by FMU name."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ReplayError(f"--fitted {path}: no such file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ReplayError(f"--fitted {path}: not valid TOML: {e}") from None
    values = {}
    for table in ("parameters", "settings"):
        part = doc.get(table, {})
        if not isinstance(part, dict):
            raise ReplayError(f"--fitted {path}: [{table}] must be a table of NAME = value")
        for name, value in part.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ReplayError(f"--fitted {path}: [{table}] {name} = {value!r}: must be a finite number")
            values[name] = float(value)
    if not values:
        raise ReplayError(f"--fitted {path}: no [parameters] (write it with stickslip fit)")
    return values


def fitted_starts(path) -> dict:
    """The [start.<experiment>] tables of a fitted.toml: {experiment: {q_start[i] or qd_start[i]:
    value}}, the start state the fit found for the joints moving at the experiment's first
    sample (:func:`stickslip.fit.start.start_unknowns`); {} where it has none."""
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return {}  # fitted_values says what is wrong with the file
    table = doc.get("start", {})
    if not isinstance(table, dict):
        raise ReplayError(f"--fitted {path}: [start] must hold a table per experiment")
    out = {}
    for name, part in table.items():
        if not isinstance(part, dict):
            raise ReplayError(f"--fitted {path}: [start.{name}] must be a table of q_start[i] / qd_start[i] = value")
        for variable, value in part.items():
            if not re.fullmatch(r"qd?_start\[[1-9][0-9]*\]", variable):
                raise ReplayError(f"--fitted {path}: [start.{name}] {variable}: only q_start[i] and qd_start[i]")
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ReplayError(f"--fitted {path}: [start.{name}] {variable} = {value!r}: must be a finite number")
            out.setdefault(name, {})[variable] = float(value)
    return out


def replay(
    spec,
    experiments=None,
    fitted: dict | None = None,
    overrides: dict | None = None,
    out=None,
    plot=True,
    say=print,
    horizon: float | None = None,
    starts: dict | None = None,
) -> dict:
    """Runs the experiments named ``experiments`` (all when None) of the loaded FitSpec
    ``spec`` with the values ``fitted`` (FMU name -> value) under each experiment's known
    ones, and ``overrides`` (``--set``) over both, each experiment of ``starts`` (its
    :func:`fitted_starts`) from the start state the fit found for it; returns
    {experiment: {"status", "message", "residual_rms", "normalized_rms", "cost", "csv", "png"}}.
    Raises :class:`ReplayError` for an unknown experiment or a value the FMU does not have."""
    from ..fmu import content_hash, unpacked
    from .problem import payload_of
    from .runner import run
    from .start import segment_starts, start_states

    fitted, overrides = dict(fitted or {}), dict(overrides or {})
    md = spec.model_description
    variables = {v.name: v for v in md.modelVariables}
    unknown = [n for n in {**fitted, **overrides} if n not in variables]
    if unknown:
        raise ReplayError(f"{unknown[0]!r} is not a variable of the FMU {spec.fmu.name}")
    by_name = {e.name: e for e in spec.experiments}
    chosen = list(experiments) if experiments else list(by_name)
    for name in chosen:
        if name not in by_name:
            raise ReplayError(f"{spec.source}: no experiment {name!r} (its experiments: {', '.join(by_name)})")
    fmu_data = Path(spec.fmu).read_bytes()
    digest = content_hash(fmu_data)
    where = unpacked(fmu_data, digest)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    out = Path(out) if out is not None else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    report = {}
    for name in chosen:
        e = by_name[name]
        values = {**{k: v for k, v in fitted.items() if k not in e.parameters}, **overrides}
        payload = payload_of(e, md, where, values, outputs)
        if payload.start is not None:  # the fitted start of the joints moving at the first sample
            unknown = [
                v for v in (starts or {}).get(name, {}) if int(v[v.index("[") + 1 : -1]) not in payload.start.moving
            ]
            if unknown:
                raise ReplayError(
                    f"--fitted: [start.{name}] {unknown[0]}: the experiment's first sample does not read that joint "
                    "as moving, so the fit had no start unknown for it (a fitted.toml of another SPEC?)"
                )
            values = {**(starts or {}).get(name, {}), **values}
        segments = None
        if horizon is not None:  # a prediction over ``horizon`` s from each measured state
            segments = start_states(e, segment_starts(e.time, horizon), md, where, values, require_measured=True)
            if segments is None:
                raise ReplayError(
                    f"--horizon: experiment {name!r} does not measure every flexible and motor joint's q, "
                    "so its state cannot be restarted from the data"
                )
        result = run(digest, payload, values, segments, fmu_data=fmu_data)
        entry = {"status": result.status, "message": result.message, "start": payload.start}
        columns = {o: result.values[:, j] for j, o in enumerate(outputs)}
        rms, normalized, cost = {}, {}, 0.0
        for c in e.channels:
            d = columns[c.output] - c.values
            rms[c.output] = float(np.sqrt(np.mean(d**2)))
            r = d / c.std
            normalized[c.output] = float(np.sqrt(np.mean(r**2)))
            cost += 0.5 * float(r @ r)
        entry.update(residual_rms=rms, normalized_rms=normalized, cost=cost)
        if out is not None:
            path = out / f"{_safe(name)}.csv"
            _write(path, e.time, columns)
            entry["csv"] = str(path)
            if plot and result.status == "ok":
                png = out / f"{_safe(name)}.png"
                figure(e, columns, md, png, f"experiment {name}: measured and simulated")
                entry["png"] = str(png)
        report[name] = entry
        if say is not None:
            status = "" if result.status == "ok" else f" ({result.status}: {' '.join(result.message.split())})"
            channels = ", ".join(f"{o} rms {rms[o]:.4g} ({normalized[o]:.3g} σ)" for o in rms)
            say(
                f"replay {name}{status}: {channels}; cost {cost:.6g}"
                + (f" -> {entry['csv']}" if "csv" in entry else "")
            )
    return report


def _write(path: Path, time, columns: dict) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["time", *columns])
        for k, t in enumerate(time):
            w.writerow([repr(float(t)), *(repr(float(v[k])) for v in columns.values())])


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)


def figure(experiment, columns: dict, md, path, title: str) -> None:
    """Measured against simulated for every channel of ``experiment``, with the residual in σ
    below each; ``columns``: the run's outputs at the samples by name (stick[i] shades the
    stiction phases). A flexible joint's q is drawn as its drive's lag q*_i − q_i, where
    stick-slip shows; a motor joint's as q itself (its q* is the rotor, θ_m/N), and each
    motor joint gets a panel of its gear wind-up θ_m/N − q (simulated, and measured where the
    motor encoder theta_m[i] is measured) against its motor torque τ_m."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..motion import motor_joints

    e = experiment
    motors = motor_joints(md)
    channels = {c.output: c for c in e.channels}
    panels = 2 * len(e.channels) + len(motors)
    fig, axes = plt.subplots(panels, 1, figsize=(9, 2.4 * panels), sharex=True, squeeze=False)
    commands = np.array([e.motion(float(t), 0.0)[0] for t in e.time])

    def shade(ax, joint):
        stick = columns.get(f"stick[{joint}]")
        if stick is not None:
            ax.fill_between(
                e.time, 0, 1, where=stick > 0.5, transform=ax.get_xaxis_transform(), color="C1", alpha=0.25, lw=0
            )

    row = 0
    for c in e.channels:
        ax, axr = axes[row, 0], axes[row + 1, 0]
        row += 2
        joint = int(c.output[c.output.index("[") + 1 : -1]) if "[" in c.output else None
        lag = c.output.startswith("q[") and joint is not None and joint not in motors
        base = commands[:, joint - 1] if lag else 0.0
        model = columns[c.output]
        ax.plot(e.time, base - c.values, ".", ms=1.5, color="0.4", label=f"measured `{c.column}`")
        ax.plot(e.time, base - model, lw=1.0, color="C0", label=f"simulated {c.output}")
        ax.set_ylabel(f"q_star[{joint}] − {c.output}" if lag else c.output)
        ax.legend(loc="best", fontsize=8)
        axr.plot(e.time, (model - c.values) / c.std, lw=0.6, color="C3")
        axr.axhline(0, color="0.5", lw=0.5)
        axr.set_ylabel(f"({c.output} − meas.)/σ")
        if joint is not None:
            shade(ax, joint)
            shade(axr, joint)
    for i in motors:
        ax = axes[row, 0]
        row += 1
        wind = columns.get(f"eps_joint[{i}]")
        if wind is not None:
            ax.plot(e.time, wind, lw=1.0, color="C0", label=f"simulated θ_m/N − q, joint {i}")
        if f"theta_m[{i}]" in channels and f"q[{i}]" in channels:
            ratio = float(e.parameters.get(f"gear_ratio[{i}]", _start(md, f"gear_ratio[{i}]")))
            measured = channels[f"theta_m[{i}]"].values / ratio - channels[f"q[{i}]"].values
            ax.plot(e.time, measured, ".", ms=1.5, color="0.4", label="measured θ_m/N − q")
        ax.set_ylabel(f"wind-up θ_m/N − q [{i}]")
        ax.legend(loc="upper left", fontsize=8)
        if e.torques is not None and f"tau_m[{i}]" in e.torques.names:
            torque = np.atleast_2d(e.torques(e.time)[0]).reshape(len(e.time), -1)[
                :, e.torques.names.index(f"tau_m[{i}]")
            ]
            twin = ax.twinx()
            twin.plot(e.time, torque, lw=0.7, color="C2", label=f"τ_m[{i}] (input)")
            twin.set_ylabel("τ_m [N·m]", color="C2")
        shade(ax, i)
    axes[-1, 0].set_xlabel("t [s]")
    fig.suptitle(f"{title}; stiction phases shaded")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _start(md, name: str) -> float:
    for v in md.modelVariables:
        if v.name == name:
            return float(v.start or 1.0)
    return 1.0
