"""Closed loop: examples/pd_control.py, a PD controller stepping the FMU at 1 kHz,
moves the flexible joints 1 and 3 of the reference manipulator from (0 rad, 0.8 m) to
(0.3 rad, 0.9 m) and holds them there."""

import importlib.util
import time

import numpy as np
import pytest

from helpers import ROOT, require_fmu

TARGET = (0.3, 0.9)


def _example():
    spec = importlib.util.spec_from_file_location("pd_control", ROOT / "examples" / "pd_control.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def pd():
    return _example()


@pytest.fixture(scope="module")
def closed_loop(pd):
    path = require_fmu()
    t0 = time.perf_counter()
    log = pd.run(path, target=TARGET, end=2.0)
    print(f"closed loop, 2 s at 1 kHz: {time.perf_counter() - t0:.2f} s wall")
    return log


def test_reaches_and_holds_target(pd, closed_loop):
    """From t = 1.5 s on, |q1 - 0.3| and |q3 - 0.9| stay below 1e-3 (rad, m); over the last
    0.3 s the joints are at rest (|qd| < 1e-4) and the error stays within 1e-5 of its final
    value (the loop holds steady, no limit cycle): the joints stick in the static-friction dead
    band around the target."""
    log = closed_loop
    s = pd.summary(log, TARGET, settle_time=1.5, hold=0.3)
    print({k: v.tolist() for k, v in s.items()})
    assert log["time"][-1] == pytest.approx(2.0)
    assert np.all(s["max_error_after_settle"] < 1e-3)
    assert np.all(s["max_rate_last"] < 1e-4)
    last = log["time"] >= log["time"][-1] - 0.3 - 1e-12
    err = log["q"][last] - np.asarray(TARGET)
    assert np.all(np.abs(err - err[-1]) <= 1e-5)
    # the move really happened through slipping, and ends stuck
    assert not log["stick"][500].any()
    assert log["stick"][-1].all()


def test_follows_path_while_moving(closed_loop):
    """While moving (0.1 s to 0.9 s) the joints follow the cycloidal path to within 2 % of
    the stroke (0.006 rad, 0.002 m): the loop is stable and well damped at 1 kHz."""
    log = closed_loop
    moving = (log["time"] >= 0.1) & (log["time"] <= 0.9)
    err = np.abs(log["q"][moving] - log["r"][moving]).max(axis=0)
    assert err[0] < 0.006 and err[1] < 0.002, err


def test_feedback_shrinks_the_friction_dead_band(pd, closed_loop):
    """The proportional feedback matters: with Kp = Kd = 0 (q* = path, open loop) the joints
    also stop, but about twice as far from the target (the dead band |q* - q| < F_s / k of
    static friction is divided by 1 + Kp = 2 with feedback; where in its band a joint stops
    depends on the approach). Asserted: the open-loop final error is at least 1.3 times the
    closed-loop one for both joints (measured: 1.7 for joint 1, 2.0 for joint 3)."""
    open_loop = pd.run(require_fmu(), target=TARGET, end=1.5, kp=(0.0, 0.0), kd=(0.0, 0.0))
    closed = np.abs(closed_loop["q"][-1] - np.asarray(TARGET))
    opened = np.abs(open_loop["q"][-1] - np.asarray(TARGET))
    print("final error open loop", opened, "closed loop", closed)
    assert np.all(opened >= 1.3 * closed)


def test_runs_as_script(pd, tmp_path, capsys):
    """`python examples/pd_control.py --end 0.05 --csv FILE` runs (main() with arguments)
    and writes a CSV with a header and one row per millisecond."""
    out = tmp_path / "pd.csv"
    pd.main(["--fmu", str(require_fmu()), "--end", "0.05", "--csv", str(out)])
    lines = out.read_text().splitlines()
    assert lines[0].startswith("time,r[1],r[3],q[1],q[3]")
    assert len(lines) == 1 + 51
