"""The FMU of the reference arm with motor drives (models/reference_rrpr_motor.toml: motor
drives on joints 1 and 3, joints 2 and 4 rigid; built by motor_fmus.py) as a master sees it.

* fmpy's validation finds no problems;
* the motor variables exist for the motor joints only, with their causality, variability,
  unit, range and start value; each description names the motor (and the joint), and the
  drive inputs q_star, qd_star, qdd_star of a motor joint say that they are ignored while
  stepping; every variable the reference FMU has is declared the same way (no motor
  variable there);
* a run through fmpy's FMU2Slave with a torque step on joint 1 and the holding torque on
  joint 3 from a static start: every output finite, the energy account E_kin + E_pot +
  E_spring + E_rotor - W_drive + Q_friction + Q_damping + Q_motor constant to 1e-6 of
  max |W_drive|; the rotor 3 held (its angle unchanged to the last bit), rotor 1 stuck while
  |tau_m| <= tau_c and slipping from the first communication point after it exceeds tau_c;
  without the holding torque the rotor 3 is driven back by its load;
* the standard drive of motor_fmus.py (torque ramps, a reversal, a parabola) for 0.5 s:
  outputs finite, the energy account closes (same tolerance), stick_m[1] changes at the
  first communication point after tau_m[1] passes tau_c; with damped gears with clearance
  the account (now with Q_damping) closes too;
* tau_m's derivatives (fmi2SetRealInputDerivatives, orders 1 and 2) hold the torque as its
  Taylor polynomial across a step: what is exact is the input function, not the integration,
  so a ramp (a parabola) given by its value and derivatives in steps of 1 ms, of 0.5 ms and
  of 10 ms is the same function of time, and with fixed sub-steps of 1e-5 s (which every
  communication step is a whole number of) the three runs agree to 1e-8 of each signal's
  largest magnitude (measured: 4e-10), while the same torque held constant over each 1 ms
  step (zero-order hold) differs by more than 1e-3; derivatives persist until set again (set
  once = set at every step, bit for bit); an order-3 derivative returns fmi2Warning naming
  tau_m and changes nothing (bit for bit), a zero one fmi2OK;
* q_star, qd_star, qdd_star (and their derivatives) of a motor joint change nothing while
  stepping (bit for bit), and at initialization set the joint's start position (rotor
  unloaded: theta_m = N q*);
* gear_ratio (and the start values static_start, theta_m_start) are fixed: set before
  initialization they are taken, after it refused with fmi2Error naming the variable, the
  instance unchanged and stepping on;
* static_start: at t = 0 theta_m = N (q + F/k + sgn(F) Delta), tau_load = F_drive / N and
  F_drive[3] the weight of links 3 and 4 along the inclined slideway (relative 1e-12, 1e-15,
  1e-9); start values theta_m_start, omega_m_start are taken as given;
* J_m, b_m, tau_c are tunable: set between steps they change the motion from then on;
* the ``stickslip`` command with the motor FMU: ``stickslip simulate`` runs with constant
  motor torques (``--set tau_m[1]=...``) and ``static_start``, noting which joints are
  motor-driven; a value the FMU refuses, an unknown name, a motion that moves a motor joint,
  ``stickslip study`` and a sweep are refused with one line on stderr, never a traceback.
"""

import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Error, fmi2Integer, fmi2OK, fmi2Real, fmi2ValueReference, fmi2Warning
from fmpy.validation import validate_fmu

from helpers import ROOT, Slave, fmu_path, input_vector, max_relative_deviation, read_csv
from motor_fmus import (
    BALANCE,
    GEAR_RATIO,
    MOTOR_COULOMB,
    MOTOR_JOINTS,
    MOTOR_VISCOUS,
    RIGID_JOINTS,
    ROTOR_INERTIA,
    balance,
    motor_slave,
    require_motor_fmu,
    run_motor,
    set_motor_inputs,
)
from urdf_fmus import BUILD_SECONDS

# CI's full run only (scripts/test.sh --quick leaves it out): the motor-drive FMU built
pytestmark = pytest.mark.full

INTERVAL = 1e-3
G = 9.81
BALANCE_TOLERANCE = 1e-6  # of max |W_drive| over the run


@pytest.fixture(scope="module")
def fmu():
    path = require_motor_fmu()
    print(f"motor FMU: {path} (build {BUILD_SECONDS.get('motor', 0.0):.1f} s)")
    return str(path)


@pytest.fixture(scope="module")
def md(fmu):
    return read_model_description(fmu)


def _by_name(md):
    return {v.name: v for v in md.modelVariables}


def _initialized(fmu, name, inputs=None, start_values=None):
    """A Slave of the motor FMU, its start values set, initialized with ``inputs`` (default:
    the reference motion's at 0) and tau_m = 0."""
    s = Slave(name, path=fmu)
    s.fmu.setupExperiment(startTime=0.0)
    for n, v in (start_values or {}).items():
        s.set(n, v)
    s.fmu.enterInitializationMode()
    s.set_inputs(input_vector(0.0) if inputs is None else inputs)
    s.fmu.exitInitializationMode()
    return s


def _column(s, rows, name):
    return rows[:, s.output_names().index(name)]


# ---------------------------------------------------------------------------
# the modelDescription


def test_fmpy_validation_finds_no_problems(fmu):
    assert validate_fmu(fmu) == []


# name: (type, causality, variability, unit per joint {1: ..., 3: ...} or one unit, min, max, start per joint)
_J = {1: None, 3: None}
MOTOR_VARIABLES = {
    "tau_m": ("Real", "input", "continuous", "N.m", -1e6, 1e6, {1: 0.0, 3: 0.0}),
    "theta_m": ("Real", "output", "continuous", "rad", None, None, _J),
    "omega_m": ("Real", "output", "continuous", "rad/s", None, None, _J),
    "stick_m": ("Boolean", "output", "discrete", None, None, None, _J),
    "n_stick_m": ("Real", "output", "continuous", None, None, None, _J),
    "tau_load": ("Real", "output", "continuous", "N.m", None, None, _J),
    "tau_f_m": ("Real", "output", "continuous", "N.m", None, None, _J),
    "gear_ratio": ("Real", "parameter", "fixed", {1: None, 3: "rad/m"}, 0.0, 1e6, GEAR_RATIO),
    "J_m": ("Real", "parameter", "tunable", "kg.m2", 0.0, 1e3, ROTOR_INERTIA),
    "b_m": ("Real", "parameter", "tunable", "N.m.s/rad", 0.0, 1e6, MOTOR_VISCOUS),
    "tau_c": ("Real", "parameter", "tunable", "N.m", 0.0, 1e6, MOTOR_COULOMB),
    "theta_m_start": ("Real", "parameter", "fixed", "rad", None, None, {1: 0.0, 3: 0.0}),
    "omega_m_start": ("Real", "parameter", "fixed", "rad/s", None, None, {1: 0.0, 3: 0.0}),
}
SINGLE_VARIABLES = {
    "E_rotor": ("Real", "output", "continuous", "J", None, None, None),
    "Q_motor": ("Real", "output", "continuous", "J", None, None, None),
    "static_start": ("Boolean", "parameter", "fixed", None, None, None, False),
}
# Lower bound excluded: the interval the description shows.
EXCLUSIVE_MIN = {"gear_ratio": "(0, 1e6]", "J_m": "(0, 1000]"}


def _check_declaration(v, ty, causality, variability, unit, lo, hi, start):
    assert (v.type, v.causality, v.variability) == (ty, causality, variability), (
        v.name,
        v.type,
        v.causality,
        v.variability,
    )
    assert v.unit == unit, (v.name, v.unit, unit)
    assert (None if v.min is None else float(v.min)) == lo, (v.name, v.min)
    assert (None if v.max is None else float(v.max)) == hi, (v.name, v.max)
    if causality == "output":
        assert v.initial == "calculated" and v.start is None, (v.name, v.initial, v.start)
    elif start is not None:
        got = (v.start in (True, "true", "1")) if ty == "Boolean" else float(v.start)
        assert got == start, (v.name, v.start, start)


def test_motor_variables_are_declared_for_the_motor_joints_only(md):
    """Every motor variable exists for joints 1 and 3 (not for the rigid joints 2 and 4)
    with its type, causality, variability, unit, range and start (the model file's motor
    data); E_rotor, Q_motor and static_start once. Every description names the motor or
    rotor and, per joint, the joint with its drive ("joint 3 (prismatic, motor drive)"); a
    lower bound the FMU excludes is written "(0, max]" in the description."""
    by = _by_name(md)
    for base, (ty, causality, variability, unit, lo, hi, start) in MOTOR_VARIABLES.items():
        for i in RIGID_JOINTS:
            assert f"{base}[{i}]" not in by, f"{base}[{i}] exists for a rigid joint"
        for i in MOTOR_JOINTS:
            v = by.get(f"{base}[{i}]")
            assert v is not None, f"{base}[{i}] missing"
            u = unit[i] if isinstance(unit, dict) else unit
            _check_declaration(v, ty, causality, variability, u, lo, hi, start[i])
            d = v.description or ""
            assert re.search(r"\b(motor|rotor)\b", d), (v.name, d)
            kind = "revolute" if i == 1 else "prismatic"
            assert f"joint {i} ({kind}, motor drive)" in d, (v.name, d)
            if base in EXCLUSIVE_MIN:
                assert EXCLUSIVE_MIN[base] in d, (v.name, d)
    for name, (ty, causality, variability, unit, lo, hi, start) in SINGLE_VARIABLES.items():
        v = by.get(name)
        assert v is not None, f"{name} missing"
        _check_declaration(v, ty, causality, variability, unit, lo, hi, start)
        assert re.search(r"\bmotors?\b|\brotors?\b", v.description or ""), (name, v.description)
    assert "motor" in by["W_drive"].description, by["W_drive"].description
    assert "fixed" in by["gear_ratio[1]"].description
    # tau_m's description tells a master how its derivatives are used.
    assert "fmi2SetRealInputDerivatives" in by["tau_m[1]"].description


def test_q_star_of_a_motor_joint_says_it_is_ignored(md):
    """q_star, qd_star, qdd_star of joints 1 and 3 are still inputs (the start position at
    initialization) and their descriptions say that they are ignored while stepping and name
    the joint's tau_m; those of the rigid joints 2 and 4 do not."""
    by = _by_name(md)
    for g in ("q_star", "qd_star", "qdd_star"):
        for i in MOTOR_JOINTS:
            v = by[f"{g}[{i}]"]
            assert v.causality == "input", v.name
            assert v.description.startswith("Ignored while stepping"), (v.name, v.description)
            assert f"tau_m[{i}]" in v.description and "start" in v.description, (v.name, v.description)
        for i in RIGID_JOINTS:
            assert "Ignored" not in by[f"{g}[{i}]"].description


def test_the_reference_fmus_variables_are_declared_the_same(md):
    """The reference FMU (no motor drive) has none of the motor variables, and every variable
    it has the motor FMU declares with the same type, causality, variability, initial, unit,
    range and start (not the same description: those of joints 1 and 3 name the motor drive)."""
    if not fmu_path().is_file():
        pytest.skip(f"{fmu_path()} does not exist")
    ref = _by_name(read_model_description(str(fmu_path())))
    motor = _by_name(md)
    new = set(motor) - set(ref)
    expected = {f"{b}[{i}]" for b in MOTOR_VARIABLES for i in MOTOR_JOINTS} | set(SINGLE_VARIABLES)
    assert new == expected, sorted(new ^ expected)
    assert set(ref) <= set(motor)
    key = lambda v: (v.type, v.causality, v.variability, v.initial, v.unit, v.min, v.max, v.start)  # noqa: E731
    differ = [n for n in ref if key(ref[n]) != key(motor[n])]
    assert not differ, differ


# ---------------------------------------------------------------------------
# runs


def _hold_and_step(fmu, hold=True, steps=200):
    """Static start with joint 2 at 0.5 rad (the slideway of joint 3 inclined, so its gear
    carries the weight of links 3 and 4); tau_m[3] the holding torque tau_load[3] (or 0),
    tau_m[1] 0 then a step to 0.5 N.m at 50 ms; joint 2 and 4 held. Returns (slave at the
    end, outputs at t = 0, rows after each step, balance at t = 0)."""
    inputs = [0.0, 0.5, 0.8, 0.0] + [0.0] * 8
    s = _initialized(fmu, "hold-and-step", inputs, {"static_start": True})
    first = s.outputs()
    b0 = balance(s)
    tau3 = s.get("tau_load[3]") if hold else 0.0
    rows = []
    for k in range(steps):
        t = k * INTERVAL
        s.set_inputs(inputs)
        s.set("tau_m[1]", 0.0 if k < 50 else 0.5)
        s.set("tau_m[3]", tau3)
        s.fmu.doStep(t, INTERVAL)
        rows.append(s.outputs())
    return s, first, np.array(rows), b0


def _balance_rows(s, rows):
    return sum(sign * _column(s, rows, name) for name, sign in BALANCE.items())


def test_torque_step_and_holding_torque(fmu):
    """tau_m[1] steps from 0 to 0.5 N.m at 50 ms, tau_m[3] holds link 3 on the inclined
    slideway. Every output finite; the energy account closes to 1e-6 of max |W_drive|; rotor
    3 stays stuck at its start angle (bit for bit); rotor 1 is stuck (omega_m = 0, theta_m
    unchanged) before the step and slipping after it, joint 1 turning, the rotor's kinetic
    energy and the motor's heat growing."""
    s, first, rows, b0 = _hold_and_step(fmu)
    try:
        assert np.all(np.isfinite(rows)), [
            n for n, ok in zip(s.output_names(), np.isfinite(rows).all(0), strict=True) if not ok
        ]
        w = _column(s, rows, "W_drive")
        bal = _balance_rows(s, rows)
        assert np.max(np.abs(bal - b0)) <= BALANCE_TOLERANCE * np.max(np.abs(w)), (
            np.max(np.abs(bal - b0)),
            np.max(np.abs(w)),
        )
        names = s.output_names()
        th3 = first[names.index("theta_m[3]")]
        assert np.all(_column(s, rows, "stick_m[3]") == 1.0)
        assert np.all(_column(s, rows, "theta_m[3]") == th3)
        stick1 = _column(s, rows, "stick_m[1]")
        assert np.all(stick1[:50] == 1.0) and np.all(stick1[50:] == 0.0), stick1
        assert np.all(_column(s, rows, "omega_m[1]")[:50] == 0.0)
        assert np.all(_column(s, rows, "omega_m[1]")[50:] > 0.0)
        q1 = _column(s, rows, "q[1]")
        assert q1[-1] > 1e-3 and np.all(np.diff(q1[60:]) > 0), q1[-1]
        assert _column(s, rows, "E_rotor")[-1] > 0 and _column(s, rows, "Q_motor")[-1] > 0
        assert w[-1] > 0
    finally:
        s.free()


def test_without_holding_torque_the_load_drives_the_rotor_back(fmu):
    """The same run with tau_m[3] = 0: the gear's load F/N (0.09 N.m) exceeds tau_c[3] =
    0.02 N.m, so rotor 3 slips back (theta_m[3] decreases) until the gear spring is relaxed
    enough for its friction to hold it again; the energy account still closes."""
    s, first, rows, b0 = _hold_and_step(fmu, hold=False, steps=60)
    try:
        th3 = _column(s, rows, "theta_m[3]")
        assert th3[-1] < first[s.output_names().index("theta_m[3]")]
        assert np.any(_column(s, rows, "stick_m[3]") == 0.0)
        bal = _balance_rows(s, rows)
        assert np.max(np.abs(bal - b0)) <= BALANCE_TOLERANCE * np.max(np.abs(_column(s, rows, "W_drive")))
    finally:
        s.free()


def test_standard_drive_energy_account_and_stick_flags(fmu):
    """The standard drive of motor_fmus.py over 0.5 s (the rigid joints on the reference
    motion): outputs finite; the energy account closes to 1e-6 of max |W_drive|; rotor 1 is
    stuck while tau_m[1] = 0.02 N.m <= tau_c = 0.03 N.m and from the first communication point
    after tau_m[1] passes tau_c (t = 52.5 ms) slipping; it reverses (omega_m[1] changes sign)
    when the torque does; rotor 3 slips once tau_m[3] passes its tau_c (t = 0.32 s)."""
    s = motor_slave("standard", path=fmu)
    try:
        b0 = balance(s)
        rows = run_motor(s, 0, 500)
        assert np.all(np.isfinite(rows))
        bal = _balance_rows(s, rows)
        w = _column(s, rows, "W_drive")
        assert np.max(np.abs(bal - b0)) <= BALANCE_TOLERANCE * np.max(np.abs(w)), np.max(np.abs(bal - b0))
        t = np.array([(k + 1) * INTERVAL for k in range(500)])
        stick1 = _column(s, rows, "stick_m[1]")
        assert stick1[0] == 1.0
        first_slip = t[np.argmax(stick1 == 0.0)]
        assert first_slip == pytest.approx(0.053), first_slip
        assert np.all(stick1[t > 0.053] == 0.0)
        omega1 = _column(s, rows, "omega_m[1]")
        assert omega1.max() > 10 and omega1.min() < -10
        stick3 = _column(s, rows, "stick_m[3]")
        slip3 = t[np.argmax(stick3 == 0.0)]
        assert 0.32 <= slip3 <= 0.322 + 1e-12, slip3
    finally:
        s.free()


def test_energy_account_with_gear_damping_and_clearance(fmu):
    """The standard drive over 0.4 s with damped gears with clearance (h[1] = 300 N.m.s/rad,
    Delta[1] = 2e-3 rad, h[3] = 1000 N.s/m, Delta[3] = 1e-4 m) and a static start: outputs
    finite, the gears' damping heat Q_damping grows and the energy account closes to 1e-6 of
    max |W_drive|."""
    start = {"h[1]": 300.0, "Delta[1]": 2e-3, "h[3]": 1000.0, "Delta[3]": 1e-4}
    with motor_slave("damped", path=fmu, start_values=start) as s:
        b0 = balance(s)
        rows = run_motor(s, 0, 400)
        assert np.all(np.isfinite(rows))
        bal = _balance_rows(s, rows)
        w = _column(s, rows, "W_drive")
        assert _column(s, rows, "Q_damping")[-1] > 0
        assert np.max(np.abs(bal - b0)) <= BALANCE_TOLERANCE * np.max(np.abs(w)), np.max(np.abs(bal - b0))


# ---------------------------------------------------------------------------
# tau_m's derivatives


RAMP = (0.01, 10.0, 0.0)  # tau_m[1] = 0.01 + 10 t N.m: past tau_c at 2 ms
PARABOLA = (0.0, 0.0, 200.0)  # tau_m[1] = 100 t^2 N.m
COMPARED = [
    "q[1]",
    "qd[1]",
    "theta_m[1]",
    "omega_m[1]",
    "tau_load[1]",
    "F_drive[1]",
    "tau_f_m[1]",
    "W_drive",
    "Q_motor",
    "E_rotor",
    "E_kin",
    "Q_friction",
]


def _torque_run(fmu, poly, h, end=0.1, mode="derivatives", every=1, extra=None):
    """tau_m[1] = a + b t + c t^2/2 (poly = (a, b, c)) in steps of h, fixed sub-steps of 1e-5 s.
    mode "derivatives": the value set at every point, rate and acceleration through
    fmi2SetRealInputDerivatives (re-set at every point only for a parabola, whose rate
    changes); "every": the derivatives re-set at every point; "hold": the value only (zero-
    order hold). ``extra(s, k)`` is called before each step. Returns the COMPARED outputs
    after every ``every``-th step."""
    a, b, c = poly
    s = _initialized(fmu, "torque", start_values={"h_min": 1e-5, "h_max": 1e-5})
    try:
        vr = s.vars.vr("tau_m[1]")
        rows = []
        n = round(end / h)
        for k in range(n):
            t = k * h
            s.set("tau_m[1]", a + b * t + c * t * t / 2)
            if mode == "every" or (mode == "derivatives" and (k == 0 or c != 0.0)):
                s.fmu.setRealInputDerivatives([vr, vr], [1, 2], [b + c * t, c])
            if extra:
                extra(s, k)
            s.set_inputs(input_vector(0.0))
            s.fmu.doStep(t, h)
            if (k + 1) % every == 0:
                rows.append([s.get(name) for name in COMPARED])
        return np.array(rows)
    finally:
        s.free()


@pytest.mark.parametrize("poly", [RAMP, PARABOLA], ids=["ramp", "parabola"])
def test_tau_m_derivatives_hold_the_taylor_polynomial(fmu, poly):
    """A ramp (a parabola) of tau_m[1] given by its value and derivatives at the communication
    points is the same function of time whatever the step: steps of 0.5 ms and of 10 ms agree
    with steps of 1 ms to 1e-8 of each signal's largest magnitude (fixed sub-steps of 1e-5 s;
    they differ by the Newton iteration's tolerance and rounding only). The zero-order hold of
    the same torque (value only, at every 1 ms point) differs by more than 1e-3."""
    a = _torque_run(fmu, poly, 1e-3)
    half = _torque_run(fmu, poly, 5e-4, every=2)
    ten = _torque_run(fmu, poly, 1e-2)
    hold = _torque_run(fmu, poly, 1e-3, mode="hold")
    assert np.all(np.isfinite(a)) and np.max(np.abs(a[:, COMPARED.index("omega_m[1]")])) > 1.0
    assert max_relative_deviation(half, a) <= 1e-8, max_relative_deviation(half, a)
    assert max_relative_deviation(ten, a[9::10]) <= 1e-8, max_relative_deviation(ten, a[9::10])
    assert max_relative_deviation(hold, a) > 1e-3, max_relative_deviation(hold, a)


def test_tau_m_derivatives_persist_until_set_again(fmu):
    """The ramp with its rate set once (at t = 0) and with the rate re-set at every point:
    bit-identical outputs."""
    once = _torque_run(fmu, RAMP, 1e-3, end=0.05)
    every = _torque_run(fmu, RAMP, 1e-3, end=0.05, mode="every")
    assert once.tobytes() == every.tobytes()


def test_higher_order_tau_m_derivatives(fmu):
    """An order-3 derivative of tau_m[1]: a non-zero one returns fmi2Warning (the first one with
    a logged message naming `tau_m[1]`) and is ignored (the run is bit-identical to one
    without it), a zero one returns fmi2OK."""
    warned = []

    def order3(s, k):
        vr = (fmi2ValueReference * 1)(s.vars.vr("tau_m[1]"))
        s.log.clear()
        value = 0.0 if k % 2 else 1e3 * (k + 1)
        status = s.fmu.fmi2SetRealInputDerivatives(s.fmu.component, vr, 1, (fmi2Integer * 1)(3), (fmi2Real * 1)(value))
        if value == 0.0:
            assert status == fmi2OK, s.log.text()
        else:
            assert status == fmi2Warning, s.log.text()
            warned.append(any("tau_m[1]" in m for (_, st, _, m) in s.log.records if st == fmi2Warning))

    plain = _torque_run(fmu, RAMP, 1e-3, end=0.02)
    with_order3 = _torque_run(fmu, RAMP, 1e-3, end=0.02, extra=order3)
    # The FMU logs the first ignored derivative of an instance (not every one).
    assert warned and warned[0], f"fmi2Warning messages naming tau_m[1]: {warned}"
    assert with_order3.tobytes() == plain.tobytes()


def test_q_star_of_motor_joints_is_ignored_while_stepping(fmu):
    """Garbage (in range) in q_star, qd_star, qdd_star of joints 1 and 3, and in their
    derivatives, during the standard drive: outputs bit-identical to the standard drive's."""
    with motor_slave("clean", path=fmu) as s:
        clean = run_motor(s, 0, 100)
    rng = np.random.default_rng(7)
    with motor_slave("garbage", path=fmu) as s:
        rows = []
        vrs = s.vars.vrs([f"q_star[{i}]" for i in MOTOR_JOINTS])
        for k in range(100):
            set_motor_inputs(s, k)
            for g, scale in (("q_star", 1.0), ("qd_star", 10.0), ("qdd_star", 100.0)):
                s.fmu.setReal(s.vars.vrs([f"{g}[{i}]" for i in MOTOR_JOINTS]), list(rng.normal(0, scale, 2)))
            s.fmu.setRealInputDerivatives(vrs + vrs, [1, 1, 2, 2], list(rng.normal(0, 10.0, 4)))
            s.fmu.doStep(k * INTERVAL, INTERVAL)
            rows.append(s.outputs())
    assert np.array(rows).tobytes() == clean.tobytes()


# ---------------------------------------------------------------------------
# start values, fixed and tunable parameters


def test_unloaded_start_from_q_star(fmu):
    """Without start values the motor joints start at q = q_star (0.3 rad, 0.85 m), the rotors
    at rest with the gear springs unloaded: theta_m = N q, tau_load = 0, eps_joint = 0; a gear
    ratio set before initialization (50) is the one used."""
    inputs = [0.3, 0.0, 0.85, 0.0] + [0.0] * 8
    with _initialized(fmu, "unloaded", inputs, {"gear_ratio[1]": 50.0}) as s:
        assert s.get("gear_ratio[1]") == 50.0
        for i, q, n in ((1, 0.3, 50.0), (3, 0.85, GEAR_RATIO[3])):
            assert s.get(f"q[{i}]") == q
            assert s.get(f"theta_m[{i}]") == n * q
            assert s.get(f"omega_m[{i}]") == 0.0
            assert s.get(f"tau_load[{i}]") == 0.0
            assert s.get(f"eps_joint[{i}]") == pytest.approx(0.0, abs=1e-15)
        s.fmu.doStep(0.0, INTERVAL)
        assert np.all(np.isfinite(s.outputs()))


def test_given_rotor_start_values(fmu):
    """use_start_values = true and static_start = false: the rotors start at theta_m_start,
    omega_m_start (given), the joints at q_start, qd_start."""
    start = {
        "use_start_values": True,
        "q_start[1]": 0.1,
        "q_start[3]": 0.9,
        "theta_m_start[1]": 10.002,
        "omega_m_start[1]": 3.0,
        "theta_m_start[3]": 0.9 * GEAR_RATIO[3],
        "omega_m_start[3]": -2.0,
    }
    with _initialized(fmu, "given", start_values=start) as s:
        assert s.get("theta_m[1]") == 10.002 and s.get("omega_m[1]") == 3.0
        assert s.get("theta_m[3]") == 0.9 * GEAR_RATIO[3] and s.get("omega_m[3]") == -2.0
        assert s.get("q[1]") == 0.1 and s.get("q[3]") == 0.9
        # rotor 1 is 0.002 rad ahead of N q: the gear spring is loaded by k (theta_m/N - q).
        assert s.get("F_drive[1]") == pytest.approx(1e6 * (10.002 / 100 - 0.1), rel=1e-9)
        s.fmu.doStep(0.0, INTERVAL)
        assert np.all(np.isfinite(s.outputs()))


def test_static_start_holds_the_links(fmu):
    """static_start with joint 2 at 0.5 rad and a clearance Delta[3] = 1e-4 m: at t = 0 every
    rotor is at rest at theta_m = N (q + F/k + sgn(F) Delta) (relative 1e-12), tau_load =
    F_drive / N (relative 1e-15), eps_joint = theta_m/N - q, and F_drive[3] is the weight of
    links 3 and 4 (8 + 4 kg) along the slideway inclined by 0.5 rad (relative 1e-9);
    F_drive[1] is 0 (joint 1's axis is vertical)."""
    inputs = [0.0, 0.5, 0.8, 0.0] + [0.0] * 8
    s = _initialized(fmu, "static", inputs, {"static_start": True, "Delta[3]": 1e-4})
    try:
        assert s.get("F_drive[3]") == pytest.approx(12.0 * G * math.sin(0.5), rel=1e-9), s.get("F_drive[3]")
        assert abs(s.get("F_drive[1]")) < 1e-20
        for i in MOTOR_JOINTS:
            n, k = s.get(f"gear_ratio[{i}]"), s.get(f"k[{i}]")
            q, f, delta = s.get(f"q[{i}]"), s.get(f"F_drive[{i}]"), s.get(f"Delta[{i}]")
            deflection = 0.0 if f == 0.0 else f / k + math.copysign(delta, f)
            assert s.get(f"theta_m[{i}]") == pytest.approx(n * (q + deflection), rel=1e-12, abs=1e-15)
            assert s.get(f"omega_m[{i}]") == 0.0
            assert s.get(f"tau_load[{i}]") == pytest.approx(f / n, rel=1e-15, abs=1e-300)
            assert s.get(f"eps_joint[{i}]") == pytest.approx(s.get(f"theta_m[{i}]") / n - q, rel=1e-9, abs=1e-18)
        assert s.get("eps_joint[3]") == pytest.approx(s.get("F_drive[3]") / 1e6 + 1e-4, rel=1e-9)
    finally:
        s.free()


@pytest.mark.parametrize(
    "name, value",
    [("gear_ratio[1]", 50.0), ("gear_ratio[3]", 1000.0), ("theta_m_start[1]", 1.0), ("static_start", True)],
)
def test_fixed_motor_variables_are_refused_after_initialization(fmu, name, value):
    """A fixed motor variable set after fmi2ExitInitializationMode is refused with fmi2Error;
    the logged message names it and says it is fixed; its value is unchanged, and the
    instance runs on exactly like one where the set was never tried."""
    with motor_slave("clean", path=fmu) as s:
        clean = run_motor(s, 0, 20)
    with motor_slave("fixed", path=fmu) as s:
        before = s.get(name)
        s.log.clear()
        with pytest.raises(FMICallException) as info:
            s.set(name, value)
        assert info.value.status == fmi2Error
        errors = [m for (_, st, _, m) in s.log.records if st == fmi2Error]
        assert any(f"`{name}`" in m and "fixed" in m for m in errors), s.log.text()
        assert s.get(name) == before
        assert run_motor(s, 0, 20).tobytes() == clean.tobytes()


@pytest.mark.parametrize("name, value", [("J_m[1]", 3e-3), ("b_m[1]", 2e-2), ("tau_c[1]", 0.3)])
def test_tunable_motor_parameters_change_the_motion_from_then_on(fmu, name, value):
    """J_m, b_m, tau_c set between two steps (at 0.1 s, rotor 1 slipping) are accepted: the
    steps before are those of the standard drive, bit for bit, and rotor 1's speed differs
    after it."""
    with motor_slave("clean", path=fmu) as s:
        clean = run_motor(s, 0, 150)
    with motor_slave("tuned", path=fmu) as s:
        before = run_motor(s, 0, 100)
        s.set(name, value)
        assert s.get(name) == value
        after = run_motor(s, 100, 50)
        j = s.output_names().index("omega_m[1]")
    assert before.tobytes() == clean[:100].tobytes()
    assert np.all(np.isfinite(after))
    assert np.max(np.abs(after[:, j] - clean[100:, j])) > 1e-3 * np.max(np.abs(clean[100:, j]))


# ---------------------------------------------------------------------------
# the stickslip command


def _stickslip(*args, cwd=None):
    """`stickslip ARGS` in a subprocess: (exit status, stdout, stderr)."""
    exe = os.path.join(os.path.dirname(sys.executable), "stickslip")
    cmd = [exe] if os.path.exists(exe) else [sys.executable, "-m", "stickslip.cli"]
    p = subprocess.run(cmd + list(args), capture_output=True, text=True, cwd=cwd or ROOT, timeout=120)
    return p.returncode, p.stdout, p.stderr


def _one_line_error(rc, err, *words):
    assert rc != 0, err
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert all(w in lines[0] for w in words), (words, lines[0])
    return lines[0]


def test_stickslip_simulate_runs_the_motor_fmu_with_constant_torques(fmu, tmp_path):
    """`stickslip simulate --fmu motor.fmu --set static_start=true --set tau_m[1]=0.5` runs:
    it notes that joints 1 and 3 are motor-driven (their q* a start position only, tau_m held
    at the values given), writes every output, the motor's among them, finite; tau_m[1] =
    0.5 N.m > tau_c turns rotor 1 from t = 0, rotor 3 (tau_m[3] = 0, unloaded at the start)
    is held by its friction, and the energy account of the CSV closes (1e-6 of max
    |W_drive|)."""
    out = tmp_path / "motor.csv"
    rc, stdout, err = _stickslip(
        "simulate",
        "--fmu",
        fmu,
        "--out",
        str(out),
        "--end",
        "0.2",
        "--set",
        "static_start=true",
        "--set",
        "tau_m[1]=0.5",
    )
    assert rc == 0, err
    assert "Traceback" not in err
    note = [line for line in stdout.splitlines() if "motor" in line]
    assert note and "joints 1, 3" in note[0] and "tau_m[1] = 0.5" in note[0], stdout
    data = read_csv(out)
    assert len(data["time"]) == 201
    for name in ("theta_m[1]", "omega_m[3]", "stick_m[1]", "tau_load[3]", "E_rotor", "Q_motor"):
        assert np.all(np.isfinite(data[name])), name
    # 0.5 N.m > tau_c[1] from t = 0: rotor 1 slips throughout; rotor 3, unloaded, is held.
    assert np.all(data["stick_m[1]"] == 0.0) and data["stick_m[3]"][0] == 1.0
    assert data["omega_m[1]"][-1] > 1.0 and data["q[1]"][-1] > 0.0
    bal = sum(sign * data[name] for name, sign in BALANCE.items())
    assert np.max(np.abs(bal - bal[0])) <= BALANCE_TOLERANCE * np.max(np.abs(data["W_drive"]))


@pytest.mark.parametrize("case", ["above-max", "at-excluded-min", "unknown-name", "not-a-number"])
def test_stickslip_simulate_refusals_are_one_line(fmu, tmp_path, case):
    """What the FMU refuses (tau_m[1] = 2e6 out of its range, J_m[1] = 0) and an unknown
    name or a value that is no number in --set end `stickslip simulate` with one line on
    stderr naming the variable (with the FMU's reason), no traceback, exit status non-zero."""
    args, words = {
        "above-max": (["--set", "tau_m[1]=2e6"], ["tau_m[1]", "[-1e6, 1e6]"]),
        "at-excluded-min": (["--set", "J_m[1]=0"], ["J_m[1]", "(0, 1000]"]),
        "unknown-name": (["--set", "tau_m[2]=1"], ["tau_m[2]"]),
        "not-a-number": (["--set", "tau_m[1]=abc"], ["tau_m[1]", "abc"]),
    }[case]
    rc, _, err = _stickslip("simulate", "--fmu", fmu, "--out", str(tmp_path / "x.csv"), "--end", "0.01", *args)
    _one_line_error(rc, err, "stickslip simulate", *words)


def test_stickslip_refuses_a_motion_that_moves_a_motor_joint_and_the_study(fmu, tmp_path):
    """A motion file with a cycloid on joint 1 (a motor joint) is refused by `stickslip
    simulate` with one line naming the joint and tau_m[1]; a `hold` of it (a start position)
    and cycloids on the rigid joints are run. `stickslip study` (whose cases prescribe the
    drive positions q*) refuses the motor FMU with one line."""
    moving = tmp_path / "moving.toml"
    moving.write_text("end = 0.02\n[[joint]]\nindex = 1\ncycloid = { q0 = 0.0, q1 = 0.5, t0 = 0.0, t1 = 0.5 }\n")
    rc, _, err = _stickslip("simulate", "--fmu", fmu, "--motion", str(moving), "--out", str(tmp_path / "m.csv"))
    _one_line_error(rc, err, "stickslip simulate", "joint 1", "motor", "tau_m[1]")
    holding = tmp_path / "holding.toml"
    holding.write_text(
        "end = 0.02\n[[joint]]\nindex = 1\nhold = 0.2\n[[joint]]\nindex = 2\n"
        "cycloid = { q0 = 0.0, q1 = 0.2, t0 = 0.0, t1 = 0.5 }\n"
    )
    rc, _, err = _stickslip("simulate", "--fmu", fmu, "--motion", str(holding), "--out", str(tmp_path / "h.csv"))
    assert rc == 0 and "Traceback" not in err, err
    data = read_csv(tmp_path / "h.csv")
    assert data["q[1]"][0] == 0.2 and data["theta_m[1]"][0] == pytest.approx(20.0) and data["q[2]"][-1] > 0.0
    rc, _, err = _stickslip(
        "study", "--fmu", fmu, "--out", str(tmp_path / "study"), "--end", "0.01", "--cases", "friction"
    )
    _one_line_error(rc, err, "stickslip study", "motor", "joints 1, 3")


def test_stickslip_sweep_refuses_the_motor_fmu(fmu, tmp_path):
    """A sweep SPEC naming the motor FMU is refused before anything runs, with one line: its
    variants would drive the joints through q* only, the motors at tau_m = 0."""
    spec = tmp_path / "spec.toml"
    spec.write_text(f'stop_time = 0.01\ncommunication_step = 1e-3\nfmu = "{fmu}"\n[grid]\n"tau_c[1]" = [0.01, 0.03]\n')
    rc, _, err = _stickslip("sweep", str(spec), "--out", str(tmp_path / "sweep"), "--workers", "1")
    _one_line_error(rc, err, "stickslip sweep", "motor", "joints 1, 3")
