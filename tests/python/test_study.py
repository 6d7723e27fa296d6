"""The source study's claims (section 4, Figs. 10-14) hold on the reference manipulator,
run through the FMU with fmpy by `stickslip study` (python/stickslip/study.py).

Each claim is an assertion on numbers of the study's cases (shared/reference-manipulator.md):
step size, friction coefficient, friction characteristic, clearance, slider length. Every
case runs twice:

* ``ci``: the FMU's default error-controlled sub-steps, communication interval 1e-3 s (the
  step case: fixed sub-steps of 5e-5, 2e-5, 4e-6 and 2e-6 s over 0.5 s). Every claim holds
  there with the same margins as at full resolution: the vibration measure and peak friction
  differ by up to a few % (1 ms samples miss vibration peaks), the stick-phase counts by at
  most 1 (the clearance case's joint 3). Stick counts come from the FMU's cumulative
  ``n_stick``, so the coarse communication interval loses no phase.
* ``full`` (``@pytest.mark.slow``, run by scripts/test.sh with --runslow): error control, interval 1e-4 s;
  the step case at fixed 5e-5, 2e-5, 2e-6, 1e-6 s over 2 s.

Runs that change the same parameters are done once per process (study.simulate): the
reference run is the step case's 2e-6 s, the friction case's 0.2, the constant
characteristic and the clearance-free variant.
"""

import shutil
import subprocess

import numpy as np
import pytest

from helpers import require_fmu
from stickslip import study

# CI's full run only (scripts/test.sh --quick leaves it out): the study's cases
pytestmark = pytest.mark.full

CI = {"interval": 1e-3}
FULL = {"interval": 1e-4}
RESOLUTIONS = [pytest.param(CI, id="ci"), pytest.param(FULL, id="full", marks=pytest.mark.slow)]


def _run(name, interval, end=study.RUN_TIME, step_h=study.DEFAULT_STEP_H):
    case = study.study_cases(step_h=step_h)[name]
    res = study.run_case(case, end, interval, require_fmu())
    for v, m in zip(case.variants, res["measures"], strict=True):
        j1, j3 = m["joint1"], m["joint3"]
        print(
            f"{name} {v.label}: max eps {m['max_eps']:.4e} m, final {m['final_eps']:.4e} m, "
            f"n_stick {j1['n_stick']}, {j3['n_stick']}, t_stick {j1['t_stick']:.4f}, {j3['t_stick']:.4f} s, "
            f"max N {j1['max_N_normal']:.1f}, {j3['max_N_normal']:.1f} N"
        )
    for c in res["claims"]:
        print(("holds: " if c.holds else "FAILS: ") + c.text)
    return case, res


@pytest.fixture(scope="module", params=RESOLUTIONS)
def resolution(request):
    return request.param


@pytest.mark.parametrize(
    "h, end, interval",
    [
        pytest.param(4e-6, 0.5, CI["interval"], id="ci"),
        pytest.param(study.DEFAULT_STEP_H, study.RUN_TIME, FULL["interval"], id="full", marks=pytest.mark.slow),
    ],
)
def test_step_half_step_reproduces_converged_run(h, end, interval):
    """Fig. 10: halving the sub-step from h to h/2 changes max |eps| by less than 1 % and each
    flexible joint's number of stiction phases by at most one (full: 2e-6 vs 1e-6 s over the
    2 s run; ci: 4e-6 vs 2e-6 s over 0.5 s). Unlike the study, where 5e-5 and 2e-5 s gave a
    different stick-slip pattern, the coarse steps agree too (same counts, max |eps| within
    1 %, phase boundaries within 0.1 ms): stick-slip transitions are located inside the
    sub-step instead of being noticed at its end."""
    case, res = _run("step", interval, end, step_h=h)
    m = res["measures"]
    fine = m[-1]
    assert [v.parameters["h_max"] for v in case.variants] == [5e-5, 2e-5, h, h / 2]
    assert all(v.parameters["h_min"] == v.parameters["h_max"] for v in case.variants)
    for x in m[:-1]:
        assert abs(x["max_eps"] - fine["max_eps"]) <= 0.01 * fine["max_eps"]
        for j in study.FLEXIBLE:
            assert abs(x[f"joint{j}"]["n_stick"] - fine[f"joint{j}"]["n_stick"]) <= 1
    for r in res["runs"][:-1]:
        d = study.differences(r, res["runs"][-1])
        assert d["max_phase_shift"] is not None and d["max_phase_shift"] < 1e-4
    assert all(c.holds for c in res["claims"])


def test_friction_larger_coefficient_worse_accuracy(resolution):
    """Fig. 11: max eps with mu_3 = 0.2 exceeds the one with mu_3 = 0.1 (by a factor of about
    two: while joint 3 slips its drive spring carries the friction force, eps_3 ~ mu_3 N_3 / k_3)."""
    _, res = _run("friction", **resolution)
    low, high = res["measures"]
    assert high["max_eps"] > 1.5 * low["max_eps"]
    assert all(c.holds for c in res["claims"])


def test_characteristic_decreasing_more_stiction_and_vibration(resolution):
    """Fig. 12: the decreasing characteristic (mu_S 0.2, mu_C 0.12, v_S 0.01 in joints 1 and 3)
    gives more stiction phases in joint 3 (17 vs 7) and a larger vibration of eps_3: the standard
    deviation of eps_3 about its 50 ms moving mean over 0-1.5 s is several times larger (about
    7x): a friction force that falls with speed is negative damping of the undamped drive
    (about -6 kN s/m at v -> 0 against a critical 7 kN s/m); the oscillation grows until its
    velocity minima reach v_S, where it sticks or is fed by friction in every cycle."""
    _, res = _run("characteristic", **resolution)
    const, decr = res["measures"]
    assert decr["joint3"]["n_stick"] > const["joint3"]["n_stick"]
    assert decr["joint3"]["vibration"] > 3.0 * const["joint3"]["vibration"]
    assert all(c.holds for c in res["claims"])


def test_clearance_large_and_roughly_constant(resolution):
    """Fig. 13: with Delta_1 = pi/90, Delta_3 = 0.002 the mean |eps_1| is far larger than without
    (more than 100x) and of the order of Delta_1 (0.5..1.5 Delta_1); over the middle of the motion
    (0.3-1.2 s) |eps_1| stays within +-25 % of its mean there: the link lags the drive by about
    the clearance, and slides back and forth inside it."""
    _, res = _run("clearance", **resolution)
    none, gap = (m["joint1"] for m in res["measures"])
    assert gap["mean_abs_eps"] > 100 * none["mean_abs_eps"]
    assert 0.5 * study.CLEARANCE[0] <= gap["mean_abs_eps"] <= 1.5 * study.CLEARANCE[0]
    lo, hi = gap["middle_deviation"]
    assert -0.25 <= lo and hi <= 0.25
    assert all(c.holds for c in res["claims"])


def test_slider_longer_lower_loads_and_error(resolution):
    """Fig. 14 (h_1 = h_3 = 1e3): with a_3 = 0.4 m the peak normal load of the slider, the peak
    friction force and max eps are lower than with 0.2 m. The slider's corner loads come from
    the bending moment over the length a_3, so doubling a_3 halves N_3."""
    _, res = _run("slider", **resolution)
    short, long_ = res["measures"]
    assert long_["joint3"]["max_N_normal"] < short["joint3"]["max_N_normal"]
    assert long_["joint3"]["max_abs_F_friction"] < short["joint3"]["max_abs_F_friction"]
    assert long_["max_eps"] < short["max_eps"]
    assert all(c.holds for c in res["claims"])


def test_stick_phases_rebuilt_from_counters():
    """study.stick_phases: number and total length equal n_stick and t_stick, also for a phase
    that begins and ends inside one communication interval (0.3-0.4 s) and for an interval in
    which one phase ends and the next begins (0.9-1.0 s)."""
    r = {
        "time": np.arange(11) * 0.1,
        "stick[3]": np.array([1, 0, 0, 0, 0, 0, 1, 1, 0, 1, 1], float),
        "n_stick[3]": np.array([1, 1, 1, 1, 2, 2, 3, 3, 3, 4, 5], float),
        "t_stick[3]": np.cumsum([0, 0.05, 0, 0, 0.02, 0, 0.04, 0.1, 0.03, 0.01, 0.06]),
    }
    phases = study.stick_phases(r, 3)
    assert len(phases) == 5
    assert sum(b - a for a, b in phases) == pytest.approx(r["t_stick[3]"][-1])
    expected = [[0, 0.05], [0.34, 0.36], [0.56, 0.73], [0.89, 0.93], [0.97, 1.0]]
    assert np.allclose(phases, expected, atol=1e-12)


def test_command_writes_csv_figure_and_summary(tmp_path):
    """`stickslip study --cases friction ...` writes friction.csv (time + the variants'
    columns), friction.png and the summary (JSON and markdown), with a progress line per case."""
    out = tmp_path / "study"
    p = subprocess.run(
        [
            shutil.which("stickslip"),
            "study",
            "--out",
            str(out),
            "--cases",
            "friction",
            "--fixed-step",
            "5e-5",
            "--interval",
            "1e-3",
            "--end",
            "0.3",
            "--fmu",
            str(require_fmu()),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "[1/1] friction" in p.stdout
    header = (out / "friction.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time" and "mu3=0.1:eps" in header and "mu3=0.2:n_stick[3]" in header
    assert (out / "friction.png").stat().st_size > 10_000
    assert "friction" in (out / "summary.json").read_text(encoding="utf-8")
    summary = (out / "summary.md").read_text(encoding="utf-8")
    assert "| μ3 = 0.1 |" in summary and "fixed sub-steps of 5e-05 s" in summary
