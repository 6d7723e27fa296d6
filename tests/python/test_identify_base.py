"""Base parameters (python/stickslip/identify/base.py) on regressors that do not come from the
engine (Pinocchio's computeJointTorqueRegressor), so that a mistake in either is not repeated:

* a pendulum (one revolute joint, gravity across its axis) in closed form: of its ten standard
  parameters exactly three act, I_zz, m·c_x and m·c_y (τ = I_zz q̈ + g m (c_x cos q − c_y sin q)
  about its axis), each a base parameter of its own;
* the KUKA iiwa's URDF: 43 base parameters, the SVD's rank (a column of rounding, m·c_z[2] at
  2e-17 of the largest, is no parameter); at states the factorization never saw,
  W π = W_b β for random π to 1e-10 of |W||π|, and every dependent column is the combination K says;
  a parameter in no combination moves no torque.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers import ROOT

pin = pytest.importorskip("pinocchio")

NAMES = ("m", "mc_x", "mc_y", "mc_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz")


def _names(n: int) -> list:
    return [f"{p}[{i}]" for i in range(1, n + 1) for p in NAMES]


def _stacked(model, states) -> np.ndarray:
    data = model.createData()
    n = model.nq
    return np.vstack([pin.computeJointTorqueRegressor(model, data, s[:n], s[n : 2 * n], s[2 * n :]) for s in states])


def test_a_pendulum_has_three_base_parameters_in_closed_form():
    from stickslip.identify.base import base_parameters, random_states

    model = pin.Model()
    model.gravity.linear = np.array([0.0, -9.81, 0.0])  # across the joint's z axis
    joint = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "joint")
    model.appendBodyToJoint(joint, pin.Inertia.Random(), pin.SE3.Identity())
    base = base_parameters(_stacked(model, random_states(1, 50, seed=1)), _names(1))
    assert sorted(base.describe()) == ["I_zz[1]", "mc_x[1]", "mc_y[1]"], base.describe()
    assert sorted(base.unidentifiable()) == sorted(set(_names(1)) - {"I_zz[1]", "mc_x[1]", "mc_y[1]"})


def test_the_iiwa_base_parameters_reproduce_every_torque():
    from stickslip.identify.base import base_parameters, random_states

    model = pin.buildModelFromUrdf(str(ROOT / "models/urdf/kuka_iiwa/kuka_iiwa.urdf"))
    n = model.nq
    W = _stacked(model, random_states(n, 400, seed=2))
    base = base_parameters(W, _names(n))
    # the SVD's rank of the columns scaled to unit norm, rounding columns (below 1e-12 of the
    # largest: a parameter that moves no torque) left out
    norms = np.linalg.norm(W, axis=0)
    real = norms > 1e-12 * norms.max()
    s = np.linalg.svd(W[:, real] / norms[real], compute_uv=False)
    assert base.count == int(np.sum(s > 1e-8 * s[0])) == 43, (base.count, s)
    print(base.count, "base parameters of", len(base.names))
    for line in base.describe():
        print(" ", line)
    rng = np.random.default_rng(3)
    W_new = _stacked(model, random_states(n, 100, seed=4))
    for _ in range(5):
        pi = rng.standard_normal(len(base.names))
        full, reduced = W_new @ pi, base.columns(W_new) @ base.of(pi)
        assert np.max(np.abs(full - reduced)) <= 1e-10 * np.linalg.norm(W_new, 2) * np.linalg.norm(pi)
    # a dependent column is the combination K says
    np.testing.assert_allclose(W_new[:, base.dependent], base.columns(W_new) @ base.K, atol=1e-10 * np.abs(W_new).max())
    for name in base.unidentifiable():
        assert not np.any(np.abs(W_new[:, base.names.index(name)]) > 1e-12 * np.abs(W_new).max()), name
