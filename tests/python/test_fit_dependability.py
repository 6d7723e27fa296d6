"""A fit never ends in a traceback (issue 41, item 3): an impossible start is dropped with a
note naming why, a start that fails keeps the others, a fit that cannot finish writes fit.json
and report.md with what finished and why the rest did not, and the command says so in one line
with its documented exit status (python/stickslip/fit/cli.py: 0 ran, 1 could not finish, 2 a
SPEC that cannot be used, 3 an internal error). The equation-error stage's values outside their
bounds are reported, replayed and written at the bound they crossed.

Measured runs are the reference arm's (fit_cases.py), 0.3 s, so that each fit takes seconds.
Two tests inject a failure into the fit's own code (pytest's monkeypatch): the guard under test
is the fit's, and the FMU runs as it does for users.
"""

from __future__ import annotations

import argparse
import json
import random
import tomllib

import pytest

import fit_cases as fc

DURATION = 0.3


def _cli(spec: dict, tmp_path, capsys, name="out") -> tuple:
    """(exit status, stdout, stderr, DIR) of ``stickslip fit`` on ``spec`` in this process."""
    from stickslip.fit.cli import main

    path = tmp_path / f"{name}.toml"
    path.write_text(fc.toml(spec))
    out = tmp_path / name
    capsys.readouterr()
    rc = main(argparse.Namespace(spec=str(path), out=str(out), workers=0, scheduler=None))
    said = capsys.readouterr()
    return rc, said.out, said.err, out


def _one_line_and_no_traceback(rc: int, stdout: str, stderr: str) -> None:
    assert "Traceback" not in stdout + stderr, stdout + stderr
    if rc != 0:
        lines = [line for line in stderr.splitlines() if line.strip()]
        assert len(lines) == 1, stderr


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return fc.write_data(tmp_path_factory.mktemp("run") / "run.csv", fc.measured(DURATION, seed=5))


def test_an_equation_error_start_outside_the_bounds_is_dropped_with_its_reason(data, tmp_path, capsys):
    """μ_k[1]'s bounds [0.18, 0.22] leave out the truth 0.17, which the equation-error stage
    finds: that start is dropped, named with the value and the bounds, and the fit goes on from
    the others to exit 0."""
    spec = fc.spec(fc.experiment(data), ["mu_k[1]"], {"mu_k[1]": 0.2}, {"mu_k[1]": (0.18, 0.22)}, max_evaluations=4)
    rc, stdout, stderr, out = _cli(spec, tmp_path, capsys)
    _one_line_and_no_traceback(rc, stdout, stderr)
    assert rc == 0, stderr
    result = json.loads((out / "fit.json").read_text())
    (dropped,) = [s for s in result["starts"] if s["origin"] == "equation-error"]
    assert dropped["status"] == "dropped" and "outside its bounds [0.18, 0.22]" in dropped["message"], dropped
    assert "start 'equation-error' dropped" in stdout
    assert any(s["status"] != "dropped" and s["cost"] is not None for s in result["starts"])


def test_a_start_that_fails_keeps_the_others(data, tmp_path, capsys, monkeypatch):
    """A start whose fit raises (injected into the second start) comes back 'failed' with the
    reason; the others give the answer."""
    from stickslip.fit import solve

    real = solve._single_stage

    def failing(problem, start, *args, **kw):
        if start.origin == "latin hypercube 1":
            raise FloatingPointError("injected into this start")
        return real(problem, start, *args, **kw)

    monkeypatch.setattr(solve, "_single_stage", failing)
    spec = fc.spec(fc.experiment(data), ["mu_k[1]"], starts=2, max_evaluations=4)
    rc, stdout, stderr, out = _cli(spec, tmp_path, capsys)
    _one_line_and_no_traceback(rc, stdout, stderr)
    assert rc == 0, stderr
    starts = {s["origin"]: s for s in json.loads((out / "fit.json").read_text())["starts"]}
    assert starts["latin hypercube 1"]["status"] == "failed", starts
    assert starts["latin hypercube 1"]["message"] == "FloatingPointError: injected into this start"
    assert starts["initial"]["cost"] is not None


# Fixed sub-steps of 0.2 ms and an iteration tolerance of 1e-12: at k[3] >= 1e9 every run is
# discarded within its first 20 ms (test_fit.py, DISCARDING).
DISCARDING = {"tolerance": 1e-12, "h_min": 2e-4, "h_max": 2e-4}


def test_a_fit_no_start_of_which_finishes_writes_what_it_did_and_exits_1(tmp_path, capsys):
    """k[3] bounded to [6e9, 1e11], where the FMU discards every run: exit 1 with one line
    naming the reason and where it is written; fit.json says FAILED, lists every start with the
    reason it ended without a cost, and there is no fitted.toml to replay."""
    data = fc.write_data(tmp_path / "run.csv", fc.measured(DURATION, seed=1, truth=DISCARDING))
    spec = fc.spec(
        fc.experiment(data, parameters=dict(DISCARDING)),
        ["k[3]"],
        {"k[3]": 1e10},
        {"k[3]": (6e9, 1e11)},
        shooting="single",
        starts=2,
        max_evaluations=3,
    )
    rc, stdout, stderr, out = _cli(spec, tmp_path, capsys)
    _one_line_and_no_traceback(rc, stdout, stderr)
    assert rc == 1
    assert "no start reached a finite cost" in stderr and "fit.json" in stderr, stderr
    result = json.loads((out / "fit.json").read_text())
    assert result["trusted"] is False and result["verdict"].startswith("FAILED: no start reached a finite cost")
    assert len(result["starts"]) >= 2 and all(s["cost"] is None for s in result["starts"])
    assert "**Verdict: FAILED" in (out / "report.md").read_text()
    assert not (out / "fitted.toml").exists()


def test_a_failure_after_the_starts_keeps_the_best_start(data, tmp_path, capsys, monkeypatch):
    """The uncertainty at the best start fails (injected): exit 1, one line; fit.json holds the
    best start's parameters without standard errors, error.log the traceback."""
    import stickslip.fit as fit_package

    def failing(*args, **kw):
        raise ZeroDivisionError("injected into the uncertainty")

    monkeypatch.setattr(fit_package, "_at_optimum", failing)
    spec = fc.spec(fc.experiment(data), ["mu_k[1]"], max_evaluations=4)
    rc, stdout, stderr, out = _cli(spec, tmp_path, capsys)
    _one_line_and_no_traceback(rc, stdout, stderr)
    assert rc == 1 and "ZeroDivisionError: injected into the uncertainty" in stderr, stderr
    result = json.loads((out / "fit.json").read_text())
    assert result["parameters"]["mu_k[1]"]["std_error"] is None
    assert 0.05 <= result["parameters"]["mu_k[1]"]["value"] <= 0.22
    assert "ZeroDivisionError" in (out / "error.log").read_text()


def test_equation_error_values_outside_their_bounds_are_what_is_replayed_and_written(data, tmp_path, capsys):
    """stage = "equation-error" with μ_k[1]'s bounds [0.18, 0.22] (the truth 0.17 outside):
    the reported value is the bound, fitted.toml holds it, the warning names the raw estimate,
    and the answer is not trusted."""
    bounds = {"mu_k[1]": (0.18, 0.22)}
    spec = fc.spec(fc.experiment(data), ["mu_k[1]"], {"mu_k[1]": 0.2}, bounds, stage="equation-error")
    rc, stdout, stderr, out = _cli(spec, tmp_path, capsys)
    _one_line_and_no_traceback(rc, stdout, stderr)
    assert rc == 0, stderr
    result = json.loads((out / "fit.json").read_text())
    value = result["parameters"]["mu_k[1]"]["value"]
    assert value == 0.18, value
    assert tomllib.loads((out / "fitted.toml").read_text())["parameters"]["mu_k[1]"] == value
    assert result["trusted"] is False
    assert any("equation-error estimate" in w and "outside its bounds" in w for w in result["warnings"])


@pytest.mark.full
def test_fuzzed_bounds_and_stages_end_in_an_answer_or_one_line(data, tmp_path, capsys):
    """12 seeded fits whose bounds may leave out the truth, sit on it, or cross zero where the
    equation-error stage may land below (b_v[3], truth 0 for the reference arm: its estimate
    from noise is negative about half the time), in either stage: each ends with exit 0 and an
    answer inside its bounds, or exit 1 with one line and fit.json; never a traceback, never a
    value outside its bounds in fit.json or fitted.toml."""
    outcomes = {}
    for case in range(12):
        rng = random.Random(case)
        names = rng.choice([["mu_k[1]"], ["b_v[3]"], ["mu_k[1]", "b_v[3]"]])
        bounds = {}
        for n in names:
            low = rng.choice({"mu_k[1]": [0.05, 0.12, 0.18, 0.2], "b_v[3]": [0.0, 1.0, 50.0]}[n])
            bounds[n] = (low, low + rng.choice({"mu_k[1]": [0.01, 0.02], "b_v[3]": [1.0, 100.0, 1000.0]}[n]))
        initial = {n: 0.5 * (a + b) for n, (a, b) in bounds.items()}
        stage = rng.choice(["output-error", "equation-error"])
        spec = fc.spec(fc.experiment(data), names, initial, bounds, stage=stage, max_evaluations=3, starts=2)
        rc, stdout, stderr, out = _cli(spec, tmp_path, capsys, name=f"case{case}")
        _one_line_and_no_traceback(rc, stdout, stderr)
        outcomes[rc] = outcomes.get(rc, 0) + 1
        assert rc in (0, 1), (case, rc, stderr)
        result = json.loads((out / "fit.json").read_text())
        if rc == 0:
            fitted = tomllib.loads((out / "fitted.toml").read_text())["parameters"]
            for n, p in result["parameters"].items():
                low, high = p["bounds"]
                assert low <= p["value"] <= high and fitted[n] == p["value"], (case, n, p)
    print(outcomes)
