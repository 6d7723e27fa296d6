"""Issue 36: replay of a fit SPEC's experiments (``stickslip simulate --spec``), the start
state from the data (stickslip.fit.start), and no silent default motion in sweep and study.

The replay that reproduces a fit's residuals through fitted.toml's own command is in
test_fit.py (test_fitted_toml_reproduces_each_of_two_experiments)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import fit_cases as fc
from sweep_cluster import STICKSLIP

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def run_spec(tmp_path_factory):
    """A SPEC of one 0.3 s run of the reference arm (no [estimate]: a replay SPEC)."""
    tmp = tmp_path_factory.mktemp("replay")
    data = fc.write_data(tmp / "run.csv", fc.measured(0.3, seed=5))
    doc = fc.spec(fc.experiment(data), ["mu_k[1]"])
    doc.pop("estimate")
    return fc.write_spec(tmp / "replay.toml", doc), tmp


def _simulate(*args, timeout=300):
    return subprocess.run([STICKSLIP, "simulate", *map(str, args)], capture_output=True, text=True, timeout=timeout)


def test_replay_at_the_truth_leaves_the_noise(run_spec):
    """The run replayed at the truth: every channel's residual is the measurement's noise
    (its rms within 15 % of σ, 300 samples), the CSV holds every output at the samples, and
    the plot is written."""
    spec, tmp = run_spec
    out = tmp / "at-truth"
    done = _simulate("--spec", spec, "--set", f"mu_k[1]={fc.TRUTH['mu_k[1]']}", "--out", out)
    assert done.returncode == 0, done.stderr
    import pandas as pd

    table = pd.read_csv(out / "run.csv")
    assert {"time", "q[1]", "q[3]", "stick[1]", "F_drive[1]"} <= set(table.columns)
    measured = pd.read_csv(tmp / "run.csv")
    for output, (column, sigma) in fc.NOISE.items():
        rms = float(np.sqrt(np.mean((table[output] - measured[column]) ** 2)))
        assert 0.85 * sigma < rms < 1.15 * sigma, (output, rms, sigma)
        assert f"{output} rms {rms:.4g}" in done.stdout
    assert (out / "run.png").stat().st_size > 10_000


def test_replay_moves_with_the_values_it_is_given(run_spec):
    """A wrong μ_k[1] (0.21 against 0.17) leaves a residual far above the noise: the --set
    reaches the run."""
    spec, tmp = run_spec
    done = _simulate("--spec", spec, "--set", "mu_k[1]=0.21", "--out", tmp / "wrong")
    assert done.returncode == 0, done.stderr
    line = next(x for x in done.stdout.splitlines() if x.startswith("replay run"))
    sigmas = float(line.split("q[1] rms ")[1].split("(")[1].split(" σ")[0])
    assert sigmas > 3, line  # 3.86 measured; 1.0 at the truth


@pytest.mark.parametrize(
    "args, message",
    [
        (["--experiment", "nope"], "no experiment 'nope'"),
        (["--fitted", "missing.toml"], "no such file"),
        (["--motion", "examples/motions/reference.toml"], "leave out --motion"),
        (["--set", "no_such[1]=1"], "'no_such[1]' is not a variable"),
        (["--out", "x.csv"], "a directory"),
    ],
)
def test_a_replay_that_cannot_run_is_one_line_and_exit_2(run_spec, args, message):
    spec, tmp = run_spec
    out = [] if "--out" in args else ["--out", tmp / "bad"]
    done = _simulate("--spec", spec, *args, *out)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert message in done.stderr, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr


def test_experiment_and_fitted_need_a_spec():
    done = _simulate("--experiment", "run")
    assert done.returncode == 2 and "--spec" in done.stderr, done.stderr


def test_a_fitted_toml_without_parameters_is_refused(run_spec):
    spec, tmp = run_spec
    bad = tmp / "fitted.toml"
    bad.write_text('[settings]\n"error_tolerance" = "tight"\n')
    done = _simulate("--spec", spec, "--fitted", bad, "--out", tmp / "bad2")
    assert done.returncode == 2 and "must be a finite number" in done.stderr, done.stderr


# ---------------------------------------------------------------------------
# the start state from the data


def test_a_still_start_within_the_noise_is_the_command_and_a_moved_one_is_measured():
    """resting(): samples within the noise band of their median for REST_SAMPLES samples are
    a joint at rest, an outlier apart; start_states() puts a still joint whose samples stand
    at its command at the command exactly, one standing elsewhere (by 50 σ) at the mean of its
    still samples, with q' = 0."""
    from stickslip.fit.filtering import AUTO
    from stickslip.fit.spec import Channel, Experiment
    from stickslip.fit.start import resting, start_states

    rng = np.random.default_rng(1)
    t = np.arange(0.0, 0.2, 1e-3)
    sigma = 2e-6
    y = 0.1 + rng.normal(0.0, sigma, len(t))
    y[3] += 20 * sigma  # an outlier
    position, count = resting(y, 0, 3 * sigma)
    assert abs(position - 0.1) < 3 * sigma / np.sqrt(count) and count > 150
    moving = 0.1 + 0.5 * t**2 * 1e3  # leaves the band at once
    assert resting(moving, 0, 3 * sigma) is None

    from fmpy import read_model_description

    md = read_model_description(str(fc.require_fmu()))

    def experiment(q1):
        motion = lambda tk, step: ([0.1, 0.0, 0.8, 0.0], [0.0] * 4, [0.0] * 4)  # noqa: E731
        channel = Channel("q[1]", "link1", sigma, values=q1)
        return Experiment("x", Path("x.csv"), t, motion, None, {}, {}, [channel], derivatives=AUTO)

    at_command = start_states(experiment(y), [0], md)
    assert at_command.q_start[0, 0] == 0.1 and at_command.qd_start[0, 0] == 0.0
    assert at_command.q_start[0, 1] == 0.8  # joint 3 not measured: its command
    elsewhere = start_states(experiment(y + 50 * sigma), [0], md)
    assert abs(elsewhere.q_start[0, 0] - (0.1 + 50 * sigma)) < 3 * sigma / np.sqrt(count)
    assert elsewhere.qd_start[0, 0] == 0.0


# ---------------------------------------------------------------------------
# no silent default motion in sweep and study


def _xarm6():
    from test_simulate_motion import _xarm6 as build

    return build()


@pytest.mark.full
def test_sweep_and_study_refuse_the_reference_motion_for_another_arm(tmp_path):
    xarm6 = _xarm6()
    spec = tmp_path / "sweep.toml"
    spec.write_text(f'fmu = "{xarm6}"\nstop_time = 0.1\ncommunication_step = 1e-3\n[grid]\n"mu_k[2]" = [0.1, 0.2]\n')
    done = subprocess.run(
        [STICKSLIP, "sweep", str(spec), "--out", str(tmp_path / "sweep"), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 1, (done.stdout, done.stderr)
    assert "--motion" in done.stderr and "reference" in done.stderr, done.stderr
    done = subprocess.run(
        [sys.executable, "-m", "stickslip.cli", "study", "--fmu", str(xarm6), "--out", str(tmp_path / "study")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode != 0 and "--motion" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr, done.stderr


def test_a_prediction_over_a_horizon_restarts_from_the_measured_state(run_spec):
    """--horizon 0.1: the 0.3 s run in three predictions from the measured state; at the truth
    the residual stays near the noise (rms below 2.5 σ: each restart carries the filtered
    state's error; measured 1.0 σ on q[1] and 1.9 σ on q[3], whose stiff drive rings after a
    restart off by a fraction of σ), and with a wrong μ_k[1] it is smaller than the whole run's (the drift is cut
    at each restart). --horizon 0 is refused (exit 2)."""
    spec, tmp = run_spec
    truth = f"mu_k[1]={fc.TRUTH['mu_k[1]']}"
    done = _simulate("--spec", spec, "--set", truth, "--horizon", 0.1, "--out", tmp / "horizon")
    assert done.returncode == 0, done.stderr
    import pandas as pd

    table, measured = pd.read_csv(tmp / "horizon" / "run.csv"), pd.read_csv(tmp / "run.csv")
    for output, (column, sigma) in fc.NOISE.items():
        rms = float(np.sqrt(np.mean((table[output] - measured[column]) ** 2)))
        assert 0.75 * sigma < rms < 2.5 * sigma, (output, rms, sigma)

    def cost(args):
        out = _simulate("--spec", spec, "--set", "mu_k[1]=0.21", *args, "--out", tmp / "h2")
        return float(out.stdout.split("cost ")[1].split()[0])

    assert cost(["--horizon", 0.1]) < cost([])
    done = _simulate("--spec", spec, "--horizon", 0, "--out", tmp / "h3")
    assert done.returncode == 2 and "--horizon" in done.stderr, done.stderr


def test_a_fit_over_a_horizon_is_replayed_by_its_fitted_toml(tmp_path):
    """[options] horizon = 0.1: the final cost is the prediction over 0.1 s from each measured
    state (0.8 s, eight segments); μ_k[1] and k[3] come back within 3 standard errors of the
    truth from 20 % and 12 % off (measured 1.9 and 0.3: the segment-cluster sandwich counts
    the restarts' shared errors, without it 3.5 and 0.7), the restart transients are named as
    a misfit (NOT TRUSTED), fit.json says how it was fitted, and fitted.toml's command (with
    --horizon 0.1) prints fit.json's residual rms to 1e-9. A horizon with shooting =
    "single" is refused."""
    import json
    import shlex

    import pandas as pd

    from stickslip.fit import fit
    from stickslip.fit.spec import FitSpecError, load

    data = fc.write_data(tmp_path / "run.csv", fc.measured(0.8, seed=6))
    doc = fc.spec(fc.experiment(data), ["mu_k[1]", "k[3]"], {"mu_k[1]": 0.2, "k[3]": 9e5}, horizon=0.1)
    spec = fc.write_spec(tmp_path / "fit.toml", doc)
    out = tmp_path / "out"
    r = fit(spec, out=out, workers=0)
    for name, p in r["parameters"].items():
        assert abs(p["value"] - fc.TRUTH[name]) <= 3 * p["std_error"], (name, p)
    assert not r["trusted"] and r["verdict"].startswith("NOT TRUSTED: misfit"), r["verdict"]
    assert r["method"]["shooting"] == "multiple, then over a 0.1 s horizon" and r["method"]["horizon_s"] == 0.1
    line = next(x for x in (out / "fitted.toml").read_text().splitlines() if "--experiment 'run'" in x)
    assert "--horizon 0.1" in line, line
    argv = [STICKSLIP, *shlex.split(line.split("stickslip ", 1)[1])]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    table, reported = pd.read_csv(out / "replay" / "run.csv"), json.loads((out / "fit.json").read_text())
    measured = pd.read_csv(data)
    for output, (column, _) in fc.NOISE.items():
        rms = float(np.sqrt(np.mean((table[output] - measured[column]) ** 2)))
        assert abs(rms - reported["residual_rms"][output]) <= 1e-9 * rms, (output, rms, reported["residual_rms"])
    with pytest.raises(FitSpecError, match="horizon"):
        load({**doc, "options": {"horizon": 0.1, "shooting": "single"}})
