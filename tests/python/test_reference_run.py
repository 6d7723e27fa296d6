"""The reference motion through the FMU equals the engine's own run.

Three runs of the 2 s reference motion (shared/reference-manipulator.md), inputs
q_star/qd_star/qdd_star from the cycloidal profiles evaluated at every
communication point t_k:

* fmpy.simulate_fmu at output_interval = 1e-3 s. fmpy applies the inputs exactly
  at t_k (its Input class, evaluated on the same grid, returns the table value
  itself: weight 0 on the left sample, 1 on the right one), but it advances with
  communicationStepSize = (k+1)*1e-3 - k*1e-3, which differs from 1e-3 in the last
  bits for most k. The engine's sub-steps then differ by ulps and, through the
  stick-slip transitions, the outputs differ from a run at exactly 1e-3 s by up to
  ~1e-7 of their range. So this run is checked (a) bit for bit against a by-hand
  FMU2Slave replay with fmpy's very communication points and step sizes, which
  proves the inputs are applied exactly, and (b) against the engine to 1e-6.
* fmpy.simulate_fmu at a binary-exact interval 2^-10 s (k*h and (k+1)*h - k*h are
  exact): equal to the engine's run at the same interval to 1e-12 (it is bit for bit).
* FMU2Slave driven by hand at exactly 1e-3 s (the engine binary's own
  arithmetic: doStep(k*1e-3, 1e-3)): equal to the engine to 1e-12 (bit for bit).
"""

import time

import numpy as np
import pytest
from fmpy import simulate_fmu

from helpers import (
    INTERVAL,
    RUN_TIME,
    assert_close_signals,
    bit_identical,
    direct_run,
    input_signals,
    input_vector,
    max_relative_deviation,
    physical,
    reference_slave,
    require_fmu,
    variables,
)

BINARY_INTERVAL = 2.0**-10


def _outputs(names):
    return names.real_outputs + names.bool_outputs


def _simulate(interval):
    path = require_fmu()
    t0 = time.perf_counter()
    res = simulate_fmu(
        str(path),
        start_time=0.0,
        stop_time=RUN_TIME,
        step_size=interval,
        output_interval=interval,
        input=input_signals(RUN_TIME, interval),
    )
    wall = time.perf_counter() - t0
    print(f"simulate_fmu 2 s at {interval:g} s: {wall:.2f} s wall")
    return res


def _as_dict(res, names):
    return {n: np.asarray(res[n], dtype=np.float64) for n in names}


@pytest.mark.full  # about 40 s
def test_simulate_fmu_applies_inputs_at_communication_points():
    """simulate_fmu of the reference motion at 1e-3 s completes (2001 samples, t = 0..2 s)
    and equals, bit for bit, FMU2Slave driven by hand with the inputs at t_k = k*1e-3 and
    fmpy's step sizes (k+1)*1e-3 - k*1e-3: fmpy sets exactly the cycloidal values at the
    communication points. Against the engine's run at exactly 1e-3 s it agrees to 1e-6 of
    each signal's range (the step sizes differ in the last bits, see the module docstring)."""
    res = _simulate(INTERVAL)
    assert len(res) == 2001
    assert res["time"][0] == 0.0 and abs(res["time"][-1] - RUN_TIME) < 1e-12

    slave = reference_slave("replay")
    try:
        rows = [slave.outputs()]
        for k in range(2000):
            t = k * INTERVAL
            slave.set_inputs(input_vector(t))
            slave.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=(k + 1) * INTERVAL - t)
            rows.append(slave.outputs())
    finally:
        slave.free()
    replay = np.array(rows)
    sim = np.array([np.asarray(res[n], dtype=np.float64) for n in slave.output_names()]).T
    assert np.array_equal(sim, replay), f"max relative deviation {max_relative_deviation(sim, replay):.3e}"

    direct = direct_run(RUN_TIME, INTERVAL)
    names = slave.output_names()
    keep = physical(names)
    dev = max_relative_deviation(sim[:, keep], np.array([direct[n] for n in names]).T[:, keep])
    print(f"simulate_fmu at 1e-3 s vs engine at exactly 1e-3 s: max relative deviation {dev:.3e}")
    assert dev < 1e-6


def test_simulate_fmu_equals_engine_at_binary_interval():
    """simulate_fmu of the reference motion at output_interval = step = 2^-10 s equals the
    engine's run (simulate_reference --interval 2^-10) to 1e-12 of each signal's largest
    magnitude, for every output (q, qd, qdd, stick, F_drive, F_friction, N_normal, f, n,
    eps_joint, eps, x_E, energies) and the time column."""
    v = variables()
    names = _outputs(v)
    res = _simulate(BINARY_INTERVAL)
    direct = direct_run(RUN_TIME, BINARY_INTERVAL)
    assert len(res) == len(direct["time"]) == 2049
    actual = _as_dict(res, [*names, "time"])
    assert_close_signals(actual, direct, [*names, "time"], rel=1e-12)
    print("bit for bit:", bit_identical(actual, direct, [*names, "time"]))


def test_by_hand_run_equals_engine_at_1ms():
    """FMU2Slave driven by hand through the 2 s reference motion (inputs at t_k,
    doStep(k*1e-3, 1e-3)) equals the engine's direct run at 1e-3 s to 1e-12 of each
    signal's largest magnitude, initial values (after initialization) included; both
    flexible joints start stuck and slip at some point."""
    slave = reference_slave("byhand")
    try:
        t0 = time.perf_counter()
        first = slave.outputs()
        rows = slave.run_reference(0, round(RUN_TIME / INTERVAL))
        wall = time.perf_counter() - t0
    finally:
        slave.free()
    print(f"FMU2Slave by hand, 2 s at 1e-3 s: {wall:.2f} s wall")
    out = np.vstack([first, rows])
    names = slave.output_names()
    actual = {n: out[:, j] for j, n in enumerate(names)}
    direct = direct_run(RUN_TIME, INTERVAL)
    assert_close_signals(actual, direct, names, rel=1e-12)
    print("bit for bit:", bit_identical(actual, direct, names))
    # the motion really is stick-slip: both flexible joints stick and slip
    for j in ("stick[1]", "stick[3]"):
        s = actual[j]
        assert s[0] == 1.0 and 0.0 in s, j
