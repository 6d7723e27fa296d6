"""Drive inputs of the FMU: the reference motion, a motion file, or a sweep's CSV table.

A motion is a function ``inputs(t, step)`` returning (q*, q*', q*'') lists, one value per
joint, set at the communication point t before the step of length ``step`` from t.

The reference motion (shared/reference-manipulator.md) is the cycloidal point-to-point
profile of every joint over T = 1.5 s, evaluated with the same floating-point operations as
``src/motion.rs``, so the inputs are bit-identical to those of the Rust engine.

A *motion file* (TOML, docs/motion.md; :func:`load_motion`) gives the motion of any chain:
per joint (a ``[joints.<name>]`` table as in a model file, or an ``[[joint]]`` entry with its
index or name) a cycloid (or a sequence of them) or a constant, or a CSV of t and q*_1..q*_n whose
rates and accelerations come from a cubic spline through the samples (:class:`SplineMotion`);
for an FMU with motor drives the CSV may also give their torques tau_m[i] (:class:`TorqueSpline`,
set with their first two derivatives by :func:`stickslip.fmu.communication_points`) and leave out
their q* columns. :func:`fmu_joints` reads the number of joints (and their URDF names, when the
FMU gives them) from the FMU's modelDescription; the file is checked against it.

The reference motion is for the reference arm only: :func:`reference_motion_refusal` says why
it must not drive another FMU (:func:`runs_reference_motion`: whether it may).

:class:`TableMotion` is the older CSV table of a sweep SPEC (``motion = "file.csv"``: linear
interpolation, optional rate columns), kept as it was so that existing sweeps reproduce.
"""

from __future__ import annotations

import csv
import hashlib
import itertools
import math
import re
import tomllib
import zipfile
from dataclasses import dataclass
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
            raise MotionError(
                f"{source}: unknown column(s) {unknown}; the FMU's inputs are "
                f"q_star[1..{joints}], qd_star[..], qdd_star[..]"
            )
        missing = [f"q_star[{i}]" for i in range(1, joints + 1) if f"q_star[{i}]" not in columns]
        if missing:
            raise MotionError(f"{source}: missing column(s) {missing}")
        for name, values in columns.items():
            if len(values) != len(self.time) or not np.all(np.isfinite(values)):
                raise MotionError(f"{source}: column `{name}` has missing or non-finite values")
        self.columns = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}

    @classmethod
    def from_csv(cls, path, joints: int) -> TableMotion:
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


# ---------------------------------------------------------------------------
# motion files (docs/motion.md)

MOTION_KEYS = ("description", "joints", "end", "settle", "joint", "csv", "boundary")
MOTION_OF_JOINT = ("cycloid", "hold")  # the keys of a [joints.<name>] table
JOINT_KEYS = ("index", "name", *MOTION_OF_JOINT)  # the keys of a [[joint]] entry
CYCLOID_KEYS = ("q0", "q1", "t0", "t1")
CYCLOID_FORM = "{ q0 = ..., q1 = ..., t0 = ..., t1 = ... }"
BOUNDARIES = {"not-a-knot": "not-a-knot", "rest": "clamped"}  # `boundary` -> scipy's bc_type
SETTLE = 0.5  # s, default time simulated after the motion comes to rest (the reference: 1.5 s + 0.5 s)


def fmu_joints(md) -> tuple:
    """(n, names) of an FMU: n the number of inputs ``q_star[i]``, names {i: URDF joint name}
    for the joints whose ``q_star[i]`` description names one in backquotes, as in
    "... of joint 2 (`iiwa_joint_2`) ..." (empty for the reference arm's FMU)."""
    n, names = 0, {}
    for v in md.modelVariables:
        m = re.fullmatch(r"q_star\[(\d+)\]", v.name)
        if v.causality != "input" or not m:
            continue
        n += 1
        # "joint 2 (`name`", "joint 2 (revolute, `name`" or "joint 2 `name`"
        found = re.search(r"\bjoint\s+(\d+)\s*(?:\([^)`]*)?`([^`]+)`", v.description or "")
        if found and int(found.group(1)) == int(m.group(1)):
            names[int(m.group(1))] = found.group(2)
    return n, names


def motor_joints(md) -> list:
    """The joints i (1-based, in order) of an FMU that have a motor drive: those with an input
    ``tau_m[i]`` (empty for an FMU without motor drives). Their q_star, qd_star, qdd_star are
    only the start position at initialization; the motor torque drives them."""
    found = [re.fullmatch(r"tau_m\[(\d+)\]", v.name) for v in md.modelVariables if v.causality == "input"]
    return sorted(int(m.group(1)) for m in found if m)


def moving_joints(motion) -> list:
    """The joints i (1-based) whose q* a :class:`CycloidMotion` or :class:`SplineMotion` changes."""
    if isinstance(motion, CycloidMotion):
        return [i for i, segs in enumerate(motion.segments, 1) if any(c.q0 != c.q1 for c in segs)]
    if isinstance(motion, SplineMotion):
        return [i for i in range(1, motion.joints + 1) if np.any(motion.spline.c[:3, :, i - 1] != 0.0)]
    return []


def is_finite_number(x) -> bool:
    """True for a finite int or float read from TOML (not a bool, NaN or inf)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


@dataclass(frozen=True)
class Cycloid:
    """q0 -> q1 over [t0, t1] on the profile of :func:`cycloidal`; q0 before, q1 after."""

    q0: float
    q1: float
    t0: float
    t1: float

    def __call__(self, t: float):
        # t - 0.0 and t1 - 0.0 are exact: with t0 = 0 the values are bit-identical to cycloidal().
        return cycloidal(self.q0, self.q1, t - self.t0, self.t1 - self.t0)


class CycloidMotion:
    """Per joint a sequence of :class:`Cycloid` segments (empty: the joint holds ``hold[i]``)."""

    def __init__(self, segments: list, hold: list, source: str, stop_time: float | None = None, settle: float = SETTLE):
        self.segments = segments  # per joint: a list of Cycloid, in time order
        self.hold = hold  # per joint: the value held when it has no segment
        self.joints = len(segments)
        self.source = source
        self.end_time = max((s[-1].t1 for s in segments if s), default=0.0)  # at rest from here on
        self.stop_time = self.end_time + settle if stop_time is None else stop_time

    def __call__(self, t: float, step: float = 0.0):
        q, qd, qdd = [], [], []
        for segs, hold in zip(self.segments, self.hold, strict=True):
            if not segs:
                a, b, c = hold, 0.0, 0.0
            else:
                seg = segs[0]
                for s in segs[1:]:
                    if t >= s.t0:
                        seg = s
                a, b, c = seg(t)
            q.append(a)
            qd.append(b)
            qdd.append(c)
        return q, qd, qdd

    def describe(self) -> str:
        moving = [i + 1 for i, s in enumerate(self.segments) if s]
        return (
            f"{self.source}: {self.joints} joints, cycloids on joint(s) {moving or 'none'}, "
            f"at rest from t = {self.end_time:g} s"
        )


class SplineMotion:
    """q*_i sampled at times t_0 < ... < t_m (a CSV), joined by a C2 cubic spline per joint.

    q*' and q*'' are the spline's first and second derivatives (SciPy's ``CubicSpline``, a
    piecewise polynomial, evaluates them exactly), so the three inputs set at a communication
    point are the value and derivatives of one twice continuously differentiable function, and the
    FMU's Taylor polynomial q* + q*' t + q*'' t^2/2 across the step is that function's
    expansion (deviating from the spline by q*''' h^3/6 at the end of a step of h).

    ``boundary``: "not-a-knot" (the default; the third derivative is continuous at the
    second and last-but-one sample, so the spline reproduces every polynomial of degree
    <= 3 exactly, on any grid) or "rest" (clamped: q*' = 0 at the first and last sample, for
    rest-to-rest motions). Before the first sample q* holds its first value, after the last
    its last value, with zero rates.

    ``torques``: the motor torques of the CSV (a :class:`TorqueSpline`), or None.
    """

    def __init__(
        self,
        time,
        q,
        source: str,
        boundary: str = "not-a-knot",
        stop_time: float | None = None,
        settle: float = SETTLE,
        torques=None,
    ):
        from scipy.interpolate import CubicSpline

        self.time = np.ascontiguousarray(time, dtype=np.float64)
        q = np.asarray(q, dtype=np.float64)  # (samples, joints)
        self.joints = q.shape[1]
        self.source = source
        self.boundary = boundary
        self.spline = CubicSpline(self.time, q, axis=0, bc_type=BOUNDARIES[boundary])
        self.first, self.last = q[0].copy(), q[-1].copy()
        self.end_time = float(self.time[-1])
        self.stop_time = self.end_time + settle if stop_time is None else stop_time
        self.torques = torques

    def evaluate(self, t: float):
        """(q, q', q'') as arrays over the joints at time t."""
        zero = np.zeros(self.joints)
        if t < self.time[0]:
            return self.first.copy(), zero, zero.copy()
        if t > self.time[-1]:
            return self.last.copy(), zero, zero.copy()
        return self.spline(t), self.spline(t, 1), self.spline(t, 2)

    def __call__(self, t: float, step: float = 0.0):
        q, qd, qdd = self.evaluate(t)
        return q.tolist(), qd.tolist(), qdd.tolist()

    def describe(self) -> str:
        return (
            f"{self.source}: {self.joints} joints, {len(self.time)} samples over "
            f"[{self.time[0]:g}, {self.time[-1]:g}] s, cubic spline ({self.boundary} ends)"
            + (f"; motor torques {', '.join(self.torques.names)} (not-a-knot)" if self.torques is not None else "")
        )


class TorqueSpline:
    """Motor torques tau_m[i] sampled at times t_0 < ... < t_m (columns of a motion's CSV),
    joined by a not-a-knot cubic spline: SciPy's ``CubicSpline`` of the samples, the same call
    as the fit's :class:`stickslip.fit.spec.Torques`, so the values are the fit's. At a
    communication point the FMU gets the value and the spline's first two derivatives
    (fmi2SetRealInputDerivatives of orders 1 and 2) and holds their Taylor polynomial across the
    step. Before the first sample the torque holds its first value, after the last its last
    value, with zero derivatives (as q* of :class:`SplineMotion`).

    ``references``: the value references of ``names`` in the FMU, set by :func:`load_motion_for`
    (None until then)."""

    def __init__(self, time, names: list, values, source: str = "motion"):
        from scipy.interpolate import CubicSpline

        self.names = list(names)
        self.source = source
        self.time = np.asarray(time, dtype=np.float64)
        values = np.asarray(values, dtype=np.float64)  # (samples, torques)
        self.values = values
        self.spline = CubicSpline(self.time, values, axis=0)
        self.first, self.last = values[0].copy(), values[-1].copy()
        self.references = None

    def __call__(self, t: float):
        """(values, first derivatives, second derivatives) at t, as arrays over ``names``."""
        zero = np.zeros(len(self.names))
        if t < self.time[0]:
            return self.first.copy(), zero, zero.copy()
        if t > self.time[-1]:
            return self.last.copy(), zero, zero.copy()
        return self.spline(t), self.spline(t, 1), self.spline(t, 2)


def motion_torques(motion) -> list:
    """The motor torques tau_m[i] a motion gives (the columns of its CSV), by name; [] for none."""
    torques = getattr(motion, "torques", None)
    return list(torques.names) if torques is not None else []


def _number(value, what: str, where: str, example: str) -> float:
    """``value`` as a float; refused unless a finite number, showing the right form ``example``."""
    if not is_finite_number(value):
        raise MotionError(f"{where}: {what} = {value!r}: must be a finite number, as in {example}")
    return float(value)


def _cycloid(entry, what: str, where: str) -> Cycloid:
    if not isinstance(entry, dict):
        raise MotionError(f"{where}: {what} = {entry!r}: must be a table {CYCLOID_FORM}")
    unknown = [k for k in entry if k not in CYCLOID_KEYS]
    if unknown:
        raise MotionError(f"{where}: {what}: unknown key(s) {unknown}; a cycloid has {list(CYCLOID_KEYS)}")
    missing = [k for k in CYCLOID_KEYS if k not in entry]
    if missing:
        raise MotionError(f"{where}: {what}: missing {missing}; a cycloid is {CYCLOID_FORM}")
    c = Cycloid(*(_number(entry[k], f"{what}.{k}", where, f"{k} = 1.0") for k in CYCLOID_KEYS))
    if not c.t1 > c.t0:
        raise MotionError(f"{where}: {what}: t1 = {c.t1:g} s must be later than t0 = {c.t0:g} s")
    if c.t0 < 0:
        raise MotionError(f"{where}: {what}: t0 = {c.t0:g} s is before the simulation starts (t = 0)")
    return c


def _joint_list(names: dict) -> str:
    return ", ".join(f"{i} {names[i]!r}" for i in sorted(names))


def _joint_index(entry: dict, what: str, joints: int, names: dict, where: str) -> int:
    """The joint (1..n) an entry [[joint]] names by ``index`` and/or ``name``."""
    if "index" not in entry and "name" not in entry:
        raise MotionError(
            f"{where}: {what}: give its `index` (1..{joints}, chain order)" + (" or its `name`" if names else "")
        )
    index = None
    if "index" in entry:
        index = entry["index"]
        if not isinstance(index, int) or isinstance(index, bool):
            raise MotionError(
                f"{where}: {what}: index = {index!r}: must be a whole number 1..{joints}, as in index = 1"
            )
        if not 1 <= index <= joints:
            raise MotionError(
                f"{where}: {what}: unknown joint index {index}: the FMU has {joints} joints "
                f"(index 1..{joints}, chain order)"
            )
    if "name" in entry:
        name = entry["name"]
        by_name = {v: i for i, v in names.items()}
        if not names:
            raise MotionError(
                f"{where}: {what}: name = {name!r}: the FMU names no joints; give `index` (1..{joints}, chain order)"
            )
        if not isinstance(name, str):
            raise MotionError(
                f"{where}: {what}: name = {name!r}: must be a joint's name in quotes, as in "
                f'name = "{names[min(names)]}"'
            )
        if name not in by_name:
            raise MotionError(
                f"{where}: {what}: unknown joint name {name!r}; the FMU's joints are {_joint_list(names)}"
            )
        if index is not None and by_name[name] != index:
            raise MotionError(f"{where}: {what}: index = {index} but name = {name!r} is joint {by_name[name]}")
        index = by_name[name]
    return index


def _table_index(key: str, joints: int, names: dict, where: str) -> int:
    """The joint (1..n) a table [joints.<key>] names: a joint name of the FMU, else an index 1..n."""
    by_name = {v: i for i, v in names.items()}
    if key in by_name:
        return by_name[key]
    if key.isascii() and key.isdigit():
        if not 1 <= int(key) <= joints:
            raise MotionError(
                f"{where}: [joints.{key}]: unknown joint index {key}: the FMU has {joints} joints "
                f"(index 1..{joints}, chain order)"
            )
        return int(key)
    if not names:
        raise MotionError(
            f"{where}: [joints.{key}]: unknown joint {key!r}: the FMU names no joints; "
            f"name them by index, [joints.1] .. [joints.{joints}] (chain order)"
        )
    raise MotionError(
        f"{where}: [joints.{key}]: unknown joint {key!r}; the FMU's joints are {_joint_list(names)} "
        f"(or their index 1..{joints})"
    )


def _entries(doc: dict, joints: int, names: dict, where: str) -> list:
    """(what, i, entry) for every per-joint entry of a motion file, in the order written:
    the [[joint]] array (``what`` "[[joint]] #k") and the [joints.<name>] tables."""
    out = []
    entries = doc.get("joint", [])
    if isinstance(entries, dict):
        raise MotionError(
            f"{where}: [joint] is a single table: write [[joint]] (double brackets) before each joint's entry, "
            f"or [joints.<name>] tables"
        )
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise MotionError(
            f"{where}: joint = {entries!r}: must be an array of tables, [[joint]] (double brackets) before each "
            f"joint's entry"
        )
    for k, entry in enumerate(entries, 1):
        what = f"[[joint]] #{k}"
        unknown = [key for key in entry if key not in JOINT_KEYS]
        if unknown:
            raise MotionError(f"{where}: {what}: unknown key(s) {unknown}; a joint has {list(JOINT_KEYS)}")
        out.append((what, _joint_index(entry, what, joints, names, where), entry))
    table = doc.get("joints", {})
    if not isinstance(table, dict):
        return out  # the number of joints, checked by load_motion
    for key, entry in table.items():
        what = f"[joints.{key}]"
        if not isinstance(entry, dict):
            form = f"hold = {entry!r}" if is_finite_number(entry) else f"cycloid = {CYCLOID_FORM} or hold = 0.5"
            raise MotionError(
                f"{where}: joints.{key} = {entry!r}: must be a table of the joint's motion, as in {what} with {form}"
            )
        unknown = [k for k in entry if k not in MOTION_OF_JOINT]
        if unknown:
            raise MotionError(
                f"{where}: {what}: unknown key(s) {unknown}; a [joints.<name>] table has {list(MOTION_OF_JOINT)} "
                f"(the table's name is the joint's)"
            )
        out.append((what, _table_index(key, joints, names, where), entry))
    return out


def _joint_motion(doc: dict, joints: int, names: dict, where: str, stop, settle) -> CycloidMotion:
    segments, hold, seen = [[] for _ in range(joints)], [0.0] * joints, {}
    for given, i, entry in _entries(doc, joints, names, where):
        what = f"joint {i}" + (f" ({names[i]!r})" if i in names else "")
        if i in seen:
            raise MotionError(f"{where}: {what} is given twice ({seen[i]} and {given}); give it once")
        seen[i] = given
        if "cycloid" in entry and "hold" in entry:
            raise MotionError(
                f"{where}: {what}: give either `cycloid` or `hold` (a cycloid starts at its q0 and holds it until t0)"
            )
        if "hold" in entry:
            hold[i - 1] = _number(entry["hold"], f"{what}: hold", where, "hold = 0.5")
        if "cycloid" in entry:
            raw = entry["cycloid"]
            raw = raw if isinstance(raw, list) else [raw]
            if not raw:
                raise MotionError(f"{where}: {what}: cycloid = []: give at least one segment")
            segs = [
                _cycloid(c, f"{what}: cycloid" + (f" #{m}" if len(raw) > 1 else ""), where)
                for m, c in enumerate(raw, 1)
            ]
            for m in range(1, len(segs)):
                a, b = segs[m - 1], segs[m]
                if b.t0 < a.t1:
                    raise MotionError(
                        f"{where}: {what}: cycloid #{m + 1} starts at t0 = {b.t0:g} s, before "
                        f"cycloid #{m} ends (t1 = {a.t1:g} s); segments must follow in time"
                    )
                if b.q0 != a.q1:
                    raise MotionError(
                        f"{where}: {what}: cycloid #{m + 1} starts at q0 = {b.q0!r} but cycloid "
                        f"#{m} ends at q1 = {a.q1!r}; q* would jump"
                    )
            segments[i - 1] = segs
            hold[i - 1] = segs[0].q0
    return CycloidMotion(segments, hold, where, stop, settle)


def _csv_motion(
    path: Path, joints: int, names: dict, where: str, boundary, stop, settle, motors: dict | None = None
) -> SplineMotion:
    """The :class:`SplineMotion` of a CSV. ``motors`` {joint i: start q*} of the FMU's motor
    drives: their torque columns tau_m[i] are taken, and their q_star[i] columns may be left out
    (q* is then constant, the start value given)."""
    motors = motors or {}
    try:
        with open(path, newline="") as f:
            rows = [
                (n, r)
                for n, r in enumerate(csv.reader(f), 1)
                if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")
            ]
    except OSError as e:
        raise MotionError(f"{where}: csv {str(path)!r}: {e.strerror}") from None
    except (UnicodeDecodeError, csv.Error) as e:
        raise MotionError(f"{where}: csv {str(path)!r}: not a CSV text file ({e})") from None
    src = f"{where}: csv {path.name!r}"
    expected = ["t"] + [f"q_star[{i}]" for i in range(1, joints + 1)]
    motor_list = ", ".join(map(str, sorted(motors)))
    torque_columns = ", ".join(f"tau_m[{i}]" for i in sorted(motors))
    if not rows:
        raise MotionError(
            f"{src}: empty; expected a header row {', '.join(expected)} and the samples"
            + (f" (and the motor torques {torque_columns})" if motors else "")
        )
    head, header = rows[0][0], [h.strip() for h in rows[0][1]]
    if not motors and len(header) != joints + 1 and not any(re.fullmatch(r"tau_m\[\d+\]", h) for h in header):
        raise MotionError(
            f"{src}: {len(header)} columns, expected {joints + 1} (t and one per joint of the "
            f"FMU's {joints}): {', '.join(expected)}"
        )
    if header[0] not in ("t", "time"):
        raise MotionError(
            f"{src}: the first column must be the time `t` (s); the header is {header}"
            + (" (a header row is required)" if _is_number(header[0]) else "")
        )
    column_of, torque_of = {}, {}  # joint index -> column of its q_star, of its tau_m
    for col, h in enumerate(header[1:], 1):
        at = f"{src}, line {head}, column {col + 1}"
        torque = re.fullmatch(r"tau_m\[(\d+)\]", h)
        if torque:
            i = int(torque.group(1))
            if i not in motors:
                raise MotionError(
                    f"{at}: {h!r}: joint {i} has no motor drive; "
                    + (
                        f"the FMU's motor drives are on joints {motor_list} ({torque_columns})"
                        if motors
                        else f"the FMU has no motor drives (no input tau_m[i]): the columns are t, then "
                        f"q_star[1]..q_star[{joints}]"
                    )
                )
            if i in torque_of:
                raise MotionError(f"{at}: {h!r} is given twice (columns {torque_of[i] + 1} and {col + 1})")
            torque_of[i] = col
            continue
        m = re.fullmatch(r"q_star\[(\d+)\]", h)
        i = int(m.group(1)) if m else {v: k for k, v in names.items()}.get(h)
        if i is None or not 1 <= i <= joints:
            raise MotionError(
                f"{at}: unknown column {h!r}; the columns are t, then q_star[1]..q_star[{joints}]"
                + (f" or the joint names {[names[k] for k in sorted(names)]}" if names else "")
                + (f", and the motor torques {torque_columns}" if motors else "")
            )
        if i in column_of:
            raise MotionError(f"{at}: joint {i} has two columns ({header[column_of[i]]!r} and {h!r})")
        column_of[i] = col
    missing = [i for i in range(1, joints + 1) if i not in column_of and i not in motors]
    if missing:
        i = missing[0]
        raise MotionError(
            f"{src}, line {head}: no column q_star[{i}]: joint {i} has no motor drive, the motion gives its "
            f"drive position; every such joint needs its column"
            + (
                f" (only a motor joint, {motor_list}, may leave its q_star out: it starts at the FMU's start value)"
                if motors
                else f" ({', '.join(expected)})"
            )
        )
    width = len(header)
    for_row = f"t and {joints} joints" if width == joints + 1 and not torque_of else "the header's columns"
    data = []
    for line, r in rows[1:]:
        if len(r) != width:
            raise MotionError(f"{src}, line {line}: {len(r)} values, expected {width} ({for_row})")
        try:
            values = [float(x) for x in r]
        except ValueError:
            raise MotionError(f"{src}, line {line}: not a number in {r}") from None
        bad = [header[j] for j, x in enumerate(values) if not math.isfinite(x)]
        if bad:
            raise MotionError(
                f"{src}, line {line}: {bad[0]} = {r[header.index(bad[0])].strip()}: must be a finite number"
            )
        data.append((line, values))
    if len(data) < 2:
        raise MotionError(f"{src}: {len(data)} sample(s); a motion needs at least 2")
    for (l0, a), (l1, b) in itertools.pairwise(data):
        if not b[0] > a[0]:
            raise MotionError(
                f"{src}, line {l1}: t = {b[0]!r} s is not later than t = {a[0]!r} s on line {l0}; "
                f"the time column must increase strictly"
            )
    table = np.array([v for _, v in data], dtype=np.float64)
    if len(column_of) == joints:
        q = table[:, [column_of[i] for i in range(1, joints + 1)]]
    else:  # a motor joint without its column: q* constant, its start value
        q = np.column_stack(
            [table[:, column_of[i]] if i in column_of else np.full(len(table), motors[i]) for i in range(1, joints + 1)]
        )
    torques = None
    if torque_of:
        order = sorted(torque_of)
        torques = TorqueSpline(
            table[:, 0], [f"tau_m[{i}]" for i in order], table[:, [torque_of[i] for i in order]], src
        )
    return SplineMotion(table[:, 0], q, src, boundary, stop, settle, torques)


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def load_motion(path, joints: int, names: dict | None = None, motors: dict | None = None):
    """The motion of a motion file (TOML, docs/motion.md) for a chain of ``joints`` joints
    whose URDF names are ``names`` ({index: name}, optional): a :class:`CycloidMotion` or a
    :class:`SplineMotion`, callable as ``motion(t, step)``, with ``joints``, ``end_time``
    (from then on every joint is at rest), ``stop_time`` (the file's `end`, else end_time +
    `settle`) and ``describe()``. ``motors`` ({joint i: start q*}, optional): the joints with a
    motor drive, whose torques tau_m[i] a CSV may give and whose q_star[i] column it may leave
    out (q* is then the start value given). Raises :class:`MotionError` naming the file and the
    problem."""
    path = Path(path)
    names = names or {}
    where = f"motion file {path}"
    if path.suffix.lower() == ".csv":
        raise MotionError(
            f"{where}: a motion file is TOML; for a CSV of t, q_star[1..{joints}] write a file "
            f'motion.toml with the line  csv = "{path.name}"  next to it (docs/motion.md)'
        )
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise MotionError(f"{where}: no such file") from None
    except OSError as e:
        raise MotionError(f"{where}: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise MotionError(f"{where}: not a UTF-8 text file ({e})") from None
    except tomllib.TOMLDecodeError as e:
        raise MotionError(f"{where}: not valid TOML: {e}") from None
    unknown = [k for k in doc if k not in MOTION_KEYS]
    if unknown:
        raise MotionError(f"{where}: unknown key(s) {unknown}; a motion file has {list(MOTION_KEYS)}")
    if "description" in doc and not isinstance(doc["description"], str):
        raise MotionError(
            f'{where}: description = {doc["description"]!r}: must be text in quotes, as in description = "pick"'
        )
    per_joint = "joint" in doc or isinstance(doc.get("joints"), dict)  # [[joint]] entries or [joints.<name>] tables
    if "joints" in doc and not isinstance(doc["joints"], dict):
        count = doc["joints"]
        if not isinstance(count, int) or isinstance(count, bool):
            raise MotionError(
                f"{where}: joints = {count!r}: must be the FMU's number of joints, as in joints = {joints}, "
                f"or a table per joint, as in [joints.{names.get(1, 1)}] with cycloid = {CYCLOID_FORM} or hold = 0.5"
            )
        if count != joints:
            raise MotionError(f"{where}: written for joints = {count!r}, but the FMU has {joints} joints")
    stop = None
    if "end" in doc:
        stop = _number(doc["end"], "end", where, "end = 2.0")
        if stop <= 0:
            raise MotionError(f"{where}: end = {stop:g} s: must be positive")
    settle = _number(doc.get("settle", SETTLE), "settle", where, "settle = 0.5")
    if settle < 0:
        raise MotionError(f"{where}: settle = {settle:g} s: must be >= 0")
    if "csv" in doc:
        if per_joint:
            raise MotionError(f"{where}: give either `csv` or per-joint entries ([[joint]], [joints.<name>]), not both")
        if not isinstance(doc["csv"], str) or not doc["csv"]:
            raise MotionError(
                f'{where}: csv = {doc["csv"]!r}: must be the path of a CSV file, as in csv = "motion.csv"'
            )
        boundary = doc.get("boundary", "not-a-knot")
        if boundary not in BOUNDARIES:
            raise MotionError(f"{where}: boundary = {boundary!r}: must be one of {list(BOUNDARIES)}")
        return _csv_motion(path.parent / doc["csv"], joints, names, where, boundary, stop, settle, motors)
    if "boundary" in doc:
        raise MotionError(f"{where}: `boundary` applies to a `csv` motion only")
    if not per_joint:
        raise MotionError(
            f"{where}: no motion: give [[joint]] entries or [joints.<name>] tables (cycloid or hold), "
            f'or csv = "file.csv"'
        )
    return _joint_motion(doc, joints, names, where, stop, settle)


def load_motion_for(path, md):
    """:func:`load_motion` checked against the FMU whose modelDescription (fmpy) is ``md``: a
    CSV may give the torques tau_m[i] of its motor drives (:func:`motor_joints`; their value
    references set in ``motion.torques.references``) and leave out their q_star[i] columns (q*
    is then the FMU's start value of q_star[i]). Also refused if it moves a joint with a motor
    drive, whose q* the FMU ignores while stepping (a `hold` of it, or a constant column, its
    start position, is taken)."""
    joints, names = fmu_joints(md)
    by_name = {v.name: v for v in md.modelVariables}
    motors = {i: float(by_name[f"q_star[{i}]"].start or 0.0) for i in motor_joints(md) if f"q_star[{i}]" in by_name}
    motion = load_motion(path, joints, names, motors)
    moved = [i for i in moving_joints(motion) if i in motors]
    if moved and isinstance(motion, SplineMotion):
        i = moved[0]
        raise MotionError(
            f"{motion.source}: column q_star[{i}]: joint {i} has a motor drive: the FMU ignores its q_star while "
            f"stepping (it is only the start position), the motor torque tau_m[{i}] drives it; leave the column "
            f"out (joint {i} then starts at the FMU's start value q_star[{i}] = {motors[i]:g}) or make it constant "
            f"(its start position), and give the torque as a column tau_m[{i}]"
        )
    if moved:
        i = moved[0]
        raise MotionError(
            f"{motion.source}: joint {i} has a motor drive: the FMU ignores its q_star while "
            f"stepping (it is only the start position), the motor torque tau_m[{i}] drives it; "
            f"give joint {i} a `hold` (its start position) and set tau_m[{i}] instead"
        )
    torques = getattr(motion, "torques", None)
    if torques is not None:
        torques.references = [by_name[name].valueReference for name in torques.names]
    return motion


def motion_identity(path) -> dict:
    """What identifies a motion file's content: the sha256 of the file, and of the CSV it names.
    A sweep SPEC's older CSV table (``motion = "x.csv"``) keeps its identity {"csv_sha256": ...}."""
    path = Path(path)
    data = path.read_bytes()
    if path.suffix.lower() == ".csv":
        return {"csv_sha256": hashlib.sha256(data).hexdigest()}
    out = {"motion_sha256": hashlib.sha256(data).hexdigest()}
    try:
        name = tomllib.loads(data.decode("utf-8")).get("csv")
    except (UnicodeDecodeError, tomllib.TOMLDecodeError):
        name = None
    if isinstance(name, str) and (path.parent / name).is_file():
        out["csv_sha256"] = hashlib.sha256((path.parent / name).read_bytes()).hexdigest()
    return out


# ---------------------------------------------------------------------------
# the reference motion is for the reference arm only

REFERENCE_MODEL = Path(__file__).resolve().parents[2] / "models" / "reference_rrpr.toml"
KINEMATIC_KEYS = ("type", "theta", "d", "a", "alpha")  # what makes a [[joint]] of a model file the reference arm's


def _kinematics(doc: dict):
    """[(type, theta, d, a, alpha), ...] of a model file's [[joint]] array; None for a model
    without one (a URDF arm's)."""
    joints = doc.get("joint")
    if not isinstance(joints, list) or not all(isinstance(j, dict) for j in joints):
        return None
    return [tuple(j.get(k) for k in KINEMATIC_KEYS) for j in joints]


def _fmu_model(fmu) -> dict:
    """The model file the FMU ``fmu`` (a .fmu file, or the directory it is unpacked in) was built
    from, its resources/model.toml, parsed; OSError, KeyError, zipfile.BadZipFile or
    tomllib.TOMLDecodeError if it cannot be read."""
    fmu = Path(fmu)
    if fmu.is_dir():
        text = (fmu / "resources" / "model.toml").read_text(encoding="utf-8")
    else:
        with zipfile.ZipFile(fmu) as z:
            text = z.read("resources/model.toml").decode("utf-8")
    return tomllib.loads(text)


def reference_motion_refusal(fmu) -> str | None:
    """Why the reference arm's cycloids (:func:`reference_inputs`, the default motion of
    ``stickslip simulate`` and :func:`stickslip.simulate.run`) must not drive the FMU ``fmu`` (a
    .fmu file, or the directory it is unpacked in): None if the model it was built from
    (resources/model.toml) has the reference arm's joints, those of models/reference_rrpr.toml:
    4 joints R R P R with its DH geometry (type, theta, d, a, alpha; the drives may differ, as
    in models/reference_rrpr_motor.toml); else one line saying what it is and what to give
    instead (``--motion MOTION.toml``, and for an FMU with motor drives their tau_m columns)."""
    from fmpy import read_model_description

    from .fmi3 import is_fmi3, scalar_view

    try:
        md = read_model_description(str(fmu))
    except Exception as e:  # noqa: BLE001 -- any unreadable FMU
        return f"{fmu}: not a readable FMU ({' '.join(str(e).split())})"
    if is_fmi3(md):
        md = scalar_view(md)
    joints, _ = fmu_joints(md)
    motors = motor_joints(md)
    try:
        model = _fmu_model(fmu)
        what = None
    except (OSError, KeyError, zipfile.BadZipFile, UnicodeDecodeError) as e:
        model, what = {}, f"it has no readable resources/model.toml ({' '.join(str(e).split())})"
    except tomllib.TOMLDecodeError as e:
        model, what = {}, f"its resources/model.toml is not valid TOML ({' '.join(str(e).split())})"
    reference = tomllib.loads(REFERENCE_MODEL.read_text(encoding="utf-8"))
    if what is None:
        mine, theirs = _kinematics(model), _kinematics(reference)
        name = model.get("name", "?")
        if mine == theirs:
            return None
        if mine is None:
            what = f"its model `{name}` is " + (
                f"a URDF arm of {joints} joints" if "urdf" in model else f"an arm of {joints} joints"
            )
        elif len(mine) != len(theirs) or [j[0] for j in mine] != [j[0] for j in theirs]:
            kinds = " ".join({"revolute": "R", "prismatic": "P"}.get(j[0], "?") for j in mine)
            what = f"its model `{name}` has {len(mine)} joints ({kinds})"
        else:
            i = next(k for k, (a, b) in enumerate(zip(mine, theirs, strict=True), 1) if a != b)
            what = f"its model `{name}` has joint {i} at another place than the reference arm's (theta, d, a, alpha)"
    kinds = " ".join({"revolute": "R", "prismatic": "P"}.get(j[0], "?") for j in _kinematics(reference))
    line = (
        f"{fmu}: {what}, not the reference arm (4 joints {kinds}, models/reference_rrpr.toml) whose cycloids are "
        f"the default motion: give --motion MOTION.toml, a motion of this arm's {joints} joints (docs/motion.md; "
        f"examples/motions/)"
    )
    if motors:
        line += (
            f"; its motor drives on joints {', '.join(map(str, motors))} take their torques from the motion's CSV, "
            f"columns {', '.join(f'tau_m[{i}]' for i in motors)} (or held at --set tau_m[i]=VALUE)"
        )
    return line


def runs_reference_motion(fmu) -> bool:
    """Whether the reference arm's cycloids may drive the FMU ``fmu`` (:func:`reference_motion_refusal`)."""
    return reference_motion_refusal(fmu) is None
