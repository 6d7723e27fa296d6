"""The physical ranges of parameters and inputs, through the real FMU.

Every Real parameter (tunable or fixed) and every input that declares ``min`` or
``max`` in the FMU's modelDescription is tested at both ends; the list and the
bounds are read from the modelDescription (fmpy's ``read_model_description``), so
a new variable is covered without editing this file.

* At ``max``: exactly ``max`` is accepted (fmi2SetReal returns fmi2OK, fmi2GetReal
  returns it) in a mode where the variable may be set (fixed parameters before
  initialization, the others in an initialized instance); the next double above and
  1e300 are refused with fmi2Error and a logged fmi2Error message that names the
  variable and shows its range, the same numbers as the XML's ``min``/``max``.
* At ``min``: FMI 2.0 reads ``min`` as inclusive. Where the FMU excludes ``min``
  itself (a positive quantity), the modelDescription must say so in the variable's
  description, with the interval ``(min, max]`` the error message shows; then
  ``min`` is refused and the next double above it accepted. Otherwise ``min`` is
  accepted and the next double below refused. Which variables exclude ``min`` is
  pinned in ``EXCLUSIVE_MIN`` (the README's range table).
* After each refused call the instance is still usable: the previous value is kept,
  and a 1 ms ``fmi2DoStep`` returns fmi2OK with every Real output finite (a fixed
  parameter's instance leaves initialization mode first).

Setting a parameter exactly at a bound may make the model inconsistent (mu_k = 2 >
mu_s, h_min = 1e-2 > h_max): the set still returns fmi2OK, relations are checked at
the next step. So the value at the bound is tested by the set alone; the step runs
after the start value has been set back.

The range checks run against the reference FMU and against the FMU of a URDF arm (the
KUKA iiwa of models/urdf/kuka_iiwa, 7 joints, built once per process by urdf_fmus.py): its
cases carry the id prefix ``iiwa:``. And against the FMU with motor drives
(models/reference_rrpr_motor.toml, motor_fmus.py), for the variables the reference FMU does not
have (tau_m, gear_ratio, J_m, b_m, tau_c): id prefix ``motor:``. For it also:

* tau_m's derivatives (fmi2SetRealInputDerivatives) at their ranges, order 1 [-1e9, 1e9] and
  order 2 [-1e12, 1e12]: each bound accepted, the next double beyond it, +-1e300 and NaN
  refused with fmi2Error and a message naming `tau_m[i]` and showing the range; a call with
  one such value among good ones takes none of them: 20 steps afterwards equal, bit for bit,
  those of an instance that never saw the refused calls;
* NaN (and +-inf) in every motor variable that can be set (inputs, parameters, start values
  theta_m_start, omega_m_start) is refused with fmi2Error naming it, the value kept.

Then the reports of issue 13, one by one: ``m[2] = 1e300``, ``slider_b[3] = 1e300``,
``q_star[3] = -1e300``, ``qd_star[2] = +-1e300`` are refused (the mass's message is
the one the README quotes), and ``d_C[1] = 1e-300`` (in range) is accepted and 300
steps of 1 ms run with every output finite.
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Error, fmi2Integer, fmi2OK, fmi2Real, fmi2True, fmi2ValueReference

from helpers import INTERVAL, Slave, fmu_path, input_vector, model_description
from motor_fmus import MOTOR_JOINTS, motor_fmu
from urdf_fmus import iiwa_fmu

# Variables (by name without the joint index) whose lower bound is excluded: the
# README's range table, `Range::positive` and the settings' exclusive bounds.
EXCLUSIVE_MIN = {"k", "slider_a", "m", "error_tolerance", "tolerance", "J_m", "gear_ratio"}

# "[-1000, 1000]", "(0, 1e6]", "[1e-9, 0.01]": an interval as the FMU writes one.
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_INTERVAL = re.compile(rf"([\[(])\s*({_NUMBER})\s*,\s*({_NUMBER})\s*\]")


def _ranged_variables(path=None):
    """(name, min, max, fixed) of every Real parameter and input with min or max."""
    path = path or fmu_path()
    if not Path(path).is_file():
        return []
    out = []
    for v in model_description(str(path)).modelVariables:
        if v.type != "Real" or v.causality not in ("parameter", "input"):
            continue
        if v.min is None and v.max is None:
            continue
        lo = None if v.min is None else float(v.min)
        hi = None if v.max is None else float(v.max)
        out.append((v.name, lo, hi, v.variability == "fixed"))
    return out


RANGED = _ranged_variables()
_NO_FMU = pytest.param(None, marks=pytest.mark.skip(reason=f"{fmu_path()} does not exist: build it first"))


def _urdf_fmus():
    """{"iiwa": path} of the URDF FMU, built at collection (only when the FMU under test
    exists); a failed build is one failing case, not a collection error."""
    if not fmu_path().is_file():
        return {}, None
    try:
        return {"iiwa": str(iiwa_fmu())}, None
    except Exception as e:  # noqa: BLE001 -- reported by the case below
        return {}, str(e)


URDF_FMUS, URDF_BUILD_ERROR = _urdf_fmus()


def _motor_fmus():
    """{"motor": path} of the motor FMU, built at collection (only when the FMU under test
    exists); a failed build is one failing case, not a collection error."""
    if not fmu_path().is_file():
        return {}, None
    try:
        return {"motor": str(motor_fmu())}, None
    except Exception as e:  # noqa: BLE001 -- reported by the case below
        return {}, str(e)


MOTOR_FMUS, MOTOR_BUILD_ERROR = _motor_fmus()
# The FMU of every case: the reference's (id = the variable), the URDF arm's (id "iiwa:…") and
# the motor FMU's (id "motor:…", only its variables the reference FMU does not have).
FMUS = {"": str(fmu_path()), **URDF_FMUS, **MOTOR_FMUS}
RANGED_BY_FMU = {key: _ranged_variables(path) for key, path in FMUS.items()}
if "motor" in RANGED_BY_FMU:
    _reference_names = {r[0] for r in RANGED_BY_FMU[""]}
    RANGED_BY_FMU["motor"] = [r for r in RANGED_BY_FMU["motor"] if r[0] not in _reference_names]


def _params(bound):
    cases = []
    for key, ranged in RANGED_BY_FMU.items():
        prefix = f"{key}:" if key else ""
        cases += [
            pytest.param((FMUS[key], *r), id=prefix + r[0]) for r in ranged if r[1 if bound == "min" else 2] is not None
        ]
    if URDF_BUILD_ERROR:
        cases.append(pytest.param("build:iiwa", id="iiwa:build"))
    if MOTOR_BUILD_ERROR:
        cases.append(pytest.param("build:motor", id="motor:build"))
    return cases or [_NO_FMU]


def _unpack(var):
    if var == "build:iiwa":
        pytest.fail(f"the URDF FMU could not be built:\n{URDF_BUILD_ERROR}")
    if var == "build:motor":
        pytest.fail(f"the motor FMU could not be built:\n{MOTOR_BUILD_ERROR}")
    return var


def _base(name):
    return name.split("[", 1)[0]


def _intervals(text):
    """Every interval in ``text`` as (exclusive min, min, max)."""
    return [(m.group(1) == "(", float(m.group(2)), float(m.group(3))) for m in _INTERVAL.finditer(text)]


def _declares_exclusive_min(name, lo, hi, path=None):
    """True if the description of ``name`` states the interval (lo, hi]."""
    v = next(v for v in model_description(str(path or fmu_path())).modelVariables if v.name == name)
    return (True, lo, hi) in _intervals(v.description or "")


# ---------------------------------------------------------------------------
# instance helpers


def _slave(name, fixed, path=None):
    """A fixed parameter's instance is in initialization mode (it may be set, and
    fmi2GetReal may read it); any other variable's instance is initialized with the
    reference motion's inputs (of joints 1 to 4; on a URDF arm the others at 0)."""
    s = Slave(f"range-{name}", path=path)
    if fixed:
        s.fmu.setupExperiment(startTime=0.0)
        s.fmu.enterInitializationMode()
    else:
        s.initialize()
    return s


def _set_status(s, name, x):
    """fmi2SetReal of one value: the status it returns (fmpy raises above fmi2Warning)."""
    vr = (fmi2ValueReference * 1)(s.vars.vr(name))
    value = (fmi2Real * 1)(x)
    try:
        return s.fmu.fmi2SetReal(s.fmu.component, vr, 1, value)
    except FMICallException as e:
        return e.status


def _accepted(s, name, x):
    s.log.clear()
    status = _set_status(s, name, x)
    assert status == fmi2OK, f"`{name}` = {x!r}: status {status}, log:\n{s.log.text()}"
    assert s.get(name) == x, f"`{name}` = {x!r} was accepted but fmi2GetReal returns {s.get(name)!r}"


def _refused(s, name, x, lo, hi, exclusive, kept):
    """``name`` = x is refused with fmi2Error; an fmi2Error message names the variable
    and shows its range (lo, hi as in the XML, bracket as enforced); the value is
    still ``kept``. Returns the message."""
    s.log.clear()
    status = _set_status(s, name, x)
    assert status == fmi2Error, f"`{name}` = {x!r}: status {status} instead of fmi2Error; log:\n{s.log.text()}"
    errors = [m for (_, st, _, m) in s.log.records if st == fmi2Error]
    named = [m for m in errors if f"`{name}`" in m]
    assert named, f"`{name}` = {x!r}: no fmi2Error message naming `{name}`; log:\n{s.log.text()}"
    want = (exclusive, -math.inf if lo is None else lo, math.inf if hi is None else hi)
    assert any(want in _intervals(m) for m in named), (
        f"`{name}` = {x!r}: no message shows the range {'(' if exclusive else '['}{want[1]}, {want[2]}]:\n"
        + "\n".join(named)
    )
    got = s.get(name)
    assert got == kept, f"`{name}` = {x!r} was refused but the value changed from {kept!r} to {got!r}"
    return named[0]


def _outputs_finite(s):
    values = np.array(s.fmu.getReal(s._real_out_vrs), dtype=np.float64)
    bad = [n for n, x in zip(s.vars.real_outputs, values, strict=True) if not math.isfinite(x)]
    assert not bad, f"outputs not finite: {bad}"


def _step_ok(s, t=0.0):
    """A 1 ms fmi2DoStep from ``t`` returns fmi2OK and every Real output is finite."""
    s.log.clear()
    try:
        status = s.fmu.fmi2DoStep(s.fmu.component, t, INTERVAL, fmi2True)
    except FMICallException as e:
        status = e.status
    assert status == fmi2OK, f"fmi2DoStep({t}, {INTERVAL}): status {status}; log:\n{s.log.text()}"
    _outputs_finite(s)


def _still_usable(s, name, fixed, v0):
    """The start value set back, the instance initialized if it was not, one 1 ms step."""
    _accepted(s, name, v0)
    if fixed:
        s.set_inputs(input_vector(0.0))
        s.fmu.exitInitializationMode()
        assert s.get(name) == v0
    _step_ok(s)


# ---------------------------------------------------------------------------
# every variable with a range


def test_every_parameter_and_input_declares_a_range():
    """Every tunable parameter and every input declares both min and max (fixed
    settings too); only the start values q_start, qd_start are unbounded. Guards the
    parametrized tests below against an FMU that declares no ranges at all."""
    if not fmu_path().is_file():
        pytest.skip(f"{fmu_path()} does not exist")
    md = model_description(str(fmu_path()))
    missing = [
        v.name
        for v in md.modelVariables
        if v.type == "Real"
        and v.causality in ("parameter", "input")
        and not _base(v.name).endswith("_start")
        and (v.min is None or v.max is None)
    ]
    assert not missing, f"no min or max declared: {missing}"
    names = {r[0] for r in RANGED}
    for must in ("m[2]", "k[1]", "slider_b[3]", "d_C[1]", "q_star[3]", "qd_star[2]", "qdd_star[4]", "h_max"):
        assert must in names


def test_urdf_fmu_declares_the_ranges_of_the_reference():
    """The URDF arm's FMU declares min and max for every tunable parameter and input
    (not q_start, qd_start), the same bounds as the reference FMU for the same kind of
    variable."""
    if not fmu_path().is_file():
        pytest.skip(f"{fmu_path()} does not exist")
    assert not URDF_BUILD_ERROR, URDF_BUILD_ERROR
    md = model_description(FMUS["iiwa"])
    missing = [
        v.name
        for v in md.modelVariables
        if v.type == "Real"
        and v.causality in ("parameter", "input")
        and not _base(v.name).endswith("_start")
        and (v.min is None or v.max is None)
    ]
    assert not missing, f"no min or max declared: {missing}"
    reference = {_base(r[0]): r[1:3] for r in RANGED_BY_FMU[""]}
    iiwa = {_base(r[0]): r[1:3] for r in RANGED_BY_FMU["iiwa"]}
    assert {"k", "mu_k", "d_A", "m", "q_star", "qd_star", "qdd_star", "h_max"} <= set(iiwa)
    differ = {b: (reference[b], iiwa[b]) for b in iiwa if b in reference and reference[b] != iiwa[b]}
    assert not differ, differ


def _motor_path():
    if not fmu_path().is_file():
        pytest.skip(f"{fmu_path()} does not exist")
    assert not MOTOR_BUILD_ERROR, MOTOR_BUILD_ERROR
    return FMUS["motor"]


def test_motor_fmu_declares_the_ranges_of_its_motor_variables():
    """The motor FMU declares min and max for every tunable parameter and input (not the start
    values q_start, qd_start, theta_m_start, omega_m_start), the reference FMU's bounds for
    every variable the two share, and the motor variables' own: tau_m [-1e6, 1e6], gear_ratio
    (0, 1e6], J_m (0, 1e3], b_m and tau_c [0, 1e6]."""
    path = _motor_path()
    md = model_description(path)
    missing = [
        v.name
        for v in md.modelVariables
        if v.type == "Real"
        and v.causality in ("parameter", "input")
        and not _base(v.name).endswith("_start")
        and (v.min is None or v.max is None)
    ]
    assert not missing, f"no min or max declared: {missing}"
    motor = {r[0]: r[1:3] for r in _ranged_variables(path)}
    reference = {r[0]: r[1:3] for r in RANGED_BY_FMU[""]}
    differ = {n: (reference[n], motor[n]) for n in reference if motor.get(n) != reference[n]}
    assert not differ, differ
    expected = {
        "tau_m": (-1e6, 1e6),
        "gear_ratio": (0.0, 1e6),
        "J_m": (0.0, 1e3),
        "b_m": (0.0, 1e6),
        "tau_c": (0.0, 1e6),
    }
    got = {f"{b}[{i}]": motor.get(f"{b}[{i}]") for b in expected for i in MOTOR_JOINTS}
    assert got == {f"{b}[{i}]": r for b, r in expected.items() for i in MOTOR_JOINTS}, got
    assert {r[0] for r in RANGED_BY_FMU["motor"]} == set(got)


def _derivative_status(s, names, orders, values):
    """fmi2SetRealInputDerivatives of several values: the status it returns."""
    n = len(names)
    vrs = (fmi2ValueReference * n)(*s.vars.vrs(names))
    try:
        return s.fmu.fmi2SetRealInputDerivatives(
            s.fmu.component, vrs, n, (fmi2Integer * n)(*orders), (fmi2Real * n)(*values)
        )
    except FMICallException as e:
        return e.status


def _motor_steps(s, steps=20):
    """``steps`` steps of 1 ms with tau_m = 0.05 N.m on every motor joint (the derivatives as
    they are): the outputs after each."""
    rows = []
    for k in range(steps):
        s.set_inputs(input_vector(0.0))
        for j in MOTOR_JOINTS:
            s.set(f"tau_m[{j}]", 0.05)
        s.fmu.doStep(k * INTERVAL, INTERVAL)
        rows.append(s.outputs())
    return np.array(rows)


TAU_M_DERIVATIVE_RANGES = {1: 1e9, 2: 1e12}  # order: the bound of the symmetric range


@pytest.mark.parametrize("order", list(TAU_M_DERIVATIVE_RANGES))
@pytest.mark.parametrize("joint", MOTOR_JOINTS)
def test_tau_m_derivative_ranges(joint, order):
    """fmi2SetRealInputDerivatives of tau_m[i] of order 1 (2): exactly +-1e9 (+-1e12) is
    accepted (fmi2OK); the next double beyond each bound, +-1e300 and NaN are refused with
    fmi2Error and an fmi2Error message naming `tau_m[i]` and showing the range; a refused
    value in a call with a good one (the other motor's) takes neither. After the refusals the
    derivatives are those set before them (small rates): 20 steps equal those of an instance
    that only made the good calls, bit for bit."""
    path = _motor_path()
    bound = TAU_M_DERIVATIVE_RANGES[order]
    name = f"tau_m[{joint}]"
    other = f"tau_m[{next(j for j in MOTOR_JOINTS if j != joint)}]"
    good = {name: 2.0, other: -1.0}  # the derivatives set before the refused calls

    def initialized(label):
        s = Slave(label, path=path)
        s.initialize()
        assert _derivative_status(s, list(good), [order, order], list(good.values())) == fmi2OK, s.log.text()
        return s

    with initialized("clean") as s:
        clean = _motor_steps(s)
    with initialized(f"derivative-{name}-{order}") as s:
        for bad in (math.nextafter(bound, math.inf), math.nextafter(-bound, -math.inf), 1e300, -1e300, math.nan):
            s.log.clear()
            status = _derivative_status(s, [name], [order], [bad])
            assert status == fmi2Error, f"{name}, order {order} = {bad!r}: status {status}; log:\n{s.log.text()}"
            named = [m for (_, st, _, m) in s.log.records if st == fmi2Error and f"`{name}`" in m]
            assert named, f"{name}, order {order} = {bad!r}: no fmi2Error message naming it:\n{s.log.text()}"
            if not math.isnan(bad):
                assert any((False, -bound, bound) in _intervals(m) for m in named), named
            # the same value after a good one in one call: neither taken
            status = _derivative_status(s, [other, name], [order, order], [123.0, bad])
            assert status == fmi2Error, status
        assert _motor_steps(s).tobytes() == clean.tobytes()
        for edge in (bound, -bound):
            s.log.clear()
            assert _derivative_status(s, [name], [order], [edge]) == fmi2OK, s.log.text()


def _settable_motor_variables():
    """(name, fixed) of the motor FMU's Real inputs and parameters the reference FMU does not
    have, start values included."""
    if not MOTOR_FMUS:
        return []
    reference = {v.name for v in model_description(str(fmu_path())).modelVariables}
    return [
        (v.name, v.variability == "fixed")
        for v in model_description(MOTOR_FMUS["motor"]).modelVariables
        if v.type == "Real" and v.causality in ("parameter", "input") and v.name not in reference
    ]


@pytest.mark.parametrize(
    "var",
    [pytest.param(v, id=f"motor:{v[0]}") for v in _settable_motor_variables()]
    or [pytest.param(None, marks=pytest.mark.skip(reason="no motor FMU"))],
)
def test_motor_variables_refuse_nan_and_infinity(var):
    """NaN, +inf and -inf set to a motor variable (tau_m, gear_ratio, J_m, b_m, tau_c,
    theta_m_start, omega_m_start) are refused with fmi2Error and an fmi2Error message naming
    it; the value is kept; the instance then steps."""
    path = _motor_path()
    name, fixed = var
    with _slave(name, fixed, path) as s:
        v0 = s.get(name)
        for bad in (math.nan, math.inf, -math.inf):
            s.log.clear()
            status = _set_status(s, name, bad)
            assert status == fmi2Error, f"`{name}` = {bad!r}: status {status}; log:\n{s.log.text()}"
            assert any(f"`{name}`" in m for (_, st, _, m) in s.log.records if st == fmi2Error), s.log.text()
            assert s.get(name) == v0
        _still_usable(s, name, fixed, v0)


@pytest.mark.parametrize("var", _params("max"))
def test_max_is_accepted_and_above_is_refused(var):
    """Exactly max is accepted; the next double above and 1e300 are refused with the
    variable and its range in the message, the value kept; the instance then steps."""
    path, name, lo, hi, fixed = _unpack(var)
    exclusive = lo is not None and _declares_exclusive_min(name, lo, hi, path)
    with _slave(name, fixed, path) as s:
        v0 = s.get(name)
        for bad in (math.nextafter(hi, math.inf), 1e300):
            _refused(s, name, bad, lo, hi, exclusive, kept=v0)
        _accepted(s, name, hi)
        _refused(s, name, math.nextafter(hi, math.inf), lo, hi, exclusive, kept=hi)
        _still_usable(s, name, fixed, v0)


@pytest.mark.parametrize("var", _params("min"))
def test_min_is_enforced_as_declared(var):
    """An excluded min (declared as such in the description, and pinned in
    EXCLUSIVE_MIN) is refused and the next double above it accepted; an included min
    is accepted and the next double below refused. Far below (-1e300) is refused.
    The message shows the same interval; the value is kept; the instance then steps."""
    path, name, lo, hi, fixed = _unpack(var)
    exclusive = _declares_exclusive_min(name, lo, hi, path)
    assert exclusive == (_base(name) in EXCLUSIVE_MIN), (
        f"`{name}`: the modelDescription declares min = {lo} "
        + ("excluded" if exclusive else f"included (no interval ({lo}, {hi}] in its description)")
        + f", expected {'excluded' if _base(name) in EXCLUSIVE_MIN else 'included'}"
    )
    with _slave(name, fixed, path) as s:
        v0 = s.get(name)
        below = math.nextafter(lo, -math.inf)
        for bad in ([lo] if exclusive else []) + [below, -1e300]:
            _refused(s, name, bad, lo, hi, exclusive, kept=v0)
        edge = math.nextafter(lo, math.inf) if exclusive else lo
        _accepted(s, name, edge)
        _refused(s, name, lo if exclusive else below, lo, hi, exclusive, kept=edge)
        _still_usable(s, name, fixed, v0)


@pytest.mark.parametrize("var", _params("max"))
def test_refused_value_in_a_batch_changes_nothing(var):
    """A set of several values with one out of range is refused as a whole: the valid
    values before it in the same call are not taken either."""
    path, name, _, hi, fixed = _unpack(var)
    with _slave(name, fixed, path) as s:
        # Another variable of the same mode and its start value, set to a valid
        # different value in the same call, before the bad one.
        ranged = RANGED_BY_FMU[next(k for k, p in FMUS.items() if p == path)]
        other = next(r for r in ranged if r[0] != name and r[3] == fixed)
        o_name, o_lo, o_hi = other[0], other[1], other[2]
        o0 = s.get(o_name)
        o_new = o_hi if o0 != o_hi else o_lo
        v0 = s.get(name)
        s.log.clear()
        with pytest.raises(FMICallException) as info:
            s.fmu.setReal(s.vars.vrs([o_name, name]), [o_new, math.nextafter(hi, math.inf)])
        assert info.value.status == fmi2Error
        assert s.get(o_name) == o0, f"`{o_name}` took {o_new!r} from a refused call"
        assert s.get(name) == v0


# ---------------------------------------------------------------------------
# issue 13


ISSUE_13 = {
    "m[2]=1e300": ("m[2]", 1e300),
    "slider_b[3]=1e300": ("slider_b[3]", 1e300),
    "q_star[3]=-1e300": ("q_star[3]", -1e300),
    "qd_star[2]=1e300": ("qd_star[2]", 1e300),
    "qd_star[2]=-1e300": ("qd_star[2]", -1e300),
}


@pytest.mark.parametrize("case", list(ISSUE_13))
def test_issue_13_values_are_refused(case):
    """The values issue 13 reported are refused with fmi2Error and a message naming the
    variable and its range; the instance keeps its value and runs 300 steps of the
    reference motion with every output finite."""
    name, x = ISSUE_13[case]
    declared = {r[0]: r for r in RANGED}
    if not fmu_path().is_file():
        pytest.skip(f"{fmu_path()} does not exist")
    assert name in declared, f"`{name}` declares no range"
    _, lo, hi, _ = declared[name]
    with _slave(name, fixed=False) as s:
        v0 = s.get(name)
        _refused(s, name, x, lo, hi, _base(name) in EXCLUSIVE_MIN, kept=v0)
        rows = s.run_reference(0, 300)
        assert np.all(np.isfinite(rows)), f"{case}: non-finite outputs after the refused set"


def test_issue_13_mass_message_is_the_documented_one():
    """The README quotes the message of `m[2]` = 1e300 word for word: the value in
    short form, the requirement in words and the interval."""
    with _slave("m[2]", fixed=False) as s:
        message = _refused(s, "m[2]", 1e300, 0.0, 1e6, True, kept=s.get("m[2]"))
        assert message.endswith("`m[2]` = 1e300: must be positive and at most 1e6: (0, 1e6]"), message


def test_issue_13_tiny_bearing_diameter_is_accepted_and_runs():
    """d_C[1] = 1e-300 lies in [0, 100]: accepted, and 300 steps of 1 ms of the
    reference motion run with fmi2OK and every output finite."""
    with _slave("d_C[1]", fixed=False) as s:
        _accepted(s, "d_C[1]", 1e-300)
        for k in range(300):
            t = k * INTERVAL
            s.set_inputs(input_vector(t))
            _step_ok(s, t)
        assert s.get("d_C[1]") == 1e-300
        assert np.all(np.isfinite(s.outputs()))
