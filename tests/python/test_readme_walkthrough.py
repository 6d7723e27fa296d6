"""The README's fmpy walkthrough works as written: a newcomer's first run of the FMU.

The first ```python block under the README heading that names fmpy ("### 1. From an FMI
master: fmpy") is executed exactly as written, in a fresh namespace, in a temporary
directory that holds the FMU at the relative path the block names
(``target/fmu/StickSlipManipulator.fmu``, a link to the FMU under test: the one
``scripts/test.sh`` builds before pytest runs, or ``$STICKSLIP_FMU``). This test builds
nothing: without the FMU it fails and says how to build it.

Checked, as the README says:

* the block writes ``q_eps.png`` (a figure of q[1], q[3] and eps over time);
* ``r`` holds the time and the q[1], q[3], eps and n_stick[3] arrays of the 2 s reference
  motion at 1 ms (2001 finite samples each), the drives moved (q1 to about pi/3 rad, q3 to
  about 1.0 m) and the arm lags (eps > 0);
* the line it prints is the one the README quotes after "prints";
* its max and final eps are those of ``stickslip simulate``'s run of the same FMU
  (``stickslip.simulate.run``, the engine's arithmetic at exactly 1 ms) to 1e-6 relative
  (fmpy's ``simulate_fmu`` steps by differences of times, which differ from 1e-3 s in the
  last bits; see test_reference_run.py), and the number of stiction phases of joint 3
  equals it.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from helpers import fmu_path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
FMU_IN_README = Path("target/fmu/StickSlipManipulator.fmu")


def walkthrough_block(text: str) -> tuple[int, str]:
    """(line number, code) of the first ```python block after the first heading naming fmpy."""
    lines = text.split("\n")
    heading = next((i for i, line in enumerate(lines) if re.match(r"^#{1,6} .*\bfmpy\b", line)), None)
    assert heading is not None, "README.md has no heading naming fmpy"
    start = next((i for i in range(heading + 1, len(lines)) if lines[i].strip() == "```python"), None)
    assert start is not None, f"README.md: no ```python block after line {heading + 1} ({lines[heading]})"
    end = next(i for i in range(start + 1, len(lines)) if lines[i].strip().startswith("```"))
    return start + 2, "\n".join(lines[start + 1 : end]) + "\n"


def quoted_output(text: str) -> str:
    """The output the README quotes after the block: the code span after "prints"."""
    m = re.search(r"prints\s+`([^`]+)`", text)
    assert m, "README.md does not quote what the fmpy example prints"
    return " ".join(m.group(1).split())


@pytest.fixture(scope="module")
def walkthrough(tmp_path_factory):
    fmu = fmu_path()
    if not fmu.is_file():
        pytest.fail(
            f"the FMU {fmu} is not built: run `bash scripts/build_fmu.sh` (scripts/test.sh builds "
            "it before pytest) or set STICKSLIP_FMU"
        )
    text = README.read_text(encoding="utf-8")
    line, code = walkthrough_block(text)
    assert str(FMU_IN_README) in code, f"the README's fmpy example no longer names {FMU_IN_README}"
    work = tmp_path_factory.mktemp("readme")
    (work / FMU_IN_README).parent.mkdir(parents=True)
    (work / FMU_IN_README).symlink_to(fmu)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    namespace: dict = {"__name__": "__readme__"}
    out = io.StringIO()
    cwd = os.getcwd()
    os.chdir(work)
    try:
        with contextlib.redirect_stdout(out):
            exec(compile(code, f"{README}:{line}", "exec"), namespace)
    finally:
        os.chdir(cwd)
        plt.close("all")
    return {"dir": work, "ns": namespace, "stdout": out.getvalue(), "text": text, "fmu": fmu}


def test_the_block_is_about_ten_lines_and_uses_fmpy():
    _, code = walkthrough_block(README.read_text(encoding="utf-8"))
    lines = [x for x in code.splitlines() if x.strip()]
    assert "simulate_fmu" in code and "from fmpy" in code
    assert len(lines) <= 15, f"the fmpy example has {len(lines)} lines; keep it short"


def test_it_writes_the_figure(walkthrough):
    png = walkthrough["dir"] / "q_eps.png"
    assert png.is_file() and png.stat().st_size > 10_000, png
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_it_simulates_the_reference_motion(walkthrough):
    r = walkthrough["ns"]["r"]
    for name in ("time", "q[1]", "q[3]", "eps", "n_stick[3]"):
        column = np.asarray(r[name], dtype=float)
        assert column.shape == (2001,), (name, column.shape)
        assert np.all(np.isfinite(column)), name
    assert r["time"][0] == 0.0 and r["time"][-1] == pytest.approx(2.0)
    assert r["q[1]"][-1] == pytest.approx(math.pi / 3, abs=1e-3)
    assert r["q[3]"][0] == pytest.approx(0.8, abs=1e-3) and r["q[3]"][-1] == pytest.approx(1.0, abs=1e-3)
    assert np.all(r["eps"] >= 0.0) and r["eps"].max() > 1e-5


def test_it_prints_what_the_readme_says(walkthrough):
    printed = " ".join(walkthrough["stdout"].split())
    assert printed == quoted_output(walkthrough["text"]), (
        f"the README's fmpy example printed\n  {printed}\nbut the README says it prints\n  "
        f"{quoted_output(walkthrough['text'])}"
    )


def test_its_numbers_are_those_of_stickslip_simulate(walkthrough):
    from stickslip.simulate import run

    r = walkthrough["ns"]["r"]
    ref = run(walkthrough["fmu"])
    eps = np.asarray(ref["eps"])
    assert len(eps) == 2001
    assert r["eps"].max() == pytest.approx(eps.max(), rel=1e-6)
    assert r["eps"][-1] == pytest.approx(eps[-1], rel=1e-6)
    assert r["n_stick[3]"][-1] == ref["n_stick[3]"][-1]
