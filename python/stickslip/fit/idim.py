"""The equation-error stage (Gautier's inverse dynamic identification model, IDIM-LS):
friction and drive parameters from the measured motion itself, without a simulation.

Along each experiment whose flexible joints' positions q are all measured:

1. q, q̇, q̈ of the flexible joints by a Savitzky-Golay fit of the encoders (cubic, about
   ±3 ms); the rigid joints' q, q̇, q̈ are their commands (exact).
2. The engine's own inverse dynamics and joint reactions at those states, from the FMU's
   own binary for this platform (its export ``stickslip_inverse_dynamics``, called with
   ctypes, on the FMU's ``resources/model.toml``; :func:`inverse_dynamics`): per joint the
   generalized force τ_s (3.9) and the friction's lever load L_s, such that the Coulomb
   part is μ·L_s ((3.11)-(3.15)).
3. In the slip phases of joint s (|q̇_s| well above the derivative's noise) its equation of
   motion (3.9)-(3.10) read backwards,

       τ_s = k_s (q*_s − q_s − σΔ_s) δ + h_s (q̇*_s − q̇_s)
             − [μ_k (1 − e) + μ_s e] L_s sgn q̇_s − b_s q̇_s,     e = exp(−|q̇_s|/v_s)

   is linear in k, h, μ_k, μ_s (for v_s > 0) and the viscous b: a linear least squares over
   the slip samples gives those of them that are estimated (the others fixed at their
   initial values).
4. With v_s = 0, μ_s comes from the breakaways instead (:func:`breakaway_mu_s`): a stiction
   phase ends where |F^d − F*| reaches μ_s L (3.16), (3.18). F* and L are taken with the
   joint held (q̇_s = q̈_s = 0, as while it sticks), so that the filtered derivatives' noise
   does not enter them; per stuck phase that ends in a slip, the ratio |F^d − F*|/L at its
   last stuck samples bounds μ_s from below and at its first slipping samples from above.
   Only breakaways whose L is a sizeable part of the typical stuck load count (where L is
   small the ratio is noise over nearly nothing), and only those whose two bounds lie close
   (where the drive loads the joint fast the ratio moves a lot from one sample to the next);
   the median of their midpoints, each weighted by the inverse of its bracket's width, is
   the estimate. μ_s of either step is raised to μ_k where it is below (the FMU refuses
   μ_s < μ_k) and clipped into the estimate's bounds.

The result is a start for the output-error stage, not the estimate: filtered derivatives
bias it, and a stiff drive's deflection is a small difference of two encoders.
"""

from __future__ import annotations

import ctypes
import functools
import platform
import re
import sys
import tomllib
from pathlib import Path

import numpy as np

LINEAR = ("k", "h", "mu_k", "mu_s", "b_v")  # parameters the slip equation is linear in
# The parameters inverse dynamics and the lever loads depend on: masses and contact geometry.
RIGID_BODY = ("m", "slider_a", "slider_b", "slider_c", "d_A", "d_B", "d_C", "l_A", "l_B")
EXPORT = "stickslip_inverse_dynamics"  # the FMU library's function beyond FMI 2.0
# Breakaways (step 4, :func:`breakaways`): a stuck phase is at least MIN_STUCK stuck samples;
# it ends in a breakaway if a slip follows within SLIP_WITHIN samples and holds for EDGE
# samples, the EDGE samples on either side are read, and their L must be at least
# LOAD_FRACTION of the median L over the stuck samples.
MIN_STUCK = 5
SLIP_WITHIN = 5
LOAD_FRACTION = 0.3
EDGE = 2
# A breakaway brackets μ_s between its bounds; one whose bounds lie further apart than BRACKET
# times their midpoint (the drive loaded the joint faster than the samples resolve) is left out.
BRACKET = 0.5


class InverseDynamicsError(ValueError):
    """The engine refused the states or the model (its message): a model file that does not
    parse, an unknown or refused setting, a state row of the wrong length, a state that is
    not finite."""


class StageUnavailable(RuntimeError):
    """The FMU's binary for this platform cannot run the engine's inverse dynamics: why, and
    what to do."""


def joint_of(name: str):
    """("mu_k", 3) of "mu_k[3]", or None."""
    m = re.fullmatch(r"([A-Za-z_]+)\[(\d+)\]", name)
    return (m.group(1), int(m.group(2))) if m else None


def platform_folder() -> str:
    """The FMI 2.0 platform folder of ``binaries/`` for this Python: linux64, win64, darwin64."""
    system = {"linux": "linux64", "win32": "win64", "darwin": "darwin64"}.get(sys.platform)
    if system is None or sys.maxsize <= 2**32:
        raise StageUnavailable(f"no FMU binary folder for {sys.platform} ({platform.machine()}, 32-bit Python?)")
    return system


def library_path(unzipdir) -> Path:
    """The FMU's shared library for this platform in the unpacked FMU ``unzipdir``."""
    folder = platform_folder()
    ext = {"linux64": ".so", "win64": ".dll", "darwin64": ".dylib"}[folder]
    description = Path(unzipdir) / "modelDescription.xml"
    found = re.search(r'<CoSimulation\b[^>]*\bmodelIdentifier="([^"]+)"', description.read_text(encoding="utf-8"))
    path = Path(unzipdir) / "binaries" / folder / f"{found.group(1) if found else '?'}{ext}"
    if not path.is_file():
        raise StageUnavailable(
            f"the FMU has no {folder} binary ({path.relative_to(unzipdir).as_posix()}): build it for this platform "
            f"(bash scripts/build_fmu.sh --platforms linux64{'' if folder == 'linux64' else ',' + folder})"
        )
    return path


@functools.cache
def _engine(path: str):
    """The export of the library at ``path``, with its C signature."""
    try:
        library = ctypes.CDLL(path)
    except OSError as e:
        raise StageUnavailable(f"{path} does not load on this machine ({platform.machine()}): {e}") from e
    try:
        function = getattr(library, EXPORT)
    except AttributeError:
        raise StageUnavailable(
            f"{Path(path).name} has no {EXPORT}: the FMU was built before the engine's inverse dynamics were "
            "exported; rebuild it with this version (bash scripts/build_fmu.sh, or package_fmu)"
        ) from None
    double_p = ctypes.POINTER(ctypes.c_double)
    size = ctypes.c_size_t
    function.argtypes = [
        ctypes.c_char_p,  # model: resources/model.toml
        ctypes.c_char_p,  # urdf: the URDF it names, or NULL
        ctypes.POINTER(ctypes.c_char_p),  # settings "m[3]=8.0", ...
        size,
        double_p,  # states, rows x [q(n), qd(n), qdd(n)]
        size,  # rows
        size,  # columns
        double_p,  # tau, rows x n
        double_p,  # lever_load, rows x n
        size,  # size of each output
        ctypes.c_char_p,  # message buffer
        size,
    ]
    function.restype = ctypes.c_int
    return function


def _model_source(unzipdir) -> tuple:
    """(model file text, text of the URDF it names or None) of the unpacked FMU."""
    resources = Path(unzipdir) / "resources"
    text = (resources / "model.toml").read_text(encoding="utf-8")
    try:
        urdf = tomllib.loads(text).get("urdf")
    except tomllib.TOMLDecodeError:
        urdf = None  # the engine says what is wrong with the file
    return text, (resources / urdf).read_text(encoding="utf-8") if isinstance(urdf, str) else None


def inverse_dynamics(unzipdir, states, settings=()) -> tuple:
    """(τ, L) at ``states`` (rows × [q(n), q̇(n), q̈(n)], SI units), both rows × n, by the
    engine in the unpacked FMU ``unzipdir``'s own binary: τ = M(q)·q̈ + bias(q, q̇) with
    gravity, L the lever load of each joint's friction (NaN for a joint without friction),
    on the FMU's model with ``settings`` (tunable parameters by FMU name, "m[3]=8.0")
    applied. Raises :class:`StageUnavailable` where the binary cannot do it and
    :class:`InverseDynamicsError` with the engine's reason where it refuses the input."""
    engine = _engine(str(library_path(unzipdir)))
    states = np.ascontiguousarray(states, dtype=np.float64)
    if states.ndim != 2:
        raise InverseDynamicsError(f"states must be rows of q, qd, qdd, not an array of shape {states.shape}")
    rows, columns = states.shape
    n = columns // 3
    tau, load = np.full((rows, n), np.nan), np.full((rows, n), np.nan)
    text, urdf = _model_source(unzipdir)
    encoded = [str(s).encode() for s in settings]
    message = ctypes.create_string_buffer(1024)
    double_p = ctypes.POINTER(ctypes.c_double)
    status = engine(
        text.encode(),
        urdf.encode() if urdf is not None else None,
        (ctypes.c_char_p * max(1, len(encoded)))(*encoded),
        len(encoded),
        states.ctypes.data_as(double_p),
        rows,
        columns,
        tau.ctypes.data_as(double_p),
        load.ctypes.data_as(double_p),
        rows * n,
        message,
        len(message),
    )
    if status != 0:
        raise InverseDynamicsError(message.value.decode(errors="replace") or f"{EXPORT} returned {status}")
    return tau, load


def estimate(spec, unzipdir: str, flexible: list, initial: dict, start_values: dict) -> tuple:
    """(θ dict of the estimated parameters this stage could estimate, notes)."""
    from scipy.signal import savgol_filter

    notes = []
    targets = {}
    for e in spec.estimates:
        j = joint_of(e.name)
        if j and j[0] in LINEAR and j[1] in flexible:
            targets.setdefault(j[1], []).append(j[0])
    if not targets:
        return {}, ["equation-error stage: no estimated parameter enters a flexible joint's slip equation linearly"]
    try:
        _engine(str(library_path(unzipdir)))
    except StageUnavailable as e:
        return {}, [f"equation-error stage could not run: {e}"]
    estimated = {e.name: e for e in spec.estimates}
    rows = {i: [] for i in targets}
    mu_k_known = dict.fromkeys(targets, 0.0)  # the largest μ_k an experiment runs with: μ_s may not be below
    phases = {i: [] for i in targets}  # per joint and experiment: what the breakaways are read from
    for ex in spec.experiments:
        measured = {c.output: c.values for c in ex.channels}
        if any(f"q[{i}]" not in measured for i in flexible):
            notes.append(f"equation-error stage: experiment {ex.name!r} does not measure every flexible joint's q")
            continue
        known = {**start_values, **initial, **ex.parameters}
        settings = [f"{k}={float(v)!r}" for k, v in known.items() if (joint_of(k) or ("",))[0] in RIGID_BODY]
        t = ex.time
        dt = float(np.median(np.diff(t)))
        window = min(len(t) - (1 - len(t) % 2), max(5, 2 * round(0.003 / dt) + 1))
        cmd = np.array([np.concatenate(ex.motion(float(tk), 0.0)) for tk in t])  # q*, q*', q*''
        n = cmd.shape[1] // 3
        q, qd, qdd = cmd[:, :n].copy(), cmd[:, n : 2 * n].copy(), cmd[:, 2 * n :].copy()
        for i in flexible:
            y = measured[f"q[{i}]"]
            q[:, i - 1] = savgol_filter(y, window, 3, mode="interp")
            qd[:, i - 1] = savgol_filter(y, window, 3, deriv=1, delta=dt, mode="interp")
            qdd[:, i - 1] = savgol_filter(y, window, 3, deriv=2, delta=dt, mode="interp")
        try:
            tau_all, load_all = inverse_dynamics(unzipdir, np.hstack([q, qd, qdd]), settings)
        except InverseDynamicsError as e:
            raise InverseDynamicsError(f"experiment {ex.name!r}: {e}") from None
        noise = min(c.std for c in ex.channels if c.output.startswith("q["))
        v_noise = 10.0 * noise / (dt * (window // 2))  # well above the filtered slope's noise
        for i, names in targets.items():
            s = i - 1
            mu_k_known[i] = max(mu_k_known[i], known.get(f"mu_k[{i}]", 0.0))
            k, h, delta = known.get(f"k[{i}]", 0.0), known.get(f"h[{i}]", 0.0), known.get(f"Delta[{i}]", 0.0)
            stretch = cmd[:, s] - q[:, s]
            engaged = np.abs(stretch) >= delta
            deflection = np.where(engaged, stretch - np.sign(stretch) * delta, 0.0)
            rate = cmd[:, n + s] - qd[:, s]
            tau, load = tau_all[:, s], load_all[:, s]
            v = qd[:, s]
            vs = known.get(f"v_s[{i}]", 0.0)
            e = np.exp(-np.abs(v) / vs) if vs > 0 else np.zeros_like(v)
            sgn = np.sign(v)
            features = {
                "k": deflection,
                "h": rate,
                "mu_k": -load * sgn * (1.0 - e),
                "mu_s": -load * sgn * e,
                "b_v": -v,
            }
            if vs <= 0:
                features.pop("mu_s")
            slip = np.abs(v) > v_noise
            free = [x for x in names if x in features]
            fixed = [x for x in features if x not in free]
            values = {
                "k": k,
                "h": h,
                "mu_k": known.get(f"mu_k[{i}]", 0.0),
                "mu_s": known.get(f"mu_s[{i}]", 0.0),
                "b_v": known.get(f"b_v[{i}]", 0.0),
            }
            y = tau - sum(features[x] * values[x] for x in fixed)
            if free:
                rows[i].append((np.column_stack([features[x] for x in free])[slip], y[slip], free))
            if vs <= 0 and "mu_s" in names:
                # F* and L with the joint held (q̇_s = q̈_s = 0), as (3.16) reads them while it sticks.
                held_qd, held_qdd = qd.copy(), qdd.copy()
                held_qd[:, s] = 0.0
                held_qdd[:, s] = 0.0
                held_tau, held_load = inverse_dynamics(unzipdir, np.hstack([q, held_qd, held_qdd]), settings)
                phases[i].append((k, h, deflection, rate, held_tau[:, s], held_load[:, s], np.abs(v), v_noise))
    theta = {}
    for i, parts in rows.items():
        free = parts[0][2] if parts else []
        A = np.vstack([p[0] for p in parts]) if parts else np.empty((0, 0))
        y = np.concatenate([p[1] for p in parts]) if parts else np.empty(0)
        if len(y) < 3 * len(free):
            notes.append(f"equation-error stage: joint {i}: {len(y)} slip samples, too few for {free}")
        elif free:
            col = np.linalg.norm(A, axis=0)
            col[col == 0] = 1.0
            sol, *_ = np.linalg.lstsq(A / col, y, rcond=None)
            sol = sol / col
            resid = y - A @ sol
            notes.append(
                f"equation-error stage: joint {i}: {len(y)} slip samples, "
                + ", ".join(f"{x}[{i}] = {v:.6g}" for x, v in zip(free, sol, strict=True))
                + f", residual rms {np.sqrt(np.mean(resid**2)):.3g}"
            )
            theta.update({f"{x}[{i}]": float(v) for x, v in zip(free, sol, strict=True)})
        name = f"mu_s[{i}]"
        if name in estimated and name not in theta and phases[i]:
            # |F^d − F*|/L with the drive's k and h of the slip equation where it estimated them.
            ratios = [
                (np.abs(theta.get(f"k[{i}]", k) * d + theta.get(f"h[{i}]", h) * r - f) / load, load, speed, v_noise)
                for k, h, d, r, f, load, speed, v_noise in phases[i]
            ]
            value, note = breakaway_mu_s(ratios)
            notes.append(f"equation-error stage: joint {i}: {note}")
            if value is not None:
                theta[name] = value
        if name in theta:  # of the slip equation (v_s > 0) or of the breakaways
            mu_k = theta.get(f"mu_k[{i}]", mu_k_known[i])
            value, said = admissible_mu_s(theta[name], mu_k, estimated[name].low, estimated[name].high)
            if said:
                notes.append(f"equation-error stage: joint {i}: {name} = {theta[name]:.4g} {said}")
            theta[name] = value
    return theta, notes


def admissible_mu_s(value: float, mu_k: float, low: float, high: float) -> tuple:
    """(μ_s, what was done, or ""): ``value`` raised to ``mu_k`` (the FMU refuses μ_s < μ_k)
    and clipped into [``low``, ``high``]."""
    taken = float(np.clip(max(value, mu_k), low, high))
    if taken == value:
        return value, ""
    return taken, f"taken as {taken:.4g} (not below mu_k = {mu_k:.4g}, within [{low:g}, {high:g}])"


def breakaways(ratio, load, speed, v_noise) -> tuple:
    """([(lower, upper) bound of μ_s per usable breakaway], number of stuck phases left out)
    of one experiment, from the ratio |F^d − F*|/L (joint held) at the last EDGE stuck samples
    of a phase (their largest) and the first EDGE slipping samples after it (their smallest).
    A stuck sample has |q̇| below 0.3 of the noise threshold ``v_noise``, a slipping one above
    it; a stuck phase is a run of at least MIN_STUCK stuck samples. It is used if it ends in a
    slip within SLIP_WITHIN samples that holds for EDGE samples, and L at those samples is at
    least LOAD_FRACTION of the median L over the stuck samples; a phase that lasts to the end
    of the run has no breakaway and is not counted."""
    stuck = speed < 0.3 * v_noise
    if not stuck.any():
        return [], 0
    typical = float(np.median(load[stuck]))
    edges = np.flatnonzero(np.diff(stuck.astype(np.int8)))  # last sample before each change
    starts = np.concatenate([[0] if stuck[0] else [], edges[~stuck[edges]] + 1]).astype(int)
    ends = edges[stuck[edges]]
    found, skipped = [], 0
    for start, end in zip(starts, ends, strict=False):  # a last phase without an end has no breakaway
        if end - start + 1 < MIN_STUCK:
            continue  # a few samples below the threshold within a slip: not a phase
        slipping = np.flatnonzero(speed[end + 1 : end + 1 + SLIP_WITHIN] > v_noise)
        first = end + 1 + int(slipping[0]) if len(slipping) else len(speed)
        before, after = slice(end + 1 - EDGE, end + 1), slice(first, first + EDGE)
        usable = (
            len(speed[after]) == EDGE
            and bool(np.all(speed[after] > v_noise))
            and min(load[before].min(), load[after].min()) >= LOAD_FRACTION * typical
        )
        if usable:
            found.append((float(np.max(ratio[before])), float(np.min(ratio[after]))))
        else:
            skipped += 1
    return found, skipped


def breakaway_mu_s(experiments: list) -> tuple:
    """(μ_s or None, a note) of the :func:`breakaways` of every experiment (each the arguments
    of one call): the midpoint of each breakaway's bounds, those whose bounds lie within
    BRACKET of it, their median weighted by the inverse of each one's width (a narrow bracket
    says more). :func:`admissible_mu_s` then keeps it above μ_k and within the bounds."""
    calls = [breakaways(*part) for part in experiments]
    found = np.array([b for part, _ in calls for b in part]).reshape(-1, 2)
    skipped = sum(k for _, k in calls)
    middle = found.mean(axis=1)
    width = np.abs(found[:, 1] - found[:, 0])
    narrow = width <= BRACKET * middle
    if not narrow.any():
        wide = f", none of them bracketing mu_s within {BRACKET:.0%}" if len(found) else ""
        return None, (
            f"mu_s left out: no usable breakaway (of {skipped + len(found)} stuck phases of at least {MIN_STUCK} "
            f"samples, {len(found)} ended in a slip that held for {EDGE} samples at a load of at least "
            f"{LOAD_FRACTION} of the typical stuck one{wide})"
        )
    middle, weight = middle[narrow], 1.0 / np.maximum(width[narrow], 1e-3 * middle[narrow])
    order = np.argsort(middle)
    value = float(middle[order][np.searchsorted(np.cumsum(weight[order]), 0.5 * weight.sum())])
    said = (
        f"mu_s = {value:.4g} from {len(middle)} breakaways (the median of their brackets' midpoints, each "
        f"weighted by its inverse width; midpoints {middle.min():.4g} to {middle.max():.4g}; "
        f"{len(found) - len(middle)} breakaways bracketing it less closely than {BRACKET:.0%} and "
        f"{skipped} stuck phases without a usable breakaway left out)"
    )
    return value, said
