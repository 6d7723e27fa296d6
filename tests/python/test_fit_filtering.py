"""The fit's derivative filter (python/stickslip/fit/filtering.py; issue 36, item 5).

* A Savitzky-Golay filter of order >= 3 reproduces a cubic exactly: its value, first and
  second derivative at every sample, the ends included, to 1e-9 of each one's largest size
  (measured: at most 5e-10, second derivatives at 1 ms, whose coefficients are 1e6 times the
  samples'; values and rates 3e-13).
* The Butterworth low-pass (forward and backward) passes a slow sine and its derivatives: in
  the interior to 1e-6, 1e-6, 1e-4 of their amplitudes (measured at most 2.8e-10, 5.9e-9,
  5.3e-5), at the ends (continued by a cubic) to 1e-5, 1e-3, 1e-2 (measured 2.2e-6, 1.8e-4,
  5.0e-3).
* :func:`~stickslip.fit.filtering.noise_gains` is the standard deviation the filter leaves
  of white noise, per unit of the noise, in the value, rate and acceleration (within 5 % of a
  simulation), and :meth:`~stickslip.fit.filtering.Filter.passband` the −3 dB frequency of the
  value (a sine there comes out at 1/√2 of its amplitude).
* ``parse`` refuses a bad value with a message that names the field; ``rough`` tells an
  encoder's samples from a command printed to 10 digits; ``describe`` states the window and
  the passband.
"""

from __future__ import annotations

import math

import numpy as np
import pytest


def _cubic(t):
    """A cubic and its first two derivatives."""
    return (
        0.3 - 1.2 * t + 2.5 * t**2 - 1.7 * t**3,
        -1.2 + 5.0 * t - 5.1 * t**2,
        5.0 - 10.2 * t,
    )


@pytest.mark.parametrize("dt", [1e-3, 4e-3])
@pytest.mark.parametrize(
    "table", ["auto", {"method": "savgol", "window": 0.011, "order": 3}, {"method": "savgol", "order": 4}]
)
def test_savitzky_golay_reproduces_a_cubic(dt, table):
    from stickslip.fit.filtering import derivatives, parse

    t = np.arange(0.0, 1.0 + dt / 2, dt)
    flt = parse(table, "derivatives")
    # Exact but for rounding: the acceleration's coefficients grow as 1/dt², so its rounding is
    # about eps·|y|·Σ|c| ≈ 1e-16 · 1e7 = 1e-9 of it at dt = 1 ms (measured 1.3e-9 on one machine,
    # below 1e-9 on another); the value's and the rate's stay below 1e-12.
    for order, (got, want) in enumerate(zip(derivatives(t, _cubic(t)[0], flt), _cubic(t), strict=True)):
        error = float(np.max(np.abs(got - want)) / np.max(np.abs(want)))
        assert error < (1e-9, 1e-9, 1e-8)[order], (table, dt, order, error)
    # Several channels at once: each as alone.
    both = derivatives(t, np.column_stack([_cubic(t)[0], -2.0 * _cubic(t)[0]]), flt)
    for got, want in zip(both, _cubic(t), strict=True):
        assert np.allclose(got[:, 1], -2.0 * want, rtol=0, atol=1e-8 * np.max(np.abs(want)))


@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_the_low_pass_passes_a_slow_sine_and_its_derivatives(dt):
    """A 1 Hz sine through a 20 Hz cut-off: value, rate and acceleration within 1e-6, 1e-6,
    1e-4 of their amplitudes after the first and before the last 0.2 s, within 1e-5, 1e-3,
    1e-2 at the ends."""
    from stickslip.fit.filtering import derivatives, parse

    t = np.arange(0.0, 4.0, dt)
    w = 2 * math.pi
    exact = (np.sin(w * t + 0.4), w * np.cos(w * t + 0.4), -w * w * np.sin(w * t + 0.4))
    got = derivatives(t, exact[0], parse({"method": "lowpass", "cutoff": 20.0}, "derivatives"))
    inner = (t > 0.2) & (t < 3.8)
    for k, (g, e, tol_in, tol_end) in enumerate(zip(got, exact, (1e-6, 1e-6, 1e-4), (1e-5, 1e-3, 1e-2), strict=True)):
        amplitude = w**k
        interior = float(np.max(np.abs(g - e)[inner])) / amplitude
        ends = float(np.max(np.abs(g - e))) / amplitude
        print(f"derivative {k}: interior {interior:.2g}, ends {ends:.2g}")
        assert interior < tol_in and ends < tol_end, (k, interior, ends)


def test_the_low_pass_refuses_a_cut_off_above_nyquist():
    from stickslip.fit.filtering import derivatives, parse

    t = np.arange(0.0, 1.0, 4e-3)
    with pytest.raises(ValueError, match="not below the samples' Nyquist frequency 125 Hz"):
        derivatives(t, np.sin(t), parse({"method": "lowpass", "cutoff": 200.0}, "derivatives"))


@pytest.mark.parametrize(
    "table",
    ["auto", {"method": "savgol", "window": 0.04, "order": 3}, {"method": "lowpass", "cutoff": 20.0}, "spline"],
)
def test_the_noise_gains_are_what_the_filter_leaves_of_white_noise(table):
    from stickslip.fit.filtering import derivatives, noise_gains, parse

    dt, n = 4e-3, 20000
    flt = parse(table, "derivatives")
    noise = np.random.default_rng(1).standard_normal(n)
    got = derivatives(dt * np.arange(n), noise, flt)
    for k, (gain, filtered) in enumerate(zip(noise_gains(flt, dt, n), got, strict=True)):
        measured = float(np.std(filtered[1000:-1000]))
        assert abs(measured / gain - 1) < 0.05, (table, k, measured, gain)


@pytest.mark.parametrize("table", ["auto", {"method": "savgol", "window": 0.04, "order": 3}])
@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_the_passband_is_the_minus_3_db_frequency(table, dt):
    from stickslip.fit.filtering import derivatives, parse

    flt = parse(table, "derivatives")
    t = np.arange(0.0, 8.0, dt)
    f = flt.passband(dt, len(t))
    out = derivatives(t, np.sin(2 * math.pi * f * t), flt)[0]
    gain = float(np.max(np.abs(out[len(t) // 4 : -len(t) // 4])))
    assert abs(gain - 2**-0.5) < 0.01, (table, dt, f, gain)


def test_the_default_is_a_quintic_over_19_samples_at_any_rate():
    from stickslip.fit.filtering import AUTO, default_filter, parse

    assert parse("auto", "derivatives") is default_filter() is AUTO
    assert AUTO.chosen and AUTO.method == "savgol" and AUTO.order == 5
    for dt in (1e-4, 1e-3, 4e-3, 1e-2):
        assert AUTO.samples(dt, 10_000) == 19
        assert 0.085 < AUTO.passband(dt, 10_000) * dt < 0.095
    assert AUTO.samples(1e-3, 12) == 11  # a shorter record: the longest odd window it holds
    window = parse({"method": "savgol", "window": 0.02, "order": 3}, "derivatives")
    assert window.samples(1e-3, 10_000) == 21 and window.samples(4e-3, 10_000) == 5


BAD = [
    ("median", "derivatives = 'median': must be"),
    (3, "derivatives = 3: must be"),
    ({"method": "kalman"}, "derivatives.method = 'kalman': one of 'savgol', 'lowpass', 'spline'"),
    ({"window": 0.02}, "derivatives.method = None"),
    ({"method": "savgol", "window": -0.01}, "derivatives.window = -0.01: a time span in seconds > 0"),
    ({"method": "savgol", "window": "20 ms"}, "derivatives.window = '20 ms'"),
    ({"method": "savgol", "window": True}, "derivatives.window = True"),
    ({"method": "savgol", "order": 1}, "derivatives.order = 1: at least 2"),
    ({"method": "savgol", "order": 9}, "derivatives.order = 9: a whole number 1..7"),
    ({"method": "savgol", "order": 2.5}, "derivatives.order = 2.5"),
    ({"method": "savgol", "cutoff": 20.0}, "unknown key(s) ['cutoff'] for method 'savgol'"),
    ({"method": "lowpass"}, "derivatives.cutoff = None: the cut-off frequency in Hz > 0"),
    ({"method": "lowpass", "cutoff": 0}, "derivatives.cutoff = 0"),
    ({"method": "lowpass", "cutoff": math.inf}, "derivatives.cutoff = inf"),
    ({"method": "lowpass", "cutoff": 20.0, "window": 0.02}, "unknown key(s) ['window'] for method 'lowpass'"),
    ({"method": "lowpass", "cutoff": 20.0, "order": 0}, "derivatives.order = 0: a whole number 1..8"),
    ({"method": "spline", "order": 3}, "unknown key(s) ['order'] for method 'spline'"),
]


@pytest.mark.parametrize("raw, says", BAD, ids=[str(b[0]) for b in BAD])
def test_parse_refuses_a_bad_value_naming_the_field(raw, says):
    from stickslip.fit.filtering import parse

    with pytest.raises(ValueError) as e:
        parse(raw, "derivatives")
    assert says in str(e.value), str(e.value)


def test_the_fit_spec_names_the_experiment_and_the_field(tmp_path):
    """Through the SPEC: one FitSpecError naming the experiment's derivatives field."""
    from helpers import require_fmu
    from stickslip.fit.spec import FitSpecError, load

    (tmp_path / "run.csv").write_text("t,motor1,link1\n0,0,0\n0.001,0,0\n0.002,0,0\n")
    doc = {
        "fmu": str(require_fmu()),
        "experiment": [
            {
                "name": "run",
                "data": "run.csv",
                "inputs": {"q_star[1]": "motor1"},
                "measured": {"q[1]": {"column": "link1", "sigma": 1e-6}},
                "derivatives": {"method": "savgol", "order": 11},
            }
        ],
        "estimate": {"mu_k[1]": {"initial": 0.15, "bounds": [0.05, 0.2]}},
    }
    with pytest.raises(FitSpecError, match=r"experiment 'run': derivatives.order = 11"):
        load(doc, tmp_path)
    doc["experiment"][0].pop("derivatives")
    doc["options"] = {"derivatives": {"method": "lowpass", "cutoff": -1.0}}
    with pytest.raises(FitSpecError, match=r"\[options\]: derivatives.cutoff = -1.0"):
        load(doc, tmp_path)


def test_rough_tells_an_encoder_from_a_command():
    """An encoder's samples (a slow motion rounded to a count of 1e-4 rad every 4 ms, or with
    noise of 2e-6 rad every 1 ms) are rough; a cycloidal command printed to 10 digits, at 1 ms
    or 4 ms, is not; neither is a short or constant column."""
    from stickslip.fit.filtering import rough

    for dt in (1e-3, 4e-3):
        t = np.arange(0.0, 2.0, dt)
        cycloid = 0.8 * (t / 2.0 - np.sin(2 * math.pi * t / 2.0) / (2 * math.pi))
        printed = np.array([float(f"{x:.10g}") for x in cycloid])
        assert not rough(printed), dt
        assert rough(np.round(cycloid / 1e-4) * 1e-4), dt
        assert rough(cycloid + 2e-6 * np.random.default_rng(1).standard_normal(len(t))), dt
    assert not rough(np.zeros(100)) and not rough([0.0, 1e-4, 0.0, 1e-4])


def test_describe_states_the_window_and_the_passband():
    from stickslip.fit.filtering import AUTO, describe, parse

    text = describe(AUTO, 1e-3, 2001)
    assert "Savitzky-Golay of order 5 over 19 samples (0.019 s)" in text, text
    assert "passband about 90.5 Hz (-3 dB)" in text and "the default" in text and "here 1 ms" in text, text
    text = describe(AUTO, 4e-3, 500)
    assert "over 19 samples (0.076 s)" in text and "passband about 22.6 Hz" in text, text
    text = describe(parse({"method": "savgol", "window": 0.04, "order": 3}, "d"), 1e-3, 2001)
    assert "order 3 over 41 samples (0.041 s)" in text and "26 Hz" in text and "default" not in text, text
    text = describe(parse({"method": "lowpass", "cutoff": 20.0}, "d"), 1e-3, 2001)
    assert "cut-off 20 Hz" in text and "passband about 17.9 Hz (-3 dB)" in text, text
    assert "passband unlimited" in describe(parse("spline", "d"), 1e-3, 2001)
