"""The FMI 3.0 FMU (StickSlipManipulator-fmi3.fmu) run by fmpy's FMI 3.0 co-simulation API:

* without early return and intermediate update it gives the FMI 2.0 FMU's outputs bit for bit;
* with early return it returns at every located stick-slip event, at the FMI 2.0 run's event
  instants, and the master's run from there goes on to the same stiction counts;
* the intermediate-update callback sees the outputs at every sub-step (without changing them),
  and the drive inputs it sets there are used: a step in q̈* inside a communication step is
  followed to 1e-8 rad instead of 2e-4 rad;
* FMU states round-trip bit for bit, serialized too; wrong call orders are refused by name.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from fmi3_slave import Slave3, require_fmu3
from helpers import INTERVAL, RUN_TIME, Slave, input_vector

# "t = 0.0201 s: joint 1 stuck -> slipping (+)" (category logEvents), FMI 2.0 and 3.0 alike
EVENT = re.compile(r"t = (\S+) s: (joint \d+|rotor of joint \d+) (.+?) -> (.+)$")


@pytest.fixture(scope="module")
def fmu3():
    return require_fmu3()


def fmi2_reference(steps: int, logging_on: bool = False):
    """The FMI 2.0 FMU over the reference motion: (outputs by stem, one row per step; event list; n_stick)."""
    s = Slave("fmi2", logging_on=logging_on)
    s.initialize()
    rows = s.run_reference(0, steps)
    names = s.output_names()
    by_stem: dict[str, list[int]] = {}
    for i, name in enumerate(names):
        by_stem.setdefault(name.split("[")[0], []).append(i)
    outputs = {stem: rows[:, idx] for stem, idx in by_stem.items()}
    events = [m.groups() for r in s.log.records if (m := EVENT.search(str(r[-1])))]
    s.free()
    return outputs, events


def events_of(log) -> list[tuple]:
    return [m.groups() for (_, category, message) in log if category == "logEvents" and (m := EVENT.search(message))]


def test_equal_to_fmi2_bit_for_bit(fmu3):
    """Inputs at the communication points only, no early return: every output of every step is
    the FMI 2.0 FMU's, to the bit (the arrays hold the FMI 2.0 scalars in their order)."""
    steps = 400
    expected, _ = fmi2_reference(steps)
    with Slave3() as s:
        s.initialize()
        got = {name: [] for name in s.output_names()}
        for k in range(steps):
            s.set_inputs(input_vector(k * INTERVAL))
            event, terminate, early, last = s.do_step(k * INTERVAL, INTERVAL)
            assert (event, terminate, early) == (False, False, False)
            assert last == pytest.approx((k + 1) * INTERVAL, abs=1e-15)
            for name in got:
                got[name].append(s.get(name))
    assert sorted(got) == sorted(expected), "the FMI 3.0 outputs are the FMI 2.0 outputs' stems"
    for name, rows in got.items():
        rows = np.array(rows).reshape(steps, -1)
        assert np.array_equal(rows, expected[name]), f"`{name}` differs from the FMI 2.0 FMU's"


def run_early_return(event_mode_used: bool):
    """The reference run with early return: inputs set at the communication points t_k only
    (between an early return and t_k+1 the FMU holds them); returns (early returns as
    (time, eventHandlingNeeded), events logged, final n_stick, outputs at every t_k)."""
    n = round(RUN_TIME / INTERVAL)
    returns, at_grid = [], []
    with Slave3(early_return_allowed=True, event_mode_used=event_mode_used, logging_on=True) as s:
        s.initialize()
        if event_mode_used:  # FMI 3.0: Event Mode after initialization when the master uses it
            s.fmu.updateDiscreteStates()
            s.fmu.enterStepMode()
        t, k = 0.0, 0
        while k < n:
            if t == k * INTERVAL:
                s.set_inputs(input_vector(t))
            event, terminate, early, last = s.do_step(t, (k + 1) * INTERVAL - t)
            assert not terminate
            if early:
                assert k * INTERVAL < last < (k + 1) * INTERVAL
                assert s.get("time")[0] == last
                returns.append((last, event))
                if event:
                    s.fmu.enterEventMode()
                    need, terminate, *_ = s.fmu.updateDiscreteStates()
                    assert not need and not terminate
                    s.fmu.enterStepMode()
                t = last
            else:
                assert not event
                k += 1
                t = k * INTERVAL
                at_grid.append(s.get("q"))
        return returns, events_of(s.log), s.get("n_stick"), np.array(at_grid)


def test_early_return_at_every_event(fmu3):
    """Every located stick→slip / slip→stick of the reference run ends a step early, at the
    instant it was located; the events are the FMI 2.0 run's, in the same order, at the same
    instants to 1e-9 s (measured: 8.4e-11 s); the stiction counts end the same."""
    n = round(RUN_TIME / INTERVAL)
    expected_q, fmi2_events = fmi2_reference(n, logging_on=True)
    returns, events, n_stick, q_grid = run_early_return(event_mode_used=True)
    assert len(fmi2_events) >= 10, "the reference run has stick-slip events"
    assert [e[1:] for e in events] == [e[1:] for e in fmi2_events]
    for (t3, *_), (t2, *_) in zip(events, fmi2_events, strict=True):
        assert abs(float(t3) - float(t2)) < 1e-9
    event_times = sorted({float(e[0]) for e in events})
    grid = [t for t in event_times if abs(t / INTERVAL - round(t / INTERVAL)) < 1e-9]
    # one early return per event instant strictly inside a step, at that instant, eventHandlingNeeded set
    assert [t for t, _ in returns] == [t for t in event_times if t not in grid]
    assert all(event for _, event in returns)
    n2 = expected_q["n_stick"][-1]
    assert np.array_equal(n_stick, n2), "the stiction phases counted at the end are the FMI 2.0 run's"
    # and the master's run goes on correctly: the link positions at the communication points
    # agree with the FMI 2.0 run's (to 1e-9 rad; the sub-step grid differs after a return)
    assert np.max(np.abs(q_grid - expected_q["q"])) < 1e-9


def test_early_return_without_event_mode(fmu3):
    """Without eventModeUsed the FMU still returns at the events, with eventHandlingNeeded false."""
    returns, _events, _, _ = run_early_return(event_mode_used=False)
    assert returns and not any(event for _, event in returns)


def test_intermediate_update_sees_every_sub_step_and_changes_nothing(fmu3):
    """The callback, called at the end of every sub-step inside a step, reads the outputs there
    (fmi3GetFloat64 from inside fmi3DoStep); the step's results stay the FMI 2.0 FMU's bit for
    bit. Calls that Intermediate Update Mode does not allow are refused."""
    steps = 100
    expected, _ = fmi2_reference(steps)
    seen, refused = [], []
    holder: dict = {}

    def callback(env, t, set_requested, get_allowed, step_finished, can_return_early, early_requested, early_time):
        s = holder["s"]
        seen.append((t, s.fmu.getFloat64([s.vr("q")], 4)[1], s.fmu.getFloat64([s.vr("time")], 1)[0]))
        try:
            s.fmu.doStep(t, 1e-3)
        except FMICallException:
            refused.append(t)

    with Slave3(intermediate_update=callback) as s:
        holder["s"] = s
        s.initialize()
        rows = []
        for k in range(steps):
            s.set_inputs(input_vector(k * INTERVAL))
            assert not s.do_step(k * INTERVAL, INTERVAL)[2]
            rows.append(s.get("q"))
        assert np.array_equal(np.array(rows), expected["q"])
        assert any("not allowed in Intermediate Update Mode" in m for _, _, m in s.log)
    times = [t for t, _, _ in seen]
    assert len(times) > 10 * steps, "many sub-steps per communication step"
    assert all(a < b for a, b in itertools.pairwise(times)), "sub-step ends in order"
    assert all(t == tm for t, _, tm in seen), "`time` in the callback is the sub-step's end"
    assert all(abs(t / INTERVAL - round(t / INTERVAL)) > 1e-12 for t in times), "only inside the steps"
    assert len(refused) == len(seen)


# A step of q̈* inside a communication step: joint 1's drive accelerates at +A, then at -A
# from T_SWITCH on; the other inputs stay at their values at t = 0.
A, T_SWITCH, END = 20.0, 0.0153, 0.05


def switched_inputs(t: float) -> list[float]:
    x = np.array(input_vector(0.0)).reshape(3, 4)
    x[1:] = 0.0
    if t < T_SWITCH:
        q, qd, qdd = 0.5 * A * t * t, A * t, A
    else:
        u = t - T_SWITCH
        q, qd, qdd = 0.5 * A * T_SWITCH**2 + A * T_SWITCH * u - 0.5 * A * u * u, A * T_SWITCH - A * u, -A
    x[0, 0], x[1, 0], x[2, 0] = q, qd, qdd
    return [float(v) for v in x.reshape(-1)]


def q1_fmi2(h: float) -> dict:
    with Slave("switch") as s:
        s.initialize(inputs=switched_inputs(0.0))
        out = {}
        for k in range(round(END / h)):
            s.set_inputs(switched_inputs(k * h))
            s.fmu.doStep(k * h, h)
            out[round((k + 1) * h, 9)] = s.get("q[1]")
        return out


def q1_fmi3(h: float, feed: bool) -> dict:
    holder: dict = {}

    def callback(env, t, set_requested, get_allowed, step_finished, can_return_early, early_requested, early_time):
        s = holder["s"]
        if feed and set_requested:
            s.fmu.setFloat64([s.vr("q_star"), s.vr("qd_star"), s.vr("qdd_star")], switched_inputs(t))

    with Slave3(intermediate_update=callback) as s:
        holder["s"] = s
        s.initialize(inputs=switched_inputs(0.0))
        out = {}
        for k in range(round(END / h)):
            s.set_inputs(switched_inputs(k * h))
            s.do_step(k * h, h)
            out[round((k + 1) * h, 9)] = s.get("q")[0]
        return out


def test_inputs_at_the_sub_steps(fmu3):
    """A step of q̈* 5.3 ms into a 10 ms communication step. The truth: the FMI 2.0 FMU with
    0.1 ms steps (T_SWITCH on its grid). With 10 ms steps the Taylor polynomial of the step's
    start misses the switch: joint 1 is 1.8e-4 rad off (measured); the master's inputs given
    at every sub-step through the intermediate update bring it to 1.7e-9 rad."""
    truth = q1_fmi2(1e-4)
    h = 1e-2
    coarse2 = q1_fmi2(h)
    plain3 = q1_fmi3(h, feed=False)
    fed3 = q1_fmi3(h, feed=True)

    def error(run):
        return max(abs(run[t] - truth[t]) for t in run)

    assert error(plain3) == error(coarse2), "without inputs in the callback: the FMI 2.0 result"
    assert error(coarse2) > 1e-4
    assert error(fed3) < 1e-8
    assert error(coarse2) > 1e4 * error(fed3)


def test_state_round_trip(fmu3):
    """fmi3GetFMUState / SetFMUState and their serialized form: the steps after a restore repeat
    bit for bit, in the same instance and in another one."""
    with Slave3() as s:
        s.initialize()
        for k in range(50):
            s.set_inputs(input_vector(k * INTERVAL))
            s.do_step(k * INTERVAL, INTERVAL)
        state = s.fmu.getFMUState()
        blob = s.fmu.serializeFMUState(state)

        def run():
            rows = []
            for k in range(50, 120):
                s.set_inputs(input_vector(k * INTERVAL))
                s.do_step(k * INTERVAL, INTERVAL)
                rows.append(np.concatenate([s.get("q"), s.get("f").ravel(), s.get("n_stick")]))
            return np.array(rows)

        first = run()
        s.fmu.setFMUState(state)
        assert np.array_equal(run(), first)
        s.fmu.freeFMUState(state)
        with Slave3("other") as o:
            o.initialize()
            restored = o.fmu.deserializeFMUState(blob)
            o.fmu.setFMUState(restored)
            s2 = s
            s = o  # run() reads `s`
            assert np.array_equal(run(), first)
            s = s2
            o.fmu.freeFMUState(restored)
        with pytest.raises(FMICallException):
            s.fmu.deserializeFMUState(blob[:-1] + bytes([blob[-1] ^ 1]))
        assert any("FMU state" in m or "checksum" in m for _, _, m in s.log)


def test_state_pointers_that_are_not_states_are_named(fmu3):
    """fmi3SetFMUState and fmi3FreeFMUState say what is wrong with a pointer that is no FMU
    state: NULL, misaligned (never read), or aligned but no live state of this FMU (the
    instance itself); a live state still works after them."""
    from ctypes import c_void_p

    with Slave3() as s:
        s.initialize()
        state = s.fmu.getFMUState()
        misaligned = c_void_p(state.value + 1)
        assert "error" in status_of(lambda: s.fmu.setFMUState(misaligned))
        assert "fmi3SetFMUState" in s.log[-1][2] and "is misaligned (not aligned to 8 bytes)" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.freeFMUState(misaligned))
        assert "is misaligned" in s.log[-1][2] and misaligned.value == state.value + 1
        assert "error" in status_of(lambda: s.fmu.setFMUState(c_void_p(s.fmu.component)))
        assert "is not a live FMU state of this FMU" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.setFMUState(c_void_p(None)))
        assert "the FMU state is NULL" in s.log[-1][2]
        s.fmu.setFMUState(state)
        s.fmu.freeFMUState(state)


def status_of(call) -> str:
    try:
        call()
    except FMICallException as e:
        return str(e)
    return "ok"


def test_wrong_call_orders_and_arguments(fmu3):
    """Each refused with fmi3Error and a message naming the call and the reason."""
    with Slave3() as s:
        assert "error" in status_of(lambda: s.do_step(0.0, INTERVAL))
        assert "fmi3DoStep: illegal call sequence: not allowed in Instantiated" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.enterEventMode())
        s.initialize()
        assert "error" in status_of(lambda: s.fmu.enterEventMode())
        assert "eventModeUsed = false" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.getFloat64([s.vr("q")], 3))
        assert "nValues = 3" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.getFloat64([10_000], 1))
        assert "unknown value reference 10000" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.getBoolean([s.vr("q")], 4))
        assert "is a Float64 variable, not Boolean" in s.log[-1][2]
        assert "error" in status_of(lambda: s.fmu.setFloat64([s.vr("time")], [1.0]))
        assert "error" in status_of(lambda: s.fmu.getInt8([s.vr("q")], 4))
        assert "no Int8 variables" in s.log[-1][2]
        assert s.fmu.getInt8([], 0) == []
        assert "error" in status_of(lambda: s.do_step(0.5, INTERVAL))
        assert "is not the FMU's time" in s.log[-1][2]
        q_star = s.vr("q_star")
        assert "error" in status_of(lambda: s.fmu.setFloat64([q_star], [float("nan")] * 4))
        assert np.array_equal(s.get("q_star"), np.array(input_vector(0.0)[:4])), "a refused set changes nothing"
        s.set_inputs(input_vector(0.0))
        assert s.do_step(0.0, INTERVAL)[3] == INTERVAL
        # fmpy's getOutputDerivatives sizes its result for scalars: the array call by hand
        assert output_derivative(s, "q", 1) == list(s.get("qd"))
        assert output_derivative(s, "q", 2) == list(s.get("qdd"))
        assert output_derivative(s, "qd", 1) == list(s.get("qdd"))
        assert "error" in status_of(lambda: output_derivative(s, "f", 1))
        assert "no derivative of order 1 of `f`" in s.log[-1][2]


def output_derivative(s: Slave3, name: str, order: int) -> list[float]:
    """fmi3GetOutputDerivatives of one array variable."""
    from fmpy.fmi3 import fmi3Float64, fmi3Int32, fmi3ValueReference

    n = s.size(name)
    values = (fmi3Float64 * n)()
    s.fmu.fmi3GetOutputDerivatives(
        s.fmu.component, (fmi3ValueReference * 1)(s.vr(name)), 1, (fmi3Int32 * 1)(order), values, n
    )
    return list(values)


def test_instantiation_is_checked(fmu3):
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Slave

    from helpers import unzip_dir

    md = read_model_description(str(fmu3))
    unzipped = unzip_dir(str(fmu3))
    wrong = FMU3Slave(guid="{wrong}", unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
    messages = []
    with pytest.raises(Exception, match="Failed to instantiate"):
        wrong.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
    assert any("instantiationToken {wrong} does not match" in m for m in messages)
    wrong.freeLibrary()


def test_scalar_view_names_every_fmi2_scalar(fmu3):
    """stickslip.fmi3.scalar_view: the FMI 3.0 arrays as the FMI 2.0 FMU's scalars, the same
    names in the same order (arrays over some joints by their `(elements: …)` note)."""
    from fmpy import read_model_description

    from helpers import fmu_path
    from stickslip.fmi3 import scalar_view

    fmi2 = [(v.name, v.causality, v.type) for v in read_model_description(str(fmu_path())).modelVariables]
    view = scalar_view(read_model_description(str(fmu3)))
    assert [(v.name, v.causality, v.type) for v in view.modelVariables] == fmi2


def test_stickslip_simulate_runs_the_fmi3_fmu(fmu3, tmp_path):
    """`stickslip simulate --fmu X-fmi3.fmu` takes the FMI 2.0 names in --set and writes the FMI 2.0
    FMU's CSV byte for byte."""
    import subprocess
    import sys

    from helpers import fmu_path

    stickslip = str(Path(sys.executable).with_name("stickslip"))
    sets = ["--set", "mu_k[3]=0.25", "--set", "mu_s[3]=0.3", "--set", "k[1]=8e5", "--set", "h_max=2e-4"]
    out = {}
    for name, fmu in (("fmi2", fmu_path()), ("fmi3", fmu3)):
        out[name] = tmp_path / f"{name}.csv"
        cmd = [stickslip, "simulate", "--fmu", str(fmu), "--end", "0.3", "--out", str(out[name]), *sets]
        subprocess.run(cmd, check=True, capture_output=True)
    assert out["fmi2"].read_bytes() == out["fmi3"].read_bytes()
    bad = [stickslip, "simulate", "--fmu", str(fmu3), "--end", "0.01", "--out", str(tmp_path / "x.csv")]
    r = subprocess.run([*bad, "--set", "mu_k[3]=-1"], capture_output=True, text=True)
    assert r.returncode == 2 and "mu_k" in r.stderr


def test_seeded_fmi3_fuzz_finds_no_crash_hang_or_silent_non_finite_output(fmu3):
    """tests/python/fuzz_fmi3.py, 4 batches of 2000 random FMI 3.0 calls (each batch in a child
    process): no crash, no hang, no fmi3Fatal, no fmi3OK step with a non-finite output, no early
    return outside its step. Longer runs: `python tests/python/fuzz_fmi3.py --batches 50 --calls 20000`."""
    from fuzz_fmi3 import fuzz

    result = fuzz(str(fmu3), seed=11, batches=4, calls=2000, timeout=120, verbose=False)
    assert result["problems"] == []
    totals = result["totals"]
    assert totals["ok"] > 2000 and totals["error"] > 1000, totals
    assert totals["callbacks"] > 0 and totals["early"] > 0, "the callback and early return were exercised"


def test_ranges_are_enforced_through_the_arrays(fmu3):
    """Every settable Float64 array of the FMI 3.0 FMU: NaN, infinity and a value above its
    declared max are refused with fmi3Error, and the array keeps its values; its start values
    are accepted back."""
    with Slave3() as s:
        s.fmu.enterInitializationMode()
        checked = 0
        for v in s.md.modelVariables:
            if v.causality not in ("parameter", "input") or v.type != "Float64":
                continue
            before = s.get(v.name)
            bad = [float("nan"), float("inf")]
            if v.max is not None and math.isfinite(float(v.max)):
                bad.append(float(v.max) * 2 + 1)
            for x in bad:
                values = list(before)
                values[-1] = x
                assert "error" in status_of(lambda vr=v.valueReference, vals=values: s.fmu.setFloat64([vr], vals))
                assert f"`{v.name}[" in s.log[-1][2] or f"`{v.name}`" in s.log[-1][2], s.log[-1]
                assert np.array_equal(s.get(v.name), before), f"a refused {v.name} changed the array"
            s.set(v.name, before)
            checked += 1
        assert checked >= 20


def events_with_exact_inputs(at_sub_steps: bool, at_early_returns: bool):
    """The reference run with the reference motion's exact inputs given at every sub-step (in
    the callback) and/or at every early return: (events logged, n_stick at the end)."""
    holder: dict = {}

    def callback(env, t, set_requested, get_allowed, step_finished, can_return_early, early_requested, early_time):
        s = holder["s"]
        s.fmu.setFloat64([s.vr("q_star"), s.vr("qd_star"), s.vr("qdd_star")], input_vector(t))

    n = round(RUN_TIME / INTERVAL)
    kw = {"intermediate_update": callback} if at_sub_steps else {}
    with Slave3(early_return_allowed=True, logging_on=True, **kw) as s:
        holder["s"] = s
        s.initialize()
        t, k = 0.0, 0
        while k < n:
            if t == k * INTERVAL or at_early_returns:
                s.set_inputs(input_vector(t))
            _, _, early, last = s.do_step(t, (k + 1) * INTERVAL - t)
            if early:
                t = last
            else:
                k += 1
                t = k * INTERVAL
        return events_of(s.log), s.get("n_stick")


@pytest.mark.parametrize("at_sub_steps, at_early_returns", [(True, False), (False, True), (True, True)])
def test_exact_inputs_at_events_add_no_stiction_slivers(fmu3, at_sub_steps, at_early_returns):
    """New inputs at the instant of a located breakaway (the reference motion's exact values,
    which differ from the held polynomial by its rounding) do not make the joint stick again
    for a sliver: a phase decided at an instant stands through the inputs set at that instant.
    The events and stiction counts are the FMI 2.0 run's (16 events; n_stick 3, 0, 7, 0)."""
    n = round(RUN_TIME / INTERVAL)
    expected, fmi2_events = fmi2_reference(n, logging_on=True)
    events, n_stick = events_with_exact_inputs(at_sub_steps, at_early_returns)
    assert [e[1:] for e in events] == [e[1:] for e in fmi2_events]
    # The exact motion is not the held Taylor polynomial: the instants move by up to 2.5e-5 s
    # with it at the sub-steps, 5.8e-7 s with it at the early returns only (measured).
    for (t3, *_), (t2, *_) in zip(events, fmi2_events, strict=True):
        assert abs(float(t3) - float(t2)) < 1e-4
    assert np.array_equal(n_stick, expected["n_stick"][-1])


def _reference_signals():
    """The reference motion at the 1 ms communication points as fmpy's input table (FMI 3.0
    arrays: one field per array variable)."""
    from stickslip.motion import reference_inputs

    n = round(RUN_TIME / INTERVAL)
    table = np.zeros(
        n + 1, dtype=[("time", float), ("q_star", float, (4,)), ("qd_star", float, (4,)), ("qdd_star", float, (4,))]
    )
    for k in range(n + 1):
        t = k * INTERVAL
        table[k] = (t, *reference_inputs(t))
    return table


@pytest.mark.parametrize("use_event_mode", [False, True])
def test_fmpy_early_return_gives_the_fmi2_events_and_stiction_counts(fmu3, use_event_mode):
    """Issue 37: fmpy's simulate_fmu with early_return_allowed (with and without event mode)
    sets the inputs again at each early return, linearly interpolated between its
    communication points (up to 6e-7 rad off the held polynomial). Those values re-sample
    the signal the FMU holds, so they continue it: the run logs the FMI 2.0 run's 16
    stick-slip events, in the same order, at its instants to 1e-9 s, and ends with n_stick
    3, 0, 7, 0 (before: 24 events, n_stick[3] = 11, the just-broken-away joint stuck again
    4e-15 to 2e-14 s after each breakaway)."""
    from fmpy import simulate_fmu

    n = round(RUN_TIME / INTERVAL)
    expected, fmi2_events = fmi2_reference(n, logging_on=True)
    messages = []
    result = simulate_fmu(
        str(fmu3),
        stop_time=RUN_TIME,
        output_interval=INTERVAL,
        input=_reference_signals(),
        output=["n_stick"],
        early_return_allowed=True,
        use_event_mode=use_event_mode,
        debug_logging=True,
        logger=lambda *args: messages.append(args),
    )
    events = [
        m.groups()
        for args in messages
        if b"logEvents" in args and (m := EVENT.search(args[-1].decode("utf-8", "replace")))
    ]
    assert len(fmi2_events) == 16
    assert [e[1:] for e in events] == [e[1:] for e in fmi2_events]
    for (t3, *_), (t2, *_) in zip(events, fmi2_events, strict=True):
        assert abs(float(t3) - float(t2)) < 1e-9
    assert np.array_equal(result["n_stick"][-1], expected["n_stick"][-1])
    assert list(result["n_stick"][-1]) == [3, 0, 7, 0]
    assert len(result) > n + 1, "the master returned early"


def test_inputs_beyond_the_held_signal_at_an_early_return_are_taken(fmu3):
    """A master that sets a genuinely different input at an early return gets it from that
    instant: joint 3's q* set 1e-4 m above the held polynomial at the first early return
    (beyond what interpolating the signal explains: |q̈*|·H²/4 ≈ 1e-7 m) moves the drive's lag
    eps_joint[3] = q*_3 − q_3 by that much at once; one set within 1e-9 m of it continues the
    held polynomial (the lag as without it, to 1e-12)."""

    def lag_after_first_return(offset: float):
        with Slave3(early_return_allowed=True) as s:
            s.initialize()
            t, k = 0.0, 0
            while True:
                if t == k * INTERVAL:
                    s.set_inputs(input_vector(t))
                _, _, early, last = s.do_step(t, (k + 1) * INTERVAL - t)
                if early:
                    if offset is not None:
                        q = np.array(s.get("q_star"))  # the held polynomial's value at the return
                        q[2] += offset
                        s.set("q_star", q)
                    _, _, _, after = s.do_step(last, 1e-6)
                    return s.get("eps_joint")[2], after
                k, t = k + 1, (k + 1) * INTERVAL

    held, t_held = lag_after_first_return(None)
    beyond, t_beyond = lag_after_first_return(1e-4)
    within, _ = lag_after_first_return(1e-9)
    assert t_held == t_beyond
    assert beyond - held == pytest.approx(1e-4, rel=1e-3)
    assert abs(within - held) < 1e-12
