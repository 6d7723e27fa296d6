"""A sweep's variant (stickslip.variant.run_variant) through the FMU's stickslip_run_experiment
(issue 43, item 2) gives the per-point loop's row (``STICKSLIP_PER_POINT=1``):

* every field but wall_s, cpu_s and worker equal bit for bit (NaN equal to NaN), for ordinary
  variants, one the FMU discards under error control (tolerance 1e-300, error_tolerance 1e-14:
  the Newmark iteration of joint 1 cannot converge at t = 0.024 s) and one it refuses at
  initialization (mu_k[3] > mu_s[3]); the message the same up to the name of the FMI call the
  FMU's message and the fallback name (the library's own calls are named
  stickslip_run_experiment);
* the inputs of the precomputed table are the numbers the per-point loop sets, motor torques
  and their derivatives included (a recording stand-in for the FMU);
* with a timeout the points go in parts, the timeout checked between them: with a stand-in
  for the library that goes on from step mode (stickslip_run_experiment's documented
  sequence through fmpy), the parts give the one call's row, a discard in a later part
  included, and a tiny timeout stops the variant (status timeout) with the metrics of the
  per-point run up to its t_end; with the real library, when it goes on from step mode, the
  same, and when it does not, the per-point loop.

About 0.1 s per 2 s run; the module takes a few seconds.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from helpers import model_description, require_fmu, unzip_dir
from stickslip import experiment, variant
from stickslip.fmu import communication_points, content_hash, initialize
from stickslip.motion import TorqueSpline, reference_inputs

STEP = 1e-3
NOT_COMPARED = ("wall_s", "cpu_s", "worker")
ORDINARY = [
    ({}, 2.0),
    ({"mu_k[3]": 0.15, "mu_s[3]": 0.2}, 2.0),
    # a draw of examples/monte_carlo.toml's tolerances
    (
        {
            "k[1]": 1.013e6,
            "k[3]": 0.987e6,
            "Delta[1]": 6.1e-4,
            "Delta[3]": 3.2e-5,
            "mu_k[1]": 0.187,
            "mu_s[1]": 0.214,
            "mu_k[3]": 0.195,
            "mu_s[3]": 0.203,
        },
        2.0,
    ),
]
DISCARDED = {"tolerance": 1e-300, "error_tolerance": 1e-14}  # error-controlled, discarded at t = 0.024 s
REFUSED = {"mu_k[3]": 0.25, "mu_s[3]": 0.2}  # mu_k > mu_s: refused at initialization


@pytest.fixture(scope="module")
def fmu():
    """(digest, bytes) of the FMU under test; skips if its library has no stickslip_run_experiment."""
    from fmpy.fmi2 import FMU2Slave

    data = require_fmu().read_bytes()
    md = model_description()
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=unzip_dir(), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x"
    )
    if experiment.function(slave) is None:
        pytest.skip(f"the FMU's library has no {experiment.NAME}: build it with scripts/build_fmu.sh")
    return content_hash(data), data


@pytest.fixture
def calls(monkeypatch):
    """Counts the calls of stickslip.experiment.run (as run_variant makes them)."""
    count = {"n": 0}
    real = experiment.run

    def counted(*args, **kw):
        count["n"] += 1
        return real(*args, **kw)

    monkeypatch.setattr(experiment, "run", counted)
    return count


def run(fmu, parameters, stop_time, per_point, monkeypatch, timeout=None, motion=reference_inputs):
    digest, data = fmu
    if per_point:
        monkeypatch.setenv("STICKSLIP_PER_POINT", "1")
    else:
        monkeypatch.delenv("STICKSLIP_PER_POINT", raising=False)
    return variant.run_variant(digest, 0, parameters, stop_time, STEP, motion, timeout=timeout, fmu_data=data)


def calls_named(message: str) -> str:
    """The message with the FMI calls' names (fmi2DoStep, stickslip_run_experiment, ...) as `<call>`."""
    return re.sub(r"\b(fmi2\w+|stickslip_run_experiment)\b", "<call>", message)


def assert_same_row(native: dict, per_point: dict):
    assert native.keys() == per_point.keys()
    for name, expected in per_point.items():
        if name in NOT_COMPARED:
            continue
        actual = native[name]
        if name == "message":
            assert calls_named(actual) == calls_named(expected), (actual, expected)
        elif isinstance(expected, float):
            assert isinstance(actual, float), (name, actual)
            both_nan = math.isnan(expected) and math.isnan(actual)
            assert both_nan or actual.hex() == expected.hex(), f"{name}: {actual!r} vs {expected!r}"
        else:
            assert actual == expected, (name, actual, expected)


@pytest.mark.parametrize(("parameters", "stop_time"), ORDINARY, ids=["defaults", "mu3", "mc_draw"])
def test_ordinary_variants_bit_identical(fmu, calls, monkeypatch, parameters, stop_time):
    per_point = run(fmu, parameters, stop_time, True, monkeypatch)
    assert calls["n"] == 0
    native = run(fmu, parameters, stop_time, False, monkeypatch)
    assert calls["n"] == 1  # the whole experiment in one call
    assert per_point["status"] == "ok" and per_point["t_end"] == 2.0
    outputs = [v.name for v in model_description().modelVariables if v.causality == "output"]
    assert all(math.isfinite(per_point[m]) for m in variant.metric_names(outputs))
    assert_same_row(native, per_point)


def test_discarded_variant_bit_identical(fmu, calls, monkeypatch):
    """The metrics cover [0, 0.024 s] in both; the FMU's reason is the same text."""
    per_point = run(fmu, DISCARDED, 0.3, True, monkeypatch)
    native = run(fmu, DISCARDED, 0.3, False, monkeypatch)
    assert calls["n"] == 1
    assert per_point["status"] == "discard" and per_point["t_end"] == 0.024, per_point
    assert "fmi2DoStep: step [0.024000000000000014" in per_point["message"]
    assert "stickslip_run_experiment: step [0.024000000000000014" in native["message"]
    assert "did not converge" in native["message"] and native["message"].endswith("at t = 0.024 s")
    assert math.isfinite(native["max_eps"])
    assert_same_row(native, per_point)


def test_refused_variant_bit_identical(fmu, calls, monkeypatch):
    per_point = run(fmu, REFUSED, 0.3, True, monkeypatch)
    native = run(fmu, REFUSED, 0.3, False, monkeypatch)
    assert calls["n"] == 1
    assert per_point["status"] == native["status"] == "refused"
    assert native["t_end"] == 0.0 and math.isnan(native["max_eps"])
    assert "below the kinetic" in native["message"] and "stickslip_run_experiment" in native["message"]
    assert_same_row(native, per_point)


def test_refused_when_set_and_unknown_names_as_before(fmu, calls, monkeypatch):
    """A value out of range (refused by fmi2SetReal) and a name the FMU does not have (an
    error row) never reach the library; the rows are the per-point loop's, message and all."""
    for parameters, status in (({"slider_a[3]": 0.0}, "refused"), ({"no_such[1]": 1.0}, "error")):
        per_point = run(fmu, parameters, 0.1, True, monkeypatch)
        native = run(fmu, parameters, 0.1, False, monkeypatch)
        assert native["status"] == status and native["message"] == per_point["message"]
        assert_same_row(native, per_point)
    assert calls["n"] == 0


def test_fixed_substeps_take_the_per_point_loop(fmu, calls, monkeypatch):
    """h_min = h_max: the library's step lengths (differences of the FMU's own times) differ
    from `step` by a rounding, which fixed sub-steps would divide evenly; so the per-point loop."""
    fixed = {"h_min": 1e-4, "h_max": 1e-4}
    native = run(fmu, fixed, 0.1, False, monkeypatch)
    assert calls["n"] == 0 and native["status"] == "ok"
    assert_same_row(native, run(fmu, fixed, 0.1, True, monkeypatch))


# ---------------------------------------------------------------------------
# the input table


class Recorder:
    """An FMU2Slave stand-in that records the inputs set before each doStep (and at initialization)."""

    def __init__(self):
        self.points, self.current = [], {}

    def setupExperiment(self, **kw):
        pass

    def enterInitializationMode(self):
        pass

    def exitInitializationMode(self):
        self.points.append(dict(self.current))

    def setReal(self, vrs, values):
        self.current.update({("value", vr): v for vr, v in zip(vrs, values, strict=True)})

    def setRealInputDerivatives(self, vrs, orders, values):
        self.current.update({(o, vr): v for vr, o, v in zip(vrs, orders, values, strict=True)})

    def doStep(self, currentCommunicationPoint, communicationStepSize):
        self.points.append(dict(self.current))


class TorqueMotion:
    """The reference motion with two motor torques (a TorqueSpline through samples)."""

    def __init__(self):
        t = np.linspace(0.0, 0.3, 7)
        self.torques = TorqueSpline(t, ["tau_m[1]", "tau_m[3]"], np.column_stack([np.sin(9 * t), t**3 - t]))
        self.torques.references = [900, 901]

    def __call__(self, t, step):
        return reference_inputs(t, step)


@pytest.mark.parametrize("motion", [reference_inputs, TorqueMotion()], ids=["reference", "torques"])
def test_input_table_is_what_the_per_point_loop_sets(motion):
    """Row k of the table: the values set at point k by stickslip.fmu.initialize (k = 0) and
    communication_points, bit for bit; the times the FMU's own (each the last plus the step)."""
    md = model_description()
    inputs = list(range(100, 112))
    stop = 0.25
    rec = Recorder()
    initialize(rec, md, {}, inputs, motion, STEP)
    for _ in communication_points(rec, inputs, motion, stop, STEP):
        pass
    steps = round(stop / STEP)
    times, drive, torque_vrs, torques = variant._inputs(motion, steps, STEP)
    assert len(times) == len(drive) == steps + 1 and len(rec.points) == steps + 1
    t = 0.0
    for k in range(steps + 1):
        assert times[k] == t
        t += STEP
    # rec.points: those set at initialization (point 0), then before the step from each point k
    for row, point in [(0, rec.points[0])] + [(k, rec.points[k + 1]) for k in range(steps)]:
        assert [point[("value", vr)] for vr in inputs] == drive[row].tolist(), row
        if torques is not None:
            for order in range(3):
                key = "value" if order == 0 else order
                assert [point[(key, vr)] for vr in torque_vrs] == torques[order][row].tolist(), (row, order)
    assert (torques is None) == (getattr(motion, "torques", None) is None)
    assert variant._inputs(motion, steps, STEP) is variant._inputs(motion, steps, STEP)  # kept per process


# ---------------------------------------------------------------------------
# timeouts: the experiment in parts


def stand_in(slave, time, drive_vrs=(), drive=None, torque_vrs=(), torques=None, output_vrs=(), out=None, **kw):
    """stickslip_run_experiment's documented sequence through fmpy, going on from step mode:
    initialization with point 0's inputs on the first call, then per point its inputs and
    fmi2DoStep(t_k, t_{k+1} - t_k), the outputs read at every point."""
    from fmpy.fmi1 import FMICallException

    n = len(time)
    out = np.full((n, len(output_vrs)), np.nan) if out is None else out
    reached = 0

    def inputs(k):
        slave.setReal(list(drive_vrs), [float(x) for x in drive[k]])
        assert not torque_vrs  # the reference FMU has none

    try:
        if not getattr(slave, "stand_in_started", False):
            slave.enterInitializationMode()
            inputs(0)
            slave.exitInitializationMode()
            slave.stand_in_started = True
        out[0] = slave.getReal(list(output_vrs))
        reached = 1
        for k in range(n - 1):
            inputs(k)
            slave.doStep(currentCommunicationPoint=float(time[k]), communicationStepSize=float(time[k + 1] - time[k]))
            out[k + 1] = slave.getReal(list(output_vrs))
            reached = k + 2
    except FMICallException as e:
        return experiment.Result(status=e.status, reached=reached, outputs=out)
    return experiment.Result(status=0, reached=reached, outputs=out)


@pytest.fixture
def parts(monkeypatch):
    """The stand-in as the library, parts of 5 ms of wall time; counts the calls."""
    count = {"n": 0}

    def counted(*args, **kw):
        count["n"] += 1
        return stand_in(*args, **kw)

    def fresh(p, name, real=variant._slave):
        slave = real(p, name)  # a new instance: initialized by the first call
        slave.stand_in_started = False
        return slave

    monkeypatch.setattr(experiment, "run", counted)
    monkeypatch.setattr(variant, "_slave", fresh)
    monkeypatch.setattr(variant, "_goes_on", lambda p: True)
    monkeypatch.setattr(variant, "CHUNK_WALL", 0.005)
    return count


@pytest.mark.parametrize(("parameters", "stop_time"), [ORDINARY[2], (DISCARDED, 0.3)], ids=["mc_draw", "discard"])
def test_parts_give_the_per_point_row(fmu, parts, monkeypatch, parameters, stop_time):
    """A timeout that never comes: the experiment in several parts (the discard, at t = 24 ms,
    in one after the first's 8 points), the row the per-point one."""
    native = run(fmu, parameters, stop_time, False, monkeypatch, timeout=1e9)
    assert parts["n"] >= 2 and native["t_end"] > variant.FIRST_CHUNK * STEP, (parts, native)
    per_point = run(fmu, parameters, stop_time, True, monkeypatch, timeout=1e9)
    assert_same_row(native, per_point)


def test_timeout_between_parts(fmu, parts, monkeypatch):
    """A timeout of 20 ms on the 2 s motion: status timeout at a t_end before the end, the
    message as before, the metrics those of a per-point run to that t_end."""
    row = run(fmu, {}, 2.0, False, monkeypatch, timeout=0.02)
    assert row["status"] == "timeout", row
    assert parts["n"] >= 2 and 0.0 < row["t_end"] < 2.0, (parts, row)
    assert row["message"] == f"stopped at t = {row['t_end']:g} s after 0.02 s wall (--timeout)"
    shorter = run(fmu, {}, row["t_end"], True, monkeypatch)
    assert shorter["status"] == "ok" and shorter["t_end"] == row["t_end"]
    assert_same_row(row | {"status": "ok", "message": ""}, shorter)


def test_timeout_with_the_library(fmu, monkeypatch):
    """The real library: a tiny timeout stops the variant, whichever way the points went (in
    parts where the library goes on from step mode, else per point); the metrics are those
    of a per-point run to its t_end."""
    row = run(fmu, {}, 2.0, False, monkeypatch, timeout=1e-3)
    assert row["status"] == "timeout", row
    assert 0.0 < row["t_end"] < 2.0
    assert row["message"] == f"stopped at t = {row['t_end']:g} s after 0.001 s wall (--timeout)"
    shorter = run(fmu, {}, row["t_end"], True, monkeypatch)
    assert_same_row(row | {"status": "ok", "message": ""}, shorter)


def test_parts_with_the_library(fmu, calls, monkeypatch):
    """Where the library goes on from step mode: parts of 5 ms of wall time give the
    per-point row; where it does not (a library that allows the instantiated state only),
    a timeout takes the per-point loop."""
    digest, data = fmu
    p = variant._prepared(variant.unpacked(data, digest))
    monkeypatch.setattr(variant, "CHUNK_WALL", 0.005)
    native = run(fmu, ORDINARY[2][0], 2.0, False, monkeypatch, timeout=1e9)
    if not variant._goes_on(p):
        assert calls["n"] == 0
        pytest.skip(f"this FMU's {experiment.NAME} does not go on from step mode: the per-point loop")
    assert calls["n"] >= 3
    assert_same_row(native, run(fmu, ORDINARY[2][0], 2.0, True, monkeypatch, timeout=1e9))
