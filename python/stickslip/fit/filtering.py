"""The derivative filter: q, q̇, q̈ (or a torque and its rates) from sampled, noisy, quantized signals.

Identification from measured motion needs velocities and accelerations that the encoders do
not give: differentiating raw samples twice multiplies their noise by about 1/Δt² (with 4 ms
samples and a 1e-4 rad count, a spline through the raw samples has a q̈ noise of 10.6 rad/s²
rms, measured below; through an arm's inertia of a few kg·m², tens of N·m). Robot
identification therefore low-pass filters the positions before differentiating (Gautier's
IDIM; Swevers et al.), and filters the torques it compares them with by the same filter
(parallel filtering, :mod:`stickslip.fit.idim`). Three filters, per experiment
(``derivatives`` of an ``[[experiment]]``, or of ``[options]`` for all):

* ``{ method = "savgol", window = 0.02, order = 5 }``: a Savitzky-Golay filter, a local
  polynomial of ``order`` (2..7, default 5) fitted over ``window`` seconds (rounded to an odd
  number of samples, at least order + 2; default :data:`AUTO_SAMPLES` samples) around each
  sample; its value and first two derivatives. :meth:`Filter.passband` is its −3 dB
  frequency, computed from its coefficients.
* ``{ method = "lowpass", cutoff = 20.0, order = 4 }``: a Butterworth low-pass of ``order``
  and ``cutoff`` Hz run forward and backward (zero phase, filtfilt), then a not-a-knot cubic
  spline through the filtered samples for the derivatives.
* ``"spline"``: no filter; the not-a-knot cubic spline through the raw samples (exact for
  commands that are smooth functions sampled without noise, such as a controller's set points).

**The default**, ``"auto"`` (:func:`default_filter`): a quintic Savitzky-Golay over
:data:`AUTO_SAMPLES` = 19 samples at any sample rate, so its passband is a fixed part of the
sample rate: about 0.09 fs (90 Hz at 1 kHz, 23 Hz at 250 Hz). Why, measured
(``python -c`` with :func:`derivatives` on a 0.5 Hz + 3 Hz motion of 0.5 and 0.05 rad over 4 s;
noise = rms of the q̈ error the samples' errors cause, bias = rms q̈ error of the exact samples):

=============================================  ====================  =====================
filter                                          4 ms, 1e-4 rad count  1 ms, count 1.5e-6 rad
                                                noise / bias (rad/s²) + 2e-6 rad noise
=============================================  ====================  =====================
spline through the raw samples                  10.6 / 0.006          12.3 / 0.0004
cubic SG over ±3 ms (the stage's old filter)    0.99 / 0.026          0.44 / 0.004
cubic SG over 0.04 s (the first default)        0.12 / 0.149          0.005 / 0.134
quintic SG over 19 samples (the default)        0.10 / 0.004          0.13 / 0.00002
Butterworth 4th order at fs/8                   0.22 / 0.006          0.26 / 0.0004
=============================================  ====================  =====================

A window of fixed duration is wrong at one end or the other: 0.04 s leaves little noise at
4 ms, but at 1 kHz it cuts what a stiff drive does within a few tens of ms. On the calibration
example (examples/calibration: 1 ms, the drive of joint 3 rings at about 37 Hz while it
sticks and slips) the equation-error stage gave k[3] and μ_k[3] 20 % low with it (4 % low with
the stage's old ±3 ms cubic, which however leaves 0.4–1 rad/s² of q̈ noise at 4 ms); with the
quintic over 19 samples 2 % low, and b_v[1], μ_k[1] within 2.2 %, μ_s[3] within 3 %, μ_s[1]
11 % high (the old filter: 52 % high). On a motor-drive arm logged at 4 ms with a 1e-4 rad
count (tests/python/test_fit_idim.py) the quintic gives J_m, b_m, τ_c and μ_k of joint 1 as
well as the cubic over 0.04 s, within 20 %. A higher order keeps the passband flat (a 3 Hz
motion's q̈ loses 1 % through the cubic over 0.04 s, nothing through the quintic) at the
noise of a cubic of about half its width. :func:`describe` says what was used, for the report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

METHODS = ("savgol", "lowpass", "spline")
AUTO_SAMPLES = 19  # the default's window, in samples: its passband about 0.09 of the sample rate
AUTO_ORDER = 5


@dataclass(frozen=True)
class Filter:
    """A derivative filter: ``method`` one of :data:`METHODS`; ``window`` (s; None:
    :data:`AUTO_SAMPLES` samples) and ``order`` of a Savitzky-Golay filter, ``cutoff`` (Hz)
    and ``order`` of a Butterworth low-pass."""

    method: str
    window: float | None = None
    order: int = AUTO_ORDER
    cutoff: float = 0.0
    chosen: bool = False  # True: the default ("auto")

    def samples(self, dt: float, n: int) -> int:
        """The Savitzky-Golay window in samples: AUTO_SAMPLES where ``window`` is None, else
        ``window``/``dt`` rounded; odd, >= order + 2, <= n (odd)."""
        k = AUTO_SAMPLES if self.window is None else round(self.window / dt)
        k = max(self.order + 2, k)
        k += 1 - k % 2
        top = n - (1 - n % 2)
        return max(min(k, top), 1)

    def reach(self, dt: float, n: int) -> float:
        """How far (s) a sample's filtered value reaches to either side: half the
        Savitzky-Golay window, about half a period of the low-pass's cut-off, one sample for
        the spline. A filtered rate's sign is that of the true rate only where the rate does
        not change sign within this reach."""
        if self.method == "savgol":
            return 0.5 * (self.samples(dt, n) - 1) * dt
        if self.method == "lowpass":
            return max(0.5 / self.cutoff, dt)
        return dt

    def passband(self, dt: float, n: int) -> float:
        """The −3 dB frequency (Hz) of the filtered value at sample interval ``dt`` (inf for
        none): of a Savitzky-Golay filter from its coefficients' frequency response; of the
        Butterworth low-pass run forward and backward (its gain squared) in closed form."""
        if self.method == "savgol":
            k = self.samples(dt, n)
            if k <= self.order:
                return math.inf
            from scipy.signal import freqz, savgol_coeffs

            w, h = freqz(savgol_coeffs(k, self.order), worN=8192)
            below = np.flatnonzero(np.abs(h) < 2**-0.5)
            return float(w[below[0]] / (2 * math.pi) / dt) if len(below) else math.inf
        if self.method == "lowpass":
            return self.cutoff * (math.sqrt(2.0) - 1.0) ** (1.0 / (2 * self.order))
        return math.inf


AUTO = Filter("savgol", None, AUTO_ORDER, chosen=True)


def default_filter() -> Filter:
    """The filter of ``derivatives = "auto"``: a quintic Savitzky-Golay over AUTO_SAMPLES samples."""
    return AUTO


def parse(raw, where: str) -> Filter:
    """The Filter of a SPEC value: "auto", "spline", or a table {method, window, order, cutoff}.
    Raises ValueError with ``where`` and the field in the message."""
    if raw == "auto":
        return AUTO
    if raw == "spline":
        return Filter("spline")
    form = '"auto", "spline", { method = "savgol", window = 0.02, order = 5 } or { method = "lowpass", cutoff = 20.0 }'
    if not isinstance(raw, dict):
        raise ValueError(f"{where} = {raw!r}: must be {form}")
    method = raw.get("method")
    if method not in METHODS:
        raise ValueError(f"{where}.method = {method!r}: one of {', '.join(map(repr, METHODS))} ({form})")
    allowed = {"savgol": ("method", "window", "order"), "lowpass": ("method", "cutoff", "order"), "spline": ("method",)}
    unknown = [k for k in raw if k not in allowed[method]]
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown} for method {method!r} (it has {list(allowed[method])})")
    order = raw.get("order", AUTO_ORDER if method == "savgol" else 4)
    top = 7 if method == "savgol" else 8
    if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= top:
        raise ValueError(f"{where}.order = {order!r}: a whole number 1..{top}")
    if method == "savgol":
        window = raw.get("window")
        if window is not None and (
            isinstance(window, bool) or not isinstance(window, (int, float)) or not 0 < window < math.inf
        ):
            raise ValueError(f"{where}.window = {window!r}: a time span in seconds > 0, as in window = 0.02")
        if order < 2:
            raise ValueError(f"{where}.order = {order}: at least 2 (a second derivative is taken)")
        return Filter("savgol", None if window is None else float(window), order)
    if method == "lowpass":
        cutoff = raw.get("cutoff")
        if isinstance(cutoff, bool) or not isinstance(cutoff, (int, float)) or not 0 < cutoff < math.inf:
            raise ValueError(f"{where}.cutoff = {cutoff!r}: the cut-off frequency in Hz > 0, as in cutoff = 20.0")
        return Filter("lowpass", cutoff=float(cutoff), order=order)
    return Filter("spline")


def derivatives(t, y, flt: Filter) -> tuple:
    """(y, ẏ, ÿ) of samples ``y`` (n, or n × channels) at times ``t`` through the filter,
    each the shape of ``y``. The samples should be (close to) evenly spaced for "savgol" and
    "lowpass" (their median interval is taken); "spline" takes any times."""
    from scipy.interpolate import CubicSpline

    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = len(t)
    if n < 2:
        z = np.zeros_like(y)
        return y.copy(), z, z.copy()
    dt = float(np.median(np.diff(t)))
    if flt.method == "savgol":
        from scipy.signal import savgol_filter

        k = flt.samples(dt, n)
        if k <= flt.order:
            return _spline(t, y)
        f = [savgol_filter(y, k, flt.order, deriv=d, delta=dt, axis=0, mode="interp") for d in (0, 1, 2)]
        return f[0], f[1], f[2]
    if flt.method == "lowpass":
        from scipy.signal import butter, sosfiltfilt

        nyquist = 0.5 / dt
        if flt.cutoff >= nyquist:
            raise ValueError(f"cutoff {flt.cutoff:g} Hz is not below the samples' Nyquist frequency {nyquist:g} Hz")
        sos = butter(flt.order, flt.cutoff / nyquist, output="sos")
        # Each end continued by the cubic fitted to its samples within one cut-off period (at
        # least 5), for four cut-off periods: the filter's start-up transients die out there,
        # and the value, slope and curvature at the ends are the data's. (sosfiltfilt's own odd
        # extension of 3 (2 sections + 1) samples left a 1 Hz sine's q̈ 7.6 times its amplitude
        # wrong at the ends with a 20 Hz cut-off at 1 kHz; the cubic 0.5 %, at 3-7 times the
        # interior's noise at the end sample.)
        fit = min(n, max(5, round(1.0 / (flt.cutoff * dt))))
        pad = max(1, round(4.0 / (flt.cutoff * dt)))
        steps = dt * np.arange(1, pad + 1)
        before = _continued(t[:fit] - t[0], y[:fit], -steps[::-1])
        after = _continued(t[-fit:] - t[-1], y[-fit:], steps)
        smooth = sosfiltfilt(sos, np.concatenate([before, y, after]), axis=0, padtype=None)[pad : pad + n]
        spline = CubicSpline(t, smooth, axis=0)
        return smooth, spline(t, 1), spline(t, 2)
    return _spline(t, y)


def noise_gains(flt: Filter, dt: float, n: int) -> tuple:
    """(g0, g1, g2): the standard deviations of the filtered value, first and second
    derivative per unit standard deviation of white noise on the samples, in the middle of a
    record of ``n`` samples at interval ``dt`` (the filter is linear: the root sum of squares
    of its response to a unit impulse). A threshold on a filtered rate is a multiple of
    g1·σ; the noise a filtered q̈ carries is g2·σ."""
    m = int(min(n, 4001))
    m -= 1 - m % 2
    if m < 3:
        return 1.0, math.inf, math.inf
    impulse = np.zeros(m)
    impulse[m // 2] = 1.0
    t = dt * np.arange(m)
    if flt.method == "savgol":  # the window of the whole record, not of the shortened one
        from scipy.signal import savgol_coeffs

        k = flt.samples(dt, n)
        if k > flt.order:
            return tuple(float(np.sqrt(np.sum(savgol_coeffs(k, flt.order, deriv=d, delta=dt) ** 2))) for d in (0, 1, 2))
    response = derivatives(t, impulse, flt)
    return tuple(float(np.sqrt(np.sum(r**2))) for r in response)


def _continued(t, y, at):
    """The cubic least-squares fit of samples ``y`` (n, or n × channels) at ``t`` (a lower
    degree for fewer than 4), evaluated at ``at``."""
    degree = min(3, len(t) - 1)
    coefficients = np.polyfit(t, y, degree)
    powers = np.vander(at, degree + 1)
    return powers @ coefficients


def rough(values) -> bool:
    """True for samples whose noise (or an encoder's rounding) dominates their differences at
    the sample rate: the rms of the fourth differences above that of the third. For white noise
    the ratio is sqrt(70/20) = 1.87; for a smooth signal sampled finely it is about ω·Δt ≪ 1
    (a set point of a controller, even printed to 10 digits, is smooth; an encoder is not)."""
    y = np.asarray(values, dtype=np.float64)
    y = y[np.isfinite(y)]
    if len(y) < 8:
        return False
    d3 = np.diff(y, 3)
    d4 = np.diff(d3)
    r3 = float(np.sqrt(np.mean(d3**2)))
    return r3 > 0 and float(np.sqrt(np.mean(d4**2))) > r3


def _spline(t, y) -> tuple:
    from scipy.interpolate import CubicSpline

    spline = CubicSpline(t, y, axis=0)
    return y.copy(), spline(t, 1), spline(t, 2)


def describe(flt: Filter, dt: float, n: int) -> str:
    """One line for the report: the filter, its window or cut-off, its passband (−3 dB of the
    filtered value) at sample interval ``dt`` for ``n`` samples, and whether it is the default."""
    if flt.method == "savgol":
        k = flt.samples(dt, n)
        text = (
            f"Savitzky-Golay of order {flt.order} over {k} samples ({k * dt:.3g} s), passband about "
            f"{flt.passband(dt, n):.3g} Hz (-3 dB)"
        )
    elif flt.method == "lowpass":
        text = (
            f"Butterworth low-pass of order {flt.order}, cut-off {flt.cutoff:g} Hz, forward and backward "
            f"(zero phase), passband about {flt.passband(dt, n):.3g} Hz (-3 dB)"
        )
    else:
        text = "none (a cubic spline through the raw samples), passband unlimited"
    return text + (f" (the default: {AUTO_SAMPLES} samples at any rate; here {dt * 1e3:.3g} ms)" if flt.chosen else "")
