"""Measured runs made by the FMU itself, for the calibration example and the fit's tests.

:func:`measure` runs the FMU with the true parameters over a motion given in closed form
(as a servo would follow it), samples the motor-side commands q*_i exactly and the chosen
outputs with the encoder's errors: quantized to ``resolution`` (the encoder's count) and
with Gaussian noise of standard deviation ``noise`` drawn from ``seed``. What the fit is
then told is the CSV, never the parameters.

Two orders of the two errors: by default (``noise_first=False``, what the calibration example
and the fit's tests were made with) the true value is rounded to the count and the noise added
to the rounded value; with ``noise_first=True`` the noise is added to the true position and
the sum rounded to the count, as a real encoder reads a noisy position: every sample then lies
on the encoder's grid, and the error of a sample is the noise plus a rounding error of
standard deviation about resolution/sqrt(12) (for noise comparable with the count).
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
    noise_first: bool = False,
    record: list | None = None,
) -> dict:
    """Columns of a measured run: ``t``, the commanded ``inputs`` {FMU input: column} at
    every sample (exact) and each of ``outputs`` {FMU output: (column, noise, resolution)}
    with its encoder errors. ``motion`` defaults to the reference motion. ``torques``
    {tau_m[i]: (column, function of t)}: motor torques, logged at every sample; the FMU gets
    them as the fit does, through a cubic spline of the log (:class:`~stickslip.fit.spec.Torques`).
    ``noise_first``: the noise added before the rounding to ``resolution`` (the encoder's
    order; default False: rounded, then the noise added). ``record``: further FMU outputs
    (e.g. ``n_stick[1]``) returned exact, each under its own name, for checks of the true
    run; they are not measurements (leave them out of the data file)."""
    from ..motion import reference_inputs

    motion = motion or reference_inputs
    inputs = inputs or {f"q_star[{i}]": f"motor{i}" for i in range(1, 5)}
    data = Path(fmu).read_bytes()
    t = np.round(np.arange(0.0, duration + 0.5 * step, step), 12)
    names = list(outputs)
    extra = [n for n in (record or []) if n not in names]
    logged = None
    if torques:
        from .spec import Torques

        values = np.column_stack([[f(float(tk)) for tk in t] for _, f in torques.values()])
        logged = Torques(t, list(torques), values)
    payload = Payload("truth", t, motion, logged, names + extra, {})
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
        if noise_first:
            y = y + noise * rng.standard_normal(len(y))
            columns[column] = np.round(y / resolution) * resolution if resolution else y
            continue
        if resolution:
            y = np.round(y / resolution) * resolution
        columns[column] = y + noise * rng.standard_normal(len(y))
    for k, name in enumerate(extra, len(names)):
        columns[name] = result.values[:, k]
    return columns


def write_csv(columns: dict, path, digits: int = 17) -> None:
    """The columns as a CSV with a header row, ``digits`` significant digits (17: exact)."""
    names = list(columns)
    table = np.column_stack([columns[n] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt=f"%.{digits}g")
