"""The error-controlled stepper gives the fixed 2e-6 s answer, through the FMU.

The default settings (sub-steps between h_min = 2e-6 s and h_max = 5e-4 s at
error_tolerance 5e-4) are compared with fixed sub-steps of 2e-6 s (h_min =
h_max), the step the study found converged, on the reference motion and on each
of the study's variants: max and final end-point error ε within 0.1 %, the same
number of stiction phases in every joint (the engine's exact count, and the
phases seen in the stick flags sampled at 1 ms), stuck-time fractions within
0.002; with the master stepping at 1 ms and at 10 ms. A stiff variant (k = 1e8
in both drives, decreasing characteristic) needs the step floor and still
agrees. Tightening the tolerance tenfold moves max ε by less than the
tolerance promises. Sub-step counts, not times, are asserted: the speed is
measured by the benches (docs/error_control.md).
"""

import itertools
import math

import numpy as np
import pytest

from helpers import Slave

RUN_TIME = 2.0
FIXED = {"h_min": 2e-6, "h_max": 2e-6}
DECREASING = {f"{p}[{j}]": v for j in (1, 3) for p, v in (("mu_k", 0.12), ("mu_s", 0.2), ("v_s", 0.01))}
DAMPED = {"h[1]": 1e3, "h[3]": 1e3}
VARIANTS = {
    "reference": {},
    "mu3=0.1": {"mu_k[3]": 0.1, "mu_s[3]": 0.1},
    "decreasing": DECREASING,
    "clearance": {"Delta[1]": math.pi / 90, "Delta[3]": 0.002},
    "slider 0.2 damped": {**DAMPED, "slider_a[3]": 0.2},
    "slider 0.4 damped": {**DAMPED, "slider_a[3]": 0.4},
}
STIFF = {"k[1]": 1e8, "k[3]": 1e8, **DECREASING}
WATCHED = (
    "eps",
    "n_stick[1]",
    "n_stick[3]",
    "t_stick[1]",
    "t_stick[3]",
    "stick[1]",
    "stick[3]",
    "n_substeps",
    "n_rejected",
    "h_last",
)

_RUNS = {}


def run(parameters: dict, interval: float) -> dict:
    """The reference motion over 2 s at communication steps `interval` with
    `parameters` set before initialization: the watched outputs at t = 0 and
    after every step (cached per process)."""
    key = (tuple(sorted(parameters.items())), interval)
    if key not in _RUNS:
        with Slave("error-control") as s:
            s.initialize(start_values=parameters)
            rows = np.vstack([s.outputs(), s.run_reference(0, round(RUN_TIME / interval), interval)])
            names = s.output_names()
        _RUNS[key] = {n: rows[:, names.index(n)] for n in WATCHED}
    return _RUNS[key]


def sampled_phases(stick: np.ndarray) -> int:
    """Stiction phases seen in a sampled stick flag: runs of 1."""
    flags = stick.astype(bool)
    return int(flags[0]) + int(np.count_nonzero(flags[1:] & ~flags[:-1]))


def assert_same_answer(adaptive: dict, fixed: dict, label: str, interval: float):
    for what, pick in (("max", np.max), ("final", lambda x: x[-1])):
        a, f = pick(adaptive["eps"]), pick(fixed["eps"])
        assert abs(a - f) <= 1e-3 * f, f"{label}: {what} ε {a:.6e} vs {f:.6e} (fixed 2e-6 s)"
    for j in (1, 3):
        count = f"n_stick[{j}]"
        assert adaptive[count][-1] == fixed[count][-1], f"{label}: {count} {adaptive[count][-1]} vs {fixed[count][-1]}"
        if interval == 1e-3:
            phases = sampled_phases(adaptive[f"stick[{j}]"]), sampled_phases(fixed[f"stick[{j}]"])
            assert phases[0] == phases[1], f"{label}: stiction phases of joint {j} sampled at 1 ms {phases}"
        fraction = abs(adaptive[f"t_stick[{j}]"][-1] - fixed[f"t_stick[{j}]"][-1]) / RUN_TIME
        assert fraction <= 0.002, f"{label}: stuck-time fraction of joint {j} differs by {fraction}"


@pytest.mark.parametrize("interval", [1e-3, 1e-2], ids=["1ms", "10ms"])
@pytest.mark.parametrize("name", list(VARIANTS))
def test_default_error_control_gives_the_fixed_step_answer(name, interval):
    parameters = VARIANTS[name]
    adaptive, fixed = run(parameters, interval), run({**parameters, **FIXED}, interval)
    assert_same_answer(adaptive, fixed, f"{name} at {interval:g} s", interval)
    steps, fixed_steps = adaptive["n_substeps"][-1], fixed["n_substeps"][-1]
    print(
        f"{name} at {interval:g} s: {steps:.0f} sub-steps ({adaptive['n_rejected'][-1]:.0f} rejected) "
        f"vs {fixed_steps:.0f} fixed"
    )
    assert fixed_steps >= RUN_TIME / 2e-6
    assert steps < 0.2 * fixed_steps, f"{name}: {steps} sub-steps"


def test_stiff_drives_reach_the_floor_and_agree():
    """k = 1e8 in both drives with the decreasing characteristic: the vibration period is
    under 2 ms, so the error control goes down to h_min where the joints slip, and the
    result still equals the fixed-step run's."""
    adaptive, fixed = run(STIFF, 1e-3), run({**STIFF, **FIXED}, 1e-3)
    assert_same_answer(adaptive, fixed, "stiff", 1e-3)
    assert np.min(adaptive["h_last"][1:]) <= 2e-6 * (1 + 1e-9), "the floor h_min was never needed"
    assert np.max(adaptive["h_last"][1:]) > 1e-5, "the steps never grew"
    assert adaptive["n_rejected"][-1] < 0.01 * adaptive["n_substeps"][-1], "the control oscillates"


def test_tightening_the_tolerance_moves_max_eps_less_than_it_promises():
    """error_tolerance is a relative error per second of motion: over the 2 s run the
    promise is 2 tolerance. Max ε moves by less than that when the tolerance is
    tightened tenfold, and the sub-steps grow as tolerance^(-1/2)."""
    rows = []
    for tolerance in (5e-3, 5e-4, 5e-5):
        r = run({"error_tolerance": tolerance}, 1e-3)
        rows.append((tolerance, np.max(r["eps"]), r["n_substeps"][-1]))
    for (tol, eps, steps), (_, finer, finer_steps) in itertools.pairwise(rows):
        assert abs(eps - finer) <= 2.0 * tol * finer, f"tolerance {tol}: max ε {eps} vs {finer} at tol/10"
        assert 2.0 < finer_steps / steps < 5.0, f"tolerance {tol}: {steps} -> {finer_steps} sub-steps"
    fixed = np.max(run(FIXED, 1e-3)["eps"])
    assert abs(rows[-1][1] - fixed) <= 1e-5 * fixed


def test_setup_experiment_tolerance_sets_the_error_tolerance():
    """fmi2SetupExperiment(toleranceDefined, tolerance) sets error_tolerance, as FMI 2.0 intends
    for an FMU with an internal integrator; a tolerance outside (0, 0.1] is refused."""
    from fmpy.fmi1 import FMICallException

    with Slave("tolerance") as s:
        s.fmu.setupExperiment(tolerance=5e-5, startTime=0.0)
        s.fmu.enterInitializationMode()
        assert s.get("error_tolerance") == 5e-5
    with Slave("bad-tolerance") as s:
        with pytest.raises(FMICallException):
            s.fmu.setupExperiment(tolerance=0.5, startTime=0.0)
        assert any("tolerance" in message for (_, _, _, message) in s.log.records)
        s.fmu.setupExperiment(startTime=0.0)
        s.fmu.enterInitializationMode()
        assert s.get("error_tolerance") == 5e-4
