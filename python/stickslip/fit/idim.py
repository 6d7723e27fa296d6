"""The equation-error stage (Gautier's inverse dynamic identification model, IDIM-LS):
friction, drive and rotor parameters from the measured motion and torques themselves, without
a simulation.

Along each experiment whose spring-driven joints' positions q are all measured (flexible and
motor drives; a motor joint's q may come from its motor encoder, θ_m/N):

1. q, q̇, q̈ of those joints through the experiment's derivative filter
   (:func:`stickslip.fit.filtering.derivatives` with ``experiment.derivatives``; the default
   a quintic Savitzky-Golay over 19 samples, :mod:`stickslip.fit.filtering` says why); the
   rigid joints' are their commands (exact, or through the filter where the experiment's
   ``filtered_inputs`` says the column is a measurement). Every measured torque the equations
   compare with them goes through the same filter (parallel filtering: both sides of an
   equation see one filter): a motor torque τ_m[i] of the inputs (its logged samples), a
   measured F_drive[i] or tau_load[i].
2. The engine's own inverse dynamics and joint reactions at those states, from the FMU's
   own binary for this platform (its export ``stickslip_inverse_dynamics``, called with
   ctypes, on the FMU's ``resources/model.toml``; :func:`inverse_dynamics`): per joint the
   generalized force τ_s (3.9) and the friction's lever load L_s, such that the Coulomb
   part is μ·L_s ((3.11)-(3.15)). With the link's friction
   f_s = [μ_k (1 − e) + μ_s e] L_s sgn q̇_s + b_v q̇_s (e = exp(−|q̇_s|/v_s), 0 for v_s = 0),
   the drive's force on the link is F_s = τ_s + f_s while the joint slips.
3. Per joint, the equations its data give, each linear in the parameters it contains (those
   estimated are the unknowns, the others fixed at their known or initial values):

   * a flexible drive without a measured force: its slip equation (3.9)-(3.10) read
     backwards, τ_s = k_s (q*_s − q_s − σΔ_s) δ + h_s (q̇*_s − q̇_s) − f_s: k, h, μ_k, μ_s
     (v_s > 0), b_v;
   * a measured drive force F_drive[s] (rigid, flexible or motor drive; a motor's tau_load[s]
     as F = N·tau_load): F = τ_s + f_s: μ_k, μ_s (v_s > 0), b_v; and for a flexible drive
     F = k δ + h (q̇* − q̇) (a motor drive: with its rotor θ_m/N for q*, where theta_m[s] is
     measured): k, h;
   * a motor drive with its torque τ_m[s] an input (docs/motor_drives.md: J_m θ̈_m = τ_m − F/N
     − b_m θ̇_m − τ_f): with a measured force, the rotor alone, τ_m − F/N = J_m θ̈_m + b_m θ̇_m
     + τ_c sgn θ̇_m; without, the gear taken stiff (θ_m = N (q + F/k) ≈ N q),
     τ_m = J_m N q̈ + b_m N q̇ + τ_c sgn q̇ + (τ_s + f_s)/N: J_m, b_m, τ_c, μ_k, μ_s (v_s > 0),
     b_v. θ_m is the motor encoder where theta_m[s] is measured, else N (q + F/k) with a
     measured F, else N q. The gear ratio N is the FMU's gear_ratio[s] (a fixed parameter)
     unless the experiment's parameters give it.

   Rows are the samples where the joint (and a rotor, its rotor) slips with a certain
   direction: |q̇| above SLIP_SIGMAS standard deviations of the noise the filter leaves in q̇
   (the channel's sigma and count through :func:`stickslip.fit.filtering.noise_gains`), and
   above |q̈| times the filter's reach (near a reversal a filtered q̇ mixes both directions,
   so its sign is not the motion's); in the motor torque, only where the rotor turns the way
   its link does (a rotor vibrating on its gear against its link's motion feels a friction
   the stiff gear does not say: with the motor encoders measured, τ_c[3] of the motor arm was
   52 % off with those rows, 0.1 % without); the spring equations take every sample. The equations
   of a joint are solved together by linear least squares (:func:`solve_joint`), each
   weighted by the inverse of its residual rms. What the data cannot separate is said, not
   returned as numbers: two parameters whose columns are the same up to a factor (a link's
   b_v and its motor's b_m in the motor torque: b_m N q̇ against b_v q̇/N, the data fix
   b_m + b_v/N²; with tau_load measured the rotor's own equation separates them) leave the
   direction the data do not see at the initial values, with a note naming the combination
   they fix; an estimated link mass whose column (τ is affine in each mass) is collinear with
   an estimated parameter (J_m N² against the inertia of the link it turns) gets a note that
   the stage took the mass at its initial value; an estimate whose standard error exceeds
   its size is left out, with a note.
4. With v_s = 0, μ_s comes from the breakaways instead (:func:`breakaway_mu_s`): a stiction
   phase ends where |F − F*| reaches μ_s L (3.16), (3.18), F the drive's force (the spring's
   k δ + h (q̇* − q̇) with the stage's k and h, a measured force, or for a motor drive driven
   by τ_m, F = N (τ_m − J_m θ̈_m − b_m θ̇_m − τ_c s) with s the direction the link breaks away
   in: a rising torque winds the gear up by small slips of the rotor in that direction).
   F* and L are taken with the joint held (q̇_s = q̈_s = 0, as while it sticks), so that the
   filtered derivatives' noise does not enter them; per stuck phase that ends in a slip, the
   ratio |F − F*|/L at its last stuck samples bounds μ_s from below and at its first
   slipping samples from above. Only breakaways whose L is a sizeable part of the typical
   stuck load count (where L is small the ratio is noise over nearly nothing), and only
   those whose two bounds lie close (where the drive loads the joint fast the ratio moves a
   lot from one sample to the next); the median of their midpoints, each weighted by the
   inverse of its bracket's width, is the estimate. μ_s of either step is raised to μ_k
   where it is below (the FMU refuses μ_s < μ_k) and clipped into the estimate's bounds.

The result is a start for the output-error stage, not the estimate: filtered derivatives
bias it, a stiff drive's deflection is a small difference of two encoders, and a motor
drive's gear is taken stiff where its rotor is not measured (its vibration on the gear is
what the filter leaves out).
"""

from __future__ import annotations

import ctypes
import functools
import math
import platform
import re
import sys
import tomllib
from pathlib import Path

import numpy as np

from .filtering import default_filter, derivatives, noise_gains

LINEAR = ("k", "h", "mu_k", "mu_s", "b_v")  # parameters the slip equation is linear in
ROTOR = ("J_m", "b_m", "tau_c")  # a motor drive's rotor: its torque is linear in them
KINDS = LINEAR + ROTOR  # every parameter some equation of the stage is linear in
# A joint slips where its filtered |q̇| exceeds SLIP_SIGMAS standard deviations of the noise the
# filter leaves in q̇ (the encoder's noise and count through the filter's first derivative).
SLIP_SIGMAS = 6.5
# A direction of the scaled parameters (each column of unit norm) whose singular value is below
# COLLINEAR of the largest is one the data do not see: two columns alike to 0.1 %, below what the
# stage's own approximations (filtered derivatives, a stiff gear) leave of each column (a motor's
# b_m N θ̇_m against its link's b_v q̇/N: alike but for the gear's deflection rate, measured
# 4e-5 on the motor arm, where a 1e-6 rule returned b_v 42 times the truth). A parameter takes
# part in such a direction where its component exceeds INVOLVED.
COLLINEAR = 1e-3
INVOLVED = 0.05
# An estimated link mass is taken at its initial value; where 10 % more of it would move an
# estimate by more than MASS_SHIFT of itself, a note says so.
MASS_SHIFT = 0.01
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


def export(path: str, name: str, argtypes: list, what: str):
    """The function ``name`` beyond FMI of the FMU library at ``path`` with its C signature
    (``argtypes``, returning int), or :class:`StageUnavailable` saying why not: a library that
    does not load here, or one built before ``what`` was exported."""
    try:
        library = ctypes.CDLL(path)
    except OSError as e:
        raise StageUnavailable(f"{path} does not load on this machine ({platform.machine()}): {e}") from e
    try:
        function = getattr(library, name)
    except AttributeError:
        raise StageUnavailable(
            f"{Path(path).name} has no {name}: the FMU was built before {what}; rebuild it with this version "
            "(bash scripts/build_fmu.sh, or package_fmu)"
        ) from None
    function.argtypes = argtypes
    function.restype = ctypes.c_int
    return function


@functools.cache
def _engine(path: str):
    """The inverse-dynamics export of the library at ``path``."""
    double_p = ctypes.POINTER(ctypes.c_double)
    size = ctypes.c_size_t
    argtypes = [
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
    return export(path, EXPORT, argtypes, "the engine's inverse dynamics were exported")


def _model_source(unzipdir) -> tuple:
    """(model file text, text of the URDF it names or None) of the unpacked FMU."""
    resources = Path(unzipdir) / "resources"
    text = (resources / "model.toml").read_text(encoding="utf-8")
    try:
        urdf = tomllib.loads(text).get("urdf")
    except tomllib.TOMLDecodeError:
        urdf = None  # the engine says what is wrong with the file
    return text, (resources / urdf).read_text(encoding="utf-8") if isinstance(urdf, str) else None


def inverse_dynamics(unzipdir, states, settings=(), source=None) -> tuple:
    """(τ, L) at ``states`` (rows × [q(n), q̇(n), q̈(n)], SI units), both rows × n, by the
    engine in the unpacked FMU ``unzipdir``'s own binary: τ = M(q)·q̈ + bias(q, q̇) with
    gravity, L the lever load of each joint's friction (NaN for a joint without friction),
    on the FMU's model with ``settings`` (tunable parameters by FMU name, "m[3]=8.0")
    applied; ``source``: (model file text, URDF text or None) in place of the FMU's own model
    (an identified model, :mod:`stickslip.identify.model_file`). Raises
    :class:`StageUnavailable` where the binary cannot do it and :class:`InverseDynamicsError`
    with the engine's reason where it refuses the input."""
    engine = _engine(str(library_path(unzipdir)))
    states = np.ascontiguousarray(states, dtype=np.float64)
    if states.ndim != 2:
        raise InverseDynamicsError(f"states must be rows of q, qd, qdd, not an array of shape {states.shape}")
    rows, columns = states.shape
    n = columns // 3
    tau, load = np.full((rows, n), np.nan), np.full((rows, n), np.nan)
    text, urdf = _model_source(unzipdir) if source is None else source
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


def estimate(spec, unzipdir: str, flexible: list, initial: dict, start_values: dict, errors=None) -> tuple:
    """(θ dict of the estimated parameters this stage could estimate, notes). ``flexible``:
    the spring-driven joints (flexible and motor drives: those with a ``q_start`` parameter);
    ``initial``: the estimates' initial values; ``start_values``: the FMU's parameters' start
    values (the gear ratios among them). ``errors``: a dict that receives each estimate's
    standard error (the least squares' own, its residuals taken as independent; for μ_s of the
    breakaways, 1.4826 × the median absolute deviation of their midpoints over √n, or half
    the one bracket's width), and under (name, other name) the correlation of two estimates of
    one joint."""
    targets = {}
    for e in spec.estimates:
        j = joint_of(e.name)
        if j and j[0] in KINDS:
            targets.setdefault(j[1], []).append(j[0])
    if not targets:
        return {}, [
            "equation-error stage: no estimated parameter enters linearly an equation of this stage (a flexible "
            "joint's slip equation, a motor drive's torque, a measured drive force)"
        ]
    try:
        _engine(str(library_path(unzipdir)))
    except StageUnavailable as e:
        return {}, [f"equation-error stage could not run: {e}"]
    targets = {i: [x for x in KINDS if x in names] for i, names in sorted(targets.items())}
    estimated = {e.name: e for e in spec.estimates}
    masses = [e.name for e in spec.estimates if (joint_of(e.name) or ("",))[0] == "m"]
    notes = []
    equations = {i: {} for i in targets}  # joint -> equation -> [(A, y, mass columns) per experiment]
    mu_k_known = dict.fromkeys(targets, 0.0)  # the largest μ_k an experiment runs with: μ_s may not be below
    phases = {i: [] for i in targets}  # per joint and experiment: what the breakaways are read from
    lacking = {i: set() for i in targets}  # why a joint's parameters had no equation
    for ex in spec.experiments:
        made = _experiment(ex, unzipdir, flexible, initial, start_values, targets, masses, notes)
        if made is None:
            continue
        for i, (found, phase, why) in made.items():
            for label, part in found.items():
                equations[i].setdefault(label, []).append(part)
            if phase is not None:
                phases[i].append(phase)
            lacking[i] |= why
        for i in targets:
            mu_k_known[i] = max(
                mu_k_known[i], float({**start_values, **initial, **ex.parameters}.get(f"mu_k[{i}]", 0.0))
            )
    theta = {}
    for i, names in targets.items():
        # μ_s of a v_s = 0 joint is read from the breakaways, not from an equation's rows.
        quiet = ("mu_s",) if phases[i] else ()
        values, said = solve_joint(i, names, equations[i], initial, masses, lacking[i], quiet, errors)
        notes.extend(said)
        theta.update(values)
        name = f"mu_s[{i}]"
        if name in estimated and name not in theta and phases[i]:
            # |F − F*|/L with the drive's k and h of the slip equation where it estimated them.
            ratios = [
                (np.abs(force(theta) - held) / load, load, speed, v_noise)
                for force, held, load, speed, v_noise in phases[i]
            ]
            spread = []
            value, note = breakaway_mu_s(ratios, spread)
            notes.append(f"equation-error stage: joint {i}: {note}")
            if value is not None:
                theta[name] = value
                if errors is not None and spread:
                    errors[name] = spread[0]
        if name in theta:  # of the slip equation (v_s > 0) or of the breakaways
            mu_k = theta.get(f"mu_k[{i}]", mu_k_known[i])
            value, said = admissible_mu_s(theta[name], mu_k, estimated[name].low, estimated[name].high)
            if said:
                notes.append(f"equation-error stage: joint {i}: {name} = {theta[name]:.4g} {said}")
            theta[name] = value
    return theta, notes


def _experiment(ex, unzipdir, flexible, initial, start_values, targets, masses, notes):
    """The rows one experiment gives each joint of ``targets``: {joint: ({equation: (A, y,
    mass columns)}, breakaway phase or None, reasons an equation was missing)}, or None
    (with a note) where the experiment cannot be used."""
    channels = {c.output: c for c in ex.channels}
    known = {**start_values, **initial, **ex.parameters}
    motors = [i for i in flexible if f"gear_ratio[{i}]" in known]
    missing = [i for i in flexible if f"q[{i}]" not in channels and not (i in motors and f"theta_m[{i}]" in channels)]
    if missing:
        notes.append(
            f"equation-error stage: experiment {ex.name!r} does not measure every flexible joint's q "
            f"(not {', '.join(f'q[{i}]' for i in missing)})"
        )
        return None
    flt = getattr(ex, "derivatives", None) or default_filter()
    t = np.asarray(ex.time, dtype=np.float64)
    rows_n = len(t)
    dt = float(np.median(np.diff(t)))
    gains = noise_gains(flt, dt, rows_n)
    reach = flt.reach(dt, rows_n)
    settings = _settings(known)
    cmd = np.array([np.concatenate([np.asarray(x, dtype=np.float64) for x in ex.motion(float(tk), 0.0)]) for tk in t])
    n = cmd.shape[1] // 3
    q, qd, qdd = cmd[:, :n].copy(), cmd[:, n : 2 * n].copy(), cmd[:, 2 * n :].copy()
    speed_noise = dict.fromkeys(range(1, n + 1), 0.0)  # the standard deviation of each joint's filtered q̇
    rotor_encoder = []
    for i in flexible:
        if f"q[{i}]" in channels:
            c = channels[f"q[{i}]"]
            q[:, i - 1], qd[:, i - 1], qdd[:, i - 1] = derivatives(t, c.values, flt)
            speed_noise[i] = gains[1] * c.std
        else:  # a motor joint read by its motor encoder, θ_m/N: the gear's deflection F/k left out
            c, ratio = channels[f"theta_m[{i}]"], float(known[f"gear_ratio[{i}]"])
            q[:, i - 1], qd[:, i - 1], qdd[:, i - 1] = derivatives(t, c.values / ratio, flt)
            speed_noise[i] = gains[1] * c.std / ratio
            rotor_encoder.append(i)
    if rotor_encoder:
        notes.append(
            f"equation-error stage: experiment {ex.name!r}: joints {rotor_encoder} from their motor encoders "
            "(q = theta_m/N: the gear's deflection left out)"
        )
    filtered_inputs = list(getattr(ex, "filtered_inputs", []) or [])
    # Joints whose q, q̇, q̈ are exact commands, never through the filter.
    exact = [j for j in range(1, n + 1) if j not in flexible and f"q_star[{j}]" not in filtered_inputs]
    for name in filtered_inputs:
        j = int(name[name.index("[") + 1 : -1])
        if j not in flexible:  # a rigid joint's measured position, through the filter already
            inner = getattr(ex.motion, "inner", None)
            raw = np.array([inner(float(tk), 0.0)[0][j - 1] for tk in t]) if inner is not None else q[:, j - 1]
            speed_noise[j] = gains[1] * white_noise(raw)
    states = np.hstack([q, qd, qdd])
    try:
        tau_all, load_all = inverse_dynamics(unzipdir, states, settings)
        per_mass = {}
        for name in masses:  # τ is affine in each link's mass: its column, exactly
            mass = float(known[name])
            step = 0.5 * mass if mass > 0 else 1.0
            shifted = [s for s in settings if not s.startswith(f"{name}=")] + [f"{name}={mass + step!r}"]
            per_mass[name] = (inverse_dynamics(unzipdir, states, shifted)[0] - tau_all) / step
    except InverseDynamicsError as e:
        raise InverseDynamicsError(f"experiment {ex.name!r}: {e}") from None
    torques = {}
    if getattr(ex, "torques", None) is not None:
        logged = np.asarray(ex.torques(t)[0], dtype=np.float64).reshape(rows_n, -1)
        for k, name in enumerate(ex.torques.names):
            torques[int(name[name.index("[") + 1 : -1])] = logged[:, k]
    made = {}
    for i, names in targets.items():
        s = i - 1
        if i > n:
            made[i] = ({}, None, {f"the FMU has no joint {i}"})
            continue
        motor = i in motors
        ratio = float(known.get(f"gear_ratio[{i}]", 1.0))
        value = {x: float(known.get(f"{x}[{i}]", 0.0)) for x in KINDS}
        v, tau, load = qd[:, s], tau_all[:, s], load_all[:, s]
        vs = float(known.get(f"v_s[{i}]", 0.0))
        e = np.exp(-np.abs(v) / vs) if vs > 0 else np.zeros_like(v)
        sgn = np.sign(v)
        friction = {}
        if not np.isnan(load).all():
            friction = {"mu_k": load * sgn * (1.0 - e), "mu_s": load * sgn * e, "b_v": v}
            if vs <= 0:
                friction.pop("mu_s")
        slip = _certain(v, qdd[:, s], SLIP_SIGMAS * speed_noise[i], reach)
        everywhere = np.ones(rows_n, dtype=bool)
        # The drive's force on the link, where it is measured: F_drive, or a motor's gear torque F/N.
        force, force_label = None, ""
        if f"F_drive[{i}]" in channels:
            force, force_label = channels[f"F_drive[{i}]"].values, f"F_drive[{i}]"
        elif motor and f"tau_load[{i}]" in channels:
            force, force_label = ratio * channels[f"tau_load[{i}]"].values, f"tau_load[{i}]"
        force_f = derivatives(t, force, flt) if force is not None else None  # the same filter as q (parallel)
        found = []  # (equation, features, y before the fixed parameters, rows, coefficient of τ in y)
        why = set()
        phase = None
        held = None  # τ and L with the joint held (q̇ = q̈ = 0), for the breakaways
        if "mu_s" in names and vs <= 0 and (i in flexible) and friction:
            held_qd, held_qdd = qd.copy(), qdd.copy()
            held_qd[:, s] = 0.0
            held_qdd[:, s] = 0.0
            h_tau, h_load = inverse_dynamics(unzipdir, np.hstack([q, held_qd, held_qdd]), settings)
            held = (h_tau[:, s], h_load[:, s], np.abs(v), SLIP_SIGMAS * speed_noise[i])
        if i in flexible and not motor:
            stretch = cmd[:, s] - q[:, s]
            delta = float(known.get(f"Delta[{i}]", 0.0))
            engaged = np.abs(stretch) >= delta
            deflection = np.where(engaged, stretch - np.sign(stretch) * delta, 0.0)
            rate = cmd[:, n + s] - qd[:, s]
            if force is None:
                features = {"k": deflection, "h": rate, **{x: -c for x, c in friction.items()}}
                found.append(("slip equation", features, tau, slip, 1.0))
                if held is not None:
                    phase = (_spring_force(i, value, deflection, rate), *held)
            else:
                found.append(("gear spring", {"k": deflection, "h": rate}, force_f[0], everywhere, 0.0))
        if force is not None and friction:
            if i in exact:  # its motion was never filtered: τ and f through the force's filter too
                parallel = {x: derivatives(t, c, flt)[0] for x, c in friction.items()}
                found.append(
                    (f"{force_label} = tau + friction", parallel, force_f[0] - derivatives(t, tau, flt)[0], slip, -1.0)
                )
            else:
                found.append((f"{force_label} = tau + friction", friction, force_f[0] - tau, slip, -1.0))
            if held is not None and phase is None:
                phase = (_measured_force(force_f[0]), *held)
        elif force is not None:
            why.add(f"joint {i} has no friction")
        if motor:
            if f"theta_m[{i}]" in channels:  # the motor encoder
                c = channels[f"theta_m[{i}]"]
                rotor = derivatives(t, c.values, flt)
                rotor_noise = gains[1] * c.std
                if force is not None and i not in rotor_encoder:
                    stretch = rotor[0] / ratio - q[:, s]
                    delta = float(known.get(f"Delta[{i}]", 0.0))
                    engaged = np.abs(stretch) >= delta
                    deflection = np.where(engaged, stretch - np.sign(stretch) * delta, 0.0)
                    rate = rotor[1] / ratio - qd[:, s]
                    found.append(("gear spring", {"k": deflection, "h": rate}, force_f[0], everywhere, 0.0))
            elif force is not None:  # θ_m = N (q + F/k): the gear's deflection from the measured force
                stiffness = value["k"] if value["k"] > 0 else math.inf
                rotor = tuple(
                    ratio * (x + f / stiffness) for x, f in zip((q[:, s], v, qdd[:, s]), force_f, strict=True)
                )
                rotor_noise = ratio * speed_noise[i]
            else:  # θ_m = N (q + F/k), F = τ + f at the known (or initial) friction, through the filter
                stiffness = value["k"] if value["k"] > 0 else math.inf
                load_force = tau + sum((c * value[x] for x, c in friction.items()), np.zeros(rows_n))
                wind = derivatives(t, load_force, flt) if math.isfinite(stiffness) else (0.0, 0.0, 0.0)
                rotor = tuple(ratio * (x + f / stiffness) for x, f in zip((q[:, s], v, qdd[:, s]), wind, strict=True))
                rotor_noise = ratio * speed_noise[i]
            spin = _certain(rotor[1], rotor[2], SLIP_SIGMAS * rotor_noise, reach)
            rotor_features = {"J_m": rotor[2], "b_m": rotor[1], "tau_c": np.sign(rotor[1])}
            if i in torques:
                applied = derivatives(t, torques[i], flt)[0]  # the same filter as q (parallel filtering)
                if force is not None:
                    found.append(
                        (f"rotor (tau_m[{i}] - {force_label})", rotor_features, applied - force_f[0] / ratio, spin, 0.0)
                    )
                else:
                    features = {**rotor_features, **{x: c / ratio for x, c in friction.items()}}
                    found.append(
                        (
                            f"motor torque tau_m[{i}]",
                            features,
                            applied - tau / ratio,
                            slip & spin & (np.sign(rotor[1]) == sgn),
                            -1.0 / ratio,
                        )
                    )
                    if held is not None:
                        phase = (_rotor_force(i, value, ratio, applied, rotor, _coming(v, slip)), *held)
            else:
                why.add(f"tau_m[{i}] is not an input of experiment {ex.name!r}")
        if force is None and not (i in flexible and not motor):
            why.add(f"no F_drive[{i}]{f' or tau_load[{i}]' if motor else ''} measured in experiment {ex.name!r}")
        if held is not None and phase is None:
            why.add(
                f"mu_s[{i}] from breakaways needs the drive force: the spring of a flexible drive, F_drive[{i}] or "
                f"tau_load[{i}] measured, or tau_m[{i}] an input"
            )
        parts = {}
        for label, features, y0, rows, coefficient in found:
            y = y0 - sum((features[x] * value[x] for x in features if x not in names), np.zeros(rows_n))
            A = np.column_stack([features.get(x, np.zeros(rows_n)) for x in names])
            M = np.column_stack([coefficient * per_mass[m][:, s] for m in masses]) if masses else np.zeros((rows_n, 0))
            keep = rows & np.all(np.isfinite(A), axis=1) & np.isfinite(y)
            parts[label] = (A[keep], y[keep], M[keep])
        made[i] = (parts, phase, why)
    return made


def _certain(rate, accel, noise: float, reach: float):
    """The samples whose filtered ``rate`` has a certain sign: above ``noise`` (a multiple of
    the filtered rate's noise) and above what ``accel`` changes it by within the filter's
    ``reach`` (near a reversal the filter mixes both directions, and sgn of the filtered rate
    is not the rate's)."""
    top = float(np.max(np.abs(rate), initial=0.0))
    return (np.abs(rate) > max(noise, 1e-12 * top)) & (np.abs(rate) > np.abs(accel) * reach)


def _spring_force(i, value, deflection, rate):
    """F = k δ + h (q̇* − q̇) with the stage's k and h where it estimated them."""

    def force(theta):
        return theta.get(f"k[{i}]", value["k"]) * deflection + theta.get(f"h[{i}]", value["h"]) * rate

    return force


def _rotor_force(i, value, ratio, applied, rotor, direction):
    """The gear's force on the link from the rotor's equation, F = N (τ_m − J_m θ̈_m − b_m θ̇_m
    − τ_c s), with the stage's J_m, b_m, τ_c where it estimated them: while the link sticks,
    a rising torque winds the gear up by small slips of the rotor in the direction s the link
    will break away in, each ending where the rotor's friction is at its kinetic level."""

    def force(theta):
        rotor_torque = (
            theta.get(f"J_m[{i}]", value["J_m"]) * rotor[2]
            + theta.get(f"b_m[{i}]", value["b_m"]) * rotor[1]
            + theta.get(f"tau_c[{i}]", value["tau_c"]) * direction
        )
        return ratio * (applied - rotor_torque)

    return force


def _coming(rate, moving):
    """Per sample the sign of ``rate`` at the next sample where ``moving`` (at a moving sample,
    its own; after the last one, the last one's)."""
    sign = np.where(moving, np.sign(rate), np.nan)
    index = np.where(moving, np.arange(len(rate)), len(rate))
    following = np.minimum.accumulate(index[::-1])[::-1]
    last = np.flatnonzero(moving)
    out = np.zeros(len(rate))
    if len(last):
        ahead = following < len(rate)
        out[ahead] = sign[following[ahead]]
        out[~ahead] = sign[last[-1]]
    return out


def _measured_force(force):
    return lambda theta: force


def _settings(known: dict) -> list:
    """The settings "m[3]=8.0" of the rigid-body parameters (masses, contact geometry)."""
    return [f"{k}={float(v)!r}" for k, v in known.items() if (joint_of(k) or ("",))[0] in RIGID_BODY]


def white_noise(values) -> float:
    """The standard deviation of white noise on samples of a smooth signal: the rms of their
    fourth differences over sqrt(70)."""
    y = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(np.diff(y, 4) ** 2) / 70.0)) if len(y) > 8 else 0.0


def solve_joint(
    i: int, names: list, equations: dict, initial: dict, masses: list, lacking=(), quiet=(), errors=None
) -> tuple:
    """({name: value} of joint i's parameters ``names`` (kinds, "mu_k", ...) the rows of
    ``equations`` ({equation: [(A, y, mass columns) per experiment]}) determine, notes).

    Each equation's rows are weighted by the inverse of its residual rms (its own units and
    noise; three passes, the first weighted by the inverse rms of y); the columns are scaled
    to unit norm. A direction of the parameters whose relative singular value is below
    :data:`COLLINEAR` is one the data do not see (two columns the same up to a factor, as a
    link's b_v and a motor's b_m·N² in the motor's torque): it is left at the initial
    values (the least-squares solution with the least change from them) and a note says which
    combination the data fix. Columns of estimated masses (τ is affine in each link's mass)
    are checked the same way: a parameter collinear with one (a rotor's J_m·N² and the
    inertia of the link it turns) is estimated with the mass at its initial value, and a
    note says so. An estimate whose standard error (from the residuals, as if independent)
    exceeds its size is left out. ``quiet``: kinds that no row may see without a note (μ_s
    read from the breakaways)."""
    said = []
    head = f"equation-error stage: joint {i}:"
    full = [f"{x}[{i}]" for x in names]
    if not equations:
        need = "; ".join(sorted(lacking)) or "no equation of this stage has data for it"
        return {}, [f"{head} {', '.join(full)} not estimated ({need})"]
    blocks = {
        label: tuple(np.concatenate([p[k] for p in parts]) if parts else None for k in range(3))
        for label, parts in equations.items()
    }
    blocks = {label: b for label, b in blocks.items() if len(b[1])}
    counts = {label: len(b[1]) for label, b in blocks.items()}
    total = sum(counts.values())
    if total < 3 * len(names):
        return {}, [f"{head} {total} samples, too few for {names}"]
    seen = np.zeros(len(names), dtype=bool)
    for A, _, _ in blocks.values():
        seen |= np.any(A != 0.0, axis=0)
    unseen = [full[j] for j in np.flatnonzero(~seen) if names[j] not in quiet]
    if unseen:
        need = f" ({'; '.join(sorted(lacking))})" if lacking else ""
        said.append(f"{head} {', '.join(unseen)} enter(s) no equation these data give{need}: left out")
    names = [x for x, s in zip(names, seen, strict=True) if s]
    full = [f"{x}[{i}]" for x in names]
    if not names:
        return {}, said
    blocks = {label: (A[:, seen], y, M) for label, (A, y, M) in blocks.items()}
    theta0 = np.array([initial.get(f, 0.0) for f in full], dtype=np.float64)
    weight = {label: 1.0 / _rms(y) for label, (_, y, _) in blocks.items()}
    for k in range(3):
        A = np.vstack([weight[label] * b[0] for label, b in blocks.items()])
        y = np.concatenate([weight[label] * b[1] for label, b in blocks.items()])
        covariance = []
        sol, se, null, scale = truncated_lstsq(A, y, theta0, _series(blocks, equations), covariance)
        if k < 2:
            weight = {label: 1.0 / _rms(yb - Ab @ sol) for label, (Ab, yb, _) in blocks.items()}
    for direction in null:
        said.append(f"{head} {_combination(direction, scale, full, sol)}")
    if masses and len(blocks):
        said.extend(
            _mass_notes(
                head, A, y, np.vstack([weight[label] * b[2] for label, b in blocks.items()]), full, sol, masses, initial
            )
        )
    residual = {label: _rms(yb - Ab @ sol) for label, (Ab, yb, _) in blocks.items()}
    values = {}
    shown = []
    unseen = {full[j] for direction in null for j in range(len(full)) if abs(direction[j]) > INVOLVED}
    if errors is not None and covariance:
        cov = covariance[0]
        sd = np.sqrt(np.abs(np.diag(cov)))
        for a in range(len(full)):
            for b in range(len(full)):
                if a != b and sd[a] > 0 and sd[b] > 0:
                    errors[(full[a], full[b])] = float(cov[a, b] / (sd[a] * sd[b]))
    for name, x, e in zip(full, sol, se, strict=True):
        if name in unseen:
            values[name] = float(x)
            shown.append(f"{name} = {x:.6g} (not apart from another, below)")
            continue
        if not (np.isfinite(x) and np.isfinite(e)) or e > abs(x):
            said.append(
                f"{head} {name} = {x:.4g} with a standard error of {e:.2g}: not determined by these data, left out"
            )
            continue
        values[name] = float(x)
        if errors is not None:
            errors[name] = float(e)
        shown.append(f"{name} = {x:.6g} (standard error {e:.2g})")
    equations_said = ", ".join(f"{label} over {counts[label]} samples" for label in blocks)
    rms = ", ".join(f"{residual[label]:.3g}" + (f" ({label})" if len(blocks) > 1 else "") for label in blocks)
    said.insert(
        0,
        f"{head} {equations_said}"
        + (" (each weighted by the inverse of its residual rms)" if len(blocks) > 1 else "")
        + (": " + ", ".join(shown) if shown else "")
        + f", residual rms {rms}",
    )
    return values, said


def _mass_notes(head: str, A, y, M, full: list, sol, masses: list, initial: dict) -> list:
    """What the estimated link masses ``masses`` (taken at their initial values by this
    stage; their columns M of τ, per kg) do to joint's estimates: a direction the data do not
    see that joins a parameter and a mass (J_m N² and the inertia the mass gives the joint,
    where the motion leaves that inertia constant), and each estimate that a 10 % error of a
    mass moves by more than MASS_SHIFT of itself."""
    said = []
    columns = [k for k in range(M.shape[1]) if np.any(M[:, k] != 0.0)]
    if not columns:
        return said
    M = M[:, columns]
    names = [masses[k] for k in columns]
    _, _, both, scale = truncated_lstsq(np.hstack([A, M]), y, np.zeros(A.shape[1] + M.shape[1]))
    for direction in both:
        if np.any(np.abs(direction[len(full) :]) > INVOLVED) and np.any(np.abs(direction[: len(full)]) > INVOLVED):
            text = _combination(direction, scale, full + names, None)
            said.append(f"{head} {text}; this stage takes the masses at their initial values")
    for k, mass in enumerate(names):
        step = 0.1 * abs(float(initial.get(mass, 0.0)))
        shift = truncated_lstsq(A, M[:, k] * step, np.zeros(A.shape[1]))[0]
        moved = [
            f"{name} by {100 * d / x:+.2g} %"
            for name, d, x in zip(full, shift, sol, strict=True)
            if x != 0 and abs(d) > MASS_SHIFT * abs(x)
        ]
        if moved:
            said.append(
                f"{head} this stage takes {mass} at its initial value {initial.get(mass, 0.0):g}; 10 % more of it "
                f"would move {', '.join(moved)}"
            )
    return said


def _series(blocks: dict, equations: dict) -> list:
    """(start, stop) rows of each experiment's rows of each equation, in the order the
    equations' blocks are stacked (the rows of one experiment follow in time)."""
    out, offset = [], 0
    for label in blocks:
        for part in equations[label]:
            n = len(part[1])
            if n:
                out.append((offset, offset + n))
                offset += n
    return out


def _rms(y) -> float:
    value = float(np.sqrt(np.mean(np.square(y)))) if len(y) else 0.0
    return value if value > 0 else 1.0


def truncated_lstsq(A, y, theta0, blocks=None, covariance: list | None = None) -> tuple:
    """(θ, standard errors, unseen directions, column norms) of y ≈ A θ: the columns scaled to
    unit norm, the singular directions of relative size below COLLINEAR left at ``theta0``
    (the solution of least change from it); the unseen directions as unit vectors in the
    scaled coordinates (θ_j times column j's norm). Standard errors from the residuals' rms;
    with ``blocks`` (the (start, stop) rows of each time series among the rows), the larger of
    that and a Newey-West sandwich (:func:`stickslip.fit.uncertainty.long_run_covariance`):
    rows of filtered signals are correlated over the filter's reach, and independent-residual
    errors then come out several times too small. ``covariance``: a list that receives θ's
    covariance at those standard errors (with the sandwich's correlations)."""
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    As = A / scale
    U, S, Vt = np.linalg.svd(As, full_matrices=False)
    keep = S > COLLINEAR * (S[0] if len(S) else 0.0)
    z0 = theta0 * scale
    coef = (U[:, keep].T @ (y - As @ z0)) / S[keep]
    z = z0 + Vt[keep].T @ coef
    residual = y - As @ z
    dof = max(len(y) - int(keep.sum()), 1)
    s2 = float(residual @ residual) / dof
    inverse = (Vt[keep].T / S[keep] ** 2) @ Vt[keep]
    cov = s2 * inverse
    if blocks is not None:
        from .uncertainty import long_run_covariance

        meat, _ = long_run_covariance(As, residual, blocks)
        sandwich = inverse @ meat @ inverse
        se = np.maximum(np.sqrt(np.abs(np.diag(cov))), np.sqrt(np.abs(np.diag(sandwich))))
        with np.errstate(invalid="ignore", divide="ignore"):
            corr = sandwich / np.outer(np.sqrt(np.diag(sandwich)), np.sqrt(np.diag(sandwich)))
        corr = np.where(np.isfinite(corr), corr, 0.0)
        cov = corr * np.outer(se, se)
    if covariance is not None:
        covariance.append(cov / np.outer(scale, scale))
    return z / scale, np.sqrt(np.abs(np.diag(cov))) / scale, list(Vt[~keep]), scale


def _combination(direction, scale, names, theta) -> str:
    """What the data fix where the direction ``direction`` (scaled coordinates) is unseen."""
    involved = [j for j in range(len(names)) if abs(direction[j]) > INVOLVED]
    if len(involved) == 2:
        a, b = involved
        # Seen: the combination orthogonal to the unseen one, θ_a + r θ_b.
        r = -(direction[a] * scale[b]) / (direction[b] * scale[a])
        combination = f"{names[a]} {'+' if r >= 0 else '-'} {abs(r):.4g}·{names[b]}"
        value = f" = {theta[a] + r * theta[b]:.6g}" if theta is not None else ""
        return (
            f"{names[a]} and {names[b]} enter the equations as one column: the data fix {combination}{value}, "
            "not each"
            + (
                " (the estimate keeps their initial values' part along the direction the data do not see)"
                if theta is not None
                else ""
            )
        )
    unseen = " ".join(f"{direction[j] / scale[j]:+.3g}·{names[j]}" for j in involved)
    return (
        f"{', '.join(names[j] for j in involved)} are collinear in the equations: the data do not see the "
        f"direction {unseen}" + (" (the estimate keeps the initial values along it)" if theta is not None else "")
    )


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


def breakaway_mu_s(experiments: list, spread: list | None = None) -> tuple:
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
    if spread is not None:  # its standard error: the midpoints' robust spread, or the one bracket's
        one = 0.5 * float(width[narrow][0])
        spread.append(
            float(1.4826 * np.median(np.abs(middle - value)) / np.sqrt(len(middle))) if len(middle) > 1 else one
        )
    said = (
        f"mu_s = {value:.4g} from {len(middle)} breakaways (the median of their brackets' midpoints, each "
        f"weighted by its inverse width; midpoints {middle.min():.4g} to {middle.max():.4g}; "
        f"{len(found) - len(middle)} breakaways bracketing it less closely than {BRACKET:.0%} and "
        f"{skipped} stuck phases without a usable breakaway left out)"
    )
    return value, said
