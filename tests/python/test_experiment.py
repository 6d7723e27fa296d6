"""A whole experiment in one native call (``stickslip_run_experiment``, python/stickslip/experiment.py)
through the packaged FMU as the fit drives it (fmpy instantiates and sets it up, the library runs
the experiment): the per-point FMI calls' numbers bit for bit, in single and multiple shooting
and where a step is discarded; and the sensitivities of a fit's residuals, assembled over
segments and channels, against differences of free runs."""

from __future__ import annotations

import numpy as np
import pytest

import fit_cases as fc
from helpers import require_fmu


def _problem(tmp_path, names, options=None, duration=0.6):
    from stickslip.fit.problem import Evaluator, Problem, payload_of
    from stickslip.fit.spec import load
    from stickslip.fmu import content_hash, unpacked

    data = fc.write_data(tmp_path / "run.csv", fc.measured(duration, seed=2))
    spec = load(
        fc.spec(
            fc.experiment(data, parameters=dict(options or {})),
            names,
            {n: fc.TRUTH[n] for n in names},
            {n: fc.BOUNDS[n] for n in names if n != "mu_k[1]" or "mu_s[1]" in names},
        )
    )
    fmu = require_fmu().read_bytes()
    digest = content_hash(fmu)
    known = {e.name: e.initial for e in spec.estimates}
    payloads = [payload_of(e, spec.model_description, unpacked(fmu, digest), known) for e in spec.experiments]
    return Problem(spec, Evaluator(fmu, digest, payloads))


def _runs(problem, z, segment, per_point: bool, monkeypatch):
    monkeypatch.setenv("STICKSLIP_PER_POINT", "1" if per_point else "0")
    problem.forget()  # the problem keeps a point's runs: each way must run it
    return problem.runs([z], segment)[0]


@pytest.mark.parametrize("segment", [None, 0.1])
def test_the_fits_runs_are_the_per_point_calls_bit_for_bit(tmp_path, monkeypatch, segment):
    """Single shooting from the measured start, and multiple shooting in 0.1 s segments: every
    output of every sample, bit for bit, native against per point."""
    problem = _problem(tmp_path, ["mu_k[1]", "k[3]"])
    z = problem.transform.z([0.16, 7e5])
    native = _runs(problem, z, segment, False, monkeypatch)
    per_point = _runs(problem, z, segment, True, monkeypatch)
    for a, b in zip(native, per_point, strict=True):
        assert (a.status, a.reached) == (b.status, b.reached) == ("ok", len(problem.spec.experiments[0].time))
        np.testing.assert_array_equal(a.values.view(np.uint64), b.values.view(np.uint64))


def test_a_discarded_step_is_the_per_point_calls_result(tmp_path, monkeypatch):
    """Where the FMU discards a step (k[3] = 3e10 at fixed 0.2 ms sub-steps), the native run ends
    as the per-point one: status discard, the same samples reached and the same numbers."""
    problem = _problem(tmp_path, ["k[3]"], {"tolerance": 1e-12, "h_min": 2e-4, "h_max": 2e-4})
    problem.spec.estimates[0].high = 1e11
    from stickslip.fit.problem import Transform

    problem.transform = Transform(problem.spec.estimates)
    z = problem.transform.z([3e10])
    native = _runs(problem, z, None, False, monkeypatch)[0]
    per_point = _runs(problem, z, None, True, monkeypatch)[0]
    assert native.status == per_point.status == "discard", (native, per_point)
    assert native.reached == per_point.reached
    np.testing.assert_array_equal(native.values.view(np.uint64), per_point.values.view(np.uint64))
    # The same reason, from the call that made the step: stickslip_run_experiment, fmi2DoStep.
    assert native.message.startswith("stickslip_run_experiment: step [")
    assert native.message.split(": ", 1)[1] == per_point.message.split(": ", 1)[1]
    assert "not completed" in native.message


@pytest.mark.parametrize("segment", [None, 0.1])
def test_the_residuals_jacobian_from_sensitivities_is_their_differences(tmp_path, monkeypatch, segment):
    """Problem.residual_jacobian (samples x channels x estimates from the FMU, divided by each
    channel's sigma, stacked channel by channel as the residual vector is, times dtheta/dz of
    the log and linear scales) against central differences of the residuals of free runs at
    fixed 0.1 ms sub-steps, where both differentiate the same scheme: within 1e-3 of each
    column's largest value (the free runs' own noise over a change of 1e-4 of the range),
    every column exact."""
    fixed = {"h_min": 1e-4, "h_max": 1e-4, "tolerance": 1e-13}
    problem = _problem(tmp_path, ["mu_k[1]", "mu_s[1]", "k[3]"], fixed, duration=0.4)
    monkeypatch.setenv("STICKSLIP_PER_POINT", "0")
    z = problem.transform.z([0.18, 0.23, 7e5])
    fc.sensitivities_against_differences(problem, z, segment)


@pytest.mark.slow
def test_a_motor_arms_jacobian_carries_the_rotors_start_through_the_gear(tmp_path, monkeypatch):
    """On the motor arm in multiple shooting each segment's rotor starts turned to carry its
    link's load, theta_m = N (q + F/k + sgn(F) Delta) (fit/start.py): the start moves with the gear
    stiffness k[i], and the runner folds the sensitivities to theta_m_start[i] into k[i]'s column
    by the chain rule. Against the best central difference of free runs at fixed 0.1 ms
    sub-steps over 1e-3 to 1e-6 of the log range (the rotor start recomputed from the moved k in
    each): within 1e-3 of each column's largest value (measured 1.7e-4 for k[1], 1.9e-4 for k[3],
    at 1e-5 and 1e-6; at 1e-3 the stick-slip pattern changes and the differences are off by
    40-120 %); without the chain term the k columns move by more than 1e-2 (checked below)."""
    import json

    from motor_fmus import motor_fmu
    from stickslip.fit import runner
    from stickslip.fit.benchmark import generate
    from stickslip.fit.problem import Evaluator, Problem, payload_of
    from stickslip.fit.spec import load
    from stickslip.fmu import content_hash, unpacked

    require_fmu()
    fmu_path = motor_fmu()
    p = generate(fmu_path, 1, tmp_path, arm="motor", duration=0.6, n_parameters=2)
    spec = json.loads((tmp_path / "spec.json").read_text())
    truth = dict(p.truth)
    names = [f"k[{i}]" for i in (1, 3)]
    for n in names:
        value = truth.get(n) or 1e6
        spec["estimate"][n] = {"initial": value, "bounds": [0.5 * value, 2.0 * value], "scale": "log"}
    for e in spec["experiment"]:
        e["parameters"] = {**e.get("parameters", {}), "h_min": 1e-4, "h_max": 1e-4, "tolerance": 1e-13}
        for n in names:
            e["parameters"].pop(n, None)
    spec = load(spec, base_dir=tmp_path)
    data = fmu_path.read_bytes()
    digest = content_hash(data)
    known = {e.name: e.initial for e in spec.estimates}
    payloads = [payload_of(e, spec.model_description, unpacked(data, digest), known) for e in spec.experiments]
    problem = Problem(spec, Evaluator(data, digest, payloads))
    assert problem.segments(0.1)[0].motors, "the motor arm's segments start its rotors"
    monkeypatch.setenv("STICKSLIP_PER_POINT", "0")
    z = problem.transform.z([e.initial for e in spec.estimates])
    runs = problem.runs([z], 0.1, problem.sensitivity_steps(z))[0]
    J, exact = problem.residual_jacobian(runs, z)
    columns = [j for j, e in enumerate(spec.estimates) if e.name in names]
    for j in columns:
        best = np.inf
        for h in (1e-3, 1e-4, 1e-5, 1e-6):
            reference = fc.central_column(problem, z, j, 0.1, h)
            scale = np.max(np.abs(reference))
            assert scale > 0 and exact[j], (spec.estimates[j].name, exact)
            best = min(best, np.max(np.abs(J[:, j] - reference)) / scale)
        assert best <= 1e-3, (spec.estimates[j].name, best)
    # The chain term matters: without it the same columns are far off.
    monkeypatch.setattr(runner, "_rotor_chain", lambda *a, **k: {})
    runs = problem.runs([z], 0.1, problem.sensitivity_steps(z))[0]
    J0, _ = problem.residual_jacobian(runs, z)
    assert max(np.max(np.abs(J0[:, j] - J[:, j])) / np.max(np.abs(J[:, j])) for j in columns) > 1e-2


def test_a_point_asked_for_again_is_not_run_again_in_the_same_thread(tmp_path):
    """Problem.runs keeps each thread's recent points (runs are deterministic): the same point
    again costs no run and gives the same objects; another thread runs it anew (so that which
    points are found does not depend on how the starts' threads interleave); a point differing
    in the last bit, another error tolerance or another segment length is run; ``forget`` forgets."""
    import threading

    from stickslip.fit.problem import RECENT

    problem = _problem(tmp_path, ["mu_k[1]", "k[3]"], duration=0.2)
    z = problem.transform.z([0.16, 7e5])
    first = problem.runs([z])[0]
    runs = problem.evaluator.runs
    again = problem.runs([np.array(z), z])
    assert problem.evaluator.runs == runs and again[0] is first and again[1] is first
    other = {}
    t = threading.Thread(target=lambda: other.setdefault("r", problem.runs([z])[0]))
    t.start()
    t.join()
    assert problem.evaluator.runs == runs + 1 and other["r"] is not first
    np.testing.assert_array_equal(other["r"][0].values, first[0].values)
    nudged = np.array(z)
    nudged[0] = np.nextafter(nudged[0], 1.0)
    problem.runs([nudged])
    problem.runs([z], 0.1)
    problem.with_tolerance(1e-5).runs([z])
    assert problem.evaluator.runs == runs + 4
    problem.forget()
    problem.runs([z])
    assert problem.evaluator.runs == runs + 5
    # At most RECENT points are kept: the oldest is run again.
    problem.forget()
    points = [problem.transform.z([0.16 + 1e-4 * k, 7e5]) for k in range(RECENT + 1)]
    problem.runs(points)
    count = problem.evaluator.runs
    problem.runs([points[-1]])
    assert problem.evaluator.runs == count
    problem.runs([points[0]])
    assert problem.evaluator.runs == count + 1


def test_a_run_that_ends_in_an_error_is_not_kept(tmp_path):
    """A run that ends in an error which may be the worker's, not the FMU's answer (here an FMU
    that cannot be unpacked where the run is made), is not kept: asked for again, the point is
    run again, and gives the FMU's answer once the FMU is there."""
    problem = _problem(tmp_path, ["mu_k[1]", "k[3]"], duration=0.2)
    z = problem.transform.z([0.16, 7e5])
    evaluator = problem.evaluator
    digest, data = evaluator.digest, evaluator.fmu_data
    evaluator.digest, evaluator.fmu_data = "0" * 64 + "-not-unpacked", b"not a zip file"
    (broken,) = problem.runs([z])[0]
    assert broken.status == "error" and "FMU not available here" in broken.message, broken
    evaluator.digest, evaluator.fmu_data = digest, data
    count = evaluator.runs
    (good,) = problem.runs([z])[0]
    assert evaluator.runs == count + 1 and good.status == "ok"
    problem.runs([z])
    assert evaluator.runs == count + 1  # the FMU's answer is kept
