"""`stickslip simulate` with measured motor torques, and no silent default motion (issue 36).

* a motion CSV with tau_m[i] columns for the motor drives (docs/motion.md): the torque spline is
  the fit's (:class:`stickslip.fit.spec.Torques`) bit for bit; through `stickslip simulate` on
  the motor FMU (models/reference_rrpr_motor.toml) the outputs equal those of driving the FMU
  with fmpy directly, with SciPy's not-a-knot splines of the same samples set as value and
  first two derivatives (fmi2SetRealInputDerivatives orders 1 and 2) at every communication
  point (1e-12 relative; measured: equal), and differ from a run without the derivatives (so
  the comparison can fail); a constant-torque CSV writes the CSV of `--set tau_m[i]=...`
  byte for byte;
* malformed inputs (an unknown column, tau_m of a joint without a motor drive, on an FMU
  without any, a NaN torque, a missing q_star of a rigid joint, a moving q_star of a motor
  joint, a `--set tau_m[i]` the motion gives too) end `stickslip simulate` with exit 2, one line
  naming the problem, and no CSV;
* without --motion only an FMU with the reference arm's joints runs (the reference FMU and its
  motor variant, as before); the KUKA iiwa and xArm 6 FMUs, and the reference FMU repacked with
  another model file, exit 2 with one line naming --motion, docs/motion.md (and for motor drives
  the tau_m columns) and write no CSV; `simulate.run` refuses them with ValueError; the xArm 6
  with its example motion runs.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT, Slave, read_csv, require_fmu
from stickslip import cli

INTERVAL = 1e-3
EXAMPLES = ROOT / "examples" / "motions"
SAMPLE = 4e-3  # s, the logged torques' sample time
SAMPLES = 76  # t = 0 .. 0.3 s
END = 0.35  # s: past the last sample, where the torques hold their last value


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def write_csv(path: Path, header: list, columns: list) -> Path:
    rows = [",".join(header)] + [",".join(repr(float(c[k])) for c in columns) for k in range(len(columns[0]))]
    return write(path, "\n".join(rows) + "\n")


def samples():
    """t and the logged columns: q_star[2], q_star[4] (rigid joints: set points), tau_m[1],
    tau_m[3] (motor torques, N.m): smooth, not polynomials, so the splines matter."""
    t = np.array([k * SAMPLE for k in range(SAMPLES)])
    q2 = 0.2 * np.sin(4.0 * t)
    q4 = 0.3 * t**2
    tau1 = 0.3 + 0.4 * np.sin(25.0 * t) + 0.2 * t
    tau3 = -0.5 * t + 0.1 * np.cos(30.0 * t)
    return t, {"q_star[2]": q2, "q_star[4]": q4, "tau_m[1]": tau1, "tau_m[3]": tau3}


def torque_motion(directory: Path) -> Path:
    t, cols = samples()
    write_csv(directory / "logged.csv", ["t", *cols], [t, *cols.values()])
    return write(directory / "logged.toml", f'csv = "logged.csv"\nend = {END}\n')


def simulate(*args) -> int:
    return cli.main(["simulate", *map(str, args)])


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def motor(tmp_path_factory) -> Path:
    from motor_fmus import require_motor_fmu

    copy = tmp_path_factory.mktemp("motor") / "reference_rrpr_motor.fmu"
    shutil.copyfile(require_motor_fmu(), copy)
    return copy


# ---------------------------------------------------------------------------
# the torque spline


def test_the_motion_files_torques_are_the_fits(tmp_path):
    """The CSV's torques (TorqueSpline) equal the fit's Torques of the same samples, bit for bit,
    at the samples and between them; before the first sample and after the last they hold."""
    from stickslip.fit.spec import Torques
    from stickslip.motion import load_motion

    t, cols = samples()
    motion = load_motion(torque_motion(tmp_path), 4, None, {1: 0.0, 3: 0.0})
    assert motion.torques.names == ["tau_m[1]", "tau_m[3]"]
    fit = Torques(t, ["tau_m[1]", "tau_m[3]"], np.column_stack([cols["tau_m[1]"], cols["tau_m[3]"]]))
    for x in [*t, *(t[:-1] + 0.37 * SAMPLE), 0.1234567]:
        mine, theirs = motion.torques(float(x)), fit(float(x))
        for a, b in zip(mine, theirs, strict=True):
            assert np.array_equal(a, b), x
    assert np.array_equal(motion.torques(0.0)[0], [cols["tau_m[1]"][0], cols["tau_m[3]"][0]])
    value, rate, accel = motion.torques(END)
    assert np.array_equal(value, [cols["tau_m[1]"][-1], cols["tau_m[3]"][-1]])
    assert not rate.any() and not accel.any()
    # the motor joints' q* without a column: their start values, constant
    q, qd, qdd = motion(0.2)
    assert (q[0], q[2], qd[0], qd[2], qdd[0], qdd[2]) == (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


# ---------------------------------------------------------------------------
# through the motor FMU


def _direct(fmu: Path, derivatives: bool = True) -> dict:
    """The motor FMU driven with fmpy directly over [0, END]: at t_k = k * INTERVAL the rigid
    joints' q*, q*', q*'' and the motor torques with (``derivatives``) their first two
    derivatives, from SciPy's not-a-knot splines of :func:`samples` (after the last sample its
    values, with zero derivatives); the motor joints' q* their start 0. Returns {output name:
    array} at every t_k."""
    from scipy.interpolate import CubicSpline

    t, cols = samples()
    q = np.column_stack([cols["q_star[2]"], cols["q_star[4]"]])
    tau = np.column_stack([cols["tau_m[1]"], cols["tau_m[3]"]])
    q_spline, tau_spline = CubicSpline(t, q, axis=0), CubicSpline(t, tau, axis=0)

    def at(spline, x):
        if x > t[-1]:
            return [(q if spline is q_spline else tau)[-1], np.zeros(2), np.zeros(2)]
        return [spline(x, d) for d in (0, 1, 2)]

    with Slave("direct", path=str(fmu)) as s:
        taus = [s.vars.vr("tau_m[1]"), s.vars.vr("tau_m[3]")]

        def set_inputs(x):
            q, qd, qdd = at(q_spline, x)
            s.set_inputs([0.0, q[0], 0.0, q[1], 0.0, qd[0], 0.0, qd[1], 0.0, qdd[0], 0.0, qdd[1]])
            tau, rate, accel = at(tau_spline, x)
            s.fmu.setReal(taus, [float(v) for v in tau])
            if derivatives:
                s.fmu.setRealInputDerivatives(taus, [1, 1], [float(v) for v in rate])
                s.fmu.setRealInputDerivatives(taus, [2, 2], [float(v) for v in accel])

        s.fmu.setupExperiment(startTime=0.0)
        s.set("static_start", True)
        s.fmu.enterInitializationMode()
        set_inputs(0.0)
        s.fmu.exitInitializationMode()
        rows = [s.outputs()]
        for k in range(round(END / INTERVAL)):
            set_inputs(k * INTERVAL)
            s.fmu.doStep(currentCommunicationPoint=k * INTERVAL, communicationStepSize=INTERVAL)
            rows.append(s.outputs())
        data = np.array(rows)
        return {name: data[:, j] for j, name in enumerate(s.output_names())}


@pytest.mark.full  # the motor FMU, built on first use
def test_torque_columns_through_simulate_equal_fmpy_directly(motor, tmp_path, capsys):
    out = tmp_path / "replay.csv"
    assert (
        simulate("--fmu", motor, "--motion", torque_motion(tmp_path), "--out", out, "--set", "static_start=true") == 0
    )
    printed = capsys.readouterr().out
    assert "the motors run on tau_m[1], tau_m[3] of the motion's CSV" in printed, printed
    got, want = read_csv(out), _direct(motor)
    assert len(got["time"]) == round(END / INTERVAL) + 1 and set(want) <= set(got)
    for name in want:  # every output, relative to its largest value (measured: equal)
        assert np.max(np.abs(got[name] - want[name])) <= 1e-12 * np.max(np.abs(want[name])), name
    # the torques move the arm, and their derivatives count: without them the run differs
    assert np.max(np.abs(want["theta_m[1]"])) > 1.0 and abs(want["q[3]"][-1]) > 1e-6
    bare = _direct(motor, derivatives=False)
    assert np.max(np.abs(bare["theta_m[1]"] - want["theta_m[1]"])) > 1e-6 * np.max(np.abs(want["theta_m[1]"]))


@pytest.mark.full
def test_a_constant_torque_column_equals_set(motor, tmp_path):
    """tau_m[1] = 0.5, tau_m[3] = -2 as constant CSV columns against the same values by --set,
    the rigid joints moving by the same CSV columns: the same CSV, byte for byte."""
    t, cols = samples()
    q = [cols["q_star[2]"], cols["q_star[4]"]]
    write_csv(tmp_path / "a.csv", ["t", "q_star[2]", "q_star[4]"], [t, *q])
    write_csv(
        tmp_path / "b.csv",
        ["t", "q_star[2]", "tau_m[1]", "q_star[4]", "tau_m[3]"],
        [t, q[0], np.full(len(t), 0.5), q[1], np.full(len(t), -2.0)],
    )
    held, logged = (write(tmp_path / f"{x}.toml", f'csv = "{x}.csv"\nend = 0.2\n') for x in "ab")
    common = ["--fmu", motor, "--set", "static_start=true"]
    assert (
        simulate(
            *common, "--motion", held, "--out", tmp_path / "a.out", "--set", "tau_m[1]=0.5", "--set", "tau_m[3]=-2"
        )
        == 0
    )
    assert simulate(*common, "--motion", logged, "--out", tmp_path / "b.out") == 0
    assert (tmp_path / "a.out").read_bytes() == (tmp_path / "b.out").read_bytes()
    assert read_csv(tmp_path / "b.out")["omega_m[1]"][-1] > 1.0  # 0.5 N.m > tau_c: the rotor turns


@pytest.mark.full
def test_a_constant_q_star_column_of_a_motor_joint_is_its_start(motor, tmp_path):
    t, cols = samples()
    write_csv(
        tmp_path / "m.csv",
        ["t", "q_star[2]", "q_star[3]", "q_star[4]"],
        [t, cols["q_star[2]"], np.full(len(t), 0.8), cols["q_star[4]"]],
    )
    motion = write(tmp_path / "m.toml", 'csv = "m.csv"\nend = 0.01\n')
    assert simulate("--fmu", motor, "--motion", motion, "--out", tmp_path / "m.out", "--set", "static_start=true") == 0
    data = read_csv(tmp_path / "m.out")
    assert data["q[3]"][0] == 0.8 and data["q[1]"][0] == 0.0


HEAD = "t,q_star[2],q_star[4],tau_m[1],tau_m[3]\n"
ROWS = "0,0,0,0.1,0\n0.1,0.01,0,0.2,0\n0.2,0.02,0,0.3,0\n"
MALFORMED = {  # name: (CSV text, extra arguments, words of the one line on stderr)
    "unknown column": (
        "t,q_star[2],q_star[4],tau[1]\n0,0,0,0\n1,0,0,0\n",
        [],
        ["csv 'm.csv', line 1, column 4: unknown column 'tau[1]'", "tau_m[1], tau_m[3]"],
    ),
    "tau_m of a rigid joint": (
        "t,q_star[2],q_star[4],tau_m[2]\n0,0,0,0\n1,0,0,0\n",
        [],
        ["line 1, column 4: 'tau_m[2]': joint 2 has no motor drive", "joints 1, 3"],
    ),
    "NaN torque": (HEAD + "0,0,0,0.1,0\n0.1,0,0,nan,0\n", [], ["line 3: tau_m[1] = nan: must be a finite number"]),
    "missing q_star of a rigid joint": (
        "t,q_star[2],tau_m[1]\n0,0,0\n1,0,0\n",
        [],
        ["line 1: no column q_star[4]: joint 4 has no motor drive"],
    ),
    "moving q_star of a motor joint": (
        "t,q_star[1],q_star[2],q_star[4]\n0,0,0,0\n1,0.5,0,0\n",
        [],
        ["column q_star[1]: joint 1 has a motor drive", "leave the column out", "tau_m[1]"],
    ),
    "--set clash": (
        HEAD + ROWS,
        ["--set", "tau_m[1]=0.5"],
        ["--set tau_m[1]=0.5 and the motion file", "both give tau_m[1]"],
    ),
}


@pytest.mark.full
@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_torque_motions_exit_2_with_one_line(motor, tmp_path, capsys, case):
    text, extra, words = MALFORMED[case]
    write(tmp_path / "m.csv", text)
    motion = write(tmp_path / "m.toml", 'csv = "m.csv"\n')
    out = tmp_path / "out.csv"
    assert simulate("--fmu", motor, "--motion", motion, "--out", out, *extra) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith("stickslip simulate: ") and str(motion) in line, line
    assert all(w in line for w in words), (words, line)
    assert not out.exists()


def test_a_torque_column_on_an_fmu_without_motor_drives_exits_2(tmp_path, capsys):
    write(tmp_path / "m.csv", "t,q_star[1],q_star[2],q_star[3],q_star[4],tau_m[1]\n0,0,0,0.8,0,0\n1,0,0,0.8,0,0\n")
    motion = write(tmp_path / "m.toml", 'csv = "m.csv"\n')
    out = tmp_path / "out.csv"
    assert simulate("--fmu", require_fmu(), "--motion", motion, "--out", out) == 2
    line = one_line(capsys.readouterr().err)
    assert "line 1, column 6: 'tau_m[1]': joint 1 has no motor drive; the FMU has no motor drives" in line, line
    assert not out.exists()


# ---------------------------------------------------------------------------
# no silent default motion


def _xarm6() -> Path:
    prebuilt = ROOT / "target" / "fmu" / "xarm6.fmu"
    if prebuilt.is_file():
        return prebuilt
    from urdf_fmus import model_fmu

    require_fmu()
    return model_fmu("xarm6", ROOT / "models" / "urdf" / "xarm6" / "xarm6.toml", "STICKSLIP_XARM6_FMU")


def _iiwa() -> Path:
    from urdf_fmus import require_iiwa_fmu

    return require_iiwa_fmu()


def _moved_joint(tmp_path: Path) -> Path:
    """The reference FMU repacked with a model file whose joint 2 sits 0.1 m further along z1
    (d = 0.1): another arm of the same joint types."""
    import zipfile

    from urdf_fmus import rezip

    with zipfile.ZipFile(require_fmu()) as z:
        model = z.read("resources/model.toml").decode("utf-8")
    old = "theta = 1.5707963267948966      # +π/2\nd = 0.0\n"
    assert model.count(old) == 1
    edited = model.replace(old, "theta = 1.5707963267948966      # +π/2\nd = 0.1\n")
    return rezip(require_fmu(), tmp_path / "moved.fmu", replace={"resources/model.toml": edited.encode("utf-8")})


@pytest.mark.full  # the URDF FMUs, built on first use
@pytest.mark.parametrize("arm", ["kuka_iiwa", "xarm6"])
def test_a_urdf_arm_without_motion_exits_2_and_writes_nothing(arm, tmp_path, capsys):
    fmu = _iiwa() if arm == "kuka_iiwa" else _xarm6()
    out = tmp_path / "out.csv"
    assert simulate("--fmu", fmu, "--out", out) == 2
    line = one_line(capsys.readouterr().err)
    joints = {"kuka_iiwa": 7, "xarm6": 6}[arm]
    for words in (
        f"{fmu}: its model",
        "not the reference arm",
        "--motion MOTION.toml",
        "docs/motion.md",
        f"{joints} joints",
    ):
        assert words in line, (words, line)
    assert not out.exists()
    from stickslip.simulate import run

    with pytest.raises(ValueError, match="not the reference arm"):
        run(fmu, 0.01)


@pytest.mark.full
def test_the_xarm6_with_its_motion_runs(tmp_path):
    out = tmp_path / "xarm6.csv"
    assert simulate("--fmu", _xarm6(), "--motion", EXAMPLES / "xarm6.toml", "--end", "0.01", "--out", out) == 0
    assert len(read_csv(out)["time"]) == 11


def test_another_model_of_the_reference_joint_types_needs_a_motion(tmp_path, capsys):
    from stickslip.motion import reference_motion_refusal, runs_reference_motion

    moved = _moved_joint(tmp_path)
    assert not runs_reference_motion(moved)
    assert "has joint 2 at another place than the reference arm's" in reference_motion_refusal(moved)
    out = tmp_path / "out.csv"
    assert simulate("--fmu", moved, "--out", out) == 2
    assert "--motion MOTION.toml" in one_line(capsys.readouterr().err)
    assert not out.exists()


@pytest.mark.full
def test_a_motor_fmu_of_another_arm_names_the_torque_columns(motor, tmp_path, capsys):
    import zipfile

    from urdf_fmus import rezip

    with zipfile.ZipFile(motor) as z:
        model = z.read("resources/model.toml").decode("utf-8")
    edited = model.replace("d = 0.6\n", "d = 0.7\n", 1)
    assert edited != model
    other = rezip(motor, tmp_path / "other.fmu", replace={"resources/model.toml": edited.encode("utf-8")})
    assert simulate("--fmu", other, "--out", tmp_path / "out.csv") == 2
    line = one_line(capsys.readouterr().err)
    assert "has joint 1 at another place" in line and "columns tau_m[1], tau_m[3]" in line, line


def test_the_reference_fmu_without_motion_still_runs(tmp_path):
    from stickslip.motion import runs_reference_motion

    assert runs_reference_motion(require_fmu())
    out = tmp_path / "ref.csv"
    assert simulate("--fmu", require_fmu(), "--end", "0.01", "--out", out) == 0
    assert len(read_csv(out)["time"]) == 11


@pytest.mark.full
def test_the_motor_reference_fmu_without_motion_still_runs(motor, tmp_path, capsys):
    from stickslip.motion import runs_reference_motion

    assert runs_reference_motion(motor)
    out = tmp_path / "motor.csv"
    assert simulate("--fmu", motor, "--end", "0.01", "--out", out, "--set", "tau_m[1]=0.5") == 0
    note = [line for line in capsys.readouterr().out.splitlines() if line.startswith("motor drives")]
    assert note == [
        "motor drives on joints 1, 3: the motion's q* is their start position only; the motors run on "
        "tau_m[1] = 0.5, tau_m[3] = 0 N.m, held constant (--set tau_m[i]=VALUE)"
    ]
    assert len(read_csv(out)["time"]) == 11
