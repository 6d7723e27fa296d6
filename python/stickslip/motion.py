"""Drive inputs of the FMU: the reference motion, or a motion read from a CSV file.

A motion is a function ``inputs(t, step)`` returning (q*, q*', q*'') lists, one value per
joint, set at the communication point t before the step of length ``step`` from t.

The reference motion (shared/reference-manipulator.md) is the cycloidal point-to-point
profile of every joint over T = 1.5 s, evaluated with the same floating-point operations as
``src/motion.rs``, so the inputs are bit-identical to those of the Rust engine.
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

MOTION_TIME = 1.5  # T of the cycloidal profiles, s
RUN_TIME = 2.0  # the reference run, s
REFERENCE_PROFILES = (  # (start, end) of q1*, q2, q3*, q4
    (0.0, math.pi / 3.0),
    (0.0, math.pi / 12.0),
    (0.8, 1.0),
    (0.0, math.pi / 2.0),
)
INPUT_GROUPS = ("q_star", "qd_star", "qdd_star")


def cycloidal(start: float, end: float, t: float, duration: float = MOTION_TIME):
    """(q, q', q'') of the cycloidal profile s(tau) = tau - sin(2 pi tau)/(2 pi) at time t.

    The same operations, in the same order, as ``Cycloidal::eval`` in
    src/motion.rs, so the values are bit-identical to the engine's.
    """
    tau2 = math.tau
    d = end - start
    if t <= 0.0:
        return start, 0.0, 0.0
    if t >= duration:
        return end, 0.0, 0.0
    tau = t / duration
    s = tau - math.sin(tau2 * tau) / tau2
    sd = (1.0 - math.cos(tau2 * tau)) / duration
    sdd = tau2 * math.sin(tau2 * tau) / (duration * duration)
    return start + d * s, d * sd, d * sdd


def reference_inputs(t: float, step: float = 0.0):
    """(q*, q*', q*'') lists of the 4 joints of the reference motion at time t (``step`` unused:
    the rates are the profile's own)."""
    q, qd, qdd = [], [], []
    for start, end in REFERENCE_PROFILES:
        a, b, c = cycloidal(start, end, t)
        q.append(a)
        qd.append(b)
        qdd.append(c)
    return q, qd, qdd


def input_names(joints: int):
    """q_star[1..n], qd_star[1..n], qdd_star[1..n]: the order of a motion's values."""
    return [f"{g}[{i}]" for g in INPUT_GROUPS for i in range(1, joints + 1)]


class MotionError(ValueError):
    """A motion file that cannot be used; the message names the file and the problem."""


class TableMotion:
    """A motion given as a table: times and q*_i at those times, optionally q*'_i and q*''_i.

    Between the rows q* is interpolated linearly. Missing rates: q*' is the slope of that
    interpolation over the communication step [t, t + step], so that the FMU, which holds
    the inputs as their Taylor polynomial across the step, follows the piecewise-linear
    path through the rows; a missing q*'' is 0. Before the first and after the last row the
    values are held.
    """

    def __init__(self, time, columns: dict, joints: int, source: str = "motion"):
        self.time = np.asarray(time, dtype=np.float64)
        self.joints = joints
        if len(self.time) < 1:
            raise MotionError(f"{source}: no rows")
        if not np.all(np.isfinite(self.time)) or np.any(np.diff(self.time) <= 0):
            raise MotionError(f"{source}: `time` must be finite and strictly increasing")
        unknown = sorted(set(columns) - set(input_names(joints)))
        if unknown:
            raise MotionError(f"{source}: unknown column(s) {unknown}; the FMU's inputs are "
                              f"q_star[1..{joints}], qd_star[..], qdd_star[..]")
        missing = [f"q_star[{i}]" for i in range(1, joints + 1) if f"q_star[{i}]" not in columns]
        if missing:
            raise MotionError(f"{source}: missing column(s) {missing}")
        for name, values in columns.items():
            if len(values) != len(self.time) or not np.all(np.isfinite(values)):
                raise MotionError(f"{source}: column `{name}` has missing or non-finite values")
        self.columns = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}

    @classmethod
    def from_csv(cls, path, joints: int) -> "TableMotion":
        """Reads a CSV with a header row: ``time``, ``q_star[i]`` (``qd_star[i]``, ``qdd_star[i]`` optional)."""
        path = Path(path)
        try:
            with open(path, newline="") as f:
                rows = [r for r in csv.reader(f) if r and any(c.strip() for c in r)]
        except OSError as e:
            raise MotionError(f"motion file {path}: {e.strerror}") from None
        if len(rows) < 2:
            raise MotionError(f"motion file {path}: needs a header row and at least one data row")
        header = [re.sub(r"\s+", "", h) for h in rows[0]]
        if "time" not in header:
            raise MotionError(f"motion file {path}: no `time` column (header: {header})")
        try:
            data = np.array([[float(x) for x in r] for r in rows[1:]], dtype=np.float64)
        except ValueError as e:
            raise MotionError(f"motion file {path}: {e}") from None
        if data.shape[1] != len(header):
            raise MotionError(f"motion file {path}: rows have {data.shape[1]} values, the header {len(header)}")
        cols = {h: data[:, j] for j, h in enumerate(header) if h != "time"}
        return cls(data[:, header.index("time")], cols, joints, f"motion file {path}")

    def _at(self, name: str, t: float) -> float:
        return float(np.interp(t, self.time, self.columns[name]))

    def __call__(self, t: float, step: float):
        q, qd, qdd = [], [], []
        for i in range(1, self.joints + 1):
            qs = f"q_star[{i}]"
            q.append(self._at(qs, t))
            if f"qd_star[{i}]" in self.columns:
                qd.append(self._at(f"qd_star[{i}]", t))
            else:
                qd.append((self._at(qs, t + step) - q[-1]) / step if step > 0 else 0.0)
            qdd.append(self._at(f"qdd_star[{i}]", t) if f"qdd_star[{i}]" in self.columns else 0.0)
        return q, qd, qdd
