"""`stickslip sweep` on a real Dask cluster on loopback: a `dask scheduler` and two `dask
worker` processes started here (tests/python/sweep_cluster.py), the sweep submitted with
--scheduler as a user does.

* every row equals a direct fmpy run of the same parameters (hand-driven FMU2Slave at the
  same communication points, metrics computed here independently) to 1e-12 relative;
* a variant with mu_k > mu_s is a row with status `refused` and the FMU's reason;
* the FMU travels to the workers through Dask: each worker unpacked it in its own TMPDIR;
* a worker killed mid-sweep: the sweep still completes, every variant ok;
* an interrupted sweep (SIGINT) keeps its rows and a rerun runs only the missing ones; a
  changed SPEC into the same directory is refused;
* seeded samples are the same across runs and cluster sizes (2 remote workers, a local
  cluster of 1), and a smaller --samples is a prefix of the larger draw.

Short motions (0.02-0.3 s) keep the module at about a minute.
"""

from __future__ import annotations

import math
import signal
import time

import numpy as np
import pandas as pd
import pytest

from helpers import FLEXIBLE, Slave, input_vector
from sweep_cluster import loopback_cluster, sweep, sweep_process, write_spec

# CI's full run only (scripts/test.sh --quick leaves it out): Dask clusters
pytestmark = pytest.mark.full

JOINTS = (1, 2, 3, 4)


def k3_grid(n: int) -> str:
    """A SPEC line sweeping k[3] over n values 1e6, 1e6 + 1e3, …"""
    return '"k[3]" = [' + ", ".join(f"{1e6 + 1e3 * j:.0f}" for j in range(n)) + "]\n"


def lines_until(proc, seen) -> list:
    """The lines a running sweep prints, up to and including the first for which
    `seen(line)` is true."""
    lines = []
    for line in proc.stdout:
        lines.append(line)
        if seen(line):
            break
    return lines


def progressed(line: str) -> bool:
    """A progress line: some variants are done."""
    return "%" in line and "done" in line


def direct_metrics(parameters: dict, stop_time: float, step: float = 1e-3) -> dict:
    """The metrics of one variant from a hand-driven fmpy run, computed here."""
    with Slave("direct") as s:
        s.initialize(start_values=parameters)
        eps, normal = [s.get("eps")], [[s.get(f"N_normal[{i}]") for i in JOINTS]]
        for k in range(round(stop_time / step)):
            t = k * step
            s.set_inputs(input_vector(t))
            s.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=step)
            eps.append(s.get("eps"))
            normal.append([s.get(f"N_normal[{i}]") for i in JOINTS])
        out = {
            "max_eps": max(eps),
            "final_eps": eps[-1],
            "Q_friction": s.get("Q_friction"),
            "W_drive": s.get("W_drive"),
        }
        for j, i in enumerate(JOINTS):
            out[f"n_stick[{i}]"] = s.get(f"n_stick[{i}]")
            out[f"t_stick[{i}]"] = s.get(f"t_stick[{i}]")
            out[f"max_N_normal[{i}]"] = max(n[j] for n in normal)
    return out


def assert_rel(actual: float, expected: float, rel: float = 1e-12, what: str = ""):
    assert abs(actual - expected) <= rel * abs(expected), f"{what}: {actual!r} vs {expected!r}"


def test_sweep_through_scheduler_equals_direct_fmpy_runs(cluster, tmp_path):
    """3 x 2 grid over mu_k[3] and slider_a[3] (0.1 s): the ok rows equal direct runs to
    1e-12; mu_k[3] = 0.25 > mu_s[3] = 0.2 is refused by the FMU, and the row says why."""
    spec = write_spec(tmp_path / "grid.toml", '[grid]\n"mu_k[3]" = [0.1, 0.2, 0.25]\n"slider_a[3]" = [0.2, 0.4]\n')
    out = tmp_path / "out"
    p = sweep(spec, "--out", out, "--scheduler", cluster.address)
    assert p.returncode == 0, p.stdout + p.stderr
    rows = pd.read_parquet(out / "results.parquet")
    assert list(rows["run"]) == list(range(6))
    assert list(rows["mu_k[3]"]) == [0.1, 0.1, 0.2, 0.2, 0.25, 0.25]
    assert list(rows["slider_a[3]"]) == [0.2, 0.4] * 3
    assert list(rows["status"]) == ["ok"] * 4 + ["refused"] * 2
    for _, r in rows[rows["status"] == "ok"].iterrows():
        expected = direct_metrics({"mu_k[3]": r["mu_k[3]"], "slider_a[3]": r["slider_a[3]"]}, 0.1)
        for name, value in expected.items():
            assert_rel(r[name], value, what=f"run {r['run']} {name}")
        assert r["t_end"] == pytest.approx(0.1) and r["wall_s"] > 0
    for _, r in rows[rows["status"] == "refused"].iterrows():
        assert "mu_s" in r["message"] and "below the kinetic" in r["message"], r["message"]
        assert r["t_end"] == 0.0 and math.isnan(r["max_eps"])
    # The FMU went to the workers through Dask: each unpacked it in its own TMPDIR.
    for _, tmp in cluster.workers:
        assert any(d.name.startswith("stickslip-fmu-") for d in tmp.iterdir()), list(tmp.iterdir())
    assert set(rows["worker"]) and len(set(rows["worker"])) <= 2
    assert (out / "summary.png").stat().st_size > 10_000
    md = (out / "summary.md").read_text(encoding="utf-8")
    assert "| refused | 2 |" in md and "below the kinetic" in md
    assert "sweep: 6 of 6 variants" in p.stdout


SAMPLE = """[sample]
n = {n}
seed = 7
"k[1]" = {{ uniform = [9e5, 1.1e6] }}
"slider_a[3]" = {{ normal = [0.2, 0.01] }}
"v_s[3]" = {{ loguniform = [1e-3, 1e-1] }}
"""


def test_seeded_samples_reproducible_across_runs_and_cluster_sizes(cluster, tmp_path):
    """The same SPEC on the 2-worker cluster and on a local cluster of 1 worker gives the
    same draws and bit-identical metrics; --samples 3 gives the first 3 of the 6 draws."""
    spec = write_spec(tmp_path / "mc.toml", SAMPLE.format(n=6), stop_time=0.02)
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for args in (
        (a, "--scheduler", cluster.address),
        (b, "--workers", "1"),
        (c, "--scheduler", cluster.address, "--samples", "3"),
    ):
        p = sweep(spec, "--out", *args)
        assert p.returncode == 0, p.stdout + p.stderr
    ra, rb, rc = (pd.read_parquet(d / "results.parquet") for d in (a, b, c))
    columns = [
        "run",
        "k[1]",
        "slider_a[3]",
        "v_s[3]",
        "status",
        "max_eps",
        "final_eps",
        "n_stick[3]",
        "t_stick[3]",
        "max_N_normal[3]",
        "Q_friction",
        "W_drive",
    ]
    pd.testing.assert_frame_equal(ra[columns], rb[columns], check_exact=True)
    pd.testing.assert_frame_equal(rc[columns], ra[columns].head(3), check_exact=True)
    assert (ra["status"] == "ok").all()
    assert ra["k[1]"].between(9e5, 1.1e6).all() and ra["v_s[3]"].between(1e-3, 1e-1).all()
    assert ra["k[1]"].nunique() == 6


def test_worker_killed_mid_sweep_still_completes(tmp_path):
    """A cluster of its own; one of its two workers is killed (SIGKILL) once 10 % of the
    variants are done: the tasks it held run again on the other, every variant is ok."""
    spec = write_spec(tmp_path / "kill.toml", "[grid]\n" + k3_grid(20), stop_time=0.2)
    out = tmp_path / "out"
    with loopback_cluster(tmp_path / "dask") as c:
        proc = sweep_process(spec, "--out", out, "--scheduler", c.address)
        lines = lines_until(proc, progressed)
        victim, _ = c.workers[0]
        victim.send_signal(signal.SIGKILL)
        victim.wait()
        killed = pd.Timestamp.now(tz="UTC")
        rest, _ = proc.communicate(timeout=180)
        text = "".join(lines) + rest
        assert proc.returncode == 0, text
    rows = pd.read_parquet(out / "results.parquet")
    assert list(rows["run"]) == list(range(20)), text
    assert (rows["status"] == "ok").all(), rows[["run", "status", "message"]]
    pids = rows["worker"].str.rsplit(":", n=1).str[-1].astype(int)
    assert set(pids) <= {w.pid for w, _ in c.workers}  # a row names the worker process that ran it
    after = rows[rows["finished"] > killed]
    assert len(after) >= 10, rows[["run", "worker", "finished"]]  # most of the sweep came after the kill
    assert not after["worker"].str.endswith(f":{victim.pid}").any(), after[["run", "worker"]]


def test_interrupted_sweep_resumes_only_missing_variants(cluster, tmp_path):
    """SIGINT after 20 % of 20 variants: exit 130, the finished rows are in results.parquet.
    The same command again runs only the others (the first rows keep their `finished`
    time and worker); the union is every variant. A changed SPEC into DIR is refused."""
    body = '[grid]\n"mu_k[1]" = [0.15, 0.2]\n' + k3_grid(10)
    spec = write_spec(tmp_path / "resume.toml", body, stop_time=0.2)
    out = tmp_path / "out"
    proc = sweep_process(spec, "--out", out, "--scheduler", cluster.address)
    lines = lines_until(proc, lambda line: " 20 %" in line or " 30 %" in line)
    proc.send_signal(signal.SIGINT)
    rest, _ = proc.communicate(timeout=120)
    text = "".join(lines) + rest
    assert proc.returncode == 130, text
    assert "interrupted" in text and "again to continue" in text
    first = pd.read_parquet(out / "results.parquet")
    assert 0 < len(first) < 20, text
    assert (first["status"] == "ok").all()
    parts_before = set((out / "parts").glob("*.parquet"))

    time.sleep(0.01)
    p = sweep(spec, "--out", out, "--scheduler", cluster.address)
    assert p.returncode == 0, p.stdout + p.stderr
    assert f"{len(first)} already in" in p.stdout and f"{20 - len(first)} to run" in p.stdout
    final = pd.read_parquet(out / "results.parquet")
    assert list(final["run"]) == list(range(20)) and (final["status"] == "ok").all()
    new_parts = set((out / "parts").glob("*.parquet")) - parts_before
    rerun = pd.concat([pd.read_parquet(f) for f in new_parts])
    assert set(rerun["run"]) == set(range(20)) - set(first["run"])  # nothing ran twice
    kept = final.set_index("run").loc[first["run"]]
    assert (kept["finished"].to_numpy() == first["finished"].to_numpy()).all()
    assert (kept["worker"].to_numpy() == first["worker"].to_numpy()).all()

    changed = write_spec(tmp_path / "changed.toml", body, stop_time=0.3)
    p = sweep(changed, "--out", out, "--scheduler", cluster.address)
    assert p.returncode == 1
    assert "holds results of another SPEC (changed: stop_time)" in p.stderr, p.stderr


def test_metrics_names_follow_the_fmu():
    """The per-joint metric columns come from the FMU's n_stick[i] outputs, not a fixed list."""
    from stickslip.variant import metric_names

    names = metric_names(["eps", "n_stick[1]", "n_stick[3]", "W_drive"])
    assert names == [
        "max_eps",
        "final_eps",
        "n_stick[1]",
        "n_stick[3]",
        "t_stick[1]",
        "t_stick[3]",
        "max_N_normal[1]",
        "max_N_normal[3]",
        "Q_friction",
        "W_drive",
    ]
    assert FLEXIBLE == (1, 3)


def test_motion_csv_equals_reference_motion(tmp_path):
    """A motion CSV holding the reference motion at every communication point (all columns)
    gives bit-identical inputs; without rates, q*' is the slope to the next point."""
    from stickslip.motion import TableMotion, input_names, reference_inputs

    t = np.arange(0, 101) * 1e-3
    names = input_names(4)
    rows = [
        [x for x in (k * 1e-3,)] + [float(v) for part in reference_inputs(k * 1e-3) for v in part] for k in range(101)
    ]
    path = tmp_path / "motion.csv"
    path.write_text(",".join(["time", *names]) + "\n" + "\n".join(",".join(repr(x) for x in r) for r in rows))
    m = TableMotion.from_csv(path, 4)
    for k in (0, 1, 37, 100):
        assert m(k * 1e-3, 1e-3) == reference_inputs(k * 1e-3)
    q_only = TableMotion(t, {f"q_star[{i}]": [r[i] for r in rows] for i in range(1, 5)}, 4)
    _, qd, qdd = q_only(0.05, 1e-3)
    assert qd[2] == pytest.approx((rows[51][3] - rows[50][3]) / 1e-3, rel=1e-12) and qdd == [0.0] * 4


def test_lost_scheduler_keeps_finished_rows(tmp_path):
    """A cluster of its own; its scheduler is killed (SIGKILL) once 10 % of the variants are
    done: the command ends with exit 1 and a message saying so, and results.parquet holds
    the rows received before (all ok, none twice)."""
    spec = write_spec(tmp_path / "lost.toml", "[grid]\n" + k3_grid(30), stop_time=0.3)
    out = tmp_path / "out"
    with loopback_cluster(tmp_path / "dask", workers=1) as c:
        proc = sweep_process(spec, "--out", out, "--scheduler", c.address)
        lines = lines_until(proc, progressed)
        c.scheduler.send_signal(signal.SIGKILL)
        rest, _ = proc.communicate(timeout=120)
        text = "".join(lines) + rest
    assert proc.returncode == 1, text
    assert "lost the Dask scheduler" in text and "run the same command again to continue" in text, text
    rows = pd.read_parquet(out / "results.parquet")
    assert 3 <= len(rows) < 30 and rows["run"].is_unique and (rows["status"] == "ok").all(), text


def test_progress_bar_on_a_terminal_lines_otherwise(cluster, tmp_path):
    """On a terminal (a pty that reports no size, as in CI) a tqdm bar with done/total, rate,
    failed and running; through a pipe one line per 10 % with the rate and ETA."""
    import os
    import pty
    import subprocess

    from sweep_cluster import STICKSLIP

    spec = write_spec(
        tmp_path / "bar.toml", '[grid]\n"mu_k[3]" = [0.1, 0.2, 0.25]\n"slider_a[3]" = [0.2, 0.4]\n', stop_time=0.02
    )
    master, slave = pty.openpty()
    p = subprocess.Popen(
        [STICKSLIP, "sweep", str(spec), "--out", str(tmp_path / "tty"), "--scheduler", cluster.address],
        stdout=slave,
        stderr=slave,
        close_fds=True,
    )
    os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the pty closed
            break
        if not chunk:
            break
        out += chunk
    assert p.wait() == 0
    text = out.decode("utf-8", "replace")
    assert "6/6 [" in text and "variant/s, failed=2, running=0]" in text, text
    piped = sweep(spec, "--out", tmp_path / "piped", "--scheduler", cluster.address)
    tenths = [line for line in piped.stderr.splitlines() if line.startswith("sweep: ") and " % (" in line]
    assert tenths and tenths[-1].startswith("sweep: 100 % (6/6 done, 2 not ok"), piped.stderr
    assert all("variants/s, ETA" in line for line in tenths)


def test_timeout_is_a_row(cluster, tmp_path):
    """--timeout stops a variant that runs too long: a row with status `timeout`, the time it
    reached, the metrics up to there (here every variant runs too long). The variants are made
    slow by their 50,000 communication steps of 10 µs (1.2 s through fmpy measured), not by
    the stepper's speed, which the error control made far shorter than the timeout at 1 ms."""
    spec = write_spec(tmp_path / "slow.toml", '[grid]\n"mu_k[3]" = [0.15, 0.2]\n', stop_time=0.5, step=1e-5)
    out = tmp_path / "out"
    p = sweep(spec, "--out", out, "--scheduler", cluster.address, "--timeout", "0.02")
    assert p.returncode == 0, p.stdout + p.stderr
    rows = pd.read_parquet(out / "results.parquet")
    assert list(rows["status"]) == ["timeout", "timeout"], rows
    for _, r in rows.iterrows():
        assert 0 < r["t_end"] < 0.5 and "after 0.02 s wall (--timeout)" in r["message"]
        assert r["max_eps"] >= 0 and r["n_stick[3]"] >= 1  # metrics over [0, t_end] (the start is stuck)
