"""Motion files (docs/motion.md): the motion of any chain without writing Python.

* closed forms: a cycloid's q, q', q'' at chosen times to 1e-12; the reference motion written
  as a motion file gives the default inputs bit for bit;
* the CSV spline: exact for polynomials of degree <= 3 on a non-uniform grid (degree 2 is
  what the brief asks; the not-a-knot spline reproduces cubics too); the reference cycloids
  sampled every 10 ms reproduce their rates to 1e-6 and accelerations to 5e-4 of their
  largest values (measured 2.95e-7 and 1.46e-4); SciPy's evaluation of the spline equals the
  hand-written one it replaced to 1e-12 (measured 2.1e-16) and keeps each boundary condition;
* every refusal with its message;
* joints named as in a model file, [joints.<name>] (or [joints.<index>]): the same motion as
  the [[joint]] entries, bit for bit also through the iiwa FMU; one-line refusals for an
  unknown name (listing the FMU's joints), a joint given in both forms, a value of the wrong
  type (with the right form);
* through the real FMU: `stickslip simulate --motion examples/motions/reference.toml` writes
  a CSV byte-identical to the default run's; the sampled reference (CSV, spline) agrees with it
  to 5e-8 m in eps (measured 8.3e-9 m) with the same stiction counts; `stickslip sweep
  --motion` gives the same rows as the SPEC's reference motion; a refused file exits 2.
"""

from __future__ import annotations

import csv
import math
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from helpers import require_fmu
from stickslip import cli
from stickslip import spec as spec_module
from stickslip.motion import (
    Cycloid,
    CycloidMotion,
    MotionError,
    SplineMotion,
    fmu_joints,
    load_motion,
    motion_identity,
    reference_inputs,
)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples" / "motions"
TAU = 2.0 * math.pi


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def cycloid_closed_form(q0, q1, t0, t1, t):
    """q, q', q'' of q0 + (q1 - q0) (tau - sin(2 pi tau) / 2 pi), tau = (t - t0) / (t1 - t0)."""
    if t <= t0:
        return q0, 0.0, 0.0
    if t >= t1:
        return q1, 0.0, 0.0
    d, T = q1 - q0, t1 - t0
    tau = (t - t0) / T
    return (
        q0 + d * (tau - math.sin(TAU * tau) / TAU),
        d * (1.0 - math.cos(TAU * tau)) / T,
        d * TAU * math.sin(TAU * tau) / T**2,
    )


# ---------------------------------------------------------------------------
# closed forms


def test_cycloid_matches_its_closed_form_at_chosen_times():
    q0, q1, t0, t1 = -0.3, 1.2, 0.4, 1.9
    c = Cycloid(q0, q1, t0, t1)
    # tau = 0, 1/8, 1/4 (q'' largest), 1/2 (q' largest), 3/4, 1 and outside
    for t in (0.0, 0.4, 0.5875, 0.775, 1.15, 1.525, 1.9, 2.5):
        got, want = c(t), cycloid_closed_form(q0, q1, t0, t1, t)
        assert np.allclose(got, want, rtol=0, atol=1e-12), (t, got, want)
    # by hand at tau = 1/2: q = q0 + d/2, q' = 2 d / T, q'' = 0
    q, qd, qdd = c(1.15)
    assert abs(q - 0.45) < 1e-12 and abs(qd - 2.0 * 1.5 / 1.5) < 1e-12 and abs(qdd) < 1e-12
    # at tau = 1/4: q' = d / T, q'' = 2 pi d / T^2
    q, qd, qdd = c(0.775)
    assert abs(qd - 1.0) < 1e-12 and abs(qdd - TAU * 1.5 / 1.5**2) < 1e-12


def test_segments_follow_in_time_and_unlisted_joints_hold(tmp_path):
    m = load_motion(
        write(
            tmp_path / "m.toml",
            """
[[joint]]
index = 2
cycloid = [{ q0 = 0.0, q1 = 0.8, t0 = 0.0, t1 = 1.0 }, { q0 = 0.8, q1 = -0.2, t0 = 1.5, t1 = 2.5 }]
[[joint]]
index = 3
hold = 0.2
""",
        ),
        3,
    )
    assert isinstance(m, CycloidMotion) and m.end_time == 2.5 and m.stop_time == 3.0
    for t in (0.0, 0.3, 1.0, 1.2, 1.5, 2.0, 2.5, 3.0):
        q, qd, qdd = m(t)
        want = cycloid_closed_form(0.0, 0.8, 0.0, 1.0, t) if t < 1.5 else cycloid_closed_form(0.8, -0.2, 1.5, 2.5, t)
        assert np.allclose([q[1], qd[1], qdd[1]], want, rtol=0, atol=1e-12), t
        assert (q[0], qd[0], qdd[0]) == (0.0, 0.0, 0.0) and (q[2], qd[2], qdd[2]) == (0.2, 0.0, 0.0)


def test_reference_motion_file_gives_the_default_inputs_bit_for_bit():
    m = load_motion(EXAMPLES / "reference.toml", 4)
    assert m.stop_time == 2.0
    for k in range(2001):
        t = k * 1e-3
        assert m(t, 1e-3) == reference_inputs(t, 1e-3), t


# ---------------------------------------------------------------------------
# the CSV spline


def _csv(path: Path, t, q, header=None) -> Path:
    header = header or ["t"] + [f"q_star[{i}]" for i in range(1, q.shape[1] + 1)]
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in zip(t, *q.T, strict=True):
            w.writerow([repr(float(x)) for x in row])
    return path


def _spline_file(tmp_path, t, q, boundary="not-a-knot", header=None):
    _csv(tmp_path / "m.csv", t, q, header)
    return write(tmp_path / "m.toml", f'csv = "m.csv"\nboundary = "{boundary}"\n')


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_csv_spline_is_exact_for_polynomials_on_a_non_uniform_grid(tmp_path, degree):
    rng = np.random.default_rng(19)
    t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 2.0, 23)), [2.0]])  # steps from ~1e-3 to ~0.3 s
    coefficients = rng.uniform(-1.0, 1.0, (degree + 1, 3))  # 3 joints, q = sum c_p t^p
    poly = lambda x, d=0: sum(c * math.perm(p, d) * x ** (p - d) for p, c in enumerate(coefficients) if p >= d)  # noqa: E731
    q = np.array([poly(x) for x in t])
    m = load_motion(_spline_file(tmp_path, t, q), 3)
    assert isinstance(m, SplineMotion)
    times = np.concatenate([t, 0.5 * (t[1:] + t[:-1]), rng.uniform(0.0, 2.0, 200)])
    err = np.zeros(3)
    for x in times:
        got = m.evaluate(x)
        for d in range(3):
            err[d] = max(err[d], np.max(np.abs(got[d] - poly(x, d))))
    # exact up to rounding, which the smallest step (2.2e-3 s, the largest 0.37 s) amplifies in the
    # derivatives: measured 2.1e-14, 9.0e-13, 2.3e-11 for degree 2 (4.0e-14, 1.7e-12, 4.6e-11 for 3)
    assert err[0] < 1e-12 and err[1] < 2e-11 and err[2] < 5e-10, err


def test_csv_sampled_from_the_reference_cycloids_reproduces_their_rates():
    m = load_motion(EXAMPLES / "reference_sampled.toml", 4)
    assert m.boundary == "rest" and m.stop_time == 2.0
    err, big = np.zeros((3, 4)), np.zeros((3, 4))
    for x in np.arange(0.0, 2.0 + 1e-9, 1e-4):
        got, want = m.evaluate(x), reference_inputs(x)
        for d in range(3):
            err[d] = np.maximum(err[d], np.abs(got[d] - np.array(want[d])))
            big[d] = np.maximum(big[d], np.abs(want[d]))
    rel = (err / big).max(axis=1)
    assert rel[0] < 1e-8 and rel[1] < 1e-6 and rel[2] < 5e-4, rel  # measured 1.3e-9, 2.95e-7, 1.46e-4


def _horner(m: SplineMotion, t: float):
    """q, q', q'' of the spline's piece at t from its coefficients by Horner's rule: the hand-written
    evaluation that SplineMotion had before it let SciPy's CubicSpline evaluate itself."""
    k = min(int(np.searchsorted(m.time, t, side="right")) - 1, len(m.time) - 2)
    c3, c2, c1, c0 = m.spline.c[:, k, :]
    x = t - m.time[k]
    return ((c3 * x + c2) * x + c1) * x + c0, (3.0 * c3 * x + 2.0 * c2) * x + c1, 6.0 * c3 * x + 2.0 * c2


def test_csv_spline_is_scipys_with_the_files_boundary_conditions(tmp_path):
    """SplineMotion's values are those of the hand-written evaluation it replaced, to 1e-12 of the
    largest (measured 2.1e-16 on examples/motions/reference_sampled.toml), and it keeps each
    `boundary`: "rest" (clamped) q' = 0 at the first and last sample; "not-a-knot" the third
    derivative continuous at the second and the last-but-one sample; q, q', q'' continuous at
    every sample."""
    m = load_motion(EXAMPLES / "reference_sampled.toml", 4)
    err, big = np.zeros(3), np.zeros(3)
    for t in np.concatenate([np.arange(0.0, 1.5, 1e-4), m.time]):
        got, old = m.evaluate(t), _horner(m, t)
        for d in range(3):
            err[d] = max(err[d], np.max(np.abs(got[d] - old[d])))
            big[d] = max(big[d], np.max(np.abs(old[d])))
    assert np.all(err <= 1e-12 * big), err / big
    assert np.all(np.abs(m.evaluate(m.time[0])[1]) <= 1e-12 * big[1])
    assert np.all(np.abs(m.evaluate(m.time[-1])[1]) <= 1e-12 * big[1])
    rng = np.random.default_rng(28)
    t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 2.0, 10)), [2.0]])
    for boundary in ("not-a-knot", "rest"):
        m = load_motion(_spline_file(tmp_path, t, rng.normal(size=(len(t), 2)), boundary), 2)
        for x in m.time[1:-1]:  # C2: the pieces left and right of every inner sample meet there
            for d in range(3):
                left, right = m.spline(x - 1e-13 * x, d), m.spline(x, d)
                assert np.allclose(left, right, rtol=1e-9, atol=1e-9), (boundary, x, d)
        third = 6.0 * m.spline.c[0]  # per piece
        if boundary == "not-a-knot":
            assert np.allclose(third[0], third[1], rtol=1e-9) and np.allclose(third[-2], third[-1], rtol=1e-9)
        else:
            assert np.all(m.evaluate(0.0)[1] == 0.0) and np.allclose(m.evaluate(2.0)[1], 0.0, atol=1e-12)


def test_csv_holds_outside_its_samples_and_takes_joint_names(tmp_path):
    t = np.array([0.5, 1.0, 1.5, 2.0])
    q = np.array([[1.0, 2.0], [1.5, 2.0], [2.5, 2.5], [3.0, 3.0]])
    _csv(tmp_path / "m.csv", t, q[:, ::-1], ["time", "elbow", "q_star[1]"])
    m = load_motion(write(tmp_path / "m.toml", 'csv = "m.csv"\n'), 2, {2: "elbow"})
    assert m(0.0) == ([1.0, 2.0], [0.0, 0.0], [0.0, 0.0])
    assert m(2.5) == ([3.0, 3.0], [0.0, 0.0], [0.0, 0.0])
    assert np.allclose(m(1.0)[0], [1.5, 2.0], rtol=0, atol=1e-15)
    assert m.stop_time == 2.5


def test_joint_names_from_the_fmu_descriptions(tmp_path):
    def var(name, i, extra):
        return SimpleNamespace(
            name=name,
            causality="input",
            description=f"Prescribed position of joint {i} ({extra}), at the start of the step",
        )

    md = SimpleNamespace(
        modelVariables=[
            var("q_star[1]", 1, "`iiwa_joint_1`"),
            var("q_star[2]", 2, "`iiwa_joint_2`, revolute, flexible drive"),
            var("q_star[3]", 3, "revolute, rigid drive"),
            var("qd_star[1]", 1, "`iiwa_joint_1`"),
        ]
    )
    md.modelVariables.append(
        SimpleNamespace(
            name="q_star[4]", causality="input", description="Position of joint 4 `iiwa_joint_4` (revolute)"
        )
    )
    joints, names = fmu_joints(md)
    assert joints == 4 and names == {1: "iiwa_joint_1", 2: "iiwa_joint_2", 4: "iiwa_joint_4"}
    m = load_motion(
        write(
            tmp_path / "m.toml",
            """
[[joint]]
name = "iiwa_joint_2"
cycloid = { q0 = 0.0, q1 = 1.0, t0 = 0.0, t1 = 1.0 }
""",
        ),
        joints,
        names,
    )
    assert m(0.5)[0] == [0.0, 0.5, 0.0, 0.0]


def test_reference_fmu_has_four_unnamed_joints():
    from fmpy import read_model_description

    assert fmu_joints(read_model_description(str(require_fmu()))) == (4, {})


# ---------------------------------------------------------------------------
# refusals

CYC = "cycloid = { q0 = 0.0, q1 = 1.0, t0 = 0.0, t1 = 1.0 }"
REFUSED_TOML = {
    "unknown joint index": (
        f"[[joint]]\nindex = 5\n{CYC}\n",
        "[[joint]] #1: unknown joint index 5: the FMU has 4 joints",
    ),
    "index zero": (f"[[joint]]\nindex = 0\n{CYC}\n", "unknown joint index 0"),
    "index not a number": (f'[[joint]]\nindex = "2"\n{CYC}\n', "index = '2': must be a whole number 1..4"),
    "no index": (f"[[joint]]\n{CYC}\n", "[[joint]] #1: give its `index` (1..4, chain order)"),
    "t1 equal t0": (
        "[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = 1.0, t0 = 1.0, t1 = 1.0 }\n",
        "joint 1: cycloid: t1 = 1 s must be later than t0 = 1 s",
    ),
    "t1 before t0": (
        "[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = 1.0, t0 = 1.0, t1 = 0.5 }\n",
        "t1 = 0.5 s must be later than t0 = 1 s",
    ),
    "t0 negative": (
        "[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = 1.0, t0 = -1.0, t1 = 0.5 }\n",
        "t0 = -1 s is before the simulation starts",
    ),
    "nan in a cycloid": (
        "[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = nan, t0 = 0.0, t1 = 1.0 }\n",
        "joint 1: cycloid.q1 = nan: must be a finite number",
    ),
    "inf hold": ("[[joint]]\nindex = 1\nhold = inf\n", "joint 1: hold = inf: must be a finite number"),
    "cycloid key missing": (
        "[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = 1.0, t1 = 1.0 }\n",
        "joint 1: cycloid: missing ['t0']",
    ),
    "cycloid key unknown": (
        "[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = 1.0, t0 = 0.0, t1 = 1.0, T = 2 }\n",
        "joint 1: cycloid: unknown key(s) ['T']",
    ),
    "joint twice": (
        f"[[joint]]\nindex = 2\n{CYC}\n[[joint]]\nindex = 2\nhold = 1.0\n",
        "joint 2 is given twice ([[joint]] #1 and [[joint]] #2); give it once",
    ),
    "cycloid and hold": (f"[[joint]]\nindex = 1\nhold = 0.3\n{CYC}\n", "joint 1: give either `cycloid` or `hold`"),
    "segments overlap": (
        "[[joint]]\nindex = 1\ncycloid = [{ q0 = 0.0, q1 = 1.0, t0 = 0.0, t1 = 1.0 }, "
        "{ q0 = 1.0, q1 = 0.0, t0 = 0.9, t1 = 2.0 }]\n",
        "cycloid #2 starts at t0 = 0.9 s, before cycloid #1 ends (t1 = 1 s)",
    ),
    "segments jump": (
        "[[joint]]\nindex = 1\ncycloid = [{ q0 = 0.0, q1 = 1.0, t0 = 0.0, t1 = 1.0 }, "
        "{ q0 = 0.5, q1 = 0.0, t0 = 1.0, t1 = 2.0 }]\n",
        "cycloid #2 starts at q0 = 0.5 but cycloid #1 ends at q1 = 1.0; q* would jump",
    ),
    "unknown joint key": (f"[[joint]]\nindex = 1\n{CYC}\nspeed = 2\n", "[[joint]] #1: unknown key(s) ['speed']"),
    "unknown top key": (f"duration = 2\n[[joint]]\nindex = 1\n{CYC}\n", "unknown key(s) ['duration']"),
    "joints mismatch": (
        f"joints = 7\n[[joint]]\nindex = 1\n{CYC}\n",
        "written for joints = 7, but the FMU has 4 joints",
    ),
    "name without names": (f'[[joint]]\nname = "shoulder"\n{CYC}\n', "name = 'shoulder': the FMU names no joints"),
    "no motion": ('description = "nothing"\n', "no motion: give [[joint]] entries"),
    "csv and joints": (f'csv = "m.csv"\n[[joint]]\nindex = 1\n{CYC}\n', "give either `csv` or per-joint entries"),
    "boundary unknown": (
        'csv = "m.csv"\nboundary = "natural"\n',
        "boundary = 'natural': must be one of ['not-a-knot', 'rest']",
    ),
    "boundary without csv": (
        f'boundary = "rest"\n[[joint]]\nindex = 1\n{CYC}\n',
        "`boundary` applies to a `csv` motion only",
    ),
    "end not positive": (f"end = 0\n[[joint]]\nindex = 1\n{CYC}\n", "end = 0 s: must be positive"),
    "not TOML": ("[[joint]]\nindex = \n", "not valid TOML"),
    "csv file missing": ('csv = "nope.csv"\n', "csv 'nope.csv': No such file or directory"),
}


@pytest.mark.parametrize("case", list(REFUSED_TOML))
def test_motion_file_refused(tmp_path, case):
    text, message = REFUSED_TOML[case]
    write(tmp_path / "m.csv", "t,q_star[1],q_star[2],q_star[3],q_star[4]\n0,0,0,0,0\n1,1,1,1,1\n")
    if case == "csv file missing":
        (tmp_path / "m.csv").unlink()
        text = text.replace("nope.csv", "m.csv")
        message = message.replace("nope.csv", str(tmp_path / "m.csv"))
    path = write(tmp_path / "m.toml", text)
    with pytest.raises(MotionError) as e:
        load_motion(path, 4)
    assert f"motion file {path}" in str(e.value)
    assert message in str(e.value), str(e.value)


HEAD4 = "t,q_star[1],q_star[2],q_star[3],q_star[4]\n"
REFUSED_CSV = {
    "non-monotone time": (
        HEAD4 + "0,0,0,0,0\n0.2,1,1,1,1\n0.1,2,2,2,2\n",
        "line 4: t = 0.1 s is not later than t = 0.2 s on line 3; the time column must increase",
    ),
    "repeated time": (HEAD4 + "0,0,0,0,0\n0.2,1,1,1,1\n0.2,2,2,2,2\n", "line 4: t = 0.2 s is not later than t = 0.2 s"),
    "nan value": (HEAD4 + "0,0,0,0,0\n0.2,1,nan,1,1\n", "line 3: q_star[2] = nan: must be a finite number"),
    "nan time": (HEAD4 + "0,0,0,0,0\nNaN,1,1,1,1\n", "line 3: t = NaN: must be a finite number"),
    "empty value": (HEAD4 + "0,0,0,0,0\n0.2,1,,1,1\n", "line 3: not a number in"),
    "too few columns": (
        "t,q_star[1],q_star[2],q_star[3]\n0,0,0,0\n1,1,1,1\n",
        "4 columns, expected 5 (t and one per joint of the FMU's 4)",
    ),
    "too many columns": (HEAD4.strip() + ",q_star[5]\n0,0,0,0,0,0\n1,1,1,1,1,1\n", "6 columns, expected 5"),
    "short row": (HEAD4 + "0,0,0,0,0\n1,1,1,1\n", "line 3: 4 values, expected 5 (t and 4 joints)"),
    "no header": ("0,0,0,0,0\n1,1,1,1,1\n", "the first column must be the time `t` (s); the header is"),
    "unknown column": ("t,q_star[1],q_star[2],q3,q_star[4]\n0,0,0,0,0\n1,1,1,1,1\n", "unknown column 'q3'"),
    "column twice": ("t,q_star[1],q_star[2],q_star[2],q_star[4]\n0,0,0,0,0\n1,1,1,1,1\n", "joint 2 has two columns"),
    "one sample": (HEAD4 + "0,0,0,0,0\n", "1 sample(s); a motion needs at least 2"),
    "empty": ("", "empty; expected a header row t, q_star[1], q_star[2], q_star[3], q_star[4]"),
}


@pytest.mark.parametrize("case", list(REFUSED_CSV))
def test_motion_csv_refused(tmp_path, case):
    text, message = REFUSED_CSV[case]
    write(tmp_path / "m.csv", text)
    path = write(tmp_path / "m.toml", 'csv = "m.csv"\n')
    with pytest.raises(MotionError) as e:
        load_motion(path, 4)
    assert f"motion file {path}: csv 'm.csv'" in str(e.value)
    assert message in str(e.value), str(e.value)


MOTORS = {1: 0.0, 3: 0.8}  # the motor joints of a 4-joint FMU like reference_rrpr_motor, their start q*
HEAD_MOTOR = "t,q_star[2],q_star[4],tau_m[1],tau_m[3]\n"
REFUSED_TORQUE_CSV = {  # with motor drives on joints 1 and 3 (None: on no joint)
    "tau_m of a joint without motor drive": (
        MOTORS,
        "t,q_star[2],q_star[4],tau_m[2]\n0,0,0,0\n1,1,1,1\n",
        "line 1, column 4: 'tau_m[2]': joint 2 has no motor drive; the FMU's motor drives are on joints 1, 3 "
        "(tau_m[1], tau_m[3])",
    ),
    "tau_m without motor drives": (
        None,
        HEAD4.strip() + ",tau_m[1]\n0,0,0,0,0,0\n1,1,1,1,1,1\n",
        "line 1, column 6: 'tau_m[1]': joint 1 has no motor drive; the FMU has no motor drives (no input "
        "tau_m[i]): the columns are t, then q_star[1]..q_star[4]",
    ),
    "unknown column": (
        MOTORS,
        "t,q_star[2],q_star[4],torque[1]\n0,0,0,0\n1,1,1,1\n",
        "line 1, column 4: unknown column 'torque[1]'; the columns are t, then q_star[1]..q_star[4], and the "
        "motor torques tau_m[1], tau_m[3]",
    ),
    "torque twice": (
        MOTORS,
        "t,q_star[2],q_star[4],tau_m[1],tau_m[1]\n0,0,0,0,0\n1,1,1,1,1\n",
        "line 1, column 5: 'tau_m[1]' is given twice (columns 4 and 5)",
    ),
    "nan torque": (
        MOTORS,
        HEAD_MOTOR + "0,0,0,0,0\n0.2,1,1,NaN,1\n",
        "line 3: tau_m[1] = NaN: must be a finite number",
    ),
    "inf torque": (MOTORS, HEAD_MOTOR + "0,0,0,0,0\n0.2,1,1,1,-inf\n", "line 3: tau_m[3] = -inf: must be a finite"),
    "missing q_star of a rigid joint": (
        MOTORS,
        "t,q_star[2],tau_m[1]\n0,0,0\n1,1,1\n",
        "line 1: no column q_star[4]: joint 4 has no motor drive, the motion gives its drive position; every such "
        "joint needs its column (only a motor joint, 1, 3, may leave its q_star out",
    ),
    "short row": (MOTORS, HEAD_MOTOR + "0,0,0,0,0\n1,1,1,1\n", "line 3: 4 values, expected 5 (the header's columns)"),
}


@pytest.mark.parametrize("case", list(REFUSED_TORQUE_CSV))
def test_motion_csv_with_torques_refused(tmp_path, case):
    motors, text, message = REFUSED_TORQUE_CSV[case]
    write(tmp_path / "m.csv", text)
    path = write(tmp_path / "m.toml", 'csv = "m.csv"\n')
    with pytest.raises(MotionError) as e:
        load_motion(path, 4, None, motors)
    assert f"motion file {path}: csv 'm.csv'" in str(e.value)
    assert message in str(e.value), str(e.value)


def test_motion_csv_gives_motor_torques_and_motor_joints_may_leave_out_q_star(tmp_path):
    """Columns in any order; a motor joint without a q_star column holds its start value (0.8
    for joint 3) with zero rates; a motor joint with a constant one holds that; the torques are
    a not-a-knot spline: exact for a cubic in t, held outside the samples."""
    t = [0.0, 0.05, 0.12, 0.2, 0.31, 0.4]
    cubic = lambda x: 0.2 - 0.5 * x + 3.0 * x**2 - 4.0 * x**3  # noqa: E731
    rows = [f"{x!r},{0.3 * x!r},{cubic(x)!r},0.25,{-x!r},-0.1" for x in t]
    write(tmp_path / "m.csv", "time,q_star[2],tau_m[1],q_star[1],q_star[4],tau_m[3]\n" + "\n".join(rows) + "\n")
    m = load_motion(write(tmp_path / "m.toml", 'csv = "m.csv"\n'), 4, None, MOTORS)
    assert isinstance(m, SplineMotion) and m.torques.names == ["tau_m[1]", "tau_m[3]"]
    assert "motor torques tau_m[1], tau_m[3]" in m.describe()
    for x in (0.0, 0.07, 0.2, 0.33):
        q, qd, qdd = m(x)
        assert (q[0], q[2], qd[0], qd[2], qdd[0], qdd[2]) == (0.25, 0.8, 0.0, 0.0, 0.0, 0.0)
        assert abs(q[1] - 0.3 * x) < 1e-14 and abs(q[3] + x) < 1e-14
        value, rate, accel = m.torques(x)
        assert abs(value[0] - cubic(x)) < 1e-14 and abs(rate[0] - (-0.5 + 6.0 * x - 12.0 * x**2)) < 1e-12
        assert abs(accel[0] - (6.0 - 24.0 * x)) < 1e-11
        assert (value[1], rate[1], accel[1]) == (-0.1, 0.0, 0.0)
    value, rate, accel = m.torques(0.5)
    assert value[0] == cubic(0.4) and rate[0] == 0.0 and accel[0] == 0.0
    assert m.torques.references is None  # bound to an FMU by load_motion_for


def test_a_torque_motion_binds_to_the_fmus_value_references(tmp_path):
    """load_motion_for takes the motor joints and their start q* from the modelDescription and
    sets the torques' value references."""
    from stickslip.motion import load_motion_for

    variables = [
        SimpleNamespace(
            name=f"{g}[{i}]",
            causality="input",
            description="",
            start="0.8" if (g, i) == ("q_star", 3) else "0",
            valueReference=10 * k + i,
        )
        for k, g in enumerate(("q_star", "qd_star", "qdd_star"))
        for i in range(1, 5)
    ] + [
        SimpleNamespace(name=f"tau_m[{i}]", causality="input", description="", start="0", valueReference=90 + i)
        for i in (1, 3)
    ]
    md = SimpleNamespace(modelVariables=variables)
    write(tmp_path / "m.csv", HEAD_MOTOR + "0,0,0,0,0\n1,1,1,1,1\n")
    m = load_motion_for(write(tmp_path / "m.toml", 'csv = "m.csv"\n'), md)
    assert m.torques.references == [91, 93] and m(0.5)[0][2] == 0.8


def test_missing_motion_file_and_csv_given_directly_are_refused(tmp_path):
    with pytest.raises(MotionError, match=r"motion file .*no\.toml: no such file"):
        load_motion(tmp_path / "no.toml", 4)
    path = write(tmp_path / "traj.csv", HEAD4 + "0,0,0,0,0\n1,1,1,1,1\n")
    with pytest.raises(MotionError, match=r'a motion file is TOML; .* csv = "traj.csv"'):
        load_motion(path, 4)


def test_named_joint_refusals(tmp_path):
    names = {1: "a", 2: "b"}
    path = write(tmp_path / "m.toml", f'[[joint]]\nname = "c"\n{CYC}\n')
    with pytest.raises(MotionError, match="unknown joint name 'c'; the FMU's joints are 1 'a', 2 'b'"):
        load_motion(path, 2, names)
    path = write(tmp_path / "m.toml", f'[[joint]]\nindex = 1\nname = "b"\n{CYC}\n')
    with pytest.raises(MotionError, match="index = 1 but name = 'b' is joint 2"):
        load_motion(path, 2, names)


# ---------------------------------------------------------------------------
# [joints.<name>]: the model file's form


JOINTS_BY_NAME = """
[joints.b]
cycloid = [{ q0 = 0.3, q1 = 0.9, t0 = 0.0, t1 = 1.0 }, { q0 = 0.9, q1 = 0.3, t0 = 1.5, t1 = 2.5 }]

[joints.3]
hold = -1.5
"""
JOINTS_BY_ENTRY = """
[[joint]]
name = "b"
cycloid = [{ q0 = 0.3, q1 = 0.9, t0 = 0.0, t1 = 1.0 }, { q0 = 0.9, q1 = 0.3, t0 = 1.5, t1 = 2.5 }]

[[joint]]
index = 3
hold = -1.5
"""


def test_joints_tables_give_the_same_motion_as_joint_entries(tmp_path):
    """[joints.<name>] (by name, or by index where the FMU names none) is the [[joint]] entry's motion."""
    names = {1: "a", 2: "b", 3: "c"}
    tables = load_motion(write(tmp_path / "tables.toml", JOINTS_BY_NAME), 3, names)
    entries = load_motion(write(tmp_path / "entries.toml", JOINTS_BY_ENTRY), 3, names)
    assert tables.stop_time == entries.stop_time == 3.0
    for t in np.arange(0.0, 3.0, 1e-3):
        assert tables(t) == entries(t), t
    assert tables(0.5)[0][2] == -1.5 and tables(0.5)[0][0] == 0.0
    # the two forms side by side, for different joints
    mixed = load_motion(
        write(tmp_path / "mixed.toml", "[[joint]]\nindex = 3\nhold = -1.5\n[joints.b]\n" + CYC), 3, names
    )
    assert mixed(0.5)[0] == [0.0, 0.5 - math.sin(TAU * 0.5) / TAU, -1.5]


REFUSED_JOINTS = {
    "unknown name": (
        f"[joints.elbow]\n{CYC}\n",
        "[joints.elbow]: unknown joint 'elbow'; the FMU's joints are 1 'a', 2 'b', 3 'c' (or their index 1..3)",
    ),
    "index out of range": (f"[joints.4]\n{CYC}\n", "[joints.4]: unknown joint index 4: the FMU has 3 joints"),
    "both forms for one joint": (
        f'[[joint]]\nname = "b"\nhold = 0.1\n[joints.b]\n{CYC}\n',
        "joint 2 ('b') is given twice ([[joint]] #1 and [joints.b]); give it once",
    ),
    "name and index for one joint": (
        f"[joints.2]\nhold = 0.1\n[joints.b]\n{CYC}\n",
        "joint 2 ('b') is given twice ([joints.2] and [joints.b])",
    ),
    "not a table": (
        "[joints]\nb = 0.5\n",
        "joints.b = 0.5: must be a table of the joint's motion, as in [joints.b] with hold = 0.5",
    ),
    "name inside": (
        f'[joints.b]\nname = "b"\n{CYC}\n',
        "[joints.b]: unknown key(s) ['name']; a [joints.<name>] table has ['cycloid', 'hold'] (the table's name",
    ),
    "joints count of the wrong type": (
        f'joints = "3"\n[[joint]]\nindex = 1\n{CYC}\n',
        "joints = '3': must be the FMU's number of joints, as in joints = 3, or a table per joint, "
        "as in [joints.a] with cycloid = { q0 = ..., q1 = ..., t0 = ..., t1 = ... } or hold = 0.5",
    ),
    "hold not a number": (
        '[joints.a]\nhold = "up"\n',
        "joint 1 ('a'): hold = 'up': must be a finite number, as in hold = 0.5",
    ),
    "cycloid not a table": (
        "[joints.a]\ncycloid = 1.0\n",
        "joint 1 ('a'): cycloid = 1.0: must be a table { q0 = ..., q1 = ...",
    ),
    "cycloid value not a number": (
        "[joints.a]\ncycloid = { q0 = 0.0, q1 = '1', t0 = 0.0, t1 = 1.0 }\n",
        "joint 1 ('a'): cycloid.q1 = '1': must be a finite number, as in q1 = 1.0",
    ),
    "name not a string": (
        f"[[joint]]\nname = 2\n{CYC}\n",
        'name = 2: must be a joint\'s name in quotes, as in name = "a"',
    ),
    "joint a single table": (
        f"[joint]\nindex = 1\n{CYC}\n",
        "[joint] is a single table: write [[joint]] (double brackets)",
    ),
    "csv and joints tables": (f'csv = "m.csv"\n[joints.a]\n{CYC}\n', "give either `csv` or per-joint entries"),
}


@pytest.mark.parametrize("case", list(REFUSED_JOINTS))
def test_joints_tables_refused(tmp_path, case):
    text, message = REFUSED_JOINTS[case]
    path = write(tmp_path / "m.toml", text)
    with pytest.raises(MotionError) as e:
        load_motion(path, 3, {1: "a", 2: "b", 3: "c"})
    assert str(e.value).startswith(f"motion file {path}: ") and "\n" not in str(e.value)
    assert message in str(e.value), str(e.value)


def test_joints_tables_by_index_on_an_fmu_without_names(tmp_path):
    path = write(tmp_path / "m.toml", f"[joints.2]\n{CYC}\n")
    assert load_motion(path, 4)(0.5)[0][1] == 0.5 - math.sin(TAU * 0.5) / TAU
    path = write(tmp_path / "m.toml", f"[joints.shoulder]\n{CYC}\n")
    with pytest.raises(
        MotionError,
        match=r"unknown joint 'shoulder': the FMU names no joints; name them by index, \[joints.1\] .. \[joints.4\]",
    ):
        load_motion(path, 4)


def test_the_xarm6_example_in_the_model_files_form_equals_its_joint_entries(tmp_path):
    """examples/motions/xarm6.toml names its joints as its model file does, [joints.jointN]; written
    back as [[joint]] entries with `name`, the motion is the same at every millisecond."""
    names = {i: f"joint{i}" for i in range(1, 7)}
    source = (EXAMPLES / "xarm6.toml").read_text(encoding="utf-8")
    entries = re.sub(r"\[joints\.(\w+)\]", r'[[joint]]\nname = "\1"', source)
    assert source.count("\n[joints.joint") == 4 and "\n[joints." not in entries
    tables, joint = (
        load_motion(EXAMPLES / "xarm6.toml", 6, names),
        load_motion(write(tmp_path / "x.toml", entries), 6, names),
    )
    assert tables.stop_time == joint.stop_time == 2.0
    assert all(tables(t) == joint(t) for t in np.arange(0.0, 2.0005, 1e-3))


def _as_joints_tables(text: str) -> str:
    """A motion file's [[joint]] entries with `name = "X"` rewritten as [joints.X] tables."""
    return re.sub(r'\[\[joint\]\]\nname = "([^"]+)"[^\n]*\n', r"[joints.\1]\n", text)


@pytest.fixture(scope="module")
def iiwa_fmu():
    from urdf_fmus import require_iiwa_fmu

    return require_iiwa_fmu()


def test_joints_tables_through_the_iiwa_fmu_equal_joint_entries(iiwa_fmu, tmp_path):
    """examples/motions/kuka_iiwa.toml (its joints by `name` in [[joint]] entries) and the same
    motion as [joints.lbr_iiwa_joint_i] tables, the model file's form: the same outputs bit for bit."""
    from stickslip.simulate import run

    source = (EXAMPLES / "kuka_iiwa.toml").read_text(encoding="utf-8")
    tables = _as_joints_tables(source).replace("joints = 7\n", "")  # `joints` is now the table of joints
    assert "[[joint]]" not in tables and tables.count("[joints.lbr_iiwa_joint_") == 4
    path = write(tmp_path / "kuka_iiwa.toml", tables)
    a, b = run(iiwa_fmu, 0.3, 1e-3, motion=EXAMPLES / "kuka_iiwa.toml"), run(iiwa_fmu, 0.3, 1e-3, motion=path)
    assert list(a) == list(b) and len(a["time"]) == 301
    assert all(a[k] == b[k] for k in a)
    assert b["q[4]"][-1] > b["q[4]"][0] + 1e-3  # the elbow opens


def test_joints_tables_refused_naming_the_iiwa_joints(iiwa_fmu, tmp_path):
    from fmpy import read_model_description

    from stickslip.motion import load_motion_for

    md = read_model_description(str(iiwa_fmu))
    path = write(tmp_path / "m.toml", f"[joints.shoulder_lift_joint]\n{CYC}\n")
    with pytest.raises(MotionError) as e:
        load_motion_for(path, md)
    names = ", ".join(f"{i} 'lbr_iiwa_joint_{i}'" for i in range(1, 8))
    assert f"[joints.shoulder_lift_joint]: unknown joint 'shoulder_lift_joint'; the FMU's joints are {names}" in str(
        e.value
    )


# ---------------------------------------------------------------------------
# through the FMU


@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    """A private copy of the FMU under test: runs compared with each other use the same bytes
    even if target/fmu is rebuilt meanwhile."""
    copy = tmp_path_factory.mktemp("fmu") / "StickSlipManipulator.fmu"
    shutil.copyfile(require_fmu(), copy)
    return copy


@pytest.fixture(scope="module")
def default_run(fmu, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("default") / "reference.csv"
    assert cli.main(["simulate", "--fmu", str(fmu), "--out", str(out)]) == 0
    return out


def _read(path: Path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=np.float64)


def test_simulate_with_the_reference_motion_file_is_bit_identical_to_the_default(fmu, default_run, tmp_path):
    out = tmp_path / "via_file.csv"
    assert (
        cli.main(["simulate", "--fmu", str(fmu), "--motion", str(EXAMPLES / "reference.toml"), "--out", str(out)]) == 0
    )
    assert out.read_bytes() == default_run.read_bytes()
    _, data = _read(out)
    assert len(data) == 2001 and data[-1, 0] == 2.0


def test_simulate_with_the_sampled_reference_agrees_with_the_default(fmu, default_run, tmp_path):
    out = tmp_path / "sampled.csv"
    assert (
        cli.main(
            ["simulate", "--fmu", str(fmu), "--motion", str(EXAMPLES / "reference_sampled.toml"), "--out", str(out)]
        )
        == 0
    )
    (h0, a), (h1, b) = _read(default_run), _read(out)
    assert h0 == h1 and a.shape == b.shape
    col = {n: j for j, n in enumerate(h0)}
    assert np.max(np.abs(a[:, col["eps"]] - b[:, col["eps"]])) < 5e-8  # m; measured 8.3e-9 (max eps 2.0e-4)
    for j in (1, 3):
        assert np.max(np.abs(a[:, col[f"q[{j}]"]] - b[:, col[f"q[{j}]"]])) < 5e-8  # measured 6.4e-9, 9.6e-9
        assert a[-1, col[f"n_stick[{j}]"]] == b[-1, col[f"n_stick[{j}]"]]


def test_simulate_refuses_a_bad_motion_file_with_exit_2(fmu, tmp_path, capsys):
    bad = write(tmp_path / "bad.toml", f"[[joint]]\nindex = 7\n{CYC}\n")
    out = tmp_path / "out.csv"
    assert cli.main(["simulate", "--fmu", str(fmu), "--motion", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"stickslip simulate: motion file {bad}: [[joint]] #1: unknown joint index 7: the FMU has 4 joints" in err
    assert not out.exists()


def test_simulate_api_takes_a_motion_path(fmu):
    from stickslip.simulate import run

    r = run(fmu, None, 1e-3, motion=EXAMPLES / "pick_and_return.toml")
    assert abs(r["time"][-1] - 3.0) < 1e-12  # the motion's end 2.4 s plus its settle 0.6 s
    q1 = np.array(r["q[1]"])
    assert q1.max() > 0.79 and abs(q1[-1]) < 1e-3  # out to 0.8 rad and back


def test_sweep_spec_takes_a_motion_file_identified_with_its_csv(fmu, tmp_path):
    from stickslip.sweep import _motion

    spec_path = write(
        tmp_path / "spec.toml",
        f'stop_time = 0.1\ncommunication_step = 1e-3\nfmu = "{fmu}"\n[grid]\n"mu_k[3]" = [0.1, 0.2]\n',
    )
    motion = tmp_path / "m" / "sampled.toml"
    shutil.copytree(EXAMPLES, motion.parent)
    (motion.parent / "reference_sampled.toml").rename(motion)
    s = spec_module.load(spec_path, {"motion": str(motion)})
    assert s.motion == str(motion)
    from fmpy import read_model_description

    assert isinstance(_motion(s, read_model_description(str(fmu))), SplineMotion)
    before = s.digest()
    assert set(motion_identity(motion)) == {"motion_sha256", "csv_sha256"}
    csv_path = motion.parent / "reference_sampled.csv"
    csv_path.write_text(csv_path.read_text() + "1.6,1.0471975511965976,0.2617993877991494,1.0,1.5707963267948966\n")
    assert s.digest() != before  # a changed CSV is another sweep
    seven = spec_module.load(spec_path, {"motion": str(EXAMPLES / "seven_joints.toml")})
    with pytest.raises(spec_module.SpecError, match="written for joints = 7, but the FMU has 4 joints"):
        _motion(seven, read_model_description(str(fmu)))


@pytest.mark.full  # a Dask cluster
def test_sweep_with_the_reference_motion_file_gives_the_reference_rows(fmu, tmp_path):
    import pandas as pd

    spec_path = write(
        tmp_path / "spec.toml",
        f'stop_time = 0.2\ncommunication_step = 1e-3\nmotion = "reference"\n'
        f'fmu = "{fmu}"\n[grid]\n"mu_k[3]" = [0.1, 0.2]\n',
    )
    args = ["sweep", str(spec_path), "--workers", "1"]
    assert cli.main([*args, "--out", str(tmp_path / "a")]) == 0
    assert cli.main([*args, "--out", str(tmp_path / "b"), "--motion", str(EXAMPLES / "reference.toml")]) == 0
    a, b = (pd.read_parquet(tmp_path / d / "results.parquet").sort_values("run").reset_index(drop=True) for d in "ab")
    same = [c for c in a.columns if c not in ("wall_s", "cpu_s", "worker", "finished")]
    assert (a["status"] == "ok").all()
    pd.testing.assert_frame_equal(a[same], b[same])
