"""The estimates: the base parameters by weighted least squares with their standard errors, and
a physically consistent model that fits the same torques.

1. **Weights** (Gautier's two steps): ordinary least squares of the base columns, then each
   joint's rows divided by the rms of its residuals, σ_i: joints whose torques differ by orders
   of magnitude count by their noise, not their size.
2. **Base parameters** β̂: the weighted least squares of the base columns
   (:mod:`stickslip.identify.base`). Their covariance is the larger of the classical
   σ̂²(AᵀA)⁻¹ and a Newey–West sandwich per (run, joint) series
   (:func:`stickslip.fit.uncertainty.uncertainty`): filtered rows are correlated over the
   filter's reach, and independent-residual errors would understate them.
3. **A physically consistent model** θ_c (all standard parameters, friction, armature):
   the same weighted squares plus a prior that pulls each parameter towards the catalogue's
   (the FMU's model: URDF or model file) with weight ``prior`` relative to the data's mean
   information per parameter, subject to, per link, the pseudo-inertia

       J = [[½ tr(Ī)·1 − Ī, h], [hᵀ, m]] ⪰ ε·diag(ℓ², ℓ², ℓ², 1)·m_catalogue

   (Ī the inertia about the link frame's origin, h = m·c; J ≻ 0 is exactly m > 0 with an
   inertia about the centre of mass that is positive definite and obeys the triangle
   inequalities: Wensing, Kim and Slotine 2017), and friction and armature ≥ 0. It is a
   semidefinite least squares, convex: cvxpy states it, Clarabel (an interior-point conic
   solver, in Rust) solves it to its optimality tolerance with no start to choose and no local
   minimum, which a log-Cholesky parameterization with a nonlinear solver would have.
   The data decide every direction they can see (the prior's weight there is ``prior`` of
   theirs); the catalogue decides the directions they cannot (combinations that act on no
   measured torque, or on too little of it).

The base parameters of θ_c are compared with β̂: more than 3 standard errors apart means the
data want a value no physical body has (a model error: friction, torque signs, kinematics), and
a warning says which.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..fit.uncertainty import uncertainty
from .base import BaseParameters

LINK = 10  # standard parameters per link
# The pseudo-inertia's margin: ε of the catalogue mass (and its length scale squared).
EPSILON = 1e-6
# Where the base estimate of the consistent model lies further than this many standard errors
# from the unconstrained one, the data and a physical body disagree.
DISAGREE = 3.0


@dataclass
class Estimates:
    names: list  # every column: the standard parameters, then friction and armature
    base: BaseParameters
    sigma: dict  # joint -> the rms of its first-step residuals (the rows' weight)
    beta: np.ndarray  # the base parameters' weighted least squares
    std_error: np.ndarray
    std_error_classical: np.ndarray
    std_error_sandwich: np.ndarray
    correlation: np.ndarray
    theta: np.ndarray  # the physically consistent model, every column
    beta_consistent: np.ndarray
    condition: float  # of the column-scaled weighted base regressor
    solver: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    std_error_catalogue: np.ndarray = None  # what the unidentified combinations add (identification.py)


def scales(pi_catalogue, n_extra: int, extra_scale: float = 1.0) -> np.ndarray:
    """A typical size of each parameter, from the catalogue's links: m, m·ℓ, m·ℓ² with ℓ the
    link's size (the larger of |c| and its radius of gyration, at least 5 cm); ``extra_scale``
    for friction and armature."""
    out = []
    for link in np.asarray(pi_catalogue).reshape(-1, LINK):
        m = max(abs(link[0]), 1e-3)
        c = np.linalg.norm(link[1:4]) / m
        inertia = link[4] + link[6] + link[9]
        gyration = math.sqrt(max(inertia, 0.0) / (2.0 * m))
        ell = max(c, gyration, 0.05)
        out += [m, m * ell, m * ell, m * ell] + [m * ell**2] * 6
    return np.array(out + [extra_scale] * n_extra)


def _pseudo_inertia(p):
    """J(π) of one link's ten parameters (a cvxpy expression or numbers), 4 × 4."""
    import cvxpy as cp

    m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = (p[k] for k in range(LINK))
    half = 0.5 * (ixx + iyy + izz)
    return cp.bmat(
        [
            [half - ixx, -ixy, -ixz, hx],
            [-ixy, half - iyy, -iyz, hy],
            [-ixz, -iyz, half - izz, hz],
            [hx, hy, hz, m],
        ]
    )


def pseudo_inertia_eigenvalues(pi) -> np.ndarray:
    """The smallest eigenvalue of each link's pseudo-inertia (> 0: physically consistent)."""
    out = []
    for p in np.asarray(pi).reshape(-1, LINK):
        m, hx, hy, hz, ixx, ixy, iyy, ixz, iyz, izz = p
        half = 0.5 * (ixx + iyy + izz)
        J = np.array(
            [
                [half - ixx, -ixy, -ixz, hx],
                [-ixy, half - iyy, -iyz, hy],
                [-ixz, -iyz, half - izz, hz],
                [hx, hy, hz, m],
            ]
        )
        out.append(float(np.linalg.eigvalsh(J)[0]))
    return np.array(out)


def estimate(eq, base: BaseParameters, pi_catalogue, prior: float) -> Estimates:
    """The estimates of the equations ``eq`` (:class:`stickslip.identify.equations.Equations`)
    with the base parameters ``base`` of its columns and the catalogue's standard parameters."""
    A, b = eq.A, eq.b
    Ab = A[:, base.independent]
    # 1. the weights
    first = np.linalg.lstsq(Ab, b, rcond=None)[0]
    r = Ab @ first - b
    sigma = {}
    w = np.ones(len(b))
    for i in sorted(set(eq.joint.tolist())):
        rows = eq.joint == i
        s = float(np.sqrt(np.mean(r[rows] ** 2)))
        sigma[i] = s if s > 0 else 1.0
        w[rows] = 1.0 / sigma[i]
    Aw, bw = A * w[:, None], b * w
    Abw = Aw[:, base.independent]
    # 2. the base parameters and their uncertainty
    beta = np.linalg.lstsq(Abw, bw, rcond=None)[0]
    rw = Abw @ beta - bw
    base_names = [f"beta[{k + 1}]" for k in range(base.count)]
    unc = uncertainty(Abw, rw, eq.blocks, base_names, absolute_sigma=False)
    warnings = []
    for rel, direction in unc.singular:
        warnings.append(
            f"the data hardly excite the combination {direction} of base parameters (relative singular value "
            f"{rel:.1e}): a richer motion (stickslip excite) is needed to identify it"
        )
    # 3. the physically consistent model
    theta, solver = _consistent(Aw, bw, np.asarray(pi_catalogue), eq.inertial, prior, base.matrix())
    beta_c = base.of(theta)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (beta_c - beta) / unc.std_error
    far = [k for k in range(base.count) if math.isfinite(z[k]) and abs(z[k]) > DISAGREE]
    if far:
        worst = max(far, key=lambda k: abs(z[k]))
        warnings.append(
            f"the physically consistent model's base parameters lie more than {DISAGREE:g} standard errors from the "
            f"data's own least squares in {len(far)} of {base.count} (the worst: {base.describe()[worst]} by "
            f"{z[worst]:+.1f} SE): the data want values no physical body has, a model error (friction law, torque "
            "signs, kinematics, a link the catalogue gets very wrong)"
        )
    if solver["status"] != "optimal":
        warnings.append(
            f"the semidefinite least squares ended {solver['status']!r}: the consistent model is approximate"
        )
    return Estimates(
        eq.names,
        base,
        sigma,
        beta,
        unc.std_error,
        unc.std_error_classical,
        unc.std_error_sandwich,
        unc.correlation,
        theta,
        beta_c,
        unc.condition,
        solver,
        warnings,
    )


def _consistent(Aw, bw, pi_catalogue, inertial: int, prior: float, B) -> tuple:
    """(θ_c, solver record): the semidefinite least squares of the module's item 3; ``B`` the
    base parameters' matrix (β = B θ): the prior acts only across its null space, on the
    combinations no torque can show, so that it never pulls on what the data measure."""
    import cvxpy as cp

    p = Aw.shape[1]
    s = scales(pi_catalogue, p - inertial)
    # The squares through a QR of the scaled columns: p × p instead of rows × p.
    # Divided by the data's mean information per (scaled) parameter, so that the objective is
    # of order one for the solver and the prior's weight is ``prior`` itself.
    scaled = Aw * s  # the columns of x = θ / s
    Q, R = np.linalg.qr(scaled)
    information = float(np.mean(np.sum(scaled**2, axis=0)))
    R, c = R / math.sqrt(information), Q.T @ bw / math.sqrt(information)
    weight = prior
    x = cp.Variable(p)  # θ / s
    target = np.concatenate([pi_catalogue / s[:inertial], np.zeros(p - inertial)])
    Bs = B * s
    null = np.eye(p) - np.linalg.pinv(Bs) @ Bs
    objective = cp.sum_squares(R @ x - c) + weight * cp.sum_squares(null @ (x - target))
    constraints = []
    for link in range(inertial // LINK):
        at = slice(LINK * link, LINK * (link + 1))
        theta_link = cp.multiply(s[at], x[at])
        m = max(pi_catalogue[LINK * link], 1e-3)
        ell2 = s[LINK * link + 4] / s[LINK * link]
        J = _pseudo_inertia(theta_link)
        # scaled to order 1: J / (m ℓ²) on the inertia block and J / m on the mass
        D = np.diag([1.0 / math.sqrt(ell2)] * 3 + [1.0]) / math.sqrt(m)
        constraints.append(D @ J @ D - EPSILON * np.eye(4) >> 0)
    if p > inertial:
        constraints.append(x[inertial:] >= 0)
    problem = cp.Problem(cp.Minimize(objective), constraints)
    try:
        problem.solve(solver=cp.CLARABEL)
    except cp.error.SolverError as e:
        return np.concatenate([pi_catalogue, np.zeros(p - inertial)]), {
            "status": f"failed: {e}",
            "prior_weight": weight,
        }
    if x.value is None:
        return np.concatenate([pi_catalogue, np.zeros(p - inertial)]), {
            "status": problem.status,
            "prior_weight": weight,
        }
    return np.asarray(x.value) * s, {"status": problem.status, "prior_weight": weight, "solver": "Clarabel"}
