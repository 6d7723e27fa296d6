"""Issue 36: the torque-logged motor-drive arm of examples/calibration_motor, as a user runs it.

``stickslip fit calibration.toml`` (``stage = "equation-error"``: the torques' equations
are the answer) and ``stickslip simulate --spec heldout.toml --fitted ... --horizon 0.25``
on the committed data; the truth is make_data.py's TRUTH (the SPECs do not know it).
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from sweep_cluster import STICKSLIP

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "calibration_motor"


def _make_data():
    spec = importlib.util.spec_from_file_location("make_data", EXAMPLE / "make_data.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["make_data"] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _motor_fmu() -> Path:
    from motor_fmus import require_motor_fmu

    return Path(require_motor_fmu())


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    """The example's fit into a temporary DIR (the SPEC's FMU path replaced by the FMU under
    test): (DIR, fit.json)."""
    tmp = tmp_path_factory.mktemp("motor")
    fmu = _motor_fmu()
    for name in ("calibration.toml", "heldout.toml"):
        text = (EXAMPLE / name).read_text().replace('"../../target/fmu/reference_rrpr_motor.fmu"', f'"{fmu}"')
        (tmp / name).write_text(text)
    for csv in EXAMPLE.glob("*.csv"):
        (tmp / csv.name).write_bytes(csv.read_bytes())
    out = tmp / "fit"
    done = subprocess.run(
        [STICKSLIP, "fit", str(tmp / "calibration.toml"), "--out", str(out), "--workers", "0"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return tmp, out, json.loads((out / "fit.json").read_text())


@pytest.mark.full
def test_the_torques_give_every_rotor_and_friction_parameter_within_3_standard_errors(fitted):
    """Ten parameters of two motor joints from three 4 ms runs with 1 % torque noise: each
    within 3 of its standard error of the truth (measured: at most 2.1; with the least
    squares' own, independent-residual errors instead of the Newey-West sandwich, τ_c[1],
    μ_k[1] and b_m[3] were 4.3–4.7 off), τ_c and μ_k of a joint reported correlated (the
    two Coulomb levels: the data fix mostly their sum)."""
    _, _, r = fitted
    truth = _make_data().TRUTH
    truth = {**truth, "mu_s[3]": 0.2}  # left at the FMU's start value by make_data.py
    for name, p in r["parameters"].items():
        z = (p["value"] - truth[name]) / p["std_error"]
        print(f"{name}: {p['value']:.6g} ± {p['std_error']:.3g}, truth {truth[name]:g}, z {z:+.2f}")
        assert abs(z) <= 3.0, (name, p, truth[name])
    names = r["correlation"]["names"]
    matrix = r["correlation"]["matrix"]
    for i in (1, 3):
        c = matrix[names.index(f"tau_c[{i}]")][names.index(f"mu_k[{i}]")]
        assert c < -0.5, (i, c)
    assert r["method"]["stage"] == "equation-error"


@pytest.mark.full
def test_held_out_runs_are_predicted_as_well_as_the_truth_predicts_them(fitted):
    """The replay command of the docs on the three held-out runs over a 0.25 s horizon: with
    the fitted values the residual of every channel is within 30 % of the residual the true
    values leave (the logged torques' noise sets both: the drift within a horizon), and far
    below the catalogue values' (the FMU's start values)."""
    tmp, out, _ = fitted
    truth = _make_data().TRUTH

    def replay(*args):
        done = subprocess.run(
            [STICKSLIP, "simulate", "--spec", str(tmp / "heldout.toml"), "--horizon", "0.25", *args],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert done.returncode == 0, done.stderr
        found = {}
        for line in done.stdout.splitlines():
            if line.startswith("replay "):
                name, rest = line[len("replay ") :].split(": ", 1)
                for part in rest.split("; ")[0].split(", "):
                    channel, _, value = part.partition(" rms ")
                    found[(name, channel)] = float(value.split()[0])
        return found

    fit = replay("--fitted", str(out / "fitted.toml"), "--out", str(tmp / "heldout"))
    exact = replay(*[f"--set={k}={v!r}" for k, v in truth.items()], "--out", str(tmp / "heldout-truth"))
    catalogue = replay("--out", str(tmp / "heldout-catalogue"))
    assert len(fit) == 12, fit  # three runs, four channels
    for key, rms in fit.items():
        print(key, f"fitted {rms:.3g}, truth {exact[key]:.3g}, catalogue {catalogue[key]:.3g}")
        assert rms <= 1.3 * exact[key], key
    assert sum(fit.values()) < 0.5 * sum(catalogue.values())
    assert (tmp / "heldout" / "heldout_1.png").stat().st_size > 50_000


@pytest.mark.slow
def test_make_data_writes_the_committed_runs(tmp_path):
    """make_data.py says exactly how the data were made: run again, it writes the committed
    CSVs byte for byte."""
    import shutil

    work = tmp_path / "example"
    shutil.copytree(EXAMPLE, work)
    done = subprocess.run(
        [str(Path(STICKSLIP).with_name("python")), str(work / "make_data.py"), "--fmu", str(_motor_fmu())],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr
    for csv in EXAMPLE.glob("*.csv"):
        assert (work / csv.name).read_bytes() == csv.read_bytes(), csv.name
