"""Excitation trajectories (python/stickslip/identify/excitation.py, issue 42 item 6): periodic
finite Fourier series that start and end at rest, within the joints' limits, whose base
regressor's condition number SLSQP minimizes; ``stickslip excite`` writes them as a motion file
that ``stickslip simulate`` runs unchanged.

Each test's docstring says the invariant it checks and its tolerance. The ones that need the
engine's regressor take it from the FMU under test (helpers.require_fmu), and skip where that
FMU was built before the export ``stickslip_joint_torque_regressor``.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest

from helpers import ROOT, require_fmu, scratch_dir
from stickslip.cli import main as cli_main
from stickslip.identify import excitation as ex

# The reference arm's model has no position limits: these (rad, rad, m, rad) keep joint 3's
# slider within 0.7..1.0 m (the reference motion moves it 0.8 -> 1.0 m).
Q_MIN = [-1.0, -0.3, 0.7, -1.6]
Q_MAX = [1.0, 0.3, 1.0, 1.6]
LIMIT_ARGS = ["--qmin=" + ",".join(map(str, Q_MIN)), "--qmax=" + ",".join(map(str, Q_MAX))]


def random_fourier(n=3, harmonics=5, period=10.0, seed=0) -> ex.Fourier:
    z = np.random.default_rng(seed).standard_normal((n, 2 * harmonics - 1))
    return ex.Fourier.of_free(z, period, harmonics)


def reference_limits() -> ex.Limits:
    return ex.limits_of(4, {}, Q_MIN, Q_MAX)


def engine_fmu():
    """(path, unpacked directory) of the FMU under test; skips where its binary has no regressor."""
    from stickslip.fit.idim import StageUnavailable
    from stickslip.fit.regressor import joint_torque_regressor
    from stickslip.fmu import unpacked

    path = require_fmu()
    unzipdir = unpacked(path.read_bytes())
    try:
        joint_torque_regressor(unzipdir, np.zeros((0, 12)))
    except StageUnavailable as e:
        pytest.skip(f"{path}: {e}")
    return path, unzipdir


def test_the_series_derivatives_are_the_central_differences_of_q():
    """q̇ and q̈ in closed form equal the central differences of q and of q̇ (step 1e-4 s, truncation
    (ω_f L h)²/6 ≈ 2e-8) at 200 instants of two periods, to 1e-6 of the largest |q̇|, |q̈|."""
    tr = random_fourier()
    t, h = np.linspace(0.0, 2 * tr.period, 200), 1e-4
    _, qd, qdd = tr.at(t)
    (q_plus, qd_plus, _), (q_minus, qd_minus, _) = tr.at(t + h), tr.at(t - h)
    errors = (
        np.abs((q_plus - q_minus) / (2 * h) - qd).max() / np.abs(qd).max(),
        np.abs((qd_plus - qd_minus) / (2 * h) - qdd).max() / np.abs(qdd).max(),
    )
    print(f"central differences against the closed form: q̇ {errors[0]:.2g}, q̈ {errors[1]:.2g} (relative)")
    assert max(errors) < 1e-6, errors


def test_it_starts_and_ends_at_rest_and_repeats():
    """With the first harmonic eliminated (a_1 = −Σ a_l, b_1 = −Σ l b_l), q̇ and q̈ are zero at
    t = 0 and at every period's end (to 1e-12 of their largest values over the period), and q
    repeats (to 1e-12 of its range); for L = 2..7."""
    for L in range(2, 8):
        tr = random_fourier(n=4, harmonics=L, seed=L)
        q, qd, qdd = tr.at(np.linspace(0.0, tr.period, 2001))
        ends = [tr.at([k * tr.period]) for k in (0, 1, 3)]
        for q_end, qd_end, qdd_end in ends:
            assert np.abs(qd_end).max() <= 1e-12 * np.abs(qd).max(), (L, qd_end)
            assert np.abs(qdd_end).max() <= 1e-12 * np.abs(qdd).max(), (L, qdd_end)
            assert np.abs(q_end - ends[0][0]).max() <= 1e-12 * np.ptp(q), (L, q_end)
        np.testing.assert_allclose(tr.a.sum(axis=1), 0.0, atol=1e-12)
        np.testing.assert_allclose(tr.b @ np.arange(1, L + 1), 0.0, atol=1e-12)


def test_the_limits_hold_between_the_constraint_instants():
    """A trajectory scaled into its limits at the M = 20·L constraint instants (limits tightened
    by ε = (π/20)²) stays within q_min ≤ q ≤ q_max, |q̇| ≤ v, |q̈| ≤ a at 200,000 instants of a
    period (no tolerance), and reaches its tightest limit to within ε + 1e-3 (the margin is not
    wasted). Also the worst case of the margin: a single top harmonic, its extremes halfway
    between two constraint instants."""
    limits = ex.Limits(
        np.array([-1.0, 0.5, -0.2]), np.array([1.0, 0.9, 2.0]), np.array([0.4, 1.0, 3.0]),
        np.array([0.5, 2.0, 1.0]), ("user",) * 3,
    )  # fmt: skip
    fine = np.linspace(0.0, 10.0, 200_001)
    for seed in range(5):
        cons = ex.Constraints(limits, 10.0, 5)
        z = np.random.default_rng(seed).standard_normal((3, 9))
        z[:, 0] = [0.9, 0.7, 0.0]
        tr = ex.Fourier.of_free(cons.scaled_into(z, fill=True), 10.0, 5)
        q, qd, qdd = tr.at(fine)
        half = (limits.q_max - limits.q_min) / 2
        slack = np.vstack([
            (limits.q_max - q.max(axis=0)) / half,
            (q.min(axis=0) - limits.q_min) / half,
            1 - np.abs(qd).max(axis=0) / limits.qd_max,
            1 - np.abs(qdd).max(axis=0) / limits.qdd_max,
        ])  # fmt: skip
        assert np.all(slack >= 0), (seed, slack)
        assert np.all(slack.min(axis=0) <= cons.margin + 1e-3), (seed, slack)

    # The harmonic l = L alone, q = cos(ω_f L t)/(ω_f L), its peaks (at kT/L) halfway between the
    # instants (shifted by T/(2M)): its largest value exceeds theirs by less than the margin.
    L, T = 5, 10.0
    M = ex.GRID_PER_HARMONIC * L
    b = np.zeros((1, L))
    b[0, L - 1] = -1.0
    top = ex.Fourier(T, np.zeros(1), np.zeros((1, L)), b)
    between = np.abs(top.at(np.arange(M) * T / M + T / (2 * M))[0]).max()
    peak = np.abs(top.at(fine)[0]).max()
    margin = (math.pi / ex.GRID_PER_HARMONIC) ** 2
    print(f"a top harmonic's peak above its values halfway between the instants: {peak / between - 1:.4g}")
    assert peak / between - 1 <= margin


def test_the_gradient_is_the_central_differences_of_the_criterion():
    """The criterion's gradient in the free parameters (one batched engine call, analytic in the
    singular vectors) equals central differences of log10 cond (step 1e-5) to 1e-4 of its largest
    component, with and without the friction columns (measured 9e-7 and 4e-7)."""
    _, unzipdir = engine_fmu()
    limits = reference_limits()
    cons = ex.Constraints(limits, 10.0, 5)
    z = np.random.default_rng(5).standard_normal((4, 9))
    z[:, 0] = (limits.q_min + limits.q_max) / 2
    x = cons.scaled_into(z, fill=True).ravel()
    for friction in (False, True):
        criterion = ex.Criterion(unzipdir, 4, limits, 10.0, 100, friction, seed=1)
        P = [p @ ex.rest_map(5) for p in ex.basis(criterion.times, 10.0, 5)]

        def states(x, P=P):
            return np.hstack([p @ x.reshape(4, 9).T for p in P])

        g = criterion.log_condition_gradient(states(x))[1]
        analytic = sum(g[:, m * 4 : (m + 1) * 4].T @ p for m, p in enumerate(P)).ravel()
        h = 1e-5
        numeric = np.array([
            (criterion.log_condition(states(x + h * e)) - criterion.log_condition(states(x - h * e))) / (2 * h)
            for e in np.eye(len(x))
        ])  # fmt: skip
        error = np.abs(analytic - numeric).max() / np.abs(numeric).max()
        print(f"friction {friction}: gradient against central differences {error:.2g}")
        assert error < 1e-4, (friction, error)


def test_the_base_regressor_leaves_out_columns_of_rounding():
    """The criterion's columns are the rank of the regressor: 19 of the reference arm's 40
    parameters (mc_z[2], whose column is rounding, 2e-17 of the largest, is not one), the rank
    of the stacked regressor at the same states by SVD with columns below 1e-12 left out."""
    from stickslip.identify.base import random_states

    _, unzipdir = engine_fmu()
    limits = reference_limits()
    criterion = ex.Criterion(unzipdir, 4, limits, 10.0, 100, False, seed=1)
    W, _ = ex.regressor_of(unzipdir, random_states(4, ex.BASE_STATES, 1, np.column_stack([Q_MIN, Q_MAX])))
    c = np.linalg.norm(W, axis=0)
    kept = W[:, c > 1e-12 * c.max()] / c[c > 1e-12 * c.max()]
    s = np.linalg.svd(kept, compute_uv=False)
    assert len(criterion.columns) == int(np.sum(s > 1e-8 * s[0])) == 19, criterion.columns
    assert "mc_z[2]" not in criterion.columns


@pytest.mark.full
def test_the_optimized_condition_number_is_below_the_naive_ones():
    """On the reference arm (limits Q_MIN..Q_MAX, 1 rad/s, 3 rad/s²) the optimized trajectory's
    condition number is below half the best naive start's (the same harmonics, random
    coefficients scaled into the limits; measured 33.2 against 84.9), and the criterion gives it
    again from the trajectory itself (to 1e-9). Smaller than the command's default for time:
    T = 10 s, L = 4, 100 samples, 2 starts, seed 1 (about 10 s)."""
    _, unzipdir = engine_fmu()
    started = time.perf_counter()
    result = ex.design(unzipdir, reference_limits(), harmonics=4, samples=100, starts=2, seed=1, progress=print)
    wall = time.perf_counter() - started
    print(
        f"condition number {result.condition:.4g}, naive {[round(x, 1) for x in result.naive]}, "
        f"optimized {[round(x, 1) for x in result.optimized]}, {wall:.1f} s"
    )
    assert result.condition < min(result.naive) / 2
    again = ex.Criterion(unzipdir, 4, result.limits, 10.0, 100, False, seed=1)(result.trajectory)
    assert abs(again / result.condition - 1) < 1e-9


def test_the_design_is_deterministic_for_a_seed():
    """The same arguments and seed give the same coefficients and condition numbers bit for bit;
    another seed other ones (the reference arm, L = 2, 50 samples, 2 starts: a second each)."""
    _, unzipdir = engine_fmu()
    runs = [ex.design(unzipdir, reference_limits(), harmonics=2, samples=50, starts=2, seed=s) for s in (1, 1, 2)]
    assert np.array_equal(runs[0].trajectory.coefficients(), runs[1].trajectory.coefficients())
    assert runs[0].condition == runs[1].condition and runs[0].naive == runs[1].naive
    assert runs[0].optimized == runs[1].optimized
    assert not np.array_equal(runs[0].trajectory.coefficients(), runs[2].trajectory.coefficients())


def test_the_written_files_keep_the_limits(tmp_path):
    """The motion file's CSV (1 kHz, 2 periods) starts and ends at rest at the same q, its samples
    are the closed form's q (to 1e-15 relative: repr round-trips), within the limits; the JSON's
    reached maxima are those of the samples and within the limits; the CSV loads as a motion of 4
    joints whose spline q̇, q̈ at the ends are zero (the reference arm, L = 3, 50 samples, 1 start)."""
    from stickslip.motion import load_motion

    _, unzipdir = engine_fmu()
    result = ex.design(unzipdir, reference_limits(), harmonics=3, samples=50, starts=1, seed=1)
    motion = ex.write(result, tmp_path, periods=2, rate=1000.0)
    record = json.loads((tmp_path / "excitation.json").read_text())
    table = np.loadtxt(tmp_path / "excitation.csv", delimiter=",", skiprows=2)
    t, q = table[:, 0], table[:, 1:]
    assert len(t) == 20_001 and t[-1] == 20.0
    np.testing.assert_allclose(q, result.trajectory.at(t)[0], rtol=1e-15, atol=0)
    np.testing.assert_allclose(q[0], q[-1], rtol=0, atol=1e-12)
    assert np.all(q >= Q_MIN) and np.all(q <= Q_MAX)
    qd = result.trajectory.at(t)[1]
    reached = record["reached"]
    np.testing.assert_array_equal(reached["abs_qd_max"], np.abs(qd).max(axis=0))
    np.testing.assert_array_equal(reached["q_min"], q.min(axis=0))
    assert np.all(np.array(reached["abs_qd_max"]) <= 1.0) and np.all(np.array(reached["abs_qdd_max"]) <= 3.0)
    assert record["condition_number"] == result.condition and record["limits"]["q_min"] == Q_MIN
    loaded = load_motion(motion, 4)
    for end in (0.0, 20.0):
        _, qd_end, qdd_end = loaded(end)
        assert np.abs(qd_end).max() < 1e-12, qd_end
        assert np.abs(qdd_end).max() < 1e-2 * 3.0, qdd_end  # the clamped spline's q̈ at its end: small, not exact


def _excite_and_simulate(fmu, out, extra):
    """Runs ``stickslip excite`` and ``stickslip simulate`` on its motion file as commands; returns
    (excitation.json, simulated columns, wall times)."""
    walls = []
    for cmd in (
        ["excite", "--fmu", str(fmu), "--out", str(out), *extra],
        ["simulate", "--fmu", str(fmu), "--motion", str(out / "excitation.toml"), "--out", str(out / "sim.csv")],
    ):
        started = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "stickslip.cli", *cmd], capture_output=True, text=True, cwd=ROOT)
        walls.append(time.perf_counter() - started)
        assert r.returncode == 0, r.stdout + r.stderr
        print(r.stdout.strip().splitlines()[-1])
    record = json.loads((out / "excitation.json").read_text())
    import csv

    with open(out / "sim.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], np.array(rows[1:], dtype=np.float64)
    return record, {h: data[:, j] for j, h in enumerate(header)}, walls


def _follows(record, sim, rigid_tol, flexible_tol, flexible):
    tr = ex.Fourier(record["period_s"], np.array(record["q0"]), np.array(record["a"]), np.array(record["b"]))
    t = sim["time"]
    q_cmd = tr.at(np.minimum(t, record["motion"]["end_s"]))[0]
    errors = []
    for i in range(1, record["joints"] + 1):
        error = np.abs(sim[f"q[{i}]"] - q_cmd[:, i - 1]).max()
        errors.append(error)
        assert error <= (flexible_tol if i in flexible else rigid_tol), (i, error)
    return errors


@pytest.mark.full
def test_the_motion_file_runs_through_simulate_on_the_reference_arm():
    """``stickslip excite`` (T = 10 s, L = 5, 100 samples, 1 start, 1 period) writes a motion file that
    ``stickslip simulate --motion`` runs unchanged; the simulated q follows the trajectory: the rigid
    joints 2 and 4 to 1e-6 rad (measured 1.3e-9), the flexible drives 1 and 3 to 1e-3 (their
    deflection under load and friction; measured 1.2e-4 rad, 3.5e-4 m)."""
    fmu, _ = engine_fmu()
    out = scratch_dir() / "excite_reference"
    record, sim, walls = _excite_and_simulate(
        fmu, out, [*LIMIT_ARGS, "--samples", "100", "--starts", "1", "--periods", "1"]
    )
    errors = _follows(record, sim, 1e-6, 1e-3, flexible=(1, 3))
    print(f"simulated q against the trajectory: {errors}; excite {walls[0]:.1f} s, simulate {walls[1]:.1f} s")
    assert record["condition_number"] < record["naive_condition_number"]["best"]


@pytest.mark.full
def test_the_motion_file_runs_through_simulate_on_the_iiwa():
    """The same on the KUKA iiwa's FMU, its position limits from its URDF (T = 5 s, L = 4, 1 start):
    the simulated q of the rigid joints 3, 5, 6, 7 within 1e-6 rad of the trajectory, the flexible
    1, 2, 4 within 1e-2 rad (gear springs of 2.5e4-5.4e4 N·m/rad under up to 54 N·m; measured
    2e-9 and 2.2e-4, 1.2e-3, 1.2e-3 rad)."""
    from urdf_fmus import require_iiwa_fmu

    fmu = require_iiwa_fmu()
    out = scratch_dir() / "excite_iiwa"
    record, sim, walls = _excite_and_simulate(
        fmu, out, ["--period", "5", "--harmonics", "4", "--samples", "100", "--starts", "1", "--periods", "1"]
    )
    assert record["limits"]["position_source"] == ["urdf"] * 7
    assert np.all(np.array(record["reached"]["q_max"]) <= np.array(record["limits"]["q_max"]))
    errors = _follows(record, sim, 1e-6, 1e-2, flexible=(1, 2, 4))
    print(f"simulated q against the trajectory: {errors}; excite {walls[0]:.1f} s, simulate {walls[1]:.1f} s")


BAD = [
    (["--period", "0"], "--period 0"),
    (["--period", "ten"], "--period 'ten'"),
    (["--harmonics", "1"], "--harmonics 1"),
    (["--harmonics", "2.5"], "--harmonics '2.5'"),
    (["--starts", "0"], "--starts 0"),
    (["--samples", "5"], "--samples 5"),
    (["--rate", "-1"], "--rate -1"),
    (["--periods", "0"], "--periods 0"),
    (["--vmax", "1,2"], "--vmax 1,2"),
    (["--amax", "0"], "joint 1: --amax 0"),
    (["--vmax", "nan"], "--vmax nan"),
]


def _run(capsys, argv):
    code = cli_main(["excite", *argv])
    captured = capsys.readouterr()
    return code, captured.err.strip().splitlines()


def test_bad_arguments_give_one_line_and_exit_2(capsys, tmp_path):
    """Each unusable argument: exit 2, one line on stderr that starts with "stickslip excite:" and
    names the argument (or the joint), no traceback, nothing written. Among them the reference
    arm without position limits, a range beyond limits, reversed limits, a missing FMU and a file
    that is not one."""
    fmu = require_fmu()
    out = tmp_path / "out"
    base = ["--fmu", str(fmu), "--out", str(out)]
    cases = [(base + LIMIT_ARGS + args, named) for args, named in BAD]
    cases += [
        (base, "joint 1: the FMU's model gives no position limits"),
        ([*base, "--qmin=-1,-1,0.6,-1", "--qmax=1,1,0.5,1"], "joint 3: the position range [0.6, 0.5] is empty"),
        ([*base, "--qmin=1", "--qmax=-1"], "joint 1: the position range [1, -1] is empty"),
        (["--fmu", str(tmp_path / "none.fmu"), "--out", str(out)], "--fmu"),
        (["--fmu", str(ROOT / "README.md"), "--out", str(out)], "not a readable FMU"),
    ]
    for argv, named in cases:
        code, lines = _run(capsys, argv)
        assert code == 2, (argv, code, lines)
        assert len(lines) == 1 and lines[0].startswith("stickslip excite: ") and named in lines[0], (argv, lines)
    assert not out.exists()


def test_an_fmu_the_engine_cannot_serve_gives_one_line(capsys, tmp_path, monkeypatch):
    """A binary without the regressor export (StageUnavailable) exits 2, an internal error exits 3,
    each in one line naming it, never a traceback."""
    from stickslip.fit.idim import StageUnavailable

    fmu = require_fmu()
    argv = ["--fmu", str(fmu), "--out", str(tmp_path / "out"), *LIMIT_ARGS]

    def unavailable(unzipdir, states):
        raise StageUnavailable("StickSlipManipulator.so has no stickslip_joint_torque_regressor")

    monkeypatch.setattr(ex, "regressor_of", unavailable)
    code, lines = _run(capsys, argv)
    assert code == 2 and len(lines) == 1 and "no stickslip_joint_torque_regressor" in lines[0], lines

    def broken(unzipdir, states):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(ex, "regressor_of", broken)
    code, lines = _run(capsys, argv)
    assert code == 3 and lines == ["stickslip excite: internal error: ZeroDivisionError: a bug"], lines


@pytest.mark.full
def test_an_fmu_with_motor_drives_and_limits_beyond_the_urdf_are_refused(capsys, tmp_path):
    """The motor arm's FMU (joints 1 and 3 driven by torques, not positions) and an iiwa range
    beyond its URDF's <limit> (joint 2: ±2.094 rad) or a velocity beyond it: exit 2, one line."""
    from motor_fmus import require_motor_fmu
    from urdf_fmus import require_iiwa_fmu

    out = str(tmp_path / "out")
    code, lines = _run(capsys, ["--fmu", str(require_motor_fmu()), "--out", out, *LIMIT_ARGS])
    assert code == 2 and len(lines) == 1 and "joints 1, 3 have motor drives" in lines[0], lines
    iiwa = str(require_iiwa_fmu())
    code, lines = _run(capsys, ["--fmu", iiwa, "--out", out, "--qmin=-2.5", "--qmax=2.5"])
    assert code == 2 and len(lines) == 1 and "joint 2: the range [-2.5, 2.5] goes beyond" in lines[0], lines
    code, lines = _run(capsys, ["--fmu", iiwa, "--out", out, "--vmax", "20"])
    assert code == 2 and len(lines) == 1 and "beyond the URDF's velocity limit 10" in lines[0], lines


def test_the_default_limits_of_a_urdf():
    """limits_of with the model's limits and nothing from the user: the URDF's positions, the
    default acceleration, the default velocity or the URDF's where lower; a user's narrower range
    is taken (source "user within urdf")."""
    model = {1: (-2.0, 2.0, 10.0), 2: (-1.0, 1.5, 0.5)}
    limits = ex.limits_of(2, model)
    assert limits.q_min.tolist() == [-2.0, -1.0] and limits.q_max.tolist() == [2.0, 1.5]
    assert limits.qd_max.tolist() == [ex.DEFAULT_VMAX, 0.5] and limits.qdd_max.tolist() == [ex.DEFAULT_AMAX] * 2
    narrower = ex.limits_of(2, model, [-1.0, -0.5], [1.0, 0.5])
    assert narrower.source == ("user within urdf",) * 2 and narrower.q_max.tolist() == [1.0, 0.5]
    assert math.isclose(ex.Constraints(limits, 10.0, 5).margin, (math.pi / 20) ** 2)
