"""The derivative filter: q, q̇, q̈ (or a torque and its rates) from sampled, noisy, quantized signals.

Identification from measured motion needs velocities and accelerations that the encoders do
not give: differentiating raw samples twice multiplies their noise by 1/Δt² (with 4 ms
samples and a 1e-4 rad count, a spline through the raw samples has q̈ noise of hundreds of
rad/s²). Robot identification therefore low-pass filters the positions before
differentiating (Gautier's IDIM; Swevers et al.). Three filters, per experiment
(``derivatives`` of an ``[[experiment]]``, or of ``[options]`` for all):

* ``{ method = "savgol", window = 0.04, order = 3 }``: a Savitzky-Golay filter, a local
  polynomial of ``order`` fitted over ``window`` seconds (rounded to an odd number of
  samples, at least order + 2 + 1 (odd)) around each sample; its value and first two derivatives.
  A cubic over N samples passes frequencies up to about fs (order + 1)/(3.2 N − 4.6)
  (Schafer, "What is a Savitzky-Golay filter?", IEEE SP Magazine 2011), the −3 dB point.
* ``{ method = "lowpass", cutoff = 20.0, order = 4 }``: a Butterworth low-pass of ``order``
  and ``cutoff`` Hz run forward and backward (zero phase, filtfilt), then a not-a-knot cubic
  spline through the filtered samples for the derivatives.
* ``"spline"``: no filter; the not-a-knot cubic spline through the raw samples (exact for
  commands that are smooth functions sampled without noise, such as a controller's set points).

The default, ``"auto"``, is :func:`default_filter`: a cubic Savitzky-Golay over about
:data:`DEFAULT_WINDOW` seconds (at least :data:`MIN_SAMPLES` samples), chosen from the
sample rate only. :func:`describe` says what was used, for the report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

METHODS = ("savgol", "lowpass", "spline")
DEFAULT_WINDOW = 0.04  # s: a cubic passes about 30 Hz at any sample rate
MIN_SAMPLES = 7


@dataclass(frozen=True)
class Filter:
    """A derivative filter: ``method`` one of :data:`METHODS`; ``window`` (s) and ``order`` of a
    Savitzky-Golay filter, ``cutoff`` (Hz) and ``order`` of a Butterworth low-pass."""

    method: str
    window: float = DEFAULT_WINDOW
    order: int = 3
    cutoff: float = 0.0
    chosen: bool = False  # True: the default, chosen from the sample rate

    def samples(self, dt: float, n: int) -> int:
        """The Savitzky-Golay window in samples: odd, >= order + 2 (and MIN_SAMPLES for the
        default), <= n (odd)."""
        k = max(self.order + 2, round(self.window / dt))
        if self.chosen:
            k = max(k, MIN_SAMPLES)
        k += 1 - k % 2
        top = n - (1 - n % 2)
        return max(min(k, top), 1)

    def passband(self, dt: float, n: int) -> float:
        """The −3 dB frequency (Hz) of the filter at sample interval ``dt`` (inf for none)."""
        if self.method == "savgol":
            k = self.samples(dt, n)
            return (self.order + 1) / (3.2 * k - 4.6) / dt if k > 3 else math.inf
        if self.method == "lowpass":
            return self.cutoff
        return math.inf


AUTO = Filter("savgol", DEFAULT_WINDOW, 3, chosen=True)


def default_filter() -> Filter:
    """The filter of ``derivatives = "auto"``: cubic Savitzky-Golay over DEFAULT_WINDOW s."""
    return AUTO


def parse(raw, where: str) -> Filter:
    """The Filter of a SPEC value: "auto", "spline", or a table {method, window, order, cutoff}.
    Raises ValueError with ``where`` and the field in the message."""
    if raw == "auto":
        return AUTO
    if raw == "spline":
        return Filter("spline")
    form = '"auto", "spline", { method = "savgol", window = 0.04, order = 3 } or { method = "lowpass", cutoff = 20.0 }'
    if not isinstance(raw, dict):
        raise ValueError(f"{where} = {raw!r}: must be {form}")
    method = raw.get("method")
    if method not in METHODS:
        raise ValueError(f"{where}.method = {method!r}: one of {', '.join(map(repr, METHODS))} ({form})")
    allowed = {"savgol": ("method", "window", "order"), "lowpass": ("method", "cutoff", "order"), "spline": ("method",)}
    unknown = [k for k in raw if k not in allowed[method]]
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {unknown} for method {method!r} (it has {list(allowed[method])})")
    order = raw.get("order", 3 if method == "savgol" else 4)
    if isinstance(order, bool) or not isinstance(order, int) or not 1 <= order <= (7 if method == "savgol" else 8):
        raise ValueError(f"{where}.order = {order!r}: a whole number 1..{7 if method == 'savgol' else 8}")
    if method == "savgol":
        window = raw.get("window", DEFAULT_WINDOW)
        if isinstance(window, bool) or not isinstance(window, (int, float)) or not 0 < window < math.inf:
            raise ValueError(f"{where}.window = {window!r}: a time span in seconds > 0, as in window = 0.04")
        if order < 2:
            raise ValueError(f"{where}.order = {order}: at least 2 (a second derivative is taken)")
        return Filter("savgol", float(window), order)
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
        pad = min(n - 1, 3 * (2 * len(sos) + 1))
        smooth = sosfiltfilt(sos, y, axis=0, padlen=pad)
        spline = CubicSpline(t, smooth, axis=0)
        return smooth, spline(t, 1), spline(t, 2)
    return _spline(t, y)


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
    """One line for the report: the filter, its window or cut-off, and whether it was chosen."""
    if flt.method == "savgol":
        k = flt.samples(dt, n)
        text = (
            f"Savitzky-Golay of order {flt.order} over {k} samples ({k * dt:.3g} s), passing up to about "
            f"{flt.passband(dt, n):.3g} Hz"
        )
    elif flt.method == "lowpass":
        text = f"Butterworth low-pass of order {flt.order}, cut-off {flt.cutoff:g} Hz, forward and backward"
    else:
        text = "none (a cubic spline through the raw samples)"
    return text + (f" (the default for {dt * 1e3:.3g} ms samples)" if flt.chosen else "")
