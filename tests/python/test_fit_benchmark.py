"""The identification benchmark of `stickslip fit` (issue 35, item 1; python/stickslip/fit/benchmark.py,
``python scripts/bench_fit.py --suite``): seeded fit problems with a known truth, and a suite that
measures whether the fit's standard errors cover it.

* The generator (fast, the reference arm, short experiments): deterministic for a seed; truth,
  start and bounds as promised (the truth inside the bounds, the starts 20-50 % off); the data's
  encoder columns on the encoder's grid, the noise added before the rounding
  (``synthetic.measure(noise_first=True)``) while the default order is unchanged; the true run
  sticks and slips; the motion has reversals, dwells and two speeds.
* The other arms (``full``: their FMUs are built on first use): a problem of the KUKA iiwa, the
  xArm 6 and the motor-drive arm each loads as a SPEC and sticks and slips.
* The suite (``full``): one arm, one draw, two parameters, half a second: suite.json and suite.md
  are written with every field. It does not judge the fit's coverage (the fit is being changed).
* The target (``slow``, ``--runslow``): >= 40 (draw, parameter) pairs over 3 arms, the truth within
  3 standard errors for >= 90 % of them. What a fit that can be trusted must meet; it may fail
  while the fit does not.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from helpers import ROOT, require_fmu


def _generate(tmp_path, seed: int, duration: float = 0.6, **kw):
    from stickslip.fit.benchmark import generate

    return generate(require_fmu(), seed, tmp_path / f"p{seed}", arm="reference", duration=duration, **kw)


def _arm_fmu(arm: str):
    """The FMU of a benchmark arm as the tests build it (the FMU under test for the reference)."""
    if arm == "reference":
        return require_fmu()
    if arm == "motor":
        from motor_fmus import require_motor_fmu

        return require_motor_fmu()
    from urdf_fmus import model_fmu, require_iiwa_fmu

    if arm == "kuka_iiwa":
        return require_iiwa_fmu()
    require_fmu()
    return model_fmu("xarm6", ROOT / "models" / "urdf" / "xarm6" / "xarm6.toml", "STICKSLIP_XARM6_FMU")


# ---------------------------------------------------------------------------
# the generator


def test_a_seed_gives_the_same_problem_and_data(tmp_path):
    """Two draws of one seed into two directories: the same SPEC (but for the data's path), truth
    and data file byte for byte; another seed draws another problem."""
    a = _generate(tmp_path / "a", 3)
    b = _generate(tmp_path / "b", 3)
    c = _generate(tmp_path / "c", 4)
    strip = lambda p: json.dumps({**p.spec, "experiment": [{**p.spec["experiment"][0], "data": None}]})  # noqa: E731
    assert strip(a) == strip(b)
    assert a.truth == b.truth and a.initial == b.initial and a.motion == b.motion
    assert open(a.data, "rb").read() == open(b.data, "rb").read()
    assert (a.truth, a.initial) != (c.truth, c.initial)
    for p in (a, c):
        for name in ("run.csv", "spec.json", "problem.json"):
            assert (tmp_path / ("a" if p is a else "c") / f"p{p.seed}" / name).is_file()


def test_truth_starts_and_bounds_are_as_drawn(tmp_path):
    """Over six seeds: 1-2 joints, 2-4 parameters of μ_k, μ_s, k, b_v; μ_k in [0.05, 0.3], μ_s in
    [1.1, 1.6] μ_k, k within a factor 2.5 of the FMU's start value; every start 20-50 % off its
    truth, truth and start inside the bounds (k on a log scale); starts 2-4, no error_tolerance;
    the SPEC loads (stickslip.fit.spec.load checks it against the FMU, μ_s >= μ_k included)."""
    from fmpy import read_model_description

    from stickslip.fit.spec import load

    md = read_model_description(str(require_fmu()))
    start = {v.name: float(v.start) for v in md.modelVariables if v.start is not None and v.type == "Real"}
    seen = set()
    for seed in range(6):
        p = _generate(tmp_path, seed)
        values = {**p.known, **p.truth}
        assert 1 <= len(p.joints) <= 2 and 2 <= len(p.estimated) <= 4, p.estimated
        for i in p.joints:
            mu_k, mu_s, k = values[f"mu_k[{i}]"], values[f"mu_s[{i}]"], values[f"k[{i}]"]
            assert 0.05 <= mu_k <= 0.3 and 1.1 <= mu_s / mu_k <= 1.6, (mu_k, mu_s)
            assert 1 / 2.5 <= k / start[f"k[{i}]"] <= 2.5, k
        for n in p.estimated:
            seen.add(n.split("[")[0])
            truth, initial = p.truth[n], p.initial[n]
            low, high = p.bounds[n]
            assert 0.2 - 1e-12 <= abs(initial / truth - 1) <= 0.5 + 1e-12, (n, truth, initial)
            assert low < truth < high and low <= initial <= high, (n, low, truth, initial, high)
            entry = p.spec["estimate"][n]
            assert entry["initial"] == initial and entry["bounds"] == [low, high]
            assert entry.get("scale", "linear") == ("log" if n.startswith("k[") else "linear")
        assert 2 <= p.spec["options"]["starts"] <= 4
        assert "error_tolerance" not in p.spec["options"]
        assert not {"h_min", "h_max", "error_tolerance"} & set(p.spec["experiment"][0]["parameters"])
        spec = load(p.spec)
        assert [e.name for e in spec.estimates] == p.estimated
    assert seen == {"mu_k", "mu_s", "k", "b_v"}, seen


def test_encoder_columns_lie_on_the_encoders_grid(tmp_path):
    """Every measured column is a whole number of the channel's resolution (the noise was added
    before the rounding), the SPEC states each channel's sigma and resolution, and the samples
    scatter about the exact run by about sqrt(sigma² + resolution²/12)."""
    import pandas as pd

    from stickslip.fit.benchmark import simulation_cost

    p = _generate(tmp_path, 5, duration=0.5)
    data = pd.read_csv(p.data)
    for output, c in p.channels.items():
        counts = data[c["column"]].to_numpy() / c["resolution"]
        assert np.max(np.abs(counts - np.round(counts))) < 1e-6, output
        measured = p.spec["experiment"][0]["measured"][output]
        assert measured["column"] == c["column"] and measured["sigma"] == c["sigma"]
        assert 5e-7 <= c["sigma"] <= 4e-6 and 4e-7 < c["resolution"] < 7e-6, c
        if "resolution" in measured:
            assert measured["resolution"] == c["resolution"]
    # at the truth each channel's cost is about half its samples (σ the noise and the count)
    cost = simulation_cost(p.spec, p.truth)
    samples = len(data)
    for output, part in cost["channels"].items():
        assert 0.35 * samples < part < 0.7 * samples, (output, part, samples)


def test_noise_first_is_an_option_and_the_default_order_is_unchanged():
    """synthetic.measure: by default the exact value is rounded to the count and the noise added
    after (so the calibration example's data and the fit tests' reproduce); with noise_first the
    noise is added first and the sum rounded, every sample on the grid."""
    from stickslip.fit.synthetic import measure

    fmu = require_fmu()
    q = 2e-6
    kw = dict(duration=0.2, seed=9)
    rounded = measure(fmu, {}, {"q[1]": ("link1", 0.0, q)}, **kw)["link1"]
    default = measure(fmu, {}, {"q[1]": ("link1", 3e-6, q)}, **kw)["link1"]
    noise = 3e-6 * np.random.default_rng(9).standard_normal(len(rounded))
    np.testing.assert_array_equal(default, rounded + noise)
    exact = measure(fmu, {}, {"q[1]": ("link1", 0.0, 0.0)}, record=["n_stick[1]"], **kw)
    assert set(exact) == {"t", "motor1", "motor2", "motor3", "motor4", "link1", "n_stick[1]"}
    first = measure(fmu, {}, {"q[1]": ("link1", 3e-6, q)}, noise_first=True, **kw)["link1"]
    np.testing.assert_array_equal(first, np.round((exact["link1"] + noise) / q) * q)


def test_the_true_run_sticks_and_slips(tmp_path):
    """The generator's checks hold (each joint with an estimated parameter enters >= 2 stiction
    phases after the start and is stuck 5-90 % of the time), and the SPEC's own inputs at the
    truth, run at the FMU's default error control, show the same: stiction phases after the start
    and time spent slipping."""
    from stickslip.fit.runner import Payload, run
    from stickslip.fit.spec import load
    from stickslip.fmu import content_hash

    for seed in (0, 1):
        p = _generate(tmp_path, seed)
        spec = load(p.spec)
        e = spec.experiments[0]
        outputs = [f"{g}[{i}]" for i in p.joints for g in ("n_stick", "stick")]
        data = spec.fmu.read_bytes()
        res = run(
            content_hash(data), Payload("x", e.time, e.motion, e.torques, outputs, e.parameters), p.truth, None, data
        )
        assert res.status == "ok", res.message
        for k, i in enumerate(p.joints):
            check = p.checks[str(i)]
            assert check["stiction_phases"] >= 2 and 0.05 <= check["stuck_fraction"] <= 0.9, check
            n, stick = res.values[:, 2 * k], res.values[:, 2 * k + 1]
            assert n[-1] - n[0] >= 2, (i, n[-1])
            assert 0.05 < stick.mean() < 0.95, (i, stick.mean())


def test_the_motion_has_reversals_dwells_and_two_speeds(tmp_path):
    """Each flexible joint's planned q*: a settling dwell, then moves at a fast and a slow speed
    (a steady slip at each), a reversal and a dwell between moves; q*' and q*'' are the
    derivatives of q* (central differences), so the FMU's Taylor polynomial follows it."""
    from stickslip.fit.benchmark import PlannedMotion

    p = _generate(tmp_path, 2, duration=2.0)
    motion = PlannedMotion.from_dict(p.motion)
    t = np.arange(0.0, 2.0, 1e-4)
    values = [motion(x) for x in t]
    for i in (1, 3):
        q = np.array([v[0][i - 1] for v in values])
        qd = np.array([v[1][i - 1] for v in values])
        qdd = np.array([v[2][i - 1] for v in values])
        np.testing.assert_allclose(np.gradient(q, t)[1:-1], qd[1:-1], atol=1e-4 * np.abs(qd).max())
        np.testing.assert_allclose(np.gradient(qd, t)[1:-1], qdd[1:-1], atol=1e-3 * np.abs(qdd).max())
        assert np.all(qd[t < 0.25] == 0.0)  # settling
        moving = np.abs(qd) > 1e-9
        assert np.any(qd > 1e-9) and np.any(qd < -1e-9), i  # a reversal
        starts = np.flatnonzero(np.diff(moving.astype(int)) == 1)
        stops = np.flatnonzero(np.diff(moving.astype(int)) == -1)
        assert any((a - b) * 1e-4 >= 0.02 for a in starts for b in stops if a > b), i  # a dwell between moves
        plan = p.motion["plans"][str(i)]
        speeds = {abs(m["speed"]) for m in plan["moves"]}
        assert speeds == {plan["fast"], plan["slow"]} and plan["fast"] > 3 * plan["slow"], plan
        for speed in speeds:  # a steady slip at each: |q*'| at that speed for >= 40 ms
            held = np.abs(np.abs(qd) - speed) < 1e-9 * speed
            assert held.sum() * 1e-4 >= 0.04, (i, speed)


# ---------------------------------------------------------------------------
# the other arms


@pytest.mark.full
@pytest.mark.parametrize("arm", ["kuka_iiwa", "xarm6", "motor"])
def test_every_arm_gives_a_problem_that_sticks_and_slips(tmp_path, arm):
    """A problem of each URDF example and of the motor-drive arm (its torques from the PD loop,
    tau_m inputs, rotor encoders measured): the SPEC loads, its estimates are the arm's flexible
    joints' parameters, the true run sticks and slips, the data lie on their encoders' grids."""
    import pandas as pd

    from stickslip.fit.benchmark import candidates, generate
    from stickslip.fit.spec import load

    fmu = _arm_fmu(arm)
    p = generate(fmu, 11, tmp_path, arm=arm, duration=1.0)
    spec = load(p.spec)
    assert set(p.joints) <= set(candidates(spec.model_description))
    assert all(p.checks[str(i)]["stiction_phases"] >= 2 for i in p.joints), p.checks
    data = pd.read_csv(p.data)
    for output, c in p.channels.items():
        counts = data[c["column"]].to_numpy() / c["resolution"]
        assert np.max(np.abs(counts - np.round(counts))) < 1e-6, output
    if arm == "motor":
        assert {"tau_m[1]", "tau_m[3]"} <= set(p.spec["experiment"][0]["inputs"])
        assert {"theta_m[1]", "theta_m[3]"} <= set(p.channels)
        assert p.known.get("static_start") is True


# ---------------------------------------------------------------------------
# the suite


SUITE_FIT = {
    "arm",
    "fmu",
    "draw",
    "seed",
    "dir",
    "estimated",
    "truth",
    "wall_s",
    "n_evaluations",
    "cost",
    "cost_answer",
    "cost_truth",
    "cost_ratio",
    "warnings",
    "method",
    "parameters",
}
SUITE_ROW = {"arm", "seed", "parameter", "kind", "truth", "estimate", "std_error", "z", "within_3se", "within_2se"}
SUITE_GROUP = {"n", "within_3se", "within_2se", "median_abs_z", "median_cost_ratio", "fits", "fits_warned"}


@pytest.mark.full
def test_a_suite_of_one_fit_writes_its_tables(tmp_path):
    """One draw of the reference arm, two parameters, 0.5 s of data, two starts, in this process:
    suite.json has the fit with its estimates, standard errors, z, costs at the answer and at the
    truth, wall time, FMU runs, warnings and method, a row per parameter and the summary per kind,
    per arm and in total; suite.md has both tables and the fit's rows. Coverage is not judged here."""
    from stickslip.fit.benchmark import run_suite

    require_fmu()
    out = tmp_path / "suite"
    doc = run_suite(["reference"], 1, 21, out, workers=0, duration=0.5, n_parameters=2, starts=2, progress=print)
    on_disk = json.loads((out / "suite.json").read_text())
    assert on_disk == json.loads(json.dumps(doc))
    (fit,) = on_disk["fits"]
    assert "error" not in fit, fit.get("error")
    assert SUITE_FIT <= set(fit), SUITE_FIT - set(fit)
    assert len(fit["estimated"]) == 2 and list(fit["parameters"]) == fit["estimated"]
    assert fit["n_evaluations"] > 0 and fit["wall_s"] > 0
    assert fit["cost_truth"] > 0 and fit["cost_answer"] > 0
    assert math.isclose(fit["cost_ratio"], fit["cost_answer"] / fit["cost_truth"])
    assert len(on_disk["rows"]) == 2
    for row in on_disk["rows"]:
        assert SUITE_ROW <= set(row), SUITE_ROW - set(row)
        assert row["within_3se"] == (abs(row["z"]) <= 3)
    summary = on_disk["summary"]
    assert set(summary["by_arm"]) == {"reference"}
    assert set(summary["by_kind"]) == {r["kind"] for r in on_disk["rows"]}
    for group in [*summary["by_kind"].values(), *summary["by_arm"].values(), summary["total"]]:
        assert SUITE_GROUP <= set(group)
    assert summary["total"]["n"] == 2 and summary["total"]["fits"] == 1
    text = (out / "suite.md").read_text()
    assert "## Per parameter kind" in text and "## Per arm" in text and "**total**" in text
    for name in fit["estimated"]:
        assert f"`{name}`" in text
    for name in ("run.csv", "spec.json", "problem.json", "fit.json"):
        assert (out / fit["dir"] / name).is_file()


# The coverage test's size (issue 41, item 2). A pair (draw, parameter) misses where the truth
# lies beyond 3 reported standard errors. With right standard errors and a normal estimate a miss
# has probability 0.0027; the fit's standard errors are asymptotic (a linearized, sandwich
# covariance on a few hundred correlated samples), so the null allows each pair P_MISS = 0.05,
# 18 times that. The test fails at MAX_MISSES + 1 misses of N_PAIRS:
#   P(X >= 9 | n = 45, p = 0.05) = sum_{k=9}^{45} C(45, k) 0.05^k 0.95^(45-k) = 3.35e-4 < 1e-3.
# A pair of a fit that says it can be trusted must meet the exact rate 0.0027; those fail at
# MAX_TRUSTED_MISSES + 1: P(X >= 3 | n <= 45, p = 0.0027) <= 2.8e-4. (Pairs of one fit share
# its data, so misses are not independent; the bound is for independent pairs, and the fits'
# pairs were measured correlated at most weakly.)
N_PAIRS, P_MISS, MAX_MISSES = 45, 0.05, 8
P_MISS_TRUSTED, MAX_TRUSTED_MISSES = 0.0027, 2
# A planted bias: estimates moved by 2.5 of their standard errors miss with probability
# P(z > 0.5) = 0.31 per pair; the test then fails with probability P(X >= 9 | 45, 0.31) = 0.95.
PLANTED_BIAS = 2.5


def _binomial_tail(n: int, p: float, k: int) -> float:
    return sum(math.comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k, n + 1))


def coverage_failures(rows: list, bias: float = 0.0) -> list:
    """Why the rows (the suite's: z, trusted) fail the coverage test, or [] where they pass; with
    ``bias``, each estimate moved by that many standard errors first (a planted bias)."""
    z = [r["z"] + bias if r["z"] is not None and math.isfinite(r["z"]) else math.inf for r in rows]
    misses = sum(abs(x) > 3.0 for x in z)
    trusted = sum(abs(x) > 3.0 for x, r in zip(z, rows, strict=True) if r.get("trusted"))
    out = []
    if misses > MAX_MISSES * len(rows) / N_PAIRS:
        out.append(f"{misses} of {len(rows)} pairs beyond 3 SE")
    if trusted > MAX_TRUSTED_MISSES:
        out.append(f"{trusted} pairs beyond 3 SE in fits that say they can be trusted")
    return out


def test_the_coverage_test_is_sized_and_has_power():
    """The sums in the comment above, and the test on simulated pairs: 20,000 sets of 45 normal
    z at the null's miss rate (a t distribution scaled so that |z| > 3 has probability 0.05)
    fail fewer than 1 in 1000; the same with the planted bias fail at least 90 % of the time."""
    assert _binomial_tail(N_PAIRS, P_MISS, MAX_MISSES + 1) < 1e-3
    assert _binomial_tail(N_PAIRS, P_MISS, MAX_MISSES) > 1e-3  # the threshold is the tightest such
    assert _binomial_tail(N_PAIRS, P_MISS_TRUSTED, MAX_TRUSTED_MISSES + 1) < 1e-3
    from scipy.stats import norm

    assert _binomial_tail(N_PAIRS, norm.sf(3.0 - PLANTED_BIAS), MAX_MISSES + 1) > 0.9
    rng = np.random.default_rng(41)
    scale = 3.0 / norm.isf(P_MISS / 2)  # normal z widened so that P(|z| > 3) = P_MISS
    trials = 20_000
    false = biased = 0
    for _ in range(trials):
        z = rng.standard_normal(N_PAIRS) * scale
        rows = [{"z": float(x), "trusted": False} for x in z]
        false += bool(coverage_failures(rows))
        biased += bool(coverage_failures(rows, PLANTED_BIAS))
    print(f"false failures {false / trials:.2e}, failures with the planted bias {biased / trials:.3f}")
    assert false / trials < 1e-3 and biased / trials >= 0.9


@pytest.mark.slow
def test_the_truth_lies_within_3_standard_errors_as_often_as_the_standard_errors_say(tmp_path):
    """The target a fit that can be trusted must meet: 45 (draw, parameter) pairs (5 draws of 3
    parameters on each of the reference arm, the KUKA iiwa and the xArm 6, 1.5 s of data each)
    on a local cluster of 2 workers: at most MAX_MISSES pairs beyond 3 reported standard errors
    and at most MAX_TRUSTED_MISSES of them in fits that say they can be trusted (a false failure
    in fewer than 1 in 1000 runs; see above). The same rows with the planted bias fail it: the
    test can see an estimator 2.5 SE off. The table is in the output (suite.md)."""
    from stickslip.fit.benchmark import run_suite

    arms = [f"{arm}={_arm_fmu(arm)}" for arm in ("reference", "kuka_iiwa", "xarm6")]
    doc = run_suite(arms, 5, 100, tmp_path / "suite", workers=2, duration=1.5, n_parameters=3, progress=print)
    print((tmp_path / "suite" / "suite.md").read_text())
    trusted = {(f["arm"], f["seed"]): f.get("trusted") for f in doc["fits"]}
    rows = [{**r, "trusted": trusted.get((r["arm"], r["seed"]))} for r in doc["rows"]]
    assert len(rows) == N_PAIRS and len(doc["summary"]["by_arm"]) == 3, doc["summary"]["total"]
    assert not coverage_failures(rows), (coverage_failures(rows), doc["summary"])
    assert coverage_failures(rows, PLANTED_BIAS), "the planted bias went unseen"
    # At the truth's minimum (the answer's cost at most 1.01 times the truth's, both from the
    # start the data were made from) in at least 95 % of the fits (here: every one of the 15), and
    # a fit elsewhere is not trusted; a pair the data cannot separate takes the trust away too.
    at_minimum = [f for f in doc["fits"] if f.get("cost_ratio") is not None and f["cost_ratio"] <= 1.01]
    assert len(at_minimum) >= 0.95 * len(doc["fits"]), [(f["arm"], f["seed"], f.get("cost_ratio")) for f in doc["fits"]]
    assert not [f for f in doc["fits"] if f not in at_minimum and f.get("trusted")], doc["fits"]
    for f in doc["fits"]:
        fitted = json.loads((tmp_path / "suite" / f["dir"] / "fit.json").read_text())
        matrix = [[math.nan if x is None else x for x in row] for row in fitted["correlation"]["matrix"]]
        c = np.abs(np.array(matrix) - np.eye(len(matrix)))
        assert not (np.nanmax(c) >= 0.999 and fitted["trusted"]), (f["arm"], f["seed"], fitted["verdict"])


@pytest.mark.full
def test_a_start_in_motion_fitted_with_the_parameters_brings_the_iiwa_to_the_truth(tmp_path):
    """The KUKA iiwa's draw of seed 101 (1.5 s, mu_k[4], k[4], b_v[4]): joints 2 and 4 sag from
    their relaxed springs at t = 0, so the data start in motion, and their start state read off
    the derivative filter at the record's edge is off (joint 2's q' -0.0077 rad/s for a true 0,
    90 of the fitted standard errors). With the start state fitted (the default, fit_start = true)
    the fit ends at the truth's minimum (cost ratio <= 1), trusted, every estimate within 3
    standard errors, and the fitted q' of both joints within 3 of their true 0. With the start
    as read (fit_start = false) it ends above the truth's cost with a misfit, NOT TRUSTED, and a
    warning names the moving joints."""
    from stickslip.fit import fit
    from stickslip.fit.benchmark import generate, simulation_cost

    problem = generate(_arm_fmu("kuka_iiwa"), 101, tmp_path, arm="kuka_iiwa", duration=1.5, n_parameters=3, starts=1)
    spec = problem.spec

    def ratio(result):
        values = {n: p["value"] for n, p in result["parameters"].items()}
        tol = result["method"].get("error_tolerance")
        return (
            simulation_cost(spec, values, error_tolerance=tol)["cost"]
            / simulation_cost(spec, problem.truth, error_tolerance=tol)["cost"]
        )

    fitted = fit(spec, workers=0)
    print(fitted["verdict"], ratio(fitted), fitted["start_state"])
    assert fitted["trusted"] and ratio(fitted) <= 1.0
    for n, p in fitted["parameters"].items():
        assert abs(p["value"] - problem.truth[n]) <= 3 * p["std_error"], (n, p, problem.truth[n])
    assert {s["variable"] for s in fitted["start_state"].values()} == {
        "q_start[2]",
        "qd_start[2]",
        "q_start[4]",
        "qd_start[4]",
    }
    for name in ("run:qd_start[2]", "run:qd_start[4]"):
        s = fitted["start_state"][name]
        assert abs(s["value"]) <= 3 * s["std_error"], (name, s)
    s = fitted["start_state"]["run:qd_start[2]"]  # read -0.0077 rad/s; joint 4's within its noise, as 0
    assert abs(s["read"]) > 30 * s["std_error"], s
    read = json.loads(json.dumps(spec))
    read.setdefault("options", {})["fit_start"] = False
    as_read = fit(read, workers=0)
    moving = [w for w in as_read["warnings"] if "in motion" in w]
    print(as_read["verdict"], ratio(as_read), moving)
    assert not as_read["trusted"] and as_read["verdict"].startswith("NOT TRUSTED: misfit")
    assert len(moving) == 1 and "joint(s) 2, 4" in moving[0] and "fit_start" in moving[0], moving
    assert ratio(as_read) > 1.01 and as_read["start_state"] == {}
