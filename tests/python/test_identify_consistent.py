"""The identification's estimates (python/stickslip/identify/consistent.py) on torques whose truth
is known, with Pinocchio's regressor of the KUKA iiwa's URDF standing in for the engine's (the
estimator takes any regressor; the engine's is checked against Pinocchio's elsewhere):

* the truth: the URDF's links; the catalogue: every mass, centre and inertia 30 % off (a
  physically consistent body still); friction b_v, τ_c and armature I_a per joint;
* the torques: τ = Y π + b_v q̇ + τ_c sgn q̇ + I_a q̈ at a sum-of-sines motion, plus white noise
  of 1 % of each joint's torque range, positions rounded to a 20-bit encoder's count;
* the base parameters' truth lies within 3 standard errors of the weighted least squares in all
  but at most 20 of the 186 (draw, parameter) pairs over three noise draws (P(X >= 21 | 186,
  0.05) = 4.5e-4), and the same estimates moved by 2.5 SE fail that;
* the consistent model: every link's pseudo-inertia positive definite, friction and armature
  nonnegative, its base parameters within 3 SE of the unconstrained ones (no warning), and a
  held-out motion's torques predicted within 3 % relative rms per joint (the catalogue model:
  far worse).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import ROOT, allowed_misses

pin = pytest.importorskip("pinocchio")
pytest.importorskip("cvxpy")

URDF = ROOT / "models/urdf/kuka_iiwa/kuka_iiwa.urdf"
RATE = 250.0  # Hz, the log's sample rate
COUNT = 2 * math.pi / 2**20  # a 20-bit encoder's count, rad


def _model():
    return pin.buildModelFromUrdf(str(URDF))


def _pi(model) -> np.ndarray:
    return np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)])


def _perturbed(model, rng, spread=0.3):
    """The catalogue: each link's mass, centre and principal moments off by up to ±spread."""
    out = model.copy()
    for j in range(1, model.njoints):
        inertia = model.inertias[j]
        m = inertia.mass * (1 + spread * rng.uniform(-1, 1))
        c = inertia.lever * (1 + spread * rng.uniform(-1, 1, 3))
        moments = np.diag(inertia.inertia) * (1 + spread * rng.uniform(-1, 1, 3))
        # keep the triangle inequality: no moment above the sum of the other two
        moments = np.minimum(moments, 0.99 * (moments.sum() - moments))
        out.inertias[j] = pin.Inertia(m, c, np.diag(moments))
    return out


def _motion(n, seconds, seed):
    """A sum of five sines per joint (0.1–0.9 Hz, amplitudes up to 0.8 rad): q, q̇, q̈."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 1.0 / RATE)
    f = rng.uniform(0.1, 0.9, (5, n))
    a = rng.uniform(0.05, 0.16, (5, n))
    phase = rng.uniform(0, 2 * np.pi, (5, n))
    arg = 2 * np.pi * f[:, None, :] * t[None, :, None] + phase[:, None, :]
    q = np.sum(a[:, None, :] * np.sin(arg), axis=0)
    qd = np.sum(a[:, None, :] * 2 * np.pi * f[:, None, :] * np.cos(arg), axis=0)
    qdd = -np.sum(a[:, None, :] * (2 * np.pi * f[:, None, :]) ** 2 * np.sin(arg), axis=0)
    return t, q, qd, qdd


def _regressor(model):
    data = model.createData()
    n = model.nq

    def regressor(states):
        Y = np.array([pin.computeJointTorqueRegressor(model, data, s[:n], s[n : 2 * n], s[2 * n :]) for s in states])
        names = [f"{p}[{i}]" for i in range(1, n + 1) for p in ("m", "mc_x", "mc_y", "mc_z", *INERTIA)]
        return Y, _pi(model), names

    return regressor


INERTIA = ("I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz")


def _log(model, regressor, friction, seconds, seed, noise_seed):
    from stickslip.identify.spec import Log

    n = model.nq
    t, q, qd, qdd = _motion(n, seconds, seed)
    Y, pi, _ = regressor(np.hstack([q, qd, qdd]))
    tau = np.einsum("kij,j->ki", Y, pi)
    b_v, tau_c, armature = friction
    tau += b_v * qd + tau_c * np.sign(qd) + armature * qdd
    rng = np.random.default_rng(noise_seed)
    tau += 0.01 * np.ptp(tau, axis=0) * rng.standard_normal(tau.shape)
    q = np.round(q / COUNT) * COUNT
    return Log(f"run{seed}", t, q, {i + 1: tau[:, i] for i in range(n)})


def _identify(truth, catalogue, friction, noise_seed):
    from stickslip.fit.filtering import default_filter
    from stickslip.identify.consistent import estimate
    from stickslip.identify.equations import equations, filtered, structural_base

    n = truth.nq
    true_regressor = _regressor(truth)
    logs = [_log(truth, true_regressor, friction, 20.0, seed, noise_seed + seed) for seed in (1, 2)]
    motions = [filtered(log, default_filter(), coulomb=True) for log in logs]
    catalogue_regressor = _regressor(catalogue)  # the product knows only the catalogue
    eq = equations(motions, catalogue_regressor, "viscous+coulomb", True)
    base = structural_base(catalogue_regressor, n, "viscous+coulomb", True)
    return eq, base, estimate(eq, base, _pi(catalogue), prior=1e-4)


@pytest.mark.full
def test_the_base_parameters_are_covered_and_the_consistent_model_is_physical_and_predicts():
    truth = _model()
    n = truth.nq
    rng = np.random.default_rng(7)
    catalogue = _perturbed(truth, rng)
    friction = (rng.uniform(0.5, 2.0, n), rng.uniform(0.5, 3.0, n), rng.uniform(0.05, 0.5, n))
    theta_true = np.concatenate([_pi(truth), np.column_stack(friction).ravel()])
    covered, biased_covered, total = 0, 0, 0
    for draw in range(3):
        eq, base, est = _identify(truth, catalogue, friction, noise_seed=100 * draw)
        beta_true = base.of(theta_true)
        z = (est.beta - beta_true) / est.std_error
        print(
            f"draw {draw}: {base.count} base parameters, max |z| {np.max(np.abs(z)):.2f}, condition {est.condition:.3g}"
        )
        covered += int(np.sum(np.abs(z) <= 3.0))
        biased_covered += int(np.sum(np.abs(z + 2.5) <= 3.0))
        total += base.count
        from stickslip.identify.consistent import pseudo_inertia_eigenvalues

        assert np.all(pseudo_inertia_eigenvalues(est.theta[: eq.inertial]) > 0)
        assert np.all(est.theta[eq.inertial :] >= -1e-9)
        assert not [w for w in est.warnings if "physically consistent" in w], est.warnings
    print(f"covered {covered} of {total}")
    # sized (issue 41): a pair may miss with p = 0.05; allowed_misses(186, 0.05) = 20, a false
    # failure P(X >= 21 | 186, 0.05) = 4.5e-4; the same estimates moved by 2.5 SE fail it
    assert total - covered <= allowed_misses(total, 0.05)
    assert total - biased_covered > allowed_misses(total, 0.05), "the planted bias went unseen"
    # held-out: a motion neither fit saw, its torques predicted
    log = _log(truth, _regressor(truth), friction, 10.0, seed=9, noise_seed=999)
    from stickslip.fit.filtering import default_filter
    from stickslip.identify.equations import equations, filtered

    motion = filtered(log, default_filter(), coulomb=False)
    held = equations([motion], _regressor(catalogue), "viscous+coulomb", True)
    catalogue_theta = np.concatenate([_pi(catalogue), np.zeros(3 * n)])
    for i in range(1, n + 1):
        rows = held.joint == i
        measured = held.b[rows]
        rms = math.sqrt(np.mean(measured**2))
        ours = math.sqrt(np.mean((held.A[rows] @ est.theta - measured) ** 2)) / rms
        theirs = math.sqrt(np.mean((held.A[rows] @ catalogue_theta - measured) ** 2)) / rms
        print(f"joint {i}: identified {ours:.4f}, catalogue {theirs:.4f}")
        assert ours < 0.03 and ours < 0.5 * theirs
