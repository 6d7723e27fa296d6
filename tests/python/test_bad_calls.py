"""Bad calls return their status, are logged, and the master survives.

Every case runs in its own instance. The bad call must raise fmpy's
FMICallException with status fmi2Error (3), and the logger callback must have
received an fmi2Error message that names the variable or the call. Then the
instance must still be usable and must not have taken the bad value: the next 30
steps of the reference motion equal those of a clean instance bit for bit. Then
fmi2Reset, a new initialization and 30 steps equal the clean run again, and
fmi2Terminate returns fmi2OK.
"""

import math
import shutil
from ctypes import byref
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2CoSimulation, fmi2Error, fmi2ModelExchange

from helpers import LogCapture, Slave, input_vector, scratch_dir, unzip_dir

STEPS = 30


@pytest.fixture(scope="module")
def clean():
    """Outputs of a clean instance: after initialization, then after each of 30 steps."""
    with Slave("clean") as s:
        s.initialize()
        first = s.outputs()
        return np.vstack([first, s.run_reference(0, STEPS)])


def _bad_vr(s):
    return max(v.valueReference for v in s.md.modelVariables) + 1000


# Each case: (set-up before the bad call: True = initialized, False = only instantiated,
# "initmode" = in initialization mode; the bad call; words the error message must contain)
CASES = {
    "unknown-vr-getReal": (True, lambda s: s.fmu.getReal([_bad_vr(s)]), ["fmi2GetReal", "{vr}"]),
    "unknown-vr-setReal": (True, lambda s: s.fmu.setReal([_bad_vr(s)], [1.0]), ["fmi2SetReal", "{vr}"]),
    "unknown-vr-getBoolean": (True, lambda s: s.fmu.getBoolean([_bad_vr(s)]), ["fmi2GetBoolean", "{vr}"]),
    "real-vr-as-boolean": (True, lambda s: s.fmu.getBoolean([s.vars.vr("q[1]")]), ["fmi2GetBoolean"]),
    "nan-input": (True, lambda s: s.set("q_star[1]", math.nan), ["q_star[1]"]),
    "inf-input": (True, lambda s: s.set("qd_star[3]", math.inf), ["qd_star[3]"]),
    "minus-inf-parameter": (True, lambda s: s.set("h[1]", -math.inf), ["h[1]"]),
    "negative-mass": (True, lambda s: s.set("m[1]", -1.0), ["m[1]"]),
    "one-bad-value-among-good": (
        True,
        lambda s: s.fmu.setReal(s.vars.vrs(["k[1]", "mu_k[3]", "m[1]"]), [2e6, 0.1, -1.0]),
        ["m[1]"],
    ),
    "zero-stiffness": (True, lambda s: s.set("k[1]", 0.0), ["k[1]"]),
    "negative-stiffness": (True, lambda s: s.set("k[3]", -1e6), ["k[3]"]),
    "negative-slider-length": (True, lambda s: s.set("slider_a[3]", -0.2), ["slider_a[3]"]),
    "negative-friction": (True, lambda s: s.set("mu_k[3]", -0.1), ["mu_k[3]"]),
    "zero-step": (True, lambda s: s.fmu.doStep(0.0, 0.0), ["fmi2DoStep", "communicationStepSize"]),
    "negative-step": (True, lambda s: s.fmu.doStep(0.0, -1e-3), ["fmi2DoStep", "communicationStepSize"]),
    "nan-step": (True, lambda s: s.fmu.doStep(0.0, math.nan), ["fmi2DoStep", "communicationStepSize"]),
    "wrong-communication-point": (True, lambda s: s.fmu.doStep(0.5, 1e-3), ["fmi2DoStep", "currentCommunicationPoint"]),
    "fixed-parameter-after-init": (True, lambda s: s.set("h_max", 1e-6), ["h_max"]),
    "fixed-boolean-after-init": (True, lambda s: s.set("use_start_values", True), ["use_start_values"]),
    "set-output": (True, lambda s: s.fmu.setReal([s.vars.vr("q[1]")], [0.5]), ["q[1]"]),
    "directional-derivative": (
        True,
        lambda s: s.fmu.getDirectionalDerivative([s.vars.vr("q[1]")], [s.vars.vr("q_star[1]")], [1.0]),
        ["fmi2GetDirectionalDerivative"],
    ),
    "output-derivatives": (
        True,
        lambda s: s.fmu.getRealOutputDerivatives([s.vars.vr("q[1]")], [1]),
        ["fmi2GetRealOutputDerivatives"],
    ),
    "input-derivative-order-0": (
        True,
        lambda s: s.fmu.setRealInputDerivatives([s.vars.vr("q_star[1]")], [0], [1.0]),
        ["fmi2SetRealInputDerivatives", "q_star[1]"],
    ),
    "input-derivative-of-output": (
        True,
        lambda s: s.fmu.setRealInputDerivatives([s.vars.vr("q[3]")], [1], [1.0]),
        ["fmi2SetRealInputDerivatives", "q[3]"],
    ),
    "input-derivative-nan": (
        True,
        lambda s: s.fmu.setRealInputDerivatives([s.vars.vr("q_star[3]")], [1], [math.nan]),
        ["fmi2SetRealInputDerivatives", "q_star[3]"],
    ),
    "unknown-log-category": (True, lambda s: s.fmu.setDebugLogging(True, ["noSuchCategory"]), ["noSuchCategory"]),
    # call sequence
    "doStep-before-initialization": (False, lambda s: s.fmu.doStep(0.0, 1e-3), ["fmi2DoStep"]),
    "exitInit-before-enterInit": (False, lambda s: s.fmu.exitInitializationMode(), ["fmi2ExitInitializationMode"]),
    "enterInit-twice": ("initmode", lambda s: s.fmu.enterInitializationMode(), ["fmi2EnterInitializationMode"]),
    "setupExperiment-in-initmode": (
        "initmode",
        lambda s: s.fmu.setupExperiment(startTime=0.0),
        ["fmi2SetupExperiment"],
    ),
    "nan-input-in-initmode": ("initmode", lambda s: s.set("q_star[3]", math.nan), ["q_star[3]"]),
    "negative-mass-before-initialization": (False, lambda s: s.set("m[2]", -15.0), ["m[2]"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_call_returns_error_and_instance_survives(case, clean):
    """The bad call raises FMICallException(status = fmi2Error) and logs an fmi2Error
    message naming the variable or call; the instance then continues exactly like a clean
    one (the bad value was not taken), and after fmi2Reset it runs again like a clean one."""
    initialized, call, words = CASES[case]
    with Slave(f"bad-{case}") as s:
        if initialized == "initmode":
            s.fmu.setupExperiment(startTime=0.0)
            s.fmu.enterInitializationMode()
        elif initialized:
            s.initialize()
        s.log.clear()
        with pytest.raises(FMICallException) as info:
            call(s)
        assert info.value.status == fmi2Error, f"{case}: {info.value}"
        errors = [m for (_, st, _, m) in s.log.records if st == fmi2Error]
        assert errors, f"{case}: no fmi2Error message logged; log:\n{s.log.text()}"
        words = [w.format(vr=_bad_vr(s)) for w in words]
        assert any(all(w in m for w in words) for m in errors), f"{case}: {words} not in:\n{s.log.text()}"

        # the instance survives and did not take the bad value
        if initialized == "initmode":
            s.set_inputs(input_vector(0.0))
            s.fmu.exitInitializationMode()
        elif not initialized:
            s.initialize()
        assert np.array_equal(s.outputs(), clean[0])
        assert s.run_reference(0, STEPS).tobytes() == clean[1:].tobytes()

        # reset after the error, then run again
        s.fmu.reset()
        s.initialize()
        assert np.array_equal(s.outputs(), clean[0])
        assert s.run_reference(0, STEPS).tobytes() == clean[1:].tobytes()
        assert s.fmu.terminate() == 0


def _raw_instantiate(name=b"raw", fmu_type=fmi2CoSimulation, guid=None, location="", logger=True):
    """fmi2Instantiate called directly (fmpy's instantiate() would raise on NULL); returns
    (component or None, log capture, the Slave holding the library). ``location`` "" means
    the extracted FMU's resources folder, None a NULL pointer."""
    s = Slave("raw", instantiate=False)
    log = LogCapture(logger=logger)
    s.log = log
    if location == "":
        location = (Path(unzip_dir()) / "resources").as_uri()
    comp = s.fmu.fmi2Instantiate(
        name,
        fmu_type,
        (guid or s.md.guid).encode(),
        None if location is None else location.encode(),
        byref(log.callbacks),
        0,
        0,
    )
    return comp, log, s


@pytest.mark.parametrize(
    "case, kwargs, words",
    [
        ("wrong-guid", {"guid": "{00000000-0000-0000-0000-000000000000}"}, ["fmi2Instantiate", "fmuGUID"]),
        (
            "missing-resources",
            {"location": "file:///nonexistent/stickslip/resources"},
            ["fmi2Instantiate", "model.toml"],
        ),
        ("not-a-file-uri", {"location": "http://example.invalid/resources"}, ["fmi2Instantiate", "http://"]),
        ("null-resource-location", {"location": None}, ["fmi2Instantiate", "fmuResourceLocation"]),
        ("model-exchange", {"fmu_type": fmi2ModelExchange}, ["fmuType"]),
        ("null-instance-name", {"name": None}, ["instanceName"]),
        ("empty-instance-name", {"name": b""}, ["instanceName"]),
        ("no-logger", {"logger": False}, None),
    ],
)
def test_instantiate_rejects_bad_arguments(case, kwargs, words):
    """fmi2Instantiate returns NULL for a wrong GUID, an unreadable or non-file resource
    location, Model Exchange, a NULL or empty instance name, or a missing logger; where a
    logger exists, an fmi2Error message gives the reason. The process survives and a good
    instantiation afterwards works."""
    comp, log, s = _raw_instantiate(**kwargs)
    try:
        assert not comp, f"{case}: fmi2Instantiate returned an instance"
        if words is not None:
            errors = [m for (_, st, _, m) in log.records if st == fmi2Error]
            assert any(all(w in m for w in words) for m in errors), f"{case}: {words} not in:\n{log.text()}"
    finally:
        if comp:
            s.fmu.fmi2FreeInstance(comp)
        s.fmu.freeLibrary()
    with Slave("after") as good:
        good.initialize()
        good.run_reference(0, 2)


@pytest.mark.parametrize("form", ["file:///", "file:/"])
def test_resource_uri_forms_with_percent_encoding(form):
    """The resources folder at a path with a space and a '%' is found through a
    percent-encoded URI in both the file:/// and file:/ forms; the instance runs."""
    src = Path(unzip_dir()) / "resources"
    dst = scratch_dir() / "dir with space %25 and %" / "resources"
    if not dst.exists():
        shutil.copytree(src, dst)
    uri = dst.as_uri()  # file:///... with %20 and %25
    assert uri.startswith("file:///") and "%20" in uri and "%25" in uri
    if form == "file:/":
        uri = "file:/" + uri[len("file:///") :]
    comp, log, s = _raw_instantiate(location=uri)
    try:
        assert comp, f"fmi2Instantiate({uri}) returned NULL:\n{log.text()}"
        s.fmu.component = comp
        s.instantiated = True
        s.initialize()
        s.run_reference(0, 3)
        assert abs(s.get("q[3]") - 0.8) < 1e-3
    finally:
        s.free()


def test_free_after_error_and_null_free():
    """fmi2Terminate and fmi2FreeInstance after an fmi2Error work; fmi2FreeInstance(NULL)
    is harmless."""
    s = Slave("free-after-error")
    s.initialize()
    with pytest.raises(FMICallException):
        s.fmu.doStep(0.0, -1.0)
    assert s.fmu.terminate() == 0
    s.fmu.fmi2FreeInstance(None)
    s.fmu.freeInstance()
    s.freed = True


def test_input_derivatives_are_honoured_and_higher_orders_warned(clean):
    """fmi2SetRealInputDerivatives on q_star[i] with orders 1 and 2 sets the rate and
    acceleration of the drive input: 30 steps with q_star set by fmi2SetReal and its
    derivatives by fmi2SetRealInputDerivatives (qd_star, qdd_star never set) equal the clean
    run bit for bit. An order-3 derivative (not representable in the held quadratic) returns
    fmi2Warning with a logged message naming it, and changes nothing."""
    from fmpy.fmi2 import fmi2Integer, fmi2Real, fmi2ValueReference, fmi2Warning

    with Slave("derivatives") as s:
        s.initialize()
        q_vrs = s.vars.vrs([f"q_star[{i}]" for i in range(1, 5)])
        rows = []
        for k in range(STEPS):
            t = k * 1e-3
            v = input_vector(t)
            s.fmu.setReal(q_vrs, v[0:4])
            s.fmu.setRealInputDerivatives(q_vrs, [1] * 4, v[4:8])
            s.fmu.setRealInputDerivatives(q_vrs, [2] * 4, v[8:12])
            if k == 10:
                s.log.clear()
                vr = (fmi2ValueReference * 1)(q_vrs[0])
                status = s.fmu.fmi2SetRealInputDerivatives(
                    s.fmu.component, vr, 1, (fmi2Integer * 1)(3), (fmi2Real * 1)(123.0)
                )
                assert status == fmi2Warning
                assert any("q_star[1]" in m for (_, st, _, m) in s.log.records if st == fmi2Warning), s.log.text()
            s.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=1e-3)
            rows.append(s.outputs())
        assert np.array(rows).tobytes() == clean[1:].tobytes()
