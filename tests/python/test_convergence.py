"""The convergence check (`--check-convergence`, stickslip.convergence): a second run with a
tenfold tighter error tolerance and the relative spread of every metric.

* the spread formula against numbers computed by hand (counts too: 5 -> 6 phases is 1/6);
* the seeded fraction: the same variants every time, and the same on a resumed sweep;
* the Python API: its spreads are those of two hand-made runs (the variant at its own
  error_tolerance and at a tenth of it), a converged variant keeps max and final eps within
  the error control's promise, and a variant that comes to rest inside wide clearances
  after dozens of impacts is flagged (this fails if the check run did not really run with
  another tolerance: every spread would be 0);
* a checked sweep on a real Dask cluster (a `dask scheduler` and two workers on loopback,
  tests/python/sweep_cluster.py): a `<metric>_spread` column for every metric, the flagged
  variants listed and marked in summary.md; a checked and an unchecked sweep into the same
  DIR are refused;
* a check run that fails (here refused by the FMU) keeps the main row (a LocalCluster);
* `stickslip simulate --check-convergence`: the same spreads as the API, a warning on the
  terminal where one exceeds the threshold, none where none does.

The sensitive variants run the 2 s reference motion (the impacts come after the drives stop
at 1.5 s), about 0.15 s per run; the rest 0.05-0.3 s.
"""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pandas as pd
import pytest

from helpers import model_description, require_fmu
from stickslip import convergence
from stickslip.convergence import check_convergence, selected_runs, spread, spread_name
from sweep_cluster import STICKSLIP, sweep, write_spec

# CI's full run only (scripts/test.sh --quick leaves it out): Dask clusters
pytestmark = pytest.mark.full

CLEARANCES = {"Delta[1]": math.pi / 90, "Delta[3]": 0.002}  # the study's clearance case (Fig. 13)


def friction(mu: float) -> dict:
    return {"mu_k[1]": mu, "mu_s[1]": mu, "mu_k[3]": mu, "mu_s[3]": mu}


# Friction coefficients of the clearance case whose 2 s runs come to rest after 30-50 impacts
# in joint 3 (measured with the FMU of this commit: each flags stick counts, stick times or
# friction heat, spreads 0.05-0.6); the tests ask only that one of them is flagged.
SENSITIVE_MU = (0.28, 0.3, 0.36)


def default_tolerance() -> float:
    """The FMU's own error_tolerance (its start value)."""
    return float(
        model_description()
        .modelVariables[[v.name for v in model_description().modelVariables].index("error_tolerance")]
        .start
    )


# ---------------------------------------------------------------------------------------------
# the formula and the selection


def test_spread_formula_against_hand_computed_numbers():
    """|x_tight - x| / max(|x_tight|, |x|, floor), symmetric, for counts the same formula."""
    assert spread(5, 6) == pytest.approx(1 / 6, rel=1e-15)  # one stiction phase more out of 5
    assert spread(6, 5) == pytest.approx(1 / 6, rel=1e-15)
    assert spread(5, 4) == pytest.approx(0.2, rel=1e-15)  # one fewer: 1 of 5
    assert spread(2.0e-4, 2.002e-4) == pytest.approx(0.002e-4 / 2.002e-4, rel=1e-12)  # 0.1 % on max eps
    assert spread(-1.0, 1.0) == 2.0  # a sign change is a spread of 2
    assert spread(0.0, 0.0) == 0.0  # a rigid joint's stick count: 0 and 0 agree
    assert spread(0.0, 1e-16) == pytest.approx(0.1)  # below the floor 1e-15: scaled by the floor
    assert math.isnan(spread(float("nan"), 1.0)) and math.isnan(spread(None, 1.0))
    np.testing.assert_allclose(
        spread(np.array([1.0, 10.0, 0.0]), np.array([1.1, 10.0, 3.0])), [0.1 / 1.1, 0.0, 1.0], rtol=1e-15
    )
    s = {"max_eps": 0.001, "final_eps": 0.3, "n_stick[3]": 0.2, "n_stick[1]": float("nan")}
    assert convergence.not_converged(s, 0.01) == ["final_eps", "n_stick[3]"]
    assert convergence.not_converged(s, 0.25) == ["final_eps"]
    assert spread_name("n_stick[3]") == "n_stick_spread[3]"


def test_seeded_fraction_selects_the_same_variants():
    """round(F * n) variants (at least one), the same on every call, another set for another
    seed; fraction 1 is every variant; outside (0, 1] refused."""
    a = selected_runs(200, 0.1, 1)
    assert len(a) == 20 and a == selected_runs(200, 0.1, 1) and a <= set(range(200))
    assert selected_runs(200, 0.1, 2) != a
    assert selected_runs(7, 1.0, 3) == set(range(7))
    assert len(selected_runs(5, 0.01, 0)) == 1
    for bad in (0.0, -0.5, 1.5):
        with pytest.raises(ValueError, match="convergence-fraction"):
            selected_runs(10, bad, 0)


def test_tightened_settings():
    """error_tolerance / 10 from the run's own value (its parameter, else the FMU's start
    value); fixed sub-steps (h_min = h_max) halved instead."""
    require_fmu()
    md = model_description()
    tol = default_tolerance()
    assert convergence.tightened({}, md)[0] == {"error_tolerance": tol / 10}
    assert convergence.tightened({"error_tolerance": 1e-3}, md)[0] == {"error_tolerance": 1e-4}
    rerun, method = convergence.tightened({"h_min": 2e-6, "h_max": 2e-6}, md)
    assert rerun == {"h_min": 1e-6, "h_max": 1e-6} and "halved" in method


# ---------------------------------------------------------------------------------------------
# the Python API


def test_api_spreads_equal_two_hand_made_runs_and_flag_sensitive_variant():
    """check_convergence's spreads are the formula applied to two runs made here (the variant,
    and the variant with error_tolerance / 10): bit for bit. The reference arm without
    clearance keeps max and final eps within 0.1 % (the error control's promise) but the two
    runs differ (the check run is really another integration); with the study's clearances
    (Δ1 = π/90, Δ3 = 2 mm) and μ of 0.28-0.36 the arm comes to rest after dozens of impacts,
    and the stick counts no longer converge: at least one of them is flagged."""
    from stickslip.fmu import content_hash
    from stickslip.motion import reference_inputs
    from stickslip.variant import run_variant

    fmu = require_fmu()
    data = fmu.read_bytes()
    digest = content_hash(data)
    tol = default_tolerance()

    smooth = check_convergence({"mu_k[3]": 0.15, "mu_s[3]": 0.2}, fmu=fmu, stop_time=0.3)
    assert smooth.status == "checked" and smooth.rerun == {"error_tolerance": tol / 10}
    main = run_variant(digest, 0, {"mu_k[3]": 0.15, "mu_s[3]": 0.2}, 0.3, 1e-3, reference_inputs, fmu_data=data)
    tight = run_variant(
        digest,
        0,
        {"mu_k[3]": 0.15, "mu_s[3]": 0.2, "error_tolerance": tol / 10},
        0.3,
        1e-3,
        reference_inputs,
        fmu_data=data,
    )
    for m, s in smooth.spreads.items():
        a, b = main[m], tight[m]
        assert smooth.metrics[m] == a and smooth.tight[m] == b, m
        assert s == (abs(b - a) / max(abs(a), abs(b), 1e-15) if (a, b) != (0, 0) else 0.0), m
    assert 0 < smooth.spreads["max_eps"] < 1e-3 and smooth.spreads["final_eps"] < 1e-3, smooth.report()
    assert smooth.not_converged == [] and smooth.warning() is None

    flagged = {}
    for mu in SENSITIVE_MU:
        c = check_convergence(CLEARANCES | friction(mu), fmu=fmu, stop_time=2.0)
        assert c.status == "checked", c.report()
        assert c.spreads["max_eps"] < 0.01, c.report()  # the peak error is still a number
        if c.not_converged:
            flagged[mu] = c
    assert flagged, "no clearance variant flagged:\n" + "\n".join(
        check_convergence(CLEARANCES | friction(mu), fmu=fmu, stop_time=2.0).report() for mu in SENSITIVE_MU
    )
    c = next(iter(flagged.values()))
    assert "NOT CONVERGED" in c.report() and "WARNING: not converged" in c.warning()


# ---------------------------------------------------------------------------------------------
# sweeps


def test_checked_sweep_has_spreads_and_summary_flags_variants(cluster, tmp_path):
    """2 x 3 grid (no clearance / the study's clearances x μ_k[3] 0.28, 0.3, 0.36) of the 2 s motion
    with --check-convergence on the loopback cluster: every row checked, a `<metric>_spread`
    column for every metric, equal to the formula applied to the row and a check run made
    here; a clearance variant flagged, listed in summary.md's convergence section and marked
    in its list of variants; the terminal says how many; sweep.json records the check.
    Summarised with threshold 10: none flagged. An unchecked sweep into the same DIR is
    refused."""
    from stickslip.fmu import content_hash
    from stickslip.motion import reference_inputs
    from stickslip.variant import metric_names, run_variant

    # μ_k[3] 0.28, 0.3, 0.36 (μ_s[3] = 0.36, μ1 = 0.3): with the clearances each flagged
    # stick counts or times with the FMU of this commit; the test asks for one
    body = (
        '[grid]\n"Delta[1]" = [0.0, 0.03490658503988659]\n"Delta[3]" = [0.002]\n'
        '"mu_k[1]" = [0.3]\n"mu_s[1]" = [0.3]\n'
        f'"mu_k[3]" = [{", ".join(str(mu) for mu in SENSITIVE_MU)}]\n"mu_s[3]" = [0.36]\n'
    )
    spec = write_spec(tmp_path / "checked.toml", body, stop_time=2.0)
    out = tmp_path / "out"
    p = sweep(spec, "--out", out, "--scheduler", cluster.address, "--check-convergence")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "convergence check of 6 (error_tolerance / 10" in p.stdout, p.stdout
    rows = pd.read_parquet(out / "results.parquet")
    metrics = metric_names([v.name for v in model_description().modelVariables if v.causality == "output"])
    assert all(spread_name(m) in rows.columns for m in metrics)
    assert (rows["status"] == "ok").all() and (rows["convergence_status"] == "checked").all(), rows
    assert (rows["convergence_wall_s"] > 0).all()

    data = require_fmu().read_bytes()
    r = rows.iloc[-1]
    params = {n: r[n] for n in ("Delta[1]", "Delta[3]", "mu_k[1]", "mu_s[1]", "mu_k[3]", "mu_s[3]")}
    tight = run_variant(
        content_hash(data),
        99,
        params | {"error_tolerance": default_tolerance() / 10},
        2.0,
        1e-3,
        reference_inputs,
        fmu_data=data,
    )
    for m in metrics:
        assert r[spread_name(m)] == spread(r[m], tight[m]), m

    spreads = rows[[spread_name(m) for m in metrics]]
    assert spreads.notna().all().all()
    clear = rows[rows["Delta[1]"] == 0]
    assert (clear["max_eps_spread"] < 1e-2).all(), clear  # without clearance 0.1 % is promised
    flagged = rows[(spreads > 0.01).any(axis=1)]
    assert len(flagged) >= 1 and (flagged["Delta[1]"] > 0).any(), rows[["run", *spreads.columns]]

    md = (out / "summary.md").read_text(encoding="utf-8")
    assert "## Convergence" in md and f"**{len(flagged)} of 6 checked variants**" in md, md
    assert "### Not converged: the worst" in md
    worst = md.split("### Not converged: the worst")[1].split("\n## ")[0]
    for run in flagged["run"]:
        assert f"\n| {run} |" in worst, worst
    listing = md.split("## Every variant")[1]
    for _, row in rows.iterrows():
        line = next(x for x in listing.splitlines() if x.startswith(f"| {row['run']} |"))
        assert line.endswith(" |") and (("**no**" in line) == (row["run"] in set(flagged["run"]))), line
    assert " ⚠ |" in listing
    assert "not converged" in md.split("## Sensitivity")[1].split("\n## ")[0]
    assert f"{len(flagged)} with a metric not converged" in p.stderr, p.stderr
    assert (out / "summary.png").stat().st_size > 10_000

    from stickslip import spec as spec_module
    from stickslip import summary

    record = json.loads((out / "sweep.json").read_text())["convergence"]
    assert record == {
        "fraction": 1.0,
        "rerun": {"error_tolerance": default_tolerance() / 10},
        "method": record["method"],
        "checked": 6,
    }
    lenient = summary.markdown(rows, spec_module.load(spec), metrics, threshold=10, convergence=record)
    assert "**0 of 6 checked variants**" in lenient and "**no**:" not in lenient and " ⚠ |" not in lenient

    p = sweep(spec, "--out", out, "--scheduler", cluster.address)
    assert p.returncode == 1 and "holds results of a sweep with --check-convergence" in p.stderr, p.stderr
    assert "this one is without --check-convergence" in p.stderr


def test_fraction_same_variants_on_rerun_and_resume(cluster, tmp_path):
    """--convergence-fraction 0.25 of 20 variants: the 5 chosen by the SPEC's seed, the same
    in two sweeps; a sweep that lost half its rows (as an interrupted one) runs only the
    missing ones on the rerun, and the union checks the same 5; the others are `not
    selected` with NaN spreads."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    body = '[grid]\n"k[3]" = [' + ", ".join(f"{1e6 + 1e3 * j:.0f}" for j in range(20)) + "]\n"
    spec = write_spec(tmp_path / "fraction.toml", body, stop_time=0.05)
    expected = selected_runs(20, 0.25, 0)  # a grid-only SPEC has seed 0
    checked = []
    for name in ("a", "b"):
        p = sweep(
            spec,
            "--out",
            tmp_path / name,
            "--scheduler",
            cluster.address,
            "--check-convergence",
            "--convergence-fraction",
            "0.25",
        )
        assert p.returncode == 0, p.stdout + p.stderr
        rows = pd.read_parquet(tmp_path / name / "results.parquet")
        checked.append(set(rows.loc[rows["convergence_status"] == "checked", "run"]))
        others = rows[rows["convergence_status"] != "checked"]
        assert (others["convergence_status"] == "not selected").all()
        assert others["max_eps_spread"].isna().all() and others["final_eps_spread"].isna().all()
        assert rows.loc[rows["convergence_status"] == "checked", "max_eps_spread"].notna().all()
    assert checked[0] == checked[1] == expected and len(expected) == 5

    # Keep the rows of 10 runs, as a sweep interrupted there leaves them, and run again.
    out = tmp_path / "a"
    parts = sorted((out / "parts").glob("*.parquet"))
    table = pa.concat_tables([pq.read_table(f) for f in parts])
    kept = table.filter(pa.compute.less(table["run"], 10))
    for f in parts:
        f.unlink()
    pq.write_table(kept, out / "parts" / "part-interrupted-00001.parquet")
    p = sweep(
        spec, "--out", out, "--scheduler", cluster.address, "--check-convergence", "--convergence-fraction", "0.25"
    )
    assert p.returncode == 0, p.stdout + p.stderr
    assert "10 already in" in p.stdout and "10 to run" in p.stdout, p.stdout
    rows = pd.read_parquet(out / "results.parquet")
    assert list(rows["run"]) == list(range(20))
    assert set(rows.loc[rows["convergence_status"] == "checked", "run"]) == expected
    # another fraction into the same DIR is another sweep
    p = sweep(
        spec, "--out", out, "--scheduler", cluster.address, "--check-convergence", "--convergence-fraction", "0.5"
    )
    assert p.returncode == 1 and "--convergence-fraction 0.25" in p.stderr, p.stderr


def test_failed_check_run_keeps_main_row(tmp_path):
    """A check run the FMU refuses (given error_tolerance 0.5, outside (0, 0.1]) on a
    LocalCluster of 1 worker: the main rows are ok with the metrics of an unchecked sweep bit
    for bit, convergence_status `refused` with the FMU's reason, spreads NaN; a variant whose
    main run is refused (μ_k > μ_s) is `not run`. summary.md lists the failed check runs."""
    from stickslip import spec as spec_module
    from stickslip import summary
    from stickslip.sweep import Check, run_sweep

    path = write_spec(tmp_path / "fail.toml", '[grid]\n"mu_k[3]" = [0.1, 0.15, 0.25]\n', stop_time=0.05)
    spec = spec_module.load(path)
    stats = run_sweep(
        spec, tmp_path / "checked", workers=1, progress_tty=False, check=Check(1.0, rerun={"error_tolerance": 0.5})
    )
    plain = run_sweep(spec, tmp_path / "plain", workers=1, progress_tty=False)["rows"]
    rows = stats["rows"]
    assert list(rows["status"]) == ["ok", "ok", "refused"]
    assert list(rows["convergence_status"]) == ["refused", "refused", "not run"], rows
    for m in stats["metrics"]:
        assert rows[spread_name(m)].isna().all()
        pd.testing.assert_series_equal(rows[m], plain[m], check_exact=True)
    assert all("error_tolerance" in msg for msg in rows["convergence_message"][:2]), rows["convergence_message"]
    summary.write(rows, spec, stats["metrics"], tmp_path / "checked", threshold=0.01, convergence=stats["convergence"])
    md = (tmp_path / "checked" / "summary.md").read_text(encoding="utf-8")
    assert "### Check runs that failed (2;" in md and "| refused | 2 |" in md and "| not run | 1 |" in md, md
    assert "**0 of 0 checked variants**" in md


# ---------------------------------------------------------------------------------------------
# stickslip simulate --check-convergence


def simulate(*args) -> subprocess.CompletedProcess:
    return subprocess.run(
        [STICKSLIP, "simulate", "--fmu", str(require_fmu()), *map(str, args)], capture_output=True, text=True
    )


def test_simulate_check_convergence_warns_when_not_converged(tmp_path):
    """The single run checked: its spreads equal the API's (the same metrics from the CSV run's
    outputs), written to OUT.convergence.json; a warning on the terminal naming the metric
    where a spread exceeds the threshold (a clearance variant, or any run at threshold
    1e-12), none on a converged run."""
    out = tmp_path / "smooth.csv"
    p = simulate("--out", out, "--end", 0.3, "--check-convergence")
    assert p.returncode == 0, p.stdout + p.stderr
    assert "WARNING" not in p.stderr and "convergence check (error_tolerance / 10" in p.stdout, p.stdout + p.stderr
    record = json.loads(out.with_suffix(".convergence.json").read_text())
    assert record["status"] == "checked" and record["not_converged"] == []
    api = check_convergence(stop_time=0.3)
    for m, s in api.spreads.items():
        assert record["spreads"][m] == pytest.approx(s, rel=1e-9, abs=1e-15), m

    p = simulate(
        "--out", tmp_path / "tiny.csv", "--end", 0.3, "--check-convergence", "--convergence-threshold", "1e-12"
    )
    assert p.returncode == 0 and "WARNING: not converged: " in p.stderr and "max_eps" in p.stderr, p.stderr

    sets = [f"--set={n}={v}" for n, v in (CLEARANCES | friction(SENSITIVE_MU[1])).items()]
    p = simulate("--out", tmp_path / "clear.csv", "--end", 2.0, "--check-convergence", *sets)
    assert p.returncode == 0, p.stdout + p.stderr
    record = json.loads((tmp_path / "clear.csv").with_suffix(".convergence.json").read_text())
    api = check_convergence(CLEARANCES | friction(SENSITIVE_MU[1]), stop_time=2.0)
    assert record["not_converged"] == api.not_converged, (record, api.report())
    if api.not_converged:  # μ = 0.3 flags its stick counts with this FMU (see SENSITIVE_MU)
        assert "WARNING: not converged: " in p.stderr and api.not_converged[0] in p.stderr, p.stderr
        assert "NOT CONVERGED" in p.stdout
    else:
        assert "WARNING" not in p.stderr
