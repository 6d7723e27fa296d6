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
    torques: dict | None = None,
) -> dict:
    """Columns of a measured run: ``t``, the commanded ``inputs`` {FMU input: column} at
    every sample (exact) and each of ``outputs`` {FMU output: (column, noise, resolution)}
    with its encoder errors. ``motion`` defaults to the reference motion. ``torques``
    {tau_m[i]: (column, function of t)}: motor torques, logged at every sample; the FMU gets
    them as the fit does, through a cubic spline of the log (:class:`~stickslip.fit.spec.Torques`)."""
    from ..motion import reference_inputs

    motion = motion or reference_inputs
    inputs = inputs or {f"q_star[{i}]": f"motor{i}" for i in range(1, 5)}
    data = Path(fmu).read_bytes()
    t = np.round(np.arange(0.0, duration + 0.5 * step, step), 12)
    names = list(outputs)
    logged = None
    if torques:
        from .spec import Torques

        values = np.column_stack([[f(float(tk)) for tk in t] for _, f in torques.values()])
        logged = Torques(t, list(torques), values)
    payload = Payload("truth", t, motion, logged, names, {})
    result = run(content_hash(data), payload, dict(parameters), fmu_data=data)
    if result.status != "ok":
        raise RuntimeError(f"the true parameters did not run: {result.status}: {result.message}")
    rng = np.random.default_rng(seed)
    columns = {"t": t}
    for name, column in inputs.items():
        i = int(name[name.index("[") + 1 : -1])
        columns[column] = np.array([motion(float(tk), step)[0][i - 1] for tk in t])
    for k, (column, _) in enumerate((torques or {}).values()):
        columns[column] = values[:, k]
    for k, name in enumerate(names):
        column, noise, resolution = outputs[name]
        y = result.values[:, k]
        if resolution:
            y = np.round(y / resolution) * resolution
        columns[column] = y + noise * rng.standard_normal(len(y))
    return columns


def write_csv(columns: dict, path, digits: int = 17) -> None:
    """The columns as a CSV with a header row, ``digits`` significant digits (17: exact)."""
    names = list(columns)
    table = np.column_stack([columns[n] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt=f"%.{digits}g")
