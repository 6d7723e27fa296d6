"""The identification example (examples/identification, docs/calibration.md "Real arms") through
the documented commands, against make_data.py's truth (the SPEC does not know it):

* the committed logs are what make_data.py makes, byte for byte (slow: two FMUs built);
* over three noise draws of the same true runs, the base parameters' truth (the true arm's
  links through the base parameters' combinations, its μ_k and b_v) lies within 3 standard
  errors in all but at most 18 of the 171 (draw, parameter) pairs (≥ 89.5 %; a false failure
  P(X >= 19 | 171, 0.05) = 1.0e-3), and 2.5 SE off fails it; every link of every identified model is a
  physical body; the held-out runs' torques are predicted within 5 % relative rms on every
  joint, better than the catalogue model and the per-joint model (slow);
* ``stickslip identify`` on the committed SPEC writes a model file from which
  ``scripts/build_fmu.sh --model`` builds an FMU whose links are the identified ones (its
  regressor's π equal to identify.json's to 1e-12 relative) and which ``stickslip simulate``
  runs (full).
"""

from __future__ import annotations

import importlib.util
import json
import math
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from helpers import ROOT, allowed_misses
from sweep_cluster import STICKSLIP

EXAMPLE = ROOT / "examples" / "identification"
CATALOGUE_FMU = ROOT / "target" / "fmu" / "iiwa_catalogue.fmu"


def _make_data():
    spec = importlib.util.spec_from_file_location("make_data_identification", EXAMPLE / "make_data.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def catalogue_fmu():
    if not CATALOGUE_FMU.is_file():
        md = _make_data()
        md.build(EXAMPLE / "catalogue.toml", CATALOGUE_FMU)
    return CATALOGUE_FMU


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """make_data.py's clean runs (the FMUs built in a scratch directory) and the truth's θ."""
    md = _make_data()
    work = tmp_path_factory.mktemp("identification")
    runs = md.clean_runs(work)
    return md, runs, work / "truth.fmu"


@pytest.mark.slow
def test_make_data_reproduces_the_committed_logs(clean, tmp_path):
    md, runs, _ = clean
    for k, (name, columns) in enumerate(runs.items()):
        path = tmp_path / f"{name}.csv"
        md.write_csv(md.logged(columns, seed=1000 + k), path)
        assert path.read_bytes() == (EXAMPLE / f"{name}.csv").read_bytes(), name


def _truth_theta(names, truth_fmu) -> np.ndarray:
    """The truth in the equations' columns: the true arm's links and TRUE_FRICTION."""
    from stickslip.fit.regressor import joint_torque_regressor
    from stickslip.fmu import content_hash, unpacked

    md = _make_data()
    data = truth_fmu.read_bytes()
    _, pi, _ = joint_torque_regressor(unpacked(data, content_hash(data)), np.zeros((1, 21)))
    out = list(pi)
    for name in names[len(pi) :]:
        kind, _, rest = name.partition("[")
        mu, b_v = md.TRUE_FRICTION[int(rest[:-1])]
        out.append({"mu_k": mu, "b_v": b_v}[kind])
    return np.array(out)


@pytest.mark.slow
def test_the_truth_lies_within_3_standard_errors_and_held_out_torques_are_predicted(clean, catalogue_fmu, tmp_path):
    """Three noise draws of the example's runs (make_data.logged with seeds 2000+), each
    identified as the SPEC says; per draw the 43 link combinations and 14 friction parameters."""
    import tomllib

    from stickslip.identify import identification

    md, runs, truth_fmu = clean
    spec = tomllib.loads((EXAMPLE / "identify.toml").read_text())
    spec["fmu"] = str(catalogue_fmu)
    covered = biased_covered = total = 0
    for draw in range(3):
        where = tmp_path / f"draw{draw}"
        where.mkdir()
        for k, (name, columns) in enumerate(runs.items()):
            md.write_csv(md.logged(columns, seed=2000 + 10 * draw + k), where / f"{name}.csv")
        result = identification.identify(spec_for(spec, where))
        est = result["_internal"]["estimates"]
        theta = _truth_theta(est.names, truth_fmu)
        z = (est.beta - est.base.of(theta)) / est.std_error
        worst = int(np.argmax(np.abs(z)))
        print(f"draw {draw}: max |z| {abs(z[worst]):.2f} ({est.base.describe()[worst]}), warnings {result['warnings']}")
        covered += int(np.sum(np.abs(z) <= 3.0))
        biased_covered += int(np.sum(np.abs(z + 2.5) <= 3.0))
        total += len(z)
        assert min(result["pseudo_inertia_min_eigenvalue"]) > 0
        for run, rows in result["validation"].items():
            for i, row in rows.items():
                print(f"  {run} joint {i}: " + ", ".join(f"{k} {v:.4f}" for k, v in row.items()))
                assert row["identified"] < 0.05, (run, i, row)
                assert row["identified"] < row["catalogue"] and row["identified"] < row["per joint"], (run, i, row)
    print(f"covered {covered} of {total}")
    # sized (issue 41): a pair may miss with p = 0.05; allowed_misses(171, 0.05) = 18, a false
    # failure P(X >= 19 | 171, 0.05) = 1.0e-3 (pairs of one draw share its data: the bound is
    # for independent pairs); the same estimates moved by 2.5 SE fail it
    assert total - covered <= allowed_misses(total, 0.05)
    assert total - biased_covered > allowed_misses(total, 0.05), "the planted bias went unseen"


def spec_for(spec: dict, where: Path) -> dict:
    """The SPEC dict with its logs read from ``where``."""
    from stickslip.identify.spec import load

    doc = json.loads(json.dumps(spec))
    return load(doc, base_dir=where)


@pytest.mark.full
def test_the_documented_commands_build_and_run_the_identified_model(catalogue_fmu, tmp_path):
    """stickslip identify (exit 0), then build_fmu.sh --model on what it wrote, then the new
    FMU's own standard parameters and stickslip simulate on it."""
    from stickslip.fit.regressor import joint_torque_regressor
    from stickslip.fmu import content_hash, unpacked

    out = tmp_path / "identified"
    done = subprocess.run(
        [STICKSLIP, "identify", str(EXAMPLE / "identify.toml"), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stdout + done.stderr
    result = json.loads((out / "identify.json").read_text())
    fmu = tmp_path / "identified.fmu"
    build = subprocess.run(
        [
            "bash",
            str(ROOT / "scripts/build_fmu.sh"),
            "--platforms",
            "linux64",
            "--model",
            result["model_file"],
            "--out",
            str(fmu),
        ],
        capture_output=True,
        text=True,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    data = fmu.read_bytes()
    _, pi, names = joint_torque_regressor(unpacked(data, content_hash(data)), np.zeros((1, 21)))
    written = np.array([result["model"][n] for n in names])
    assert np.max(np.abs(pi - written)) <= 1e-12 * np.max(np.abs(written)), np.max(np.abs(pi - written))
    from fmpy import read_model_description

    start = {v.name: v.start for v in read_model_description(str(fmu)).modelVariables}
    for setting in result["model_settings"]:
        name, value = setting.split("=")
        assert math.isclose(float(start[name]), float(value), rel_tol=1e-12), setting
    motion = tmp_path / "hold.toml"
    motion.write_text("end = 0.5\n[[joint]]\nindex = 2\ncycloid = { q0 = 0.0, q1 = 0.3, t0 = 0.0, t1 = 0.4 }\n")
    with tempfile.TemporaryDirectory() as scratch:
        sim = subprocess.run(
            [STICKSLIP, "simulate", "--fmu", str(fmu), "--motion", str(motion), "--out", f"{scratch}/run.csv"],
            capture_output=True,
            text=True,
            timeout=600,
        )
    assert sim.returncode == 0, sim.stderr
