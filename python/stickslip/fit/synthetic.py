"""Measured runs made by the FMU itself, for the calibration example and the fit's tests.

:func:`measure` runs the FMU with the true parameters over a motion given in closed form
(as a servo would follow it), samples the motor-side commands q*_i exactly and the chosen
outputs with the encoder's errors: quantized to ``resolution`` (the encoder's count) and
with Gaussian noise of standard deviation ``noise`` drawn from ``seed``. What the fit is
then told is the CSV, never the parameters.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fmu import content_hash
from .runner import Payload, run


def measure(
    fmu,
    parameters: dict,
    outputs: dict,
    duration: float = 2.0,
    step: float = 1e-3,
    motion=None,
    inputs: dict | None = None,
    seed: int = 0,
) -> dict:
    """Columns of a measured run: ``t``, the commanded ``inputs`` {FMU input: column} at
    every sample (exact) and each of ``outputs`` {FMU output: (column, noise, resolution)}
    with its encoder errors. ``motion`` defaults to the reference motion."""
    from ..motion import reference_inputs

    motion = motion or reference_inputs
    inputs = inputs or {f"q_star[{i}]": f"motor{i}" for i in range(1, 5)}
    data = Path(fmu).read_bytes()
    t = np.round(np.arange(0.0, duration + 0.5 * step, step), 12)
    names = list(outputs)
    result = run(content_hash(data), Payload("truth", t, motion, None, names, {}), dict(parameters), fmu_data=data)
    if result.status != "ok":
        raise RuntimeError(f"the true parameters did not run: {result.status}: {result.message}")
    rng = np.random.default_rng(seed)
    columns = {"t": t}
    for name, column in inputs.items():
        i = int(name[name.index("[") + 1 : -1])
        columns[column] = np.array([motion(float(tk), step)[0][i - 1] for tk in t])
    for k, name in enumerate(names):
        column, noise, resolution = outputs[name]
        y = result.values[:, k]
        if resolution:
            y = np.round(y / resolution) * resolution
        columns[column] = y + noise * rng.standard_normal(len(y))
    return columns


def write_csv(columns: dict, path) -> None:
    """The columns as a CSV with a header row, full precision."""
    names = list(columns)
    np.savetxt(
        path,
        np.column_stack([columns[n] for n in names]),
        delimiter=",",
        header=",".join(names),
        comments="",
        fmt="%.17g",
    )
