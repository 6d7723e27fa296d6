"""Builders of the fit tests (tests/python/test_fit.py): measured runs of the reference arm
made by the FMU at known parameters (``stickslip.fit.synthetic.measure``), written as CSV,
and fit SPECs (dicts, or TOML files for the CLI) that point at them.

The truth is the one of issue 29's measurement: μ_k[1] = 0.17, μ_s[1] = 0.22, μ_k[3] = 0.2,
k[3] = 8e5, every other parameter at the FMU's start value; the drives follow the reference
motion (every q* column motor1..motor4 given), the link encoders q[1] and q[3] are measured.
Runs are cached per process: a measurement is one FMU run, and several tests share one.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np

from helpers import require_fmu

TRUTH = {"mu_k[1]": 0.17, "mu_s[1]": 0.22, "mu_k[3]": 0.2, "k[3]": 8e5}
# the FMU's start values of other parameters some tests estimate (the truth too)
START = {"d_A[1]": 0.1, "d_B[1]": 0.1, "l_A[1]": 0.06, "m[3]": 8.0, "slider_a[3]": 0.2, "mu_s[3]": 0.2, "b_v[3]": 0.0}
BOUNDS = {
    "mu_k[1]": (0.05, 0.4),
    "mu_s[1]": (0.05, 0.5),
    "mu_k[3]": (0.05, 0.4),
    "mu_s[3]": (0.05, 0.5),
    "k[3]": (1e5, 5e6),
    "d_A[1]": (0.02, 0.5),
    "d_B[1]": (0.02, 0.5),
    "l_A[1]": (0.0, 0.2),
    "m[3]": (1.0, 30.0),
    "slider_a[3]": (0.05, 1.0),
}
LOG = {"k[3]"}
NOISE = {"q[1]": ("link1", 2e-6), "q[3]": ("link3", 1e-6)}  # output: (column, sigma)
INPUTS = {f"q_star[{i}]": f"motor{i}" for i in range(1, 5)}


def _key(d: dict | None) -> tuple:
    return tuple(sorted((d or {}).items()))


@functools.cache
def _measured(duration: float, seed: int, noise: float, truth: tuple, resolution: float) -> dict:
    from stickslip.fit.synthetic import measure

    outputs = {out: (col, noise * sigma, resolution) for out, (col, sigma) in NOISE.items()}
    return measure(require_fmu(), dict(truth), outputs, duration=duration, seed=seed)


def measured(duration=0.8, seed=1, noise=1.0, truth=None, resolution=0.0) -> dict:
    """Columns t, motor1..motor4, link1, link3 of the reference arm at ``truth`` (default
    TRUTH, plus any extra entries given, e.g. fixed settings) over ``duration`` s at 1 ms;
    the encoders' noise is ``noise`` times NOISE's sigmas (0: noiseless), seeded."""
    truth = {**TRUTH, **(truth or {})}
    columns = _measured(float(duration), int(seed), float(noise), _key(truth), float(resolution))
    return {k: v.copy() for k, v in columns.items()}


def with_noise(columns: dict, seed: int, scale: float = 1.0) -> dict:
    """Noiseless columns of :func:`measured` with the encoders' noise of ``seed`` added, as
    ``measure`` adds it (one generator, the channels in NOISE's order)."""
    rng = np.random.default_rng(seed)
    out = {k: v.copy() for k, v in columns.items()}
    for column, sigma in NOISE.values():
        out[column] = out[column] + scale * sigma * rng.standard_normal(len(out[column]))
    return out


def write_data(path: Path, columns: dict) -> Path:
    from stickslip.fit.synthetic import write_csv

    write_csv(columns, path)
    return path


def estimate(names, initial=None, bounds=None) -> dict:
    """An [estimate] table of ``names``: initial values (default the truth), BOUNDS, log k."""
    out = {}
    for n in names:
        low, high = (bounds or {})[n] if n in (bounds or {}) else BOUNDS[n]
        entry = {"initial": (initial or {}).get(n, {**START, **TRUTH}[n]), "bounds": [low, high]}
        if n in LOG:
            entry["scale"] = "log"
        out[n] = entry
    return out


def experiment(data: Path, sigma_scale: float = 1.0, **extra) -> dict:
    """An [[experiment]] of a data file made by :func:`measured` (every q* column an input)."""
    return {
        "data": str(data),
        "time": "t",
        "inputs": dict(INPUTS),
        "measured": {out: {"column": col, "sigma": sigma * sigma_scale} for out, (col, sigma) in NOISE.items()},
        **extra,
    }


def spec(experiments, names, initial=None, bounds=None, **options) -> dict:
    """A fit SPEC dict: the FMU under test, the experiments, the estimates, the options. Each
    experiment is told the truth of the TRUTH parameters not estimated (as an engineer knows
    what is not fitted), unless it gives them itself."""
    if isinstance(experiments, dict):
        experiments = [experiments]
    known = {n: v for n, v in TRUTH.items() if n not in names}
    experiments = [{**e, "parameters": {**known, **e.get("parameters", {})}} for e in experiments]
    bounds = dict(bounds or {})
    for n in names:
        static = n.replace("mu_k[", "mu_s[")
        if n.startswith("mu_k[") and static not in names and n not in bounds:
            # μ_k estimated alone may not cross the known μ_s (refused at spec time)
            high = min(e["parameters"].get(static, START.get(static, 0.2)) for e in experiments)
            bounds[n] = (BOUNDS[n][0], min(BOUNDS[n][1], high))
    return {
        "fmu": str(require_fmu()),
        "experiment": experiments,
        "estimate": estimate(names, initial, bounds),
        "options": dict(options),
    }


# ---------------------------------------------------------------------------
# TOML (the venv has a reader, tomllib, but no writer)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_value(str(k))} = {_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, np.generic):
        return _value(v.item())
    raise TypeError(f"no TOML for {type(v).__name__}")


def toml(doc: dict) -> str:
    """``doc`` as TOML: the top-level values (inline tables and arrays included), then each
    [[experiment]] (its ``measured`` as [experiment.measured] when a table), then the other
    tables. Anything a TOML file can hold round-trips; a value it cannot (None) is a
    TypeError."""
    experiments = doc.get("experiment")
    blocks = isinstance(experiments, dict) or (
        isinstance(experiments, list) and bool(experiments) and all(isinstance(e, dict) for e in experiments)
    )
    top = [(k, v) for k, v in doc.items() if not isinstance(v, dict) and not (k == "experiment" and blocks)]
    lines = [f"{_value(str(k))} = {_value(v)}" for k, v in top]
    if blocks:
        for e in experiments if isinstance(experiments, list) else [experiments]:
            lines.append("[[experiment]]")
            lines += [f"{_value(str(k))} = {_value(v)}" for k, v in e.items() if k != "measured"]
            if isinstance(e.get("measured"), dict):
                lines.append("[experiment.measured]")
                lines += [f"{_value(str(k))} = {_value(v)}" for k, v in e["measured"].items()]
            elif "measured" in e:
                lines.append(f"measured = {_value(e['measured'])}")
    for k, v in doc.items():
        if isinstance(v, dict) and not (k == "experiment" and blocks):
            lines.append(f"[{_value(str(k))}]")
            lines += [f"{_value(str(kk))} = {_value(vv)}" for kk, vv in v.items()]
    return "\n".join(lines) + "\n"


def write_spec(path: Path, doc: dict) -> Path:
    path.write_text(toml(doc))
    return path


def central_column(problem, z, j: int, segment=None, h: float = 1e-4):
    """Column j of a fit Problem's residual Jacobian in z by central differences of free runs
    (single shooting, or multiple shooting with ``segment`` s): z_j moved by ±h of its range."""
    plus, minus = np.array(z, dtype=np.float64), np.array(z, dtype=np.float64)
    plus[j] += h
    minus[j] -= h
    rp, rm = problem.residuals([plus, minus], segment)
    return (rp - rm) / (2 * h)


def sensitivities_against_differences(problem, z, segment=None, tolerance: float = 1e-3):
    """The residuals' Jacobian at z from the FMU's sensitivities (Problem.residual_jacobian),
    checked: every column exact, and within ``tolerance`` of its largest value of
    :func:`central_column` (run at fixed sub-steps, where both differentiate the same scheme).
    Returns it."""
    runs = problem.runs([z], segment, problem.sensitivity_steps(z))[0]
    J, exact = problem.residual_jacobian(runs, z)
    assert exact.all(), exact
    for j in range(len(z)):
        reference = central_column(problem, z, j, segment)
        scale = np.max(np.abs(reference))
        worst = np.max(np.abs(J[:, j] - reference))
        assert scale > 0 and worst <= tolerance * scale, (problem.spec.estimates[j].name, worst / scale)
    return J
