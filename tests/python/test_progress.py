"""Progress on stderr (stickslip.progress): a tqdm bar on a terminal, one whole line per 10 %
of the work elsewhere, for `stickslip sweep` (test_sweep_cluster.py checks its bar and lines)
and `stickslip simulate`: its output through a pipe, as in a log, has no carriage return and a
line per tenth of the steps.
"""

from __future__ import annotations

import io
import os
import pty
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import require_fmu
from stickslip.progress import Progress

# CI's full run only (scripts/test.sh --quick leaves it out): Dask clusters and a pty
pytestmark = pytest.mark.full

STICKSLIP = str(Path(sys.executable).with_name("stickslip"))
LINE = re.compile(r"^reference motion: +(\d+) % \(t = (\d\.\d{3}) s of 0\.2 s, \d+\.\d s wall\)$")


def test_a_line_per_tenth_where_there_is_no_terminal():
    out = io.StringIO()
    p = Progress(40, "{desc}: {percent:3d} % ({done}/{total}, x = {x})", already=20, tty=False, stream=out, desc="job")
    for k in range(20):
        p.advance(x=k)
    p.close()
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue() and len(lines) == 10
    assert lines[0] == "job:  10 % (22/40, x = 1)" and lines[-1] == "job: 100 % (40/40, x = 19)"


def test_a_bar_on_a_terminal():
    out = io.StringIO()
    p = Progress(20, "unused", tty=True, stream=out, unit="step", desc="job")
    for _ in range(20):
        p.advance(t=0.5)
    p.close()
    assert "\r" in out.getvalue() and "job: 100%" in out.getvalue() and "20/20" in out.getvalue()


@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    copy = tmp_path_factory.mktemp("fmu") / "StickSlipManipulator.fmu"
    shutil.copyfile(require_fmu(), copy)
    return copy


def test_simulate_through_a_pipe_writes_a_line_per_tenth(fmu, tmp_path):
    r = subprocess.run(
        [STICKSLIP, "simulate", "--fmu", str(fmu), "--end", "0.2", "--out", str(tmp_path / "r.csv")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert "\r" not in r.stderr and "\r" not in r.stdout
    progress = [line for line in r.stderr.splitlines() if line.startswith("reference motion:")]
    assert len(progress) == 10 and all(LINE.match(line) for line in progress), r.stderr
    tenths = [LINE.match(line).groups() for line in progress]
    assert tenths == [(str(10 * k), f"{0.02 * k:.3f}") for k in range(1, 11)], tenths


def test_simulate_on_a_terminal_draws_a_bar(fmu, tmp_path):
    master, slave = pty.openpty()
    p = subprocess.Popen(
        [STICKSLIP, "simulate", "--fmu", str(fmu), "--end", "0.2", "--out", str(tmp_path / "r.csv")],
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
    os.close(master)
    assert p.wait() == 0
    text = out.decode("utf-8", "replace")
    assert "reference motion: 100%" in text and "200/200" in text and "step/s" in text, text
