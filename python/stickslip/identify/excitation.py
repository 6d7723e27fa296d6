"""Excitation trajectories: a periodic motion whose joint torques fix the base parameters as
well as the joints' limits allow (Swevers, Ganseman, Tükel, De Schutter and Van Brussel,
"Optimal robot excitation and identification", IEEE Trans. Robotics and Automation 13(5), 1997).

Each joint i follows a finite Fourier series of fundamental ω_f = 2π/T and L harmonics:

    q_i(t)   = q0_i + Σ_l [a_il/(ω_f l) sin(ω_f l t) − b_il/(ω_f l) cos(ω_f l t)],
    q̇_i(t)  =        Σ_l [a_il cos(ω_f l t) + b_il sin(ω_f l t)],
    q̈_i(t)  = ω_f    Σ_l l [−a_il sin(ω_f l t) + b_il cos(ω_f l t)].

It is periodic, so a run of several periods can be averaged period by period (noise down by √P,
and the derivatives of the averaged q without a filter's lag). It starts and ends at rest:
q̇_i(0) = Σ_l a_il = 0 and q̈_i(0) = ω_f Σ_l l b_il = 0, and by the period the same at t = kT.
Both are imposed by eliminating the first harmonic, a_i1 = −Σ_{l≥2} a_il and
b_i1 = −Σ_{l≥2} l b_il (:func:`rest_map`): the free parameters are q0_i and a_il, b_il for
l = 2..L, 2L − 1 per joint (L ≥ 2: one harmonic at rest is no motion).

The criterion (:class:`Criterion`) is the condition number of the base regressor W_b
(:mod:`stickslip.identify.base`: of the full regressor's 10n columns only the identifiable ones,
else it is infinite) stacked at ``samples`` instants kT/N of one period, from the engine's own
joint-torque regressor in the FMU's binary (:func:`stickslip.fit.regressor.joint_torque_regressor`);
with ``friction``, two columns more per joint, q̇_i and sign(q̇_i) in joint i's rows (viscous and
Coulomb friction). Rows are the joint torques as they are (N·m, N for a prismatic joint),
unweighted. Each column is scaled to unit 2-norm before the singular values are taken: the
condition number then does not depend on the parameters' units (kg against kg·m²) and is within
√p of the smallest any column scaling gives (van der Sluis, 1969), so the optimizer improves
what the motion separates, not a choice of units.

The limits are linear in the free parameters, q, q̇, q̈ being linear in them, and are imposed at
M = 20·L instants of one period with every limit tightened by ε = (πL/M)² = (π/20)² (2.5 %),
so that they hold at every t: near its extreme a trigonometric polynomial p of degree L falls by
at most ½ (ω_f L)² max|p − p̄| h² within h (Bernstein's inequality for p''), and the nearest
instant is h ≤ T/(2M) away; that is ε/2 of the extreme for q̇ and q̈ (mean zero) and ε of the
half range for q (whose mean q0 lies in its range). :func:`design` minimizes log10 of the
condition number from ``starts`` seeded random starts by SLSQP (scipy.optimize.minimize) under
those linear constraints, its gradient from the extreme singular vectors and one batched call of
the engine (:meth:`Criterion.log_condition_gradient`). Each start is the *naive* trajectory: the same
harmonics with standard-normal coefficients, centred in the position range and scaled until its
tightest limit is reached; its condition number is reported for comparison.
"""

from __future__ import annotations

import json
import math
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .base import base_parameters, random_states

DEFAULT_PERIOD = 10.0  # T, s
DEFAULT_HARMONICS = 5  # L
# Defaults below the reference motion's peaks (1.4 rad/s, 2.9 rad/s² on joint 1), in the joint's
# unit (rad, or m for a prismatic joint); a URDF's <limit velocity> lowers the velocity's.
DEFAULT_VMAX = 1.0  # rad/s
DEFAULT_AMAX = 3.0  # rad/s²
DEFAULT_SAMPLES = 200  # N, instants of one period the criterion stacks
DEFAULT_STARTS = 8
DEFAULT_RATE = 1000.0  # samples per second of the motion file, Hz
DEFAULT_PERIODS = 5  # periods the motion file runs
# M = 20·L instants for the limits, margin ε = (π/20)² = 2.5 %: with 40·L (0.6 %) SLSQP took
# twice as long on its 6·n·M constraints for a condition number 3 % lower (the reference arm).
GRID_PER_HARMONIC = 20
BASE_STATES = 300  # random states the base parameters are found at (identify.base)
MAX_ITERATIONS = 100  # SLSQP iterations per start
STEP = 1e-6  # forward-difference step of the gradient in each state component (rad, rad/s, rad/s²; m, ...)
ROUNDING = 1e-12  # a regressor column below this fraction of the largest is rounding: no torque
STEM = "excitation"  # DIR/excitation.toml, .csv, .json


class ExcitationError(ValueError):
    """An excitation that cannot be designed as asked: the message names the argument or the
    joint and what is wrong."""


# ---------------------------------------------------------------------------
# the trajectory


def rest_map(harmonics: int) -> np.ndarray:
    """E, (1 + 2L) × (2L − 1): the coefficients [q0, a_1..a_L, b_1..b_L] of one joint from its free
    parameters [q0, a_2..a_L, b_2..b_L], with a_1 = −Σ_{l≥2} a_l (q̇(0) = 0) and
    b_1 = −Σ_{l≥2} l b_l (q̈(0) = 0)."""
    L = harmonics
    E = np.zeros((1 + 2 * L, 2 * L - 1))
    E[0, 0] = 1.0
    for harmonic in range(2, L + 1):
        za, zb = harmonic - 1, L + harmonic - 2  # the free a_l, b_l
        E[harmonic, za], E[1, za] = 1.0, -1.0
        E[L + harmonic, zb], E[L + 1, zb] = 1.0, -float(harmonic)
    return E


def basis(t, period: float, harmonics: int) -> tuple:
    """(Φ_q, Φ_q̇, Φ_q̈), each len(t) × (1 + 2L): q(t) = Φ_q c for one joint's coefficients
    c = [q0, a_1..a_L, b_1..b_L] (the series of the module's docstring), likewise q̇ and q̈."""
    t = np.asarray(t, dtype=np.float64).reshape(-1, 1)
    w = 2.0 * math.pi / period
    wl = w * np.arange(1, harmonics + 1)
    s, c = np.sin(wl * t), np.cos(wl * t)
    one, zero = np.ones_like(t), np.zeros_like(t)
    return (
        np.hstack([one, s / wl, -c / wl]),
        np.hstack([zero, c, s]),
        np.hstack([zero, -wl * s, wl * c]),
    )


@dataclass(frozen=True)
class Fourier:
    """The trajectory of n joints: q0 (n), a and b (n × L, rad/s or m/s), period T (s)."""

    period: float
    q0: np.ndarray
    a: np.ndarray
    b: np.ndarray

    @property
    def harmonics(self) -> int:
        return self.a.shape[1]

    @classmethod
    def of_free(cls, z, period: float, harmonics: int) -> Fourier:
        """The trajectory of the free parameters ``z`` (n × (2L − 1), rows [q0, a_2..a_L, b_2..b_L])."""
        c = np.asarray(z, dtype=np.float64) @ rest_map(harmonics).T
        L = harmonics
        return cls(period, c[:, 0].copy(), c[:, 1 : L + 1].copy(), c[:, L + 1 :].copy())

    def coefficients(self) -> np.ndarray:
        """n × (1 + 2L): each joint's [q0, a_1..a_L, b_1..b_L]."""
        return np.hstack([self.q0[:, None], self.a, self.b])

    def at(self, t) -> tuple:
        """(q, q̇, q̈) at the instants ``t``, each len(t) × n."""
        c = self.coefficients()
        return tuple(phi @ c.T for phi in basis(t, self.period, self.harmonics))

    def states(self, t) -> np.ndarray:
        """len(t) rows of [q(n), q̇(n), q̈(n)], as the regressor takes them."""
        return np.hstack(self.at(t))


# ---------------------------------------------------------------------------
# limits


@dataclass(frozen=True)
class Limits:
    """Per joint (n each, the joint's unit: rad or m): q_min < q_max, |q̇| ≤ qd_max, |q̈| ≤ qdd_max;
    ``source`` says per joint where the position limits come from ("urdf" or "user")."""

    q_min: np.ndarray
    q_max: np.ndarray
    qd_max: np.ndarray
    qdd_max: np.ndarray
    source: tuple

    def as_dict(self) -> dict:
        return {
            "q_min": self.q_min.tolist(),
            "q_max": self.q_max.tolist(),
            "qd_max": self.qd_max.tolist(),
            "qdd_max": self.qdd_max.tolist(),
            "position_source": list(self.source),
        }


def urdf_limits(unzipdir, names: dict) -> dict:
    """{joint i: (lower, upper, velocity or None)} of the joints whose URDF ``<limit>`` gives
    lower and upper, read from the URDF the unpacked FMU's resources/model.toml names (its
    joints by their URDF names ``names``, {i: name}); empty for a model without a URDF."""
    resources = Path(unzipdir) / "resources"
    by_name = {}
    try:
        urdf = tomllib.loads((resources / "model.toml").read_text(encoding="utf-8")).get("urdf")
        if not isinstance(urdf, str):
            return {}
        for joint in ET.parse(resources / urdf).getroot().iter():
            limit = next((e for e in joint if e.tag.rpartition("}")[2] == "limit"), None)
            if joint.tag.rpartition("}")[2] != "joint" or limit is None:
                continue
            lower, upper, velocity = (limit.get(x) for x in ("lower", "upper", "velocity"))
            if joint.get("type") in ("revolute", "prismatic") and lower is not None and upper is not None:
                by_name[joint.get("name")] = (float(lower), float(upper), float(velocity) if velocity else None)
    except (OSError, ValueError, ET.ParseError) as e:
        raise ExcitationError(f"the FMU's model or its URDF cannot be read for the joints' limits: {e}") from None
    return {i: by_name[name] for i, name in names.items() if name in by_name}


def limits_of(n: int, model: dict, q_min=None, q_max=None, qd_max=None, qdd_max=None) -> Limits:
    """The limits of n joints: positions from ``model`` ({i: (lower, upper, velocity)},
    :func:`urdf_limits`) where the user gives none (``q_min``, ``q_max``: n values, None for
    the model's), velocities and accelerations from the user (n values) or the defaults (the
    velocity's at most the URDF's). A user's limit beyond the model's, a joint without either,
    and an empty or reversed range raise :class:`ExcitationError`."""
    low, high, vel, acc, source = [], [], [], [], []
    for i in range(1, n + 1):
        lower, upper, velocity = model.get(i, (None, None, None))
        lo = q_min[i - 1] if q_min is not None else None
        hi = q_max[i - 1] if q_max is not None else None
        if (lo is None) != (hi is None) and lower is None:
            raise ExcitationError(f"joint {i}: the model has no position limits: give both --qmin and --qmax")
        if lo is None and hi is None:
            if lower is None:
                raise ExcitationError(
                    f"joint {i}: the FMU's model gives no position limits (no URDF <limit>): give --qmin and --qmax, "
                    f"{n} values comma-separated (--qmin=-1,... with '=' for a leading minus)"
                )
            source.append("urdf")
        else:
            source.append("user" if lower is None else "user within urdf")
        lo = lower if lo is None else lo
        hi = upper if hi is None else hi
        if lower is not None and (lo < lower or hi > upper):
            raise ExcitationError(
                f"joint {i}: the range [{lo:g}, {hi:g}] goes beyond the URDF's limits [{lower:g}, {upper:g}]"
            )
        if not lo < hi:
            raise ExcitationError(f"joint {i}: the position range [{lo:g}, {hi:g}] is empty: need qmin < qmax")
        v = qd_max[i - 1] if qd_max is not None else min(DEFAULT_VMAX, velocity or math.inf)
        if velocity is not None and v > velocity:
            raise ExcitationError(f"joint {i}: --vmax {v:g} is beyond the URDF's velocity limit {velocity:g}")
        low.append(lo)
        high.append(hi)
        vel.append(v)
        acc.append(DEFAULT_AMAX if qdd_max is None else qdd_max[i - 1])
    for what, values in (("--vmax", vel), ("--amax", acc)):
        bad = [(i, x) for i, x in enumerate(values, 1) if not x > 0]
        if bad:
            raise ExcitationError(f"joint {bad[0][0]}: {what} {bad[0][1]:g}: must be positive")
    return Limits(*(np.array(x, dtype=np.float64) for x in (low, high, vel, acc)), tuple(source))


class Constraints:
    """The limits as linear inequalities G x ≤ h in the free parameters x (n × (2L − 1),
    flattened), at M = 20·L instants of one period, every limit tightened by ε = (π/20)² so
    that they hold between the instants too (the module's docstring)."""

    def __init__(self, limits: Limits, period: float, harmonics: int):
        M = GRID_PER_HARMONIC * harmonics
        self.margin = (math.pi / GRID_PER_HARMONIC) ** 2
        E = rest_map(harmonics)
        self.phi = [p @ E for p in basis(period * np.arange(M) / M, period, harmonics)]  # each M × (2L − 1)
        n, k = len(limits.q_min), 2 * harmonics - 1
        centre, half = (limits.q_max + limits.q_min) / 2, (limits.q_max - limits.q_min) / 2
        self.q_low, self.q_high = centre - half * (1 - self.margin), centre + half * (1 - self.margin)
        self.qd_max, self.qdd_max = limits.qd_max * (1 - self.margin), limits.qdd_max * (1 - self.margin)
        blocks, bounds = [], []
        for i in range(n):
            rows = np.vstack([self.phi[0], -self.phi[0], self.phi[1], -self.phi[1], self.phi[2], -self.phi[2]])
            G = np.zeros((rows.shape[0], n * k))
            G[:, i * k : (i + 1) * k] = rows
            blocks.append(G)
            bounds.append(
                np.repeat(
                    [self.q_high[i], -self.q_low[i], self.qd_max[i], self.qd_max[i], self.qdd_max[i], self.qdd_max[i]],
                    M,
                )
            )
        self.G, self.h = np.vstack(blocks), np.concatenate(bounds)

    def scaled_into(self, z, fill: bool = False) -> np.ndarray:
        """``z`` (n × (2L − 1)) with each joint's q0 clamped into its tightened range and its
        harmonics scaled about q0 until every limit holds (``fill``: also up, until the tightest
        one is reached)."""
        z = np.array(z, dtype=np.float64)
        for i in range(len(z)):
            z[i, 0] = np.clip(z[i, 0], self.q_low[i], self.q_high[i])
            moving = z[i].copy()
            moving[0] = 0.0
            q, qd, qdd = (p @ moving for p in self.phi)
            reach = max(
                q.max() / max(self.q_high[i] - z[i, 0], 1e-300),
                -q.min() / max(z[i, 0] - self.q_low[i], 1e-300),
                np.abs(qd).max() / self.qd_max[i],
                np.abs(qdd).max() / self.qdd_max[i],
            )
            if reach > 1.0 or (fill and reach > 0.0):
                z[i, 1:] /= reach
        return z


# ---------------------------------------------------------------------------
# the criterion


def regressor_of(unzipdir, states) -> tuple:
    """(W stacked rows·n × 10n, names) of the engine's joint-torque regressor at ``states``."""
    from ..fit.regressor import joint_torque_regressor

    Y, _, names = joint_torque_regressor(unzipdir, states)
    return Y.reshape(-1, Y.shape[2]), list(names)


class Criterion:
    """The condition number of the base regressor (with ``friction``: and the friction columns
    q̇_i, sign q̇_i of each joint), stacked at ``samples`` instants kT/N of one period, each
    column scaled to unit 2-norm (the module's docstring); as log10, with its gradient."""

    def __init__(self, unzipdir, n: int, limits: Limits, period: float, samples: int, friction: bool, seed: int):
        self.unzipdir, self.n, self.friction = unzipdir, n, friction
        self.times = period * np.arange(samples) / samples
        box = np.column_stack([limits.q_min, limits.q_max])
        W, names = regressor_of(unzipdir, random_states(n, BASE_STATES, seed, box))
        # base_parameters takes every column that is not exactly zero for a parameter; a parameter
        # that acts on no torque can leave rounding in its column (mc_z[2] of the reference arm
        # and of the iiwa: 2e-17 of the largest column, by the engine and by Pinocchio alike).
        norms = np.linalg.norm(W, axis=0)
        W[:, norms <= ROUNDING * norms.max()] = 0.0
        self.base = base_parameters(W, names)
        self.columns = self.base.describe() + (
            [f"{kind}[{i}]" for i in range(1, n + 1) for kind in ("viscous", "coulomb")] if friction else []
        )

    def _friction(self, states) -> np.ndarray:
        """rows·n × 2n: q̇_i and sign q̇_i in joint i's rows."""
        n, qd = self.n, states[:, self.n : 2 * self.n]
        F = np.zeros((len(states), n, 2 * n))
        for i in range(n):
            F[:, i, 2 * i], F[:, i, 2 * i + 1] = qd[:, i], np.sign(qd[:, i])
        return F.reshape(-1, 2 * n)

    def matrix(self, states) -> np.ndarray:
        """The stacked base regressor (and friction columns) at ``states`` (rows × 3n)."""
        W = self.base.columns(regressor_of(self.unzipdir, states)[0])
        return np.hstack([W, self._friction(states)]) if self.friction else W

    @staticmethod
    def _spectrum(W) -> tuple:
        """(column norms c, W scaled, its eigenvalues λ and eigenvectors V of the scaled W'W, ascending)
        or None for a zero or non-finite column. The p × p eigenproblem instead of the rows' SVD:
        that took 5 ms to this one's 0.2 on two busy cores, and is exact to p·ε·cond² (4e-7
        relative at cond 1e4; the trajectories here are below 1e3)."""
        c = np.linalg.norm(W, axis=0)
        if not np.all(c > 0) or not np.all(np.isfinite(W)):
            return None
        scaled = W / c
        lam, V = np.linalg.eigh(scaled.T @ scaled)
        return (c, scaled, lam, V) if lam[0] > 0 else None

    @classmethod
    def condition(cls, W) -> float:
        """cond of W with each column scaled to unit 2-norm (inf for a zero column or a rank deficit)."""
        found = cls._spectrum(W)
        return math.inf if found is None else float(math.sqrt(found[2][-1] / found[2][0]))

    def __call__(self, trajectory: Fourier) -> float:
        return self.condition(self.matrix(trajectory.states(self.times)))

    def log_condition(self, states) -> float:
        """log10 cond at ``states`` (inf where it is infinite)."""
        value = self.condition(self.matrix(states))
        return math.log10(value) if math.isfinite(value) else math.inf

    def log_condition_gradient(self, states) -> tuple:
        """(log10 cond, ∂ log10 cond/∂states, N × 3n) at ``states``. A singular value σ of the scaled
        matrix Ŵ (columns w_j/c_j) with vectors u, v moves by dσ = uᵀ dŴ v, and
        dŵ_j = (dw_j − ŵ_j ŵ_jᵀ dw_j)/c_j with ŵ_jᵀ u = σ v_j: dσ = Σ_j v_j (u − σ v_j ŵ_j)ᵀ dw_j / c_j.
        A row block of W depends on its own instant's state alone, so one forward difference per
        state component, all instants at once (3n + 1 rows of states in one call of the engine),
        gives every ∂W/∂s; the friction columns' are exact (1 for q̇_i, 0 for sign q̇_i)."""
        N, n = states.shape[0], self.n
        h = STEP
        batch = [states] + [states + h * np.eye(3 * n)[j] for j in range(3 * n)]
        W_all = self.base.columns(regressor_of(self.unzipdir, np.vstack(batch))[0]).reshape(3 * n + 1, N * n, -1)
        W = np.hstack([W_all[0], self._friction(states)]) if self.friction else W_all[0]
        found = self._spectrum(W)
        if found is None:
            return math.inf, np.zeros_like(states)
        c, scaled, lam, V = found
        H = np.zeros_like(W)
        for k, sign in ((-1, 1.0), (0, -1.0)):  # + d log σ_max − d log σ_min
            sigma, v = math.sqrt(lam[k]), V[:, k]
            u = scaled @ v / sigma
            H += sign * (np.outer(u, v) - sigma * scaled * v**2) / c / sigma
        H /= math.log(10.0)
        r = W_all.shape[2]
        rigid = H[:, :r].reshape(N, n, r)
        g = np.empty((N, 3 * n))
        for j in range(3 * n):
            g[:, j] = np.einsum("knr,knr->k", rigid, ((W_all[j + 1] - W_all[0]) / h).reshape(N, n, r))
        if self.friction:
            F = H[:, r:].reshape(N, n, 2 * n)
            for i in range(n):
                g[:, n + i] += F[:, i, 2 * i]
        return 0.5 * math.log10(lam[-1] / lam[0]), g


# ---------------------------------------------------------------------------
# the design


@dataclass
class Design:
    """What :func:`design` found: the best trajectory and its condition number, each start's
    naive and optimized condition numbers, the criterion's columns, the wall time."""

    trajectory: Fourier
    condition: float
    naive: list  # per start, the random start's condition number
    optimized: list  # per start, after SLSQP
    columns: list  # the criterion's columns: base parameters (and friction)
    limits: Limits
    samples: int
    friction: bool
    seed: int
    wall_s: float


def design(
    unzipdir,
    limits: Limits,
    period: float = DEFAULT_PERIOD,
    harmonics: int = DEFAULT_HARMONICS,
    samples: int = DEFAULT_SAMPLES,
    starts: int = DEFAULT_STARTS,
    seed: int = 1,
    friction: bool = False,
    progress=None,
) -> Design:
    """The trajectory of ``harmonics`` harmonics and period ``period`` (s) within ``limits``
    that minimizes the criterion (:class:`Criterion`) on the unpacked FMU ``unzipdir``'s
    model, best of ``starts`` seeded random starts; deterministic for a ``seed``.
    ``progress(text)`` gets a line per start."""
    wall = time.perf_counter()
    n, L = len(limits.q_min), harmonics
    constraints = Constraints(limits, period, L)
    criterion = Criterion(unzipdir, n, limits, period, samples, friction, seed)
    rng = np.random.default_rng(seed)
    shape = (n, 2 * L - 1)

    P = [p @ rest_map(L) for p in basis(criterion.times, period, L)]  # states of the free parameters

    def states(x):
        z = x.reshape(shape)
        return np.hstack([p @ z.T for p in P])

    def log_cond(x):
        return criterion.log_condition(states(x))

    def gradient(x):
        g = criterion.log_condition_gradient(states(x))[1]
        return sum(g[:, m * n : (m + 1) * n].T @ p for m, p in enumerate(P)).ravel()

    from scipy.optimize import minimize

    linear = {"type": "ineq", "fun": lambda x: constraints.h - constraints.G @ x, "jac": lambda x: -constraints.G}
    best, naive, optimized = None, [], []
    for k in range(starts):
        z = rng.standard_normal(shape)
        z[:, 0] = (limits.q_min + limits.q_max) / 2
        z = constraints.scaled_into(z, fill=True)
        naive.append(10 ** log_cond(z.ravel()))
        started = time.perf_counter()
        found = minimize(
            log_cond, z.ravel(), jac=gradient, method="SLSQP", constraints=[linear], options={"maxiter": MAX_ITERATIONS}
        )
        # SLSQP ends within its tolerance of the constraints, or anywhere where it fails: the
        # limits are made to hold exactly, and a start that got worse keeps its naive trajectory.
        x = constraints.scaled_into(found.x.reshape(shape)).ravel()
        value = 10 ** log_cond(x) if np.all(np.isfinite(x)) else math.inf
        if not value <= naive[-1]:
            x, value = z.ravel(), naive[-1]
        optimized.append(value)
        if best is None or value < best[1]:
            best = (x, value)
        if progress:
            progress(
                f"start {k + 1}/{starts}: condition number {naive[-1]:.4g} -> {value:.4g} "
                f"({found.nit} iterations, {time.perf_counter() - started:.1f} s)"
            )
    return Design(
        Fourier.of_free(best[0].reshape(shape), period, L),
        best[1],
        naive,
        optimized,
        criterion.columns,
        limits,
        samples,
        friction,
        seed,
        time.perf_counter() - wall,
    )


# ---------------------------------------------------------------------------
# the files


def write(result: Design, out, periods: int = DEFAULT_PERIODS, rate: float = DEFAULT_RATE, about: dict | None = None):
    """Writes DIR/excitation.toml (a motion file, docs/motion.md), the CSV it names (t and
    q_star[1..n] at ``rate`` samples per second, at least, over ``periods`` periods, from rest
    to rest) and excitation.json (coefficients, condition numbers, limits and the largest
    |q|, |q̇|, |q̈| reached over the samples); ``about``: more entries for the JSON. Returns the
    motion file's path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    tr = result.trajectory
    n = len(tr.q0)
    end = periods * tr.period
    count = math.ceil(end * rate - 1e-9)
    t = end * np.arange(count + 1) / count
    q, qd, qdd = tr.at(t)
    csv_path, motion_path = out / f"{STEM}.csv", out / f"{STEM}.toml"
    with open(csv_path, "w", encoding="utf-8") as f:
        f.write(
            f"# excitation trajectory (stickslip excite, {STEM}.json): {tr.harmonics} harmonics, period "
            f"{tr.period:g} s, {periods} periods, condition number {result.condition:.6g}\n"
        )
        f.write(",".join(["t", *(f"q_star[{i}]" for i in range(1, n + 1))]) + "\n")
        for k in range(len(t)):
            f.write(",".join(repr(float(x)) for x in (t[k], *q[k])) + "\n")
    motion_path.write_text(
        "# written by stickslip excite: a periodic excitation trajectory that starts and ends at rest\n"
        "# (docs/motion.md, 'Excitation trajectories'); run it with\n"
        f"#   stickslip simulate --fmu FMU --motion {motion_path.name}\n"
        f'description = "excitation: {tr.harmonics} harmonics, period {tr.period:g} s, {periods} periods, '
        f'condition number {result.condition:.4g}"\n'
        f'csv = "{csv_path.name}"\n'
        'boundary = "rest"\n',
        encoding="utf-8",
    )
    ordered = sorted(result.naive)
    record = {
        **(about or {}),
        "joints": n,
        "period_s": tr.period,
        "harmonics": tr.harmonics,
        "omega_f_rad_s": 2 * math.pi / tr.period,
        "formula": "q_i(t) = q0_i + sum_l [a_il/(w_f l) sin(w_f l t) - b_il/(w_f l) cos(w_f l t)], w_f = 2 pi/T",
        "q0": tr.q0.tolist(),
        "a": tr.a.tolist(),
        "b": tr.b.tolist(),
        "condition_number": result.condition,
        "naive_condition_number": {"best": ordered[0], "median": float(np.median(ordered)), "each": result.naive},
        "optimized_condition_number": result.optimized,
        "criterion": {
            "samples_per_period": result.samples,
            "scaling": "each column to unit 2-norm; rows the joint torques unweighted",
            "friction": result.friction,
            "columns": result.columns,
        },
        "seed": result.seed,
        "starts": len(result.naive),
        "limits": result.limits.as_dict(),
        "reached": {
            "q_min": q.min(axis=0).tolist(),
            "q_max": q.max(axis=0).tolist(),
            "abs_q_max": np.abs(q).max(axis=0).tolist(),
            "abs_qd_max": np.abs(qd).max(axis=0).tolist(),
            "abs_qdd_max": np.abs(qdd).max(axis=0).tolist(),
        },
        "motion": {"file": motion_path.name, "csv": csv_path.name, "periods": periods, "rate_hz": rate, "end_s": end},
        "wall_s": result.wall_s,
    }
    (out / f"{STEM}.json").write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    return motion_path


# ---------------------------------------------------------------------------
# the command


def add_arguments(p) -> None:
    each = "one value for every joint or n comma-separated"
    p.add_argument("--fmu", required=True, help="the arm's FMU: its model, its URDF's limits, its engine's regressor")
    p.add_argument("--out", required=True, metavar="DIR", help="writes DIR/excitation.toml, .csv and .json")
    p.add_argument("--period", metavar="T", default=str(DEFAULT_PERIOD), help=f"s (default {DEFAULT_PERIOD:g})")
    p.add_argument(
        "--harmonics", metavar="L", default=str(DEFAULT_HARMONICS), help=f"≥ 2 (default {DEFAULT_HARMONICS})"
    )
    p.add_argument(
        "--vmax", metavar="V", help=f"|q̇| limit, rad/s (m/s), {each} (default {DEFAULT_VMAX:g}, the URDF's if lower)"
    )
    p.add_argument("--amax", metavar="A", help=f"|q̈| limit, rad/s² (m/s²), {each} (default {DEFAULT_AMAX:g})")
    p.add_argument(
        "--qmin", metavar="Q", help=f"lower position limits, rad (m), {each} (default the URDF's; --qmin=-1,...)"
    )
    p.add_argument("--qmax", metavar="Q", help=f"upper position limits, {each} (default the URDF's)")
    p.add_argument("--seed", default="1", help="seed of the random starts (default 1)")
    p.add_argument(
        "--starts", metavar="K", default=str(DEFAULT_STARTS), help=f"random starts (default {DEFAULT_STARTS})"
    )
    p.add_argument("--friction", action="store_true", help="the criterion with q̇_i and sign(q̇_i) columns per joint")
    p.add_argument(
        "--samples",
        metavar="N",
        default=str(DEFAULT_SAMPLES),
        help=f"criterion instants per period ({DEFAULT_SAMPLES})",
    )
    p.add_argument(
        "--rate", metavar="HZ", default=f"{DEFAULT_RATE:g}", help=f"motion file samples per s ({DEFAULT_RATE:g})"
    )
    p.add_argument(
        "--periods", metavar="P", default=str(DEFAULT_PERIODS), help=f"periods in the motion file ({DEFAULT_PERIODS})"
    )


def _number(text, what: str, integer: bool = False, least=None):
    try:
        value = int(text) if integer else float(text)
    except (TypeError, ValueError):
        raise ExcitationError(f"{what} {text!r}: must be {'a whole number' if integer else 'a number'}") from None
    if not math.isfinite(value) or (least is not None and value < least):
        raise ExcitationError(f"{what} {text}: must be {'finite' if least is None else f'at least {least:g}'}")
    return value


def per_joint(text, n: int, what: str):
    """n floats of ``text`` (one value for all joints, or n comma-separated), None for None."""
    if text is None:
        return None
    values = [_number(x.strip(), what) for x in str(text).split(",")]
    if len(values) not in (1, n):
        raise ExcitationError(f"{what} {text}: {len(values)} values for {n} joints: give 1 or {n}")
    return values * n if len(values) == 1 else values


def main(a) -> int:
    """``stickslip excite``: exit 0 with the files written; 2 for an argument or FMU that cannot be
    used (one line naming it); 3 for an internal error (one line)."""
    from ..fit.idim import InverseDynamicsError, StageUnavailable
    from ..fmu import model_description, unpacked
    from ..motion import fmu_joints, motor_joints

    try:
        period = _number(a.period, "--period")
        harmonics = _number(a.harmonics, "--harmonics", integer=True, least=2)
        seed = _number(a.seed, "--seed", integer=True, least=0)
        starts = _number(a.starts, "--starts", integer=True, least=1)
        samples = _number(a.samples, "--samples", integer=True, least=1)
        rate = _number(a.rate, "--rate")
        periods = _number(a.periods, "--periods", integer=True, least=1)
        for what, value in (("--period", period), ("--rate", rate)):
            if not value > 0:
                raise ExcitationError(f"{what} {value:g}: must be positive")
        if samples < 2 * harmonics + 1:
            raise ExcitationError(
                f"--samples {samples}: below 2L + 1 = {2 * harmonics + 1} the samples alias the harmonics"
            )
        if rate * period < 4 * harmonics:
            raise ExcitationError(f"--rate {rate:g}: below 4 samples per period of the highest harmonic")
        path = Path(a.fmu)
        try:
            data = path.read_bytes()
            md = model_description(data)
            unzipdir = unpacked(data)
        except Exception as e:  # noqa: BLE001 -- a missing, unreadable or broken FMU is one line
            raise ExcitationError(f"--fmu {a.fmu}: not a readable FMU ({' '.join(str(e).split())})") from None
        n, names = fmu_joints(md)
        motors = motor_joints(md)
        if motors:
            raise ExcitationError(
                f"--fmu {a.fmu}: joints {', '.join(map(str, motors))} have motor drives, driven by their torques "
                "tau_m, not by a position: an excitation trajectory drives positions (q_star) only"
            )
        limits = limits_of(
            n,
            urdf_limits(unzipdir, names),
            per_joint(a.qmin, n, "--qmin"),
            per_joint(a.qmax, n, "--qmax"),
            per_joint(a.vmax, n, "--vmax"),
            per_joint(a.amax, n, "--amax"),
        )
        print(
            f"excite: {n} joints of {path.name}, {harmonics} harmonics, period {period:g} s, {starts} starts "
            f"(seed {seed}){', friction columns' if a.friction else ''}",
            flush=True,
        )
        result = design(unzipdir, limits, period, harmonics, samples, starts, seed, a.friction, progress=_say)
    except (ExcitationError, StageUnavailable) as e:
        print(f"stickslip excite: {e}", file=sys.stderr)
        return 2
    except InverseDynamicsError as e:
        print(f"stickslip excite: the engine refused the FMU's model: {e}", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 -- never a traceback on the console
        print(f"stickslip excite: internal error: {type(e).__name__}: {' '.join(str(e).split())}", file=sys.stderr)
        return 3
    try:
        motion = write(
            result, a.out, periods, rate, {"fmu": str(path), "joint_names": {str(i): x for i, x in names.items()}}
        )
    except OSError as e:
        print(f"stickslip excite: --out {a.out}: {e.strerror or e}", file=sys.stderr)
        return 2
    ordered = sorted(result.naive)
    print(
        f"excite: condition number {result.condition:.4g} (naive trajectories: best {ordered[0]:.4g}, median "
        f"{float(np.median(ordered)):.4g}) of {len(result.columns)} columns, {result.wall_s:.1f} s -> {motion}"
    )
    return 0


def _say(text: str) -> None:
    print(f"  {text}", flush=True)
