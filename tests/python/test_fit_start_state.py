"""The start state as unknowns of the fit (python/stickslip/fit/start.py, ``start_unknowns``):
a joint moving at an experiment's first sample starts every run from a q_start[i], qd_start[i]
the fit estimates with the parameters; the first segment of multiple shooting starts there,
the later ones from their own reading; the replay of fitted.toml starts there too.

Data that begin mid-motion: the reference arm's measured run with its first rows cut off, so
that joints 1 and 3 move at the first sample."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

import fit_cases as fc
from sweep_cluster import STICKSLIP

CUT = 0.15  # s: where the record begins; joints 1 and 3 move there (0.135 and 0.023 rad/s)


def _cut(columns: dict, t0: float = CUT) -> dict:
    keep = columns["t"] >= t0 - 1e-9
    return {k: v[keep] for k, v in columns.items()}


def _spec(tmp_path, names, duration=0.6, seed=2, options=None, **extra):
    data = fc.write_data(tmp_path / "run.csv", _cut(fc.measured(duration, seed=seed)))
    return fc.spec(
        fc.experiment(data, **extra),
        names,
        {n: fc.TRUTH[n] for n in names},
        None,
        **(options or {}),
    )


def _problem(doc):
    """The fit's Problem of ``doc`` with its start unknowns, as fit() makes it."""
    from dataclasses import replace

    from helpers import require_fmu
    from stickslip.fit.problem import Evaluator, Problem, payload_of
    from stickslip.fit.spec import load
    from stickslip.fit.start import start_unknowns
    from stickslip.fmu import content_hash, unpacked

    spec = load(doc)
    fmu = require_fmu().read_bytes()
    digest = content_hash(fmu)
    known = {e.name: e.initial for e in spec.estimates}
    payloads = [payload_of(e, spec.model_description, unpacked(fmu, digest), known) for e in spec.experiments]
    unknowns = [u for e, p in zip(spec.experiments, payloads, strict=True) for u in start_unknowns(e, p.start)]
    spec = replace(spec, estimates=[*spec.estimates, *unknowns])
    return Problem(spec, Evaluator(fmu, digest, payloads)), unknowns


# ---------------------------------------------------------------------------
# no FMU run


def test_the_first_segment_starts_from_a_fitted_state_and_the_others_from_their_reading():
    """Segments.state: the run's parameters q_start[i] / qd_start[i] replace the reading at the
    first segment only; a joint they do not name keeps its reading; the rotor's start follows
    the state it is given."""
    from stickslip.fit.start import Segments

    seg = Segments(
        np.array([0, 10]),
        [1, 3],
        np.array([[0.1, 0.8], [0.2, 0.9]]),
        np.array([[0.5, 0.0], [0.6, 0.1]]),
        [3],
        np.array([[40.0], [20.0]]),
        [100.0],
    )
    values = {"q_start[1]": 0.11, "qd_start[3]": -0.2}
    q, qd = seg.state(0, values)
    assert q.tolist() == [0.11, 0.8] and qd.tolist() == [0.5, -0.2]
    q, qd = seg.state(1, values)
    assert q.tolist() == [0.2, 0.9] and qd.tolist() == [0.6, 0.1]
    assert seg.state(0)[0].tolist() == [0.1, 0.8]
    stiffness = {"k[3]": 1e4, "Delta[3]": 0.0}
    rotor = seg.rotor(0, stiffness.get, seg.state(0, {"q_start[3]": 0.85, "qd_start[3]": 0.3}))
    assert rotor["theta_m_start[3]"] == pytest.approx(100.0 * (0.85 + 40.0 / 1e4), rel=1e-15)
    assert rotor["omega_m_start[3]"] == pytest.approx(30.0, rel=1e-15)


def test_the_noise_of_a_reading_is_the_filters_own_at_that_sample():
    """reading_noise against the Savitzky-Golay filter's coefficients (the root sum of squares
    per unit noise, closed form) at the record's first sample, the second and the middle,
    within 6 % with 2000 draws (their own error 1.6 %): at the edge the rate's noise is 6.1
    times the middle's."""
    from scipy.signal import savgol_coeffs

    from stickslip.fit.filtering import AUTO
    from stickslip.fit.start import reading_noise

    dt, std = 1e-3, 3e-6
    t = dt * np.arange(400)
    value, rate = reading_noise(t, std, [0, 1, 200], AUTO, np.random.default_rng(3), draws=2000)
    for m, pos in enumerate((0, 1, 9)):
        for got, deriv in ((value[m], 0), (rate[m], 1)):
            c = savgol_coeffs(19, 5, deriv=deriv, pos=pos, delta=dt, use="dot")
            assert got == pytest.approx(std * math.sqrt(float(np.sum(c**2))), rel=0.06), (pos, deriv)
    assert rate[0] / rate[2] == pytest.approx(6.1, rel=0.1)


def test_only_joints_read_moving_get_start_unknowns_within_the_noise_of_their_reading(tmp_path):
    """On the record cut at 0.15 s both measured joints move: q_start and qd_start of each, their
    bounds START_SIGMAS of the reading's noise at the first sample around the reading (and two
    counts for q). On the uncut record both stand at their command at rest: none."""
    from helpers import require_fmu
    from stickslip.fit.filtering import AUTO
    from stickslip.fit.spec import load
    from stickslip.fit.start import START_SIGMAS, reading_noise, start_states, start_unknowns

    require_fmu()
    doc = _spec(tmp_path, ["mu_k[1]"])
    e = load(doc).experiments[0]
    seg = start_states(e, [0], load(doc).model_description)
    unknowns = start_unknowns(e, seg)
    assert [u.name for u in unknowns] == ["run:q_start[1]", "run:qd_start[1]", "run:q_start[3]", "run:qd_start[3]"]
    assert all(u.start_of == "run" for u in unknowns)
    assert [u.variable for u in unknowns] == ["q_start[1]", "qd_start[1]", "q_start[3]", "qd_start[3]"]
    for c, (uq, uv) in zip(e.channels, (unknowns[:2], unknowns[2:]), strict=True):
        sq, sv = reading_noise(e.time, c.std, [0], AUTO, np.random.default_rng(0))
        assert uq.initial == pytest.approx(0.5 * (uq.low + uq.high), abs=1e-15)
        assert uq.high - uq.initial == pytest.approx(START_SIGMAS * sq[0] + 2.0 * (c.resolution or 0.0), rel=0.2)
        assert uv.high - uv.initial == pytest.approx(START_SIGMAS * sv[0], rel=0.2)
        assert abs(uv.initial) > START_SIGMAS * sv[0] / 10  # read as moving
    still = fc.write_data(tmp_path / "still.csv", fc.measured(0.6, seed=2))
    e0 = load(fc.spec(fc.experiment(still), ["mu_k[1]"])).experiments[0]
    assert start_unknowns(e0, start_states(e0, [0], load(doc).model_description)) == []


def test_a_fitted_start_of_bad_form_in_fitted_toml_is_refused(tmp_path):
    """fitted_starts: a [start.<experiment>] of something else than q_start[i] / qd_start[i], a
    value that is not a finite number, or a [start] that is not a table of tables: a
    ReplayError naming the table and the entry."""
    from stickslip.fit.replay import ReplayError, fitted_starts

    good = tmp_path / "good.toml"
    good.write_text('[parameters]\n"mu_k[1]" = 0.2\n[start."run"]\n"q_start[1]" = 0.1\n"qd_start[1]" = -0.5\n')
    assert fitted_starts(good) == {"run": {"q_start[1]": 0.1, "qd_start[1]": -0.5}}
    for body, message in (
        ('[start."run"]\n"k[3]" = 1.0\n', r"\[start.run\] k\[3\]: only q_start"),
        ('[start."run"]\n"q_start[a]" = 1.0\n', r"\[start.run\] q_start\[a\]: only q_start"),
        ('[start."run"]\n"q_start[1]" = nan\n', "must be a finite number"),
        ('[start."run"]\n"q_start[1]" = "x"\n', "must be a finite number"),
        ('[start."run"]\n"q_start[1]" = true\n', "must be a finite number"),
        ("start = 3\n", r"\[start\] must hold a table"),
        ("[start]\nrun = 3\n", r"\[start.run\] must be a table"),
    ):
        bad = tmp_path / "bad.toml"
        bad.write_text(body + '[parameters]\n"mu_k[1]" = 0.2\n')
        with pytest.raises(ReplayError, match=message):
            fitted_starts(bad)


def test_fit_start_must_be_true_or_false():
    from stickslip.fit.spec import FitSpecError, load

    doc = fc.spec(fc.experiment(Path("x.csv")), ["mu_k[1]"], fit_start="yes")
    with pytest.raises(FitSpecError, match="fit_start = 'yes': must be true or false"):
        load(doc)


# ---------------------------------------------------------------------------
# through the FMU


@pytest.mark.parametrize("segment", [None, 0.1])
def test_the_jacobian_of_the_start_unknowns_is_their_differences_and_0_after_the_first_segment(
    tmp_path, monkeypatch, segment
):
    """Problem.residual_jacobian with the start unknowns' columns (the FMU's sensitivities to
    q_start[i], qd_start[i]) against central differences of free runs at fixed 0.1 ms sub-steps
    (1e-4 of each range): within 1e-3 of each column's largest value, every column exact. In
    multiple shooting a start unknown's column is 0 on every row after the first segment (a
    later segment starts from its own reading), exactly, and not before."""
    fixed = {"h_min": 1e-4, "h_max": 1e-4, "tolerance": 1e-13}
    problem, unknowns = _problem(_spec(tmp_path, ["mu_k[1]", "k[3]"], duration=0.45, parameters=fixed))
    assert len(unknowns) == 4
    monkeypatch.setenv("STICKSLIP_PER_POINT", "0")
    z = problem.transform.z([0.18, 7e5, *(u.initial for u in unknowns)])
    J = fc.sensitivities_against_differences(problem, z, segment)
    if segment is not None:
        seg = problem.segments(segment)[0]
        n = len(problem.spec.experiments[0].time)
        later = np.concatenate([c * n + np.arange(seg.starts[1], n) for c in range(2)])
        first = np.concatenate([c * n + np.arange(1, seg.starts[1]) for c in range(2)])
        for j in range(2, len(z)):
            assert np.all(J[later, j] == 0.0), problem.spec.estimates[j].name
            assert np.max(np.abs(J[first, j])) > 0.0, problem.spec.estimates[j].name


@pytest.mark.slow
def test_a_record_that_begins_in_motion_gets_its_start_and_parameters_back_and_replays_as_fitted(tmp_path):
    """The reference arm's run cut at 0.15 s, mu_k[1] and k[3] from 15 % and 12 % off: the fit
    estimates the start state of both joints with them. Each parameter comes back within 3
    standard errors of the truth, the fitted q_start[i] within 3 of the noiseless record's q at
    0.15 s, and the fit is trusted. fit.json keeps the start state apart from the parameters (report.md tables it);
    fitted.toml holds it in [start."run"], and its replay command reproduces fit.json's residual
    rms to 1e-9. With fit_start = false the fit starts from the reading and ends at a higher
    cost."""
    import json
    import shlex

    import pandas as pd

    from stickslip.fit import fit

    names = ["mu_k[1]", "k[3]"]
    doc = _spec(tmp_path, names, duration=0.8)
    doc["estimate"]["mu_k[1]"]["initial"] = 0.17 * 1.15
    doc["estimate"]["k[3]"]["initial"] = 8e5 * 0.88
    spec = fc.write_spec(tmp_path / "fit.toml", doc)
    out = tmp_path / "out"
    r = fit(spec, out=out, workers=0)
    assert set(r["parameters"]) == set(names)
    for name, p in r["parameters"].items():
        assert abs(p["value"] - fc.TRUTH[name]) <= 3 * p["std_error"], (name, p)
    assert r["trusted"], (r["verdict"], r["warnings"])
    truth = _cut(fc.measured(0.8, seed=2, noise=0.0))
    states = r["start_state"]
    assert set(states) == {"run:q_start[1]", "run:qd_start[1]", "run:q_start[3]", "run:qd_start[3]"}
    for i, column in ((1, "link1"), (3, "link3")):
        s = states[f"run:q_start[{i}]"]
        assert s["experiment"] == "run" and s["variable"] == f"q_start[{i}]"
        assert abs(s["value"] - truth[column][0]) <= 3 * s["std_error"], (i, s, truth[column][0])
    report = (out / "report.md").read_text()
    assert "| start unknown |" in report and "| `run:qd_start[1]` |" in report
    toml = (out / "fitted.toml").read_text()
    assert '[start."run"]' in toml and '"qd_start[3]" = ' in toml
    line = next(x for x in toml.splitlines() if "--experiment 'run'" in x)
    argv = [STICKSLIP, *shlex.split(line.split("stickslip ", 1)[1])]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    table, reported = pd.read_csv(out / "replay" / "run.csv"), json.loads((out / "fit.json").read_text())
    measured = pd.read_csv(tmp_path / "run.csv")
    for output, (column, _) in fc.NOISE.items():
        rms = float(np.sqrt(np.mean((table[output] - measured[column]) ** 2)))
        assert abs(rms - reported["residual_rms"][output]) <= 1e-9 * rms, (output, rms, reported["residual_rms"])
    read = fit(fc.write_spec(tmp_path / "read.toml", {**doc, "options": {"fit_start": False}}), workers=0)
    assert read["start_state"] == {} and set(read["parameters"]) == set(names)
    assert read["cost"] > r["cost"], (read["cost"], r["cost"])


def test_a_fitted_start_for_a_joint_the_data_read_at_rest_is_refused(tmp_path):
    """replay with a fitted start of joint 1 on a record whose first sample reads it at rest (a
    fitted.toml of another SPEC): a ReplayError naming the table and the variable, before any
    run."""
    from stickslip.fit.replay import ReplayError, replay
    from stickslip.fit.spec import load

    still = fc.write_data(tmp_path / "still.csv", fc.measured(0.6, seed=2))
    spec = load(fc.spec(fc.experiment(still), ["mu_k[1]"]), replay=True)
    with pytest.raises(ReplayError, match=r"\[start.still\] q_start\[1\]: the experiment's first sample does not read"):
        replay(spec, None, {"mu_k[1]": 0.17}, starts={"still": {"q_start[1]": 0.1}}, plot=False, say=lambda x: None)


def test_each_experiments_start_moves_its_own_rows_only(tmp_path, monkeypatch):
    """Two experiments cut at 0.15 s and 0.2 s, fitted together: each has its own start unknowns
    (named after it), a run of one takes only its own, and in the residuals' Jacobian (from the
    FMU's sensitivities, at fixed 0.1 ms sub-steps) a start unknown's column is 0 on the other
    experiment's rows, exactly, and matches central differences of free runs on its own (1e-3
    of its largest value)."""
    fixed = {"h_min": 1e-4, "h_max": 1e-4, "tolerance": 1e-13}
    columns = fc.measured(0.45, seed=2)
    experiments = []
    for name, t0 in (("a", 0.15), ("b", 0.2)):
        data = fc.write_data(tmp_path / f"{name}.csv", _cut(columns, t0))
        experiments.append(fc.experiment(data, name=name, parameters=fixed))
    problem, unknowns = _problem(fc.spec(experiments, ["mu_k[1]"], {"mu_k[1]": 0.18}))
    assert [u.name for u in unknowns] == [
        f"{e}:{v}[{i}]" for e in "ab" for i in (1, 3) for v in ("q_start", "qd_start")
    ]
    z = problem.transform.z([0.18, *(u.initial for u in unknowns)])
    assert sorted(problem.parameters(z, 1)) == ["mu_k[1]", "q_start[1]", "q_start[3]", "qd_start[1]", "qd_start[3]"]
    assert problem.parameters(z, 1)["q_start[1]"] == unknowns[4].initial
    monkeypatch.setenv("STICKSLIP_PER_POINT", "0")
    runs = problem.runs([z], None, problem.sensitivity_steps(z))[0]
    J, exact = problem.residual_jacobian(runs, z)
    assert exact.all(), exact
    rows_a = 2 * len(problem.spec.experiments[0].time)
    for j, u in enumerate(unknowns, start=1):
        own, other = (
            (slice(0, rows_a), slice(rows_a, None)) if u.start_of == "a" else (slice(rows_a, None), slice(0, rows_a))
        )
        assert np.all(J[other, j] == 0.0), u.name
        reference = fc.central_column(problem, z, j)
        assert np.all(reference[other] == 0.0), u.name
        scale = np.max(np.abs(reference[own]))
        assert scale > 0 and np.max(np.abs(J[own, j] - reference[own])) <= 1e-3 * scale, u.name
