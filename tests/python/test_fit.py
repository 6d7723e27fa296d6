"""`stickslip fit` (issue 29): the parameters of the reference arm's FMU recovered from runs the
FMU itself measured at known parameters (tests/python/fit_cases.py), with standard errors that
hold up under repeated noise, warnings where the data cannot tell parameters apart, runs the FMU
refuses or discards penalized rather than fatal, several starts and several experiments, the
same estimates on a Dask cluster as in one process, every bad input refused in one line with
exit status 2 and nothing written, and the result files.

The experiments are short (0.3-1 s of the reference motion at 1 ms) and fit 1-3 parameters,
in this process (``workers=0``) except on the cluster, so that the module runs in a few minutes
on two cores. The truth: μ_k[1] = 0.17, μ_s[1] = 0.22, μ_k[3] = 0.2, k[3] = 8e5 (the
parameters not estimated are given to the fit as known).
"""

from __future__ import annotations

import json
import math
import random
import shlex
import subprocess
import tempfile
import tomllib
from pathlib import Path

import numpy as np
import pytest

import fit_cases as fc
from helpers import allowed_misses, require_fmu
from sweep_cluster import STICKSLIP

# The measurement's own integration: tight enough to stand for the exact solution.
EXACT = {"error_tolerance": 1e-8}


def _fit(spec, **kw):
    from stickslip.fit import fit

    return fit(spec, workers=kw.pop("workers", 0), **kw)


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(abs(b), 1e-300)


def _noise_floor(result: dict) -> float:
    """The cost expected at the truth: half the number of samples (each (model - measured)/σ
    of unit variance)."""
    return 0.5 * result["method"]["samples"]


# ---------------------------------------------------------------------------
# estimates and their uncertainty


@pytest.mark.full
def test_noiseless_data_give_the_true_parameters_to_1e_4(tmp_path):
    """Noiseless encoders (no noise, no quantization), measured at error_tolerance 1e-8, the
    inputs the four q* columns (rates from the fit's cubic spline): μ_k[1], μ_s[1], k[3] from
    2 % off come back to 1e-4 relative, the fit's runs at error_tolerance 1e-6. What limits
    it (largest relative error over the three, measured on this case): the integration of the
    fitted runs down to about 1e-6 (6e-5 at the FMU's default 5e-4, 6e-7 at 1e-5), then the
    spline of the inputs (8.5e-8 at 1e-6 and at 1e-7; 3e-11 with the exact motion file
    examples/motions/reference.toml instead of the columns)."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.5, noise=0.0, truth=EXACT))
    names = ["mu_k[1]", "mu_s[1]", "k[3]"]
    initial = {n: 1.02 * fc.TRUTH[n] for n in names}
    r = _fit(fc.spec(fc.experiment(data), names, initial, shooting="single", error_tolerance=1e-6))
    errors = {n: _rel(r["parameters"][n]["value"], fc.TRUTH[n]) for n in names}
    print("relative errors:", {n: f"{e:.2e}" for n, e in errors.items()}, "cost", r["cost"])
    assert r["converged"]
    assert max(errors.values()) <= 1e-4, errors


def _coverage(tmp_path, names: list, duration: float, seeds: int = 20):
    """Fits of ``names`` to the same run under ``seeds`` noise draws, started at the truth:
    (estimates, standard errors, results)."""
    base = fc.measured(duration, noise=0.0, truth=EXACT)
    values, errors, results = [], [], []
    for seed in range(seeds):
        data = fc.write_data(tmp_path / f"seed{seed}.csv", fc.with_noise(base, seed))
        r = _fit(fc.spec(fc.experiment(data), names, shooting="single"))
        values.append([r["parameters"][n]["value"] for n in names])
        errors.append([r["parameters"][n]["std_error"] for n in names])
        results.append(r)
    return np.array(values), np.array(errors), results


def _check_coverage(names, values, errors, results):
    truth = np.array([fc.TRUTH[n] for n in names])
    inside = np.abs(values - truth) <= 3.0 * errors
    spread = values.std(axis=0, ddof=1) / errors.mean(axis=0)
    print(
        f"truth within 3 SE in {inside.sum(axis=0).tolist()} of {len(values)} seeds ({names}), "
        f"all at once in {int(inside.all(axis=1).sum())}; std(estimates)/mean(SE) {np.round(spread, 3).tolist()}; "
        f"(estimate - truth)/SE {np.round((values - truth) / errors, 2).tolist()}"
    )
    # Sized (issue 41): each of the 20 seeds' pairs may miss with p = 0.05 (an asymptotic
    # standard error's allowance, 18 times the normal 0.0027); allowed_misses(20, 0.05) = 5, a
    # false failure P(X >= 6 | 20, 0.05) = 3.3e-4. With 20 pairs it sees an estimator 4 SE off
    # (misses with p = 0.84: fails with P(X >= 6 | 20, 0.84) > 0.9999), not reliably one 2.5 SE
    # off (p = 0.31: 0.6); the 45-pair benchmark and the identification's 171 pairs see that.
    allowed = allowed_misses(len(values), 0.05)
    misses = (~inside).sum(axis=0)
    assert np.all(misses <= allowed), (misses, allowed)
    biased = np.abs(values + 4.0 * errors - truth) <= 3.0 * errors
    assert np.all((~biased).sum(axis=0) > allowed), "the planted bias went unseen"
    assert np.all((spread >= 0.5) & (spread <= 2.0)), spread
    for r in results:
        assert r["converged"]
        assert 0.9 <= r["rms_normalized_residual"] <= 1.1, r["rms_normalized_residual"]
        assert not [w for w in r["warnings"] if "identifiable" in w], r["warnings"]


@pytest.mark.full
def test_standard_errors_hold_up_under_20_noise_seeds(tmp_path):
    """The encoders' noise of the issue (2e-6 rad on q[1], 1e-6 m on q[3]), 20 seeds, 0.5 s,
    μ_k[1] and k[3] fitted from the truth (single shooting: the start is in the basin) at the
    FMU's default error_tolerance while the measurement was integrated at 1e-8: each
    parameter's truth lies within 3 reported standard errors in at least 15 of the 20 (sized
    in _check_coverage: a false failure in 3.3e-4 of runs; moved 4 SE it fails), and
    the estimates scatter as the standard errors say (std over the seeds / mean SE in [0.5,
    2]); no identifiability warning (the pair is well determined). Measured: 19 and 20 of 20,
    ratios 1.21 and 1.17."""
    names = ["mu_k[1]", "k[3]"]
    _check_coverage(names, *_coverage(tmp_path, names, 0.5))


@pytest.mark.slow
def test_standard_errors_hold_up_under_20_noise_seeds_three_parameters(tmp_path):
    """As above with μ_s[1] as well (the pair μ_k[1], μ_s[1] through the fit's μ_s − μ_k ≥ 0),
    over 0.8 s. Measured: 20, 20, 20 of 20; ratios 1.13, 0.88, 0.83."""
    names = ["mu_k[1]", "mu_s[1]", "k[3]"]
    _check_coverage(names, *_coverage(tmp_path, names, 0.8))


def test_a_pair_the_data_cannot_separate_is_named(tmp_path):
    """Joint 1's bearing friction is μ·(R_A·d_A/2 + R_B·d_B/2 + ⅔|f_z|·d_C/2) (3.13)-(3.14),
    and over this motion the radial loads are set by the moment on the joint, R_A ≈ R_B: the
    data fix d_A[1] + d_B[1] and hardly their difference (correlation -0.9995 measured). The
    fit warns naming both; the standard error of the sum, from the reported standard errors
    and correlation, is less than a quarter of either's, and the sum is the truth's (0.2 m)
    within 3 of it."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.5, seed=3))
    names = ["d_A[1]", "d_B[1]"]
    r = _fit(fc.spec(fc.experiment(data), names, shooting="single"))
    corr = r["correlation"]["matrix"][0][1]
    print("correlation", corr, r["warnings"])
    assert corr < -0.95
    named = [w for w in r["warnings"] if "d_A[1]" in w and "d_B[1]" in w and "identifiable" in w]
    assert named, r["warnings"]
    a, b = (r["parameters"][n] for n in names)
    se_sum = math.sqrt(a["std_error"] ** 2 + b["std_error"] ** 2 + 2 * corr * a["std_error"] * b["std_error"])
    print("sum", a["value"] + b["value"], "+-", se_sum, "each +-", a["std_error"], b["std_error"])
    assert se_sum < 0.25 * min(a["std_error"], b["std_error"])
    assert abs(a["value"] + b["value"] - 0.2) <= 3 * se_sum


def test_the_equation_error_stage_starts_near_the_truth(tmp_path):
    """Issue 29, item 2: the equation-error stage (IDIM-LS on the measured motion, no
    simulation) gives a start of its own, and from the encoders of 1 s of the reference motion
    it lands within 10 % of μ_k[1] and k[3] though the initial values are 30 % off."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(1.0, seed=1))
    initial = {"mu_k[1]": 0.12, "k[3]": 5.6e5}
    r = _fit(fc.spec(fc.experiment(data), list(initial), initial, shooting="single", max_evaluations=1))
    print(r["method"]["equation_error_stage"])
    stage = [s for s in r["starts"] if s["origin"] == "equation-error"]
    assert stage, r["method"]["equation_error_stage"]
    for n, v in stage[0]["initial"].items():
        assert _rel(v, fc.TRUTH[n]) < 0.1, (n, v)


# ---------------------------------------------------------------------------
# runs the FMU discards or refuses

# Fixed sub-steps of 0.2 ms and an iteration tolerance of 1e-12: at k[3] >= 1e9 (almost
# everywhere above: 2.5e9 runs) the Newmark iteration of joint 3 cannot converge and the FMU
# answers fmi2Discard within the first 20 ms; the truth (8e5) runs, and fast.
DISCARDING = {"tolerance": 1e-12, "h_min": 2e-4, "h_max": 2e-4}


@pytest.mark.full
def test_starts_in_a_region_the_fmu_discards_are_reported_and_the_fit_finishes(tmp_path):
    """k[3] on a log scale over [1e5, 1e11] with the settings above: the initial value 3e10
    and the Latin hypercube's top stratum [6e9, 1e11] lie where every run is discarded, its
    bottom stratum [1e5, 1.6e6] in the basin of the truth. The fit does not end: the
    discarded runs are counted in failed_runs with the FMU's reason, the starts that ended
    there have no cost, and the best start is the truth within 3 standard errors at the noise
    floor."""
    from stickslip.fit.runner import Payload, run
    from stickslip.fmu import content_hash
    from stickslip.motion import reference_inputs

    columns = fc.measured(0.5, seed=1, truth=DISCARDING)
    fmu = require_fmu().read_bytes()
    at_start = run(
        content_hash(fmu),
        Payload("probe", columns["t"], reference_inputs, None, ["q[3]"], {}),
        {**fc.TRUTH, **DISCARDING, "k[3]": 3e10},
        fmu_data=fmu,
    )
    assert at_start.status == "discard", at_start
    data = fc.write_data(tmp_path / "run.csv", columns)
    spec = fc.spec(
        fc.experiment(data, parameters=dict(DISCARDING)),
        ["k[3]"],
        {"k[3]": 3e10},
        {"k[3]": (1e5, 1e11)},
        shooting="single",
        starts=6,
        seed=1,
        max_evaluations=25,
    )
    r = _fit(spec)
    failed = r["failed_runs"]
    print(failed["by_status"], [(s["origin"], s["cost"], s["status"]) for s in r["starts"]])
    assert failed["count"] > 0 and failed["by_status"].get("discard", 0) > 0, failed
    assert all(f["status"] in ("discard", "refused") and f["message"] for f in failed["first"])
    assert any("not completed" in f["message"] for f in failed["first"]), failed["first"]
    initial = next(s for s in r["starts"] if s["origin"] == "initial")
    assert initial["cost"] is None and initial["status"] == "failed", initial
    k = r["parameters"]["k[3]"]
    assert math.isfinite(r["cost"]) and r["cost"] < 1.2 * _noise_floor(r), r["cost"]
    assert abs(k["value"] - fc.TRUTH["k[3]"]) <= 3 * k["std_error"], k


def test_a_start_the_fmu_refuses_is_penalized_not_fatal(tmp_path):
    """The FMU refuses bearings of joint 1 shorter than 1 mm in all (l_A + l_B, at
    fmi2ExitInitializationMode) though each length alone is in its range: with l_B[1] = 0.2 mm
    known and l_A[1] estimated in [0, 0.2] m from 0.5 mm, the initial point and its
    neighbours are refused. The fit goes on: failed_runs counts them as refused with the
    FMU's reason, the initial start ends without a cost, another start gives a finite one."""
    known = {"l_B[1]": 0.0002}
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.3, seed=1, truth=known))
    spec = fc.spec(
        fc.experiment(data, parameters=known),
        ["l_A[1]"],
        {"l_A[1]": 0.0005},
        {"l_A[1]": (0.0, 0.2)},
        shooting="single",
        starts=3,
        seed=1,
        max_evaluations=25,
    )
    r = _fit(spec)
    failed = r["failed_runs"]
    print(failed["by_status"], [(s["origin"], s["cost"], s["status"]) for s in r["starts"]])
    assert failed["by_status"].get("refused", 0) > 0, failed
    assert any("l_a + bearings.l_b" in f["message"] for f in failed["first"]), failed["first"]
    initial = next(s for s in r["starts"] if s["origin"] == "initial")
    assert initial["cost"] is None, initial
    assert math.isfinite(r["cost"])
    assert r["parameters"]["l_A[1]"]["value"] > 0.0008


# ---------------------------------------------------------------------------
# several starts, several experiments


def _poor_start(tmp_path, **options) -> dict:
    """μ_k[1] from 0.13 (the truth 0.17) in [0.12, 0.20] over 0.7 s, single shooting."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.7, seed=1))
    return fc.spec(
        fc.experiment(data), ["mu_k[1]"], {"mu_k[1]": 0.13}, {"mu_k[1]": (0.12, 0.20)}, shooting="single", **options
    )


@pytest.mark.full
def test_multi_start_finds_the_minimum_a_poor_start_misses(tmp_path):
    """Over 0.7 s the cost in μ_k[1] has three minima, each a different stick-slip pattern of
    joints 1 and 3: 0.13 (cost 1e5), 0.17 (the truth, at the noise floor) and 0.21 (7e4),
    separated by maxima near 0.145 and 0.19. Bounds [0.12, 0.20], starts = 5: the initial
    value 0.13 and a Latin hypercube of 4 whose stratum [0.16, 0.18] lies in the truth's
    basin by construction. A Latin hypercube start reaches the noise floor and is the
    result, within 3 standard errors of the truth. (The start from 0.13 stayed at more than
    20 times the noise floor while single shooting took one Jacobian step, 10⁻³ of the
    range; from a coarse to a fine step it reaches the floor too: 705.8 for 701.)"""
    r = _fit(_poor_start(tmp_path, starts=5, seed=1, max_evaluations=30))
    floor = _noise_floor(r)
    print("noise floor", floor, [(s["origin"], s["initial"], s["cost"], s["parameters"]) for s in r["starts"]])
    lhs = [s for s in r["starts"] if s["origin"].startswith("latin hypercube")]
    assert len(lhs) == 4
    assert any(s["cost"] is not None and s["cost"] < 1.1 * floor for s in lhs), lhs
    assert r["cost"] < 1.1 * floor
    p = r["parameters"]["mu_k[1]"]
    assert abs(p["value"] - 0.17) <= 3 * p["std_error"], p


@pytest.mark.full
def test_a_fit_stuck_in_a_wrong_minimum_says_so(tmp_path):
    """The poor start of the test above alone (0.13 for 0.17, single shooting, one start),
    allowed one evaluation per stage: it ends short of the truth, at more than twice the
    noise floor (measured 1533 for 701; with evaluations to spare it walks on to the truth).
    The result must not pass as an answer: ``trusted`` is false, the verdict says NOT
    TRUSTED, and a warning names a channel whose residuals the noise model does not explain
    and says what it may mean."""
    r = _fit(_poor_start(tmp_path, max_evaluations=1))
    assert r["cost"] > 2 * _noise_floor(r)
    assert r["trusted"] is False and r["verdict"].startswith("NOT TRUSTED: misfit in q["), r["verdict"]
    misfit = [w for w in r["warnings"] if w.startswith("misfit in q[")]
    assert misfit and "local minimum" in misfit[0], r["warnings"]


@pytest.mark.full
def test_a_parameter_held_at_a_wrong_value_is_a_misfit_of_its_channel(tmp_path):
    """The data made with μ_k[3] = 0.2; the SPEC holds it at 0.16 and estimates μ_k[1] only:
    joint 3's lag cannot be followed, whatever μ_k[1] is. The warning names q[3]."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.5, seed=2))
    spec = fc.spec(fc.experiment(data, parameters={"mu_k[3]": 0.16}), ["mu_k[1]"], shooting="single")
    r = _fit(spec)
    assert r["trusted"] is False, r["verdict"]
    assert any(w.startswith("misfit in q[3]") for w in r["warnings"]), r["warnings"]


@pytest.fixture(scope="module")
def two_experiments(tmp_path_factory):
    """Two runs of the reference motion with different payloads of the sliding link, m[3] = 8
    kg (0.5 s, noise seed 1) and 12 kg (0.4 s, seed 2), each told its payload; μ_k[1] and k[3]
    fitted from each alone and from both (absolute sigmas: the standard errors follow from J
    alone). Returns (spec of both, out dir of both, results of A, B, both)."""
    tmp = tmp_path_factory.mktemp("two")
    heavy = {"m[3]": 12.0}
    a = fc.experiment(fc.write_data(tmp / "light.csv", fc.measured(0.5, seed=1)), parameters={"m[3]": 8.0})
    b = fc.experiment(fc.write_data(tmp / "heavy.csv", fc.measured(0.4, seed=2, truth=heavy)), parameters=heavy)
    names = ["mu_k[1]", "k[3]"]
    options = {"shooting": "single", "absolute_sigma": True}
    both = fc.write_spec(tmp / "both.toml", fc.spec([a, b], names, **options))
    out = tmp / "out"
    results = [_fit(fc.spec(a, names, **options)), _fit(fc.spec(b, names, **options)), _fit(both, out=out)]
    return both, out, results


@pytest.mark.full
def test_two_experiments_are_fitted_together(two_experiments):
    """Both experiments enter: each channel of each has its residual_rms (keyed
    experiment:output) at the noise's level, which it could not be if the 12 kg run were
    simulated with 8 kg; the cost is at the noise floor of both together; each parameter's
    standard error is that of the two experiments' information added, 1/SE² = 1/SE_A² +
    1/SE_B² (to 10 %), below either alone; the truth within 3 of them."""
    _, _, (a, b, both) = two_experiments
    print({k: v for k, v in both["residual_rms"].items()}, both["cost"], _noise_floor(both))
    assert set(both["residual_rms"]) == {f"{e}:{o}" for e in ("light", "heavy") for o in ("q[1]", "q[3]")}
    for key, rms in both["residual_rms"].items():
        sigma = fc.NOISE[key.split(":")[1]][1]
        assert 0.85 * sigma < rms < 1.15 * sigma, (key, rms)
    assert both["method"]["samples"] == a["method"]["samples"] + b["method"]["samples"]
    assert both["cost"] < 1.1 * _noise_floor(both)
    for n, p in both["parameters"].items():
        se_a, se_b = a["parameters"][n]["std_error"], b["parameters"][n]["std_error"]
        combined = (se_a**-2 + se_b**-2) ** -0.5
        print(n, "SE light", se_a, "heavy", se_b, "both", p["std_error"], "expected", combined)
        assert p["std_error"] < min(se_a, se_b)
        assert _rel(p["std_error"], combined) < 0.1
        assert abs(p["value"] - fc.TRUTH[n]) <= 3 * p["std_error"], (n, p)


def _rerun_from_fitted_toml(spec_source, out, experiment_index: int = 0) -> dict:
    """Replays an experiment of the SPEC with DIR/fitted.toml by the command its comment
    gives (stickslip simulate --spec ... --fitted ...), and returns the residual rms per
    output it prints, read back from its CSV."""
    import pandas as pd

    from stickslip.fit.spec import load

    spec = load(spec_source)
    e = spec.experiments[experiment_index]
    line = next(x for x in (out / "fitted.toml").read_text().splitlines() if f"--experiment '{e.name}'" in x)
    command = line.split("stickslip ", 1)[1]
    replay_dir = out.parent / f"replay-{experiment_index}"
    argv = [STICKSLIP, *shlex.split(command.replace(f"--out {out / 'replay'}", f"--out {replay_dir}"))]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"replay {e.name}:" in done.stdout, done.stdout
    table = pd.read_csv(replay_dir / f"{e.name}.csv")
    rms = {}
    for c in e.channels:
        key = c.output if len(spec.experiments) == 1 else f"{e.name}:{c.output}"
        rms[key] = float(np.sqrt(np.mean((table[c.output].to_numpy() - c.values) ** 2)))
        assert f"{c.output} rms {rms[key]:.4g}" in done.stdout, (c.output, done.stdout)
    return rms


@pytest.mark.full
def test_fitted_toml_reproduces_each_of_two_experiments(two_experiments):
    """fitted.toml must let each experiment be replayed as fitted: the command its comment
    gives (stickslip simulate --spec --fitted) prints and writes each experiment's residual
    rms, fit.json's to 1e-9."""
    spec, out, _ = two_experiments
    reported = json.loads((out / "fit.json").read_text())["residual_rms"]
    for k in range(2):
        for key, rms in _rerun_from_fitted_toml(spec, out, k).items():
            assert _rel(rms, reported[key]) < 1e-9, (key, rms, reported[key])


# ---------------------------------------------------------------------------
# result files, and the same fit on a Dask cluster


@pytest.fixture(scope="module")
def small_fit(tmp_path_factory):
    """μ_k[1] and k[3] from 0.4 s, 4 % off, two starts, multiple then single shooting, in this
    process, DIR written: (spec path, out dir, result)."""
    tmp = tmp_path_factory.mktemp("small")
    data = fc.write_data(tmp / "run.csv", fc.measured(0.4, seed=4))
    names = ["mu_k[1]", "k[3]"]
    doc = fc.spec(
        fc.experiment(data),
        names,
        {"mu_k[1]": 0.163, "k[3]": 8.3e5},
        starts=2,
        seed=3,
        shooting="auto",
        max_evaluations=15,
    )
    spec = fc.write_spec(tmp / "fit.toml", doc)
    out = tmp / "out"
    return spec, out, _fit(spec, out=out)


SCHEMA_PARAMETER = {"value", "std_error", "initial", "bounds", "at_bound"}
SCHEMA_TOP = {
    "parameters",
    "correlation",
    "cost",
    "rms_normalized_residual",
    "residual_rms",
    "n_evaluations",
    "wall_s",
    "converged",
    "warnings",
    "starts",
}


def test_result_files_and_fit_json_schema(small_fit):
    """DIR holds fit.json with the issue's schema (every key; each parameter's value,
    std_error, initial, bounds, at_bound; the correlation's names and a symmetric matrix of unit
    diagonal; each start's initial, cost, parameters), report.md naming every parameter,
    fitted.toml, fit_<experiment>.png and correlation.png (PNG files), and nothing else
    half-written beside it."""
    spec, out, result = small_fit
    doc = json.loads((out / "fit.json").read_text())
    assert SCHEMA_TOP <= set(doc), SCHEMA_TOP - set(doc)
    # A fit at the noise floor: trusted, its goodness of fit per channel in fit.json.
    assert doc["trusted"] is True and doc["verdict"].startswith("the residuals are what the noise model says")
    assert set(doc["goodness_of_fit"]["channels"]) == {"q[1]", "q[3]"}
    assert doc["goodness_of_fit"]["p_value"] > 1e-3
    names = ["mu_k[1]", "k[3]"]
    assert list(doc["parameters"]) == names
    given = tomllib.loads(spec.read_text())["estimate"]
    for n, p in doc["parameters"].items():
        assert SCHEMA_PARAMETER <= set(p), (n, p)
        assert isinstance(p["value"], float) and p["std_error"] > 0 and p["at_bound"] is False
        assert p["initial"] == given[n]["initial"] and p["bounds"] == given[n]["bounds"], (p, given[n])
    assert doc["correlation"]["names"] == names
    m = np.array(doc["correlation"]["matrix"], dtype=float)
    assert m.shape == (2, 2) and np.allclose(np.diag(m), 1.0) and np.allclose(m, m.T)
    assert set(doc["residual_rms"]) == {"q[1]", "q[3]"}
    assert isinstance(doc["n_evaluations"], int) and doc["n_evaluations"] > 0
    assert doc["wall_s"] > 0 and isinstance(doc["converged"], bool) and isinstance(doc["warnings"], list)
    assert len(doc["starts"]) >= 2
    for s in doc["starts"]:
        assert {"initial", "cost", "parameters"} <= set(s), s
        assert set(s["initial"]) == set(names)
    assert doc["cost"] == min(s["cost"] for s in doc["starts"] if s["cost"] is not None)
    assert doc["cost"] < 1.1 * _noise_floor(result)
    report = (out / "report.md").read_text()
    assert all(f"`{n}`" in report for n in names)
    for png in ("fit_run.png", "correlation.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
    assert (out / "fitted.toml").is_file()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".out")]


def test_fitted_toml_reproduces_the_fitted_run(small_fit):
    """The experiment run with fitted.toml's values gives fit.json's residual rms of every
    channel to 1e-9 relative."""
    spec, out, _ = small_fit
    reported = json.loads((out / "fit.json").read_text())["residual_rms"]
    rerun = _rerun_from_fitted_toml(spec, out)
    print(rerun, reported)
    assert set(rerun) == set(reported)
    for key, rms in rerun.items():
        assert _rel(rms, reported[key]) < 1e-9, (key, rms, reported[key])


@pytest.mark.full
def test_fitted_toml_reproduces_a_fit_at_a_tighter_error_tolerance(tmp_path):
    """A fit whose runs use [options] error_tolerance = 1e-5: fitted.toml must say so (a
    --set or entry of error_tolerance), so that its values rerun the fitted run: residual
    rms equal to fit.json's to 1e-9."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.3, seed=5))
    spec = fc.write_spec(
        tmp_path / "fit.toml", fc.spec(fc.experiment(data), ["k[3]"], shooting="single", error_tolerance=1e-5)
    )
    out = tmp_path / "out"
    _fit(spec, out=out)
    reported = json.loads((out / "fit.json").read_text())["residual_rms"]
    for key, rms in _rerun_from_fitted_toml(spec, out).items():
        assert _rel(rms, reported[key]) < 1e-9, (key, rms, reported[key])


@pytest.mark.full
def test_fit_on_a_dask_scheduler_equals_the_fit_in_one_process(cluster, small_fit, tmp_path):
    """`stickslip fit SPEC --out DIR --scheduler ADDRESS` on a real scheduler with two worker
    processes (tests/python/sweep_cluster.py): the runs are deterministic, so fit.json's
    estimates, standard errors, cost, residuals, every start's cost and the number of FMU runs
    equal those of the in-process fit to 1e-12."""
    spec, _, local = small_fit
    out = tmp_path / "remote"
    p = subprocess.run(
        [STICKSLIP, "fit", str(spec), "--out", str(out), "--scheduler", cluster.address],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert p.returncode == 0, p.stdout + p.stderr
    remote = json.loads((out / "fit.json").read_text())
    for n, q in local["parameters"].items():
        for key in ("value", "std_error"):
            assert _rel(remote["parameters"][n][key], q[key]) <= 1e-12, (n, key, remote["parameters"][n][key], q[key])
    assert _rel(remote["cost"], local["cost"]) <= 1e-12
    for key, rms in local["residual_rms"].items():
        assert _rel(remote["residual_rms"][key], rms) <= 1e-12
    # A merged start has no cost (None): which starts merge is the same too.
    assert [s["status"] for s in remote["starts"]] == [s["status"] for s in local["starts"]]
    for a, b in zip(remote["starts"], local["starts"], strict=True):
        assert (a["cost"] is None) == (b["cost"] is None) and (a["cost"] is None or _rel(a["cost"], b["cost"]) <= 1e-12)
    assert remote["n_evaluations"] == local["n_evaluations"]
    assert np.allclose(remote["correlation"]["matrix"], local["correlation"]["matrix"], rtol=0, atol=1e-12)


# ---------------------------------------------------------------------------
# bad input: one line naming the field, exit status 2, nothing written


@pytest.fixture(scope="module")
def short_run():
    """50 ms of the reference motion, measured with noise: the columns of a valid data file."""
    return fc.measured(0.05, seed=1)


def _base(tmp_path, columns: dict) -> dict:
    data = fc.write_data(tmp_path / "run.csv", columns)
    doc = fc.spec(fc.experiment(data), ["mu_k[1]", "k[3]"], shooting="single")
    doc["experiment"][0]["data"] = "run.csv"  # relative to the SPEC
    return doc


def _drop(columns, name):
    return {k: v for k, v in columns.items() if k != name}


def _set_rows(columns, column, rows, value):
    out = {k: v.copy() for k, v in columns.items()}
    out[column][rows] = value
    return out


def _swap_times(columns):
    out = {k: v.copy() for k, v in columns.items()}
    out["t"][[10, 11]] = out["t"][[11, 10]]
    return out


def _head(columns, n):
    return {k: v[:n] for k, v in columns.items()}


def _exp(doc):
    return doc["experiment"][0]


def _est(doc, name="mu_k[1]"):
    return doc["estimate"][name]


# (id, change to the SPEC dict (in place), change to the data columns or None, words the one line must hold)
BAD = [
    ("column-missing", None, lambda c: _drop(c, "link3"), ["run.csv", "'link3'", "q[3]"]),
    ("column-misnamed", lambda d: _exp(d)["measured"]["q[3]"].update(column="lnk3"), None, ["'lnk3'", "link3"]),
    ("input-column-missing", lambda d: _exp(d)["inputs"].update({"q_star[1]": "motor9"}), None, ["'motor9'"]),
    ("time-column-missing", lambda d: _exp(d).update(time="time"), None, ["'time'"]),
    ("time-not-increasing", None, _swap_times, ["'t'", "strictly increasing", "line 13"]),
    ("nan-samples", None, lambda c: _set_rows(c, "link1", [5, 7], np.nan), ["NaN", "rows 7, 9", "drop_nan"]),
    ("input-unknown", lambda d: _exp(d)["inputs"].update({"q_star[7]": "motor1"}), None, ["q_star[7]"]),
    ("input-a-rate", lambda d: _exp(d)["inputs"].update({"qd_star[1]": "motor1"}), None, ["qd_star[1]"]),
    (
        "output-unknown",
        lambda d: _exp(d)["measured"].update({"q[9]": {"column": "link1", "sigma": 1e-6}}),
        None,
        ["q[9]"],
    ),
    (
        "output-a-parameter",
        lambda d: _exp(d)["measured"].update({"k[3]": {"column": "link1", "sigma": 1.0}}),
        None,
        ["k[3]", "output"],
    ),
    (
        "parameter-unknown",
        lambda d: d["estimate"].update({"mu_k[2]": {"initial": 0.1, "bounds": [0.0, 1.0]}}),
        None,
        ["mu_k[2]"],
    ),
    (
        "parameter-fixed",
        lambda d: d["estimate"].update({"h_max": {"initial": 1e-4, "bounds": [1e-5, 1e-3]}}),
        None,
        ["h_max", "tunable"],
    ),
    (
        "parameter-an-output",
        lambda d: d["estimate"].update({"q[1]": {"initial": 0.1, "bounds": [0.0, 1.0]}}),
        None,
        ["q[1]", "tunable"],
    ),
    ("known-parameter-unknown", lambda d: _exp(d)["parameters"].update({"mass[3]": 8.0}), None, ["mass[3]"]),
    ("known-parameter-out-of-range", lambda d: _exp(d)["parameters"].update({"m[3]": -1.0}), None, ["m[3]", "range"]),
    ("initial-outside-bounds", lambda d: _est(d).update(initial=0.3), None, ["mu_k[1]", "initial", "bounds"]),
    ("bounds-inverted", lambda d: _est(d).update(bounds=[0.2, 0.05]), None, ["mu_k[1]", "bounds", "low"]),
    ("bounds-beyond-the-fmu-range", lambda d: _est(d, "k[3]").update(bounds=[1e5, 1e13]), None, ["k[3]", "range"]),
    ("bounds-not-a-pair", lambda d: _est(d).update(bounds=[0.1]), None, ["mu_k[1]", "bounds"]),
    ("initial-not-a-number", lambda d: _est(d).update(initial="0.17"), None, ["mu_k[1]", "initial"]),
    ("initial-nan", lambda d: _est(d).update(initial=math.nan), None, ["mu_k[1]", "initial"]),
    ("log-scale-from-zero", lambda d: _est(d, "k[3]").update(bounds=[0.0, 5e6]), None, ["k[3]", "log"]),
    ("mu-k-above-known-mu-s", lambda d: _est(d).update(bounds=[0.05, 0.3]), None, ["mu_k[1]", "mu_s[1]"]),
    ("sigma-zero", lambda d: _exp(d)["measured"]["q[1]"].update(sigma=0.0), None, ["q[1]", "sigma"]),
    ("sigma-negative", lambda d: _exp(d)["measured"]["q[3]"].update(sigma=-1e-6), None, ["q[3]", "sigma"]),
    ("sigma-missing", lambda d: _exp(d)["measured"]["q[3]"].pop("sigma"), None, ["q[3]", "sigma"]),
    (
        "resolution-negative",
        lambda d: _exp(d)["measured"]["q[1]"].update(resolution=-1e-6),
        None,
        ["q[1]", "resolution"],
    ),
    (
        "resolution-a-word",
        lambda d: _exp(d)["measured"]["q[3]"].update(resolution="fine"),
        None,
        ["q[3]", "resolution"],
    ),
    ("resolution-nan", lambda d: _exp(d)["measured"]["q[3]"].update(resolution=math.nan), None, ["q[3]", "resolution"]),
    ("one-sample", None, lambda c: _head(c, 1), ["1 sample", "two"]),
    ("no-samples", None, lambda c: _head(c, 0), ["run.csv"]),
    ("unknown-top-key", lambda d: d.update(fmuu="x.fmu"), None, ["fmuu"]),
    ("unknown-experiment-key", lambda d: _exp(d).update(dataa="run.csv"), None, ["dataa"]),
    ("unknown-estimate-key", lambda d: _est(d).update(intial=0.1), None, ["intial", "initial"]),
    ("unknown-option", lambda d: d["options"].update(startz=4), None, ["startz", "starts"]),
    ("unknown-measured-key", lambda d: _exp(d)["measured"]["q[1]"].update(colum="link1"), None, ["colum"]),
    ("option-bad-loss", lambda d: d["options"].update(loss="l3"), None, ["loss"]),
    ("option-starts-zero", lambda d: d["options"].update(starts=0), None, ["starts"]),
    ("option-segment-negative", lambda d: d["options"].update(segment=-0.1), None, ["segment"]),
    ("data-file-missing", lambda d: _exp(d).update(data="nope.csv"), None, ["nope.csv", "no such file"]),
    ("fmu-missing", lambda d: d.update(fmu="nope.fmu"), None, ["nope.fmu"]),
    ("no-experiment", lambda d: d.pop("experiment"), None, ["experiment"]),
    ("no-estimate", lambda d: d.update(estimate={}), None, ["estimate"]),
    ("no-measured", lambda d: _exp(d).update(measured={}), None, ["measured"]),
    ("inputs-and-motion", lambda d: _exp(d).update(motion="m.toml"), None, ["inputs", "motion"]),
    ("estimated-and-known", lambda d: _exp(d)["parameters"].update({"k[3]": 8e5}), None, ["k[3]", "estimated"]),
    (
        "mu-s-initial-below-mu-k",
        lambda d: d["estimate"].update({"mu_s[1]": {"initial": 0.15, "bounds": [0.05, 0.5]}}),
        None,
        ["mu_s[1]", "mu_k[1]"],
    ),
]


def _cli(argv: list, capsys) -> tuple:
    from stickslip.cli import main

    capsys.readouterr()
    rc = main(argv)
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


def _check_refused(rc, err, words, out):
    lines = err.splitlines()
    assert rc == 2, (rc, err)
    assert len(lines) == 1 and err.endswith("\n") and lines[0].startswith("stickslip fit: "), err
    for w in words:
        assert w in lines[0], (w, lines[0])
    assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]


def _ragged(columns):
    """The CSV text with one row a field longer than the header."""
    names = list(columns)
    lines = [",".join(names)] + [",".join(repr(float(columns[n][k])) for n in names) for k in range(len(columns["t"]))]
    lines[10] += ",1.0"
    return "\n".join(lines) + "\n"


# Found by the fuzz test below (and fixed): values of the wrong type, a ragged CSV row
# (pandas' message spans two lines), an error_tolerance outside the FMU's range.

BAD_TYPES = [
    ("time-not-a-string", lambda d: _exp(d).update(time=1.5), None, ["time"], ()),
    ("input-column-not-a-string", lambda d: _exp(d)["inputs"].update({"q_star[1]": 5}), None, ["q_star[1]"], ()),
    ("bounds-not-numbers", lambda d: _est(d).update(bounds=["a", 0.2]), None, ["mu_k[1]", "bounds"], ()),
    ("fmu-not-a-string", lambda d: d.update(fmu=[1]), None, ["fmu"], ()),
    ("data-not-a-string", lambda d: _exp(d).update(data=5), None, ["data"], ()),
    (
        "ragged-csv-row",
        None,
        _ragged,
        ["run.csv", "line 11"],
        (),
    ),
    (
        "error-tolerance-out-of-range",
        lambda d: d["options"].update(error_tolerance=0.5),
        None,
        ["error_tolerance"],
        (),
    ),
]


@pytest.mark.parametrize(
    "change, data_change, words",
    [pytest.param(*b[1:], id=b[0]) for b in BAD] + [pytest.param(*b[1:4], id=b[0], marks=b[4]) for b in BAD_TYPES],
)
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, short_run, capsys, change, data_change, words):
    columns = data_change(short_run) if data_change else short_run
    doc = _base(tmp_path, short_run if isinstance(columns, str) else columns)
    if isinstance(columns, str):
        (tmp_path / "run.csv").write_text(columns)
    if change:
        change(doc)
        if "mu_s[1]" in doc["estimate"]:  # estimated: no longer a known value
            _exp(doc)["parameters"].pop("mu_s[1]", None)
    spec = fc.write_spec(tmp_path / "fit.toml", doc)
    out = tmp_path / "out"
    rc, _, err = _cli(["fit", str(spec), "--out", str(out), "--workers", "0"], capsys)
    _check_refused(rc, err, words, out)


@pytest.mark.parametrize(
    "text, words",
    [
        ('fmu = "x.fmu"\n[[experiment]\ndata = "run.csv"\n', ["not valid TOML"]),
        ("fmu = \n", ["not valid TOML"]),
        ("[options]\nstarts = 2\n[options]\nseed = 1\n", ["not valid TOML"]),
        (b"\xff\xfe\x00garbage", ["not valid TOML"]),
    ],
    ids=["unclosed-table", "no-value", "table-twice", "not-text"],
)
def test_malformed_toml_is_one_line_exit_2(tmp_path, capsys, text, words):
    spec = tmp_path / "fit.toml"
    spec.write_bytes(text if isinstance(text, bytes) else text.encode())
    out = tmp_path / "out"
    rc, _, err = _cli(["fit", str(spec), "--out", str(out), "--workers", "0"], capsys)
    _check_refused(rc, err, [str(spec), *words], out)


def test_missing_spec_and_negative_workers_exit_2(tmp_path, short_run, capsys):
    out = tmp_path / "out"
    rc, _, err = _cli(["fit", str(tmp_path / "none.toml"), "--out", str(out)], capsys)
    _check_refused(rc, err, ["none.toml", "no such file"], out)
    spec = fc.write_spec(tmp_path / "fit.toml", _base(tmp_path, short_run))
    rc, _, err = _cli(["fit", str(spec), "--out", str(out), "--workers", "-1"], capsys)
    _check_refused(rc, err, ["--workers"], out)


def test_bad_input_through_the_installed_command(tmp_path, short_run):
    """The same as a user sees it: `stickslip fit` as a process, a time column that goes back:
    exit 2, one line on stderr, DIR not created."""
    spec = fc.write_spec(tmp_path / "fit.toml", _base(tmp_path, _swap_times(short_run)))
    out = tmp_path / "out"
    p = subprocess.run(
        [STICKSLIP, "fit", str(spec), "--out", str(out), "--workers", "0"], capture_output=True, text=True, timeout=300
    )
    _check_refused(p.returncode, p.stderr, ["strictly increasing"], out)


def _nan_spec(tmp_path, short_run):
    columns = _set_rows(short_run, "link3", [5, 7], np.nan)
    doc = _base(tmp_path, columns)
    doc["options"]["drop_nan"] = True
    return fc.write_spec(tmp_path / "fit.toml", doc)


def test_nan_rows_are_dropped_only_when_asked(tmp_path, short_run, capsys):
    """With [options] drop_nan = true the rows with a NaN sample (data rows 6 and 8, lines 7
    and 9) are left out of the experiment and the fit runs (exit 0) on the rest."""
    from stickslip.fit.spec import load

    spec = _nan_spec(tmp_path, short_run)
    e = load(spec).experiments[0]
    assert e.dropped_rows == [7, 9]
    assert len(e.time) == len(short_run["t"]) - 2 and np.all(np.isfinite(e.channels[1].values))
    assert not np.isin(short_run["t"][[5, 7]], e.time).any()
    out = tmp_path / "out"
    rc, _, err = _cli(["fit", str(spec), "--out", str(out), "--workers", "0"], capsys)
    assert rc == 0, err
    assert (out / "fit.json").is_file()


def test_dropped_rows_are_named_in_the_result(tmp_path, short_run):
    """spec.py: rows with NaN samples are dropped "(named in the report)": report.md or
    fit.json names lines 7 and 9."""
    spec = _nan_spec(tmp_path, short_run)
    out = tmp_path / "out"
    _fit(spec, out=out)
    text = (out / "report.md").read_text() + (out / "fit.json").read_text()
    assert "7, 9" in text or "[7, 9]" in text or "7 and 9" in text, text


# ---------------------------------------------------------------------------
# fuzz: any SPEC or data file is either loaded or refused in one line

GARBAGE = [
    "text",
    "",
    0,
    -1,
    1,
    10**30,
    -(10**30),
    1e308,
    -1e308,
    math.nan,
    math.inf,
    -math.inf,
    True,
    False,
    0.5,
    -0.5,
    [],
    [1],
    [0.1, 0.2],
    [0.3, 0.1],
    [1, 2, 3],
    ["a", "b"],
    [math.nan, 1.0],
    {},
    {"a": 1},
    {"column": "link1"},
    {"initial": 0.1},
    "q[1]",
    "link1",
    "mu_k[1]",
    "run.csv",
    "../run.csv",
    "/",
    "é\u00e9\u0000",
]


def _paths(node, prefix=()):
    """Every (path, container) of the nested dicts and lists of a SPEC."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield (*prefix, k)
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield (*prefix, i)
            yield from _paths(v, (*prefix, i))


def _parent(doc, path):
    node = doc
    for k in path[:-1]:
        node = node[k]
    return node


def _mutate_spec(doc: dict, rng: random.Random) -> str:
    paths = list(_paths(doc))
    path = rng.choice(paths)
    parent, key = _parent(doc, path), path[-1]
    kind = rng.choice(["delete", "rename", "value", "value", "value"])
    if kind == "delete":
        del parent[key]
    elif kind == "rename" and isinstance(parent, dict):
        new = rng.choice([key + "x", key.upper(), key[:-1], key.replace("[", "("), "", " " + key, key + "[1]"])
        parent[new] = parent.pop(key)
    else:
        parent[key] = rng.choice(GARBAGE)
        kind = "value"
    return f"{kind} {'/'.join(map(str, path))}"


DATA_MUTATIONS = [
    *("shuffle", "swap", "reverse", "constant-time", "truncate", "empty", "header-only", "bytes"),
    *("cell", "cell", "huge", "drop-column", "duplicate-header", "ragged", "short-row", "blank-lines", "semicolons"),
]


def _mutate_data(path, columns: dict, rng: random.Random) -> str:
    names = list(columns)
    rows = np.column_stack([columns[n] for n in names])
    lines = [",".join(names)] + [",".join(repr(float(x)) for x in row) for row in rows]
    kind = rng.choice(DATA_MUTATIONS)
    r = rng.randrange(1, len(lines))
    if kind == "shuffle":
        body = lines[1:]
        rng.shuffle(body)
        lines = lines[:1] + body
    elif kind == "swap":
        s = rng.randrange(1, len(lines))
        lines[r], lines[s] = lines[s], lines[r]
    elif kind == "cell":
        cells = lines[r].split(",")
        cells[rng.randrange(len(cells))] = rng.choice(["abc", "", "nan", "inf", "-inf", "1e999", "0x10", '"1"', "1,5"])
        lines[r] = ",".join(cells)
    elif kind == "drop-column":
        j = rng.randrange(len(names))
        lines = [",".join(c for i, c in enumerate(line.split(",")) if i != j) for line in lines]
    elif kind == "duplicate-header":
        cells = lines[0].split(",")
        cells[rng.randrange(len(cells))] = cells[rng.randrange(len(cells))]
        lines[0] = ",".join(cells)
    elif kind == "empty":
        lines = []
    elif kind == "header-only":
        lines = lines[:1]
    elif kind == "ragged":
        lines[r] += ",1.0"
    elif kind == "short-row":
        lines[r] = ",".join(lines[r].split(",")[:-1])
    elif kind == "reverse":
        lines = lines[:1] + lines[:0:-1]
    elif kind == "constant-time":
        lines = lines[:1] + ["0.0," + ",".join(line.split(",")[1:]) for line in lines[1:]]
    elif kind == "huge":
        cells = lines[r].split(",")
        cells[rng.randrange(len(cells))] = rng.choice(["1e300", "-1e300", "1e-300", "123456789012345678901234567890"])
        lines[r] = ",".join(cells)
    elif kind == "blank-lines":
        lines.insert(r, "")
    elif kind == "semicolons":
        lines = [line.replace(",", ";") for line in lines]
    text = "\n".join(lines) + ("\n" if lines else "")
    if kind == "truncate":
        text = text[: rng.randrange(len(text))]
    if kind == "bytes":
        raw = bytearray(text.encode())
        for _ in range(rng.randrange(1, 20)):
            raw[rng.randrange(len(raw))] = rng.randrange(256)
        path.write_bytes(bytes(raw))
    else:
        path.write_text(text)
    return f"data {kind}"


TOML_GARBAGE = ["=", "[", "]", '"', "{", "\\", "\x00", "é"]


def _mutate_toml(text: str, rng: random.Random) -> str:
    lines = text.splitlines()
    kind = rng.choice(["truncate", "drop-line", "duplicate-line", "garbage"])
    if kind == "truncate":
        return text[: rng.randrange(len(text))]
    k = rng.randrange(len(lines))
    if kind == "drop-line":
        del lines[k]
    elif kind == "duplicate-line":
        lines.insert(k, lines[k])
    else:
        lines[k] = lines[k][: rng.randrange(len(lines[k]) + 1)] + rng.choice(TOML_GARBAGE)
    return "\n".join(lines) + "\n"


def test_fuzzed_specs_and_data_load_or_are_refused_in_one_line(tmp_path, short_run):
    """200 seeded mutations of a valid SPEC (as a dict and as TOML: keys deleted or renamed,
    values of the wrong type, NaN, ±inf, huge numbers, strings) and of its data file (rows
    shuffled, swapped or reversed, the file truncated or emptied, bytes garbled, cells not
    numbers or huge, columns dropped or duplicated, ragged rows), and of the TOML text itself
    (with the keys of issue 36: start, derivatives, stage, horizon; and of issue 43: fit_start):
    ``stickslip.fit.spec.load`` either returns a spec or raises FitSpecError with a one-line
    message; nothing else."""
    from stickslip.fit.spec import FitSpec, FitSpecError, load

    short = _head(short_run, 20)
    outcomes, problems = {"loaded": 0, "refused": 0}, []
    for case in range(200):
        rng = random.Random(case)
        root = tmp_path / f"case{case}"
        root.mkdir()
        doc = _base(root, short)
        # the encoder's count joins the mutated keys (a number, or "auto")
        _exp(doc)["measured"]["q[1]"]["resolution"] = rng.choice([1.5e-6, "auto", 0.0])
        # issue 36's keys join them too: the start, the derivative filter, the stage, a horizon
        _exp(doc)["start"] = rng.choice(["data", "rest"])
        _exp(doc)["derivatives"] = rng.choice(
            ["auto", "spline", {"method": "savgol", "window": 0.02, "order": 3}, {"method": "lowpass", "cutoff": 50.0}]
        )
        doc.setdefault("options", {})["stage"] = rng.choice(["output-error", "equation-error"])
        if rng.random() < 0.5:
            doc["options"].update(horizon=0.01, shooting="auto")
        doc["options"]["fit_start"] = rng.choice([True, False])  # issue 43's start unknowns
        data = root / "run.csv"
        what = []
        for _ in range(rng.choice([1, 1, 2, 3])):
            if rng.random() < 0.6 and list(_paths(doc)):
                what.append(_mutate_spec(doc, rng))
            else:
                what.append(_mutate_data(data, short, rng))
        source = doc
        if rng.random() >= 0.4:  # as a TOML file, sometimes with its text mangled
            source = fc.toml(doc)
            if rng.random() < 0.2:
                source = _mutate_toml(source, rng)
                what.append("toml text")
            (root / "fit.toml").write_text(source)
        try:
            spec = load(doc, base_dir=root) if source is doc else load(root / "fit.toml")
            assert isinstance(spec, FitSpec)
            outcomes["loaded"] += 1
        except FitSpecError as e:
            outcomes["refused"] += 1
            message = str(e)
            if not message.strip() or "\n" in message or "\r" in message:
                problems.append((case, what, f"message not one line: {message!r}"))
        except Exception as e:  # noqa: BLE001 -- the finding: any other exception
            problems.append((case, what, f"{type(e).__name__}: {e}", str(source)[:300]))
    print(outcomes)
    assert not problems, f"{len(problems)} of 200:\n" + "\n".join(map(str, problems))


@pytest.mark.full
def test_a_motor_drive_is_fitted_from_measured_torques(tmp_path):
    """Issue 29: "fitting a motor-drive FMU from measured tau_m works the same way". The
    motor arm (models/reference_rrpr_motor.toml) driven by the motor torques of
    motor_fmus.TORQUE_SEGMENTS, logged every 1 ms (the FMU gets them, as the fit does,
    through a cubic spline of the log), link encoders with noise; the rotor inertia J_m[1]
    and the rotor's Coulomb level tau_c[1] from guesses 50 % and 33 % off: the truth (the
    model file's values) within 3 standard errors, residuals at the noise; multiple shooting
    first (issue 36: each segment's rotor turned to carry its link's load, from the measured
    link), then single shooting from the experiment's own start (static_start)."""
    from motor_fmus import GEAR_RATIO, MOTOR_COULOMB, MOTOR_JOINTS, ROTOR_INERTIA, require_motor_fmu, torque
    from stickslip.fit.synthetic import measure, write_csv

    fmu = require_motor_fmu()
    torques = {f"tau_m[{j}]": (f"tau{j}", lambda t, j=j: torque(j, t)[0]) for j in MOTOR_JOINTS}
    columns = measure(
        fmu,
        {"static_start": True},
        {"q[1]": ("link1", 2e-6, 0.0), "q[3]": ("link3", 1e-6, 0.0)},
        duration=0.5,
        seed=3,
        torques=torques,
    )
    write_csv(columns, tmp_path / "motor.csv")
    assert GEAR_RATIO[1] > 1  # the link moves by the rotor's angle over the gear ratio
    truth = {"J_m[1]": ROTOR_INERTIA[1], "tau_c[1]": MOTOR_COULOMB[1]}
    spec = {
        "fmu": str(fmu),
        "experiment": [
            {
                "data": str(tmp_path / "motor.csv"),
                "time": "t",
                "inputs": {
                    **{f"q_star[{i}]": f"motor{i}" for i in range(1, 5)},
                    "tau_m[1]": "tau1",
                    "tau_m[3]": "tau3",
                },
                "parameters": {"static_start": True},
                "measured": {"q[1]": {"column": "link1", "sigma": 2e-6}, "q[3]": {"column": "link3", "sigma": 1e-6}},
            }
        ],
        "estimate": {
            "J_m[1]": {"initial": 4.5e-4, "bounds": [1e-4, 1e-3], "scale": "log"},
            "tau_c[1]": {"initial": 0.04, "bounds": [0.005, 0.1]},
        },
    }
    r = _fit(spec)
    assert r["method"]["shooting"] == "multiple, then single"
    for name, value in truth.items():
        p = r["parameters"][name]
        print(name, p["value"], p["std_error"], (p["value"] - value) / p["std_error"])
        assert abs(p["value"] - value) <= 3 * p["std_error"], (name, p, value)
    assert 0.9 < r["rms_normalized_residual"] < 1.1, r["rms_normalized_residual"]


def test_a_jacobian_that_is_neither_kind_is_refused_naming_both():
    from stickslip.fit.spec import FitSpecError, load

    columns = fc.measured(0.2, seed=1)
    with tempfile.TemporaryDirectory() as d:
        data = fc.write_data(Path(d) / "run.csv", columns)
        spec = fc.spec(fc.experiment(data), ["mu_s[1]"], {"mu_s[1]": 0.25}, {"mu_s[1]": (0.05, 0.5)})
        spec["options"]["jacobian"] = "adjoint"
        with pytest.raises(FitSpecError, match=r"jacobian = 'adjoint': one of 'sensitivities', 'differences'"):
            load(spec)


@pytest.mark.slow
def test_the_fmus_sensitivities_give_the_answer_of_differences():
    """The same single-shooting fit with ``jacobian = "sensitivities"`` and with the default
    differences: the estimates agree within 0.5 standard errors (issue 43's criterion), and the
    sensitivities' Jacobian columns were exact (none fell back to differences)."""
    columns = fc.measured(1.0, seed=3)
    with tempfile.TemporaryDirectory() as d:
        data = fc.write_data(Path(d) / "run.csv", columns)
        names = ["mu_k[1]", "mu_s[1]", "k[3]"]
        initial = {n: fc.TRUTH[n] * f for n, f in zip(names, (0.9, 1.1, 0.8), strict=True)}
        bounds = {n: fc.BOUNDS[n] for n in names}
        answers = {}
        for kind in ("differences", "sensitivities"):
            spec = fc.spec(fc.experiment(data), names, initial, bounds, shooting="single", seed=1)
            spec["options"]["jacobian"] = kind
            answers[kind] = _fit(spec)
    a, b = answers["differences"], answers["sensitivities"]
    for k in names:
        print(k, a["parameters"][k]["value"], b["parameters"][k]["value"], a["parameters"][k]["std_error"])
    print(b["jacobian_columns"], a["n_evaluations"], b["n_evaluations"])
    for k in names:
        se = a["parameters"][k]["std_error"]
        assert abs(a["parameters"][k]["value"] - b["parameters"][k]["value"]) <= 0.5 * se, k
        assert b["parameters"][k]["std_error"] == pytest.approx(se, rel=0.1), k
    assert b["jacobian_columns"]["runs with sensitivities"] > 0
    assert b["jacobian_columns"]["differences"] == 0, b["jacobian_columns"]
    assert a["jacobian_columns"]["runs with sensitivities"] == 0
