"""The engine's joint-torque regressor against Pinocchio's on the same URDF (issue 42, item 1).

The rigid-body inverse dynamics are linear in each link's ten standard inertial parameters,
τ = Y(q, q̇, q̈)·π. For both example arms of models/urdf (KUKA LBR iiwa, 7 joints; UFACTORY
xArm 6, 6 joints), the FMU of the arm's model file (built as tests/python/urdf_fmus.py builds
it) gives Y and π through its own binary (``stickslip.fit.regressor.joint_torque_regressor``,
the export ``stickslip_joint_torque_regressor``), and Pinocchio, loading the same URDF
(``urdf_reference.pinocchio_model``), gives ``computeJointTorqueRegressor`` and each joint's
``inertias[j].toDynamicParameters()``. At 50 random states (seeded; q uniform within the URDF's
limits, q̇ in ±2 rad/s, q̈ in ±20 rad/s²):

* π: the engine's link frame is Pinocchio's joint frame (the URDF child link frame, the bodies on
  fixed joints after it merged in) turned by R_a, the rotation taking z to the joint's axis, so
  π_engine = T·π_pin with per link m the same, m·c turned by R_aᵀ and I by R_aᵀ·I·R_a (T the
  identity for these arms, whose axes are all +z; the map is built from the URDF's axes all the
  same); the two agree to 1e-12 of each link's largest parameter of its kind (mass, first
  moment, inertia);
* Y: the same map taken over, Y_engine·T = Y_pin, to 1e-12 of each column's largest entry over
  the states (a column that is zero in Pinocchio's but for rounding, its largest entry below 1e-12
  of Y's: to 1e-12 of Y's largest entry);
* Y·π: equals the engine's inverse dynamics (``stickslip.fit.idim.inverse_dynamics``) and
  Pinocchio's ``rnea`` to 1e-12 of the joint's largest |τ| over the states.

The names of π are ``m[i]``, ``mc_x[i]``, …, ``I_zz[i]`` in Pinocchio's order. Bad input is
refused with the engine's reason, and a library without the export says so.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
from fmpy import extract  # noqa: E402

from helpers import require_fmu  # noqa: E402
from stickslip.fit import idim  # noqa: E402
from stickslip.fit.regressor import PARAMETERS, joint_torque_regressor  # noqa: E402
from urdf_fmus import model_fmu, require_iiwa_fmu  # noqa: E402
from urdf_reference import ARMS, model_file, pinocchio_model  # noqa: E402

# CI's full run only (scripts/test.sh --quick leaves it out): URDF arms' FMUs built and compared with Pinocchio
pytestmark = pytest.mark.full

REL = 1e-12
SAMPLES = 50
SEED = 42
# Each link's parameters by kind, for the scale of a comparison of π.
KINDS = {"mass": [0], "first moment": [1, 2, 3], "inertia": [4, 5, 6, 7, 8, 9]}


def arm_fmu(arm: str):
    """The FMU of the arm's model file, built on first use (skips without the FMU under test)."""
    if arm == "kuka_iiwa":
        return require_iiwa_fmu()
    require_fmu()
    return model_fmu("xarm6", ARMS["xarm6"], "STICKSLIP_XARM6_FMU")


def axis_alignment(a: np.ndarray) -> np.ndarray:
    """R_a, the rotation taking z to the unit axis ``a``, as the engine builds it
    (src/model/urdf_model.rs, ``axis_alignment``)."""

    def towards(u):
        k = np.cross(u, a)
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        return np.eye(3) + kx + kx @ kx / (1.0 + u @ a)

    z = np.array([0.0, 0.0, 1.0])
    return towards(z) if a[2] >= 0.0 else towards(-z) @ np.diag([1.0, -1.0, -1.0])


def frame_map(rotation: np.ndarray) -> np.ndarray:
    """T (10 × 10) with π_engine = T·π_pin for a link whose engine frame is Pinocchio's turned by
    ``rotation``: m kept, h → Rᵀh, I → RᵀIR (I in the order xx, xy, yy, xz, yz, zz)."""
    upper = [(0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2)]
    t = np.zeros((10, 10))
    t[0, 0] = 1.0
    t[1:4, 1:4] = rotation.T
    for col, (a, b) in enumerate(upper):
        unit = np.zeros((3, 3))
        unit[a, b] = unit[b, a] = 1.0
        turned = rotation.T @ unit @ rotation
        t[4:, 4 + col] = [turned[r, c] for r, c in upper]
    return t


@pytest.fixture(scope="module", params=sorted(ARMS))
def comparison(request):
    """Per arm: the engine's Y, π and τ and Pinocchio's Y, π and τ at the random states, and T."""
    arm = request.param
    mf = model_file(ARMS[arm])
    model = pinocchio_model(mf)
    data = model.createData()
    rng = np.random.default_rng(SEED + len(arm))
    q = rng.uniform(model.lowerPositionLimit, model.upperPositionLimit, (SAMPLES, model.nq))
    qd = rng.uniform(-2.0, 2.0, (SAMPLES, model.nv))
    qdd = rng.uniform(-20.0, 20.0, (SAMPLES, model.nv))
    unzipdir = extract(str(arm_fmu(arm)))
    try:
        states = np.hstack([q, qd, qdd])
        y, pi, names = joint_torque_regressor(unzipdir, states)
        tau, _ = idim.inverse_dynamics(unzipdir, states)
    finally:
        shutil.rmtree(unzipdir, ignore_errors=True)
    n = mf.n
    t = np.zeros((10 * n, 10 * n))
    for i in range(1, n + 1):
        t[10 * (i - 1) : 10 * i, 10 * (i - 1) : 10 * i] = frame_map(axis_alignment(mf.axis(i)))
    ref = {
        "Y": np.array([pin.computeJointTorqueRegressor(model, data, *s).copy() for s in zip(q, qd, qdd, strict=True)]),
        "pi": np.concatenate([model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)]),
        "tau": np.array([pin.rnea(model, data, *s).copy() for s in zip(q, qd, qdd, strict=True)]),
    }
    return {"arm": arm, "n": n, "Y": y, "pi": pi, "names": names, "tau": tau, "T": t, "ref": ref}


def test_the_names_are_pinocchios_order(comparison):
    n = comparison["n"]
    names = comparison["names"]
    assert len(names) == len(comparison["pi"]) == 10 * n
    assert names[:10] == [f"{p}[1]" for p in PARAMETERS]
    assert names[10 * n - 1] == f"I_zz[{n}]"
    assert PARAMETERS == ("m", "mc_x", "mc_y", "mc_z", "I_xx", "I_xy", "I_yy", "I_xz", "I_yz", "I_zz")


def test_standard_parameters_are_pinocchios_in_the_engines_frames(comparison):
    n, pi = comparison["n"], comparison["pi"]
    expected = comparison["T"] @ comparison["ref"]["pi"]
    worst = 0.0
    for i in range(n):
        for kind, index in KINDS.items():
            e, p = pi[10 * i + np.array(index)], expected[10 * i + np.array(index)]
            scale = np.abs(p).max()
            deviation = np.abs(e - p).max()
            assert deviation <= REL * scale, f"{comparison['arm']} link {i + 1} {kind}: {e} vs {p}"
            worst = max(worst, deviation / scale if scale > 0 else 0.0)
    print(f"{comparison['arm']}: π within {worst:.1e} of Pinocchio's")


def test_the_regressor_is_pinocchios(comparison):
    y_engine = comparison["Y"] @ comparison["T"]  # Y_engine·T, rows × n × 10n
    y_pin = comparison["ref"]["Y"]
    assert y_engine.shape == y_pin.shape
    largest = np.abs(y_pin).max()
    worst, zero_columns = 0.0, 0
    for k in range(y_pin.shape[2]):
        scale = np.abs(y_pin[:, :, k]).max()
        deviation = np.abs(y_engine[:, :, k] - y_pin[:, :, k]).max()
        if scale <= REL * largest:  # zero but for rounding (mc_z[2] of the xArm: 8.9e-16 in Pinocchio's, 0 here)
            zero_columns += 1
            assert deviation <= REL * largest, f"{comparison['arm']}: column {comparison['names'][k]} is {deviation}"
            continue
        assert deviation <= REL * scale, f"{comparison['arm']}: column {comparison['names'][k]}: {deviation / scale:e}"
        worst = max(worst, deviation / scale)
    print(f"{comparison['arm']}: Y·T within {worst:.1e} of each column's largest entry ({zero_columns} columns zero)")


def test_y_times_pi_is_the_inverse_dynamics(comparison):
    product = comparison["Y"] @ comparison["pi"]
    for what, tau in (("the engine's", comparison["tau"]), ("Pinocchio's rnea", comparison["ref"]["tau"])):
        scale = np.abs(tau).max(axis=0)
        deviation = (np.abs(product - tau).max(axis=0) / scale).max()
        assert deviation <= REL, f"{comparison['arm']}: Y·π against {what} τ: {deviation:e}"
        print(f"{comparison['arm']}: Y·π within {deviation:.1e} of {what} τ")


def test_bad_input_and_a_binary_without_the_export_are_refused(tmp_path):
    """The engine's reason as InverseDynamicsError (the row and name of a state that is not finite,
    a wrong row length, an unknown setting); StageUnavailable for a library without the export
    (the FMI 3.0 FMU's, which exports the fmi3 functions only)."""
    fmu = require_fmu()
    unzipdir = extract(str(fmu), unzipdir=str(tmp_path / "fmu"))
    states = np.zeros((3, 12))
    states[2, 9] = np.nan
    for bad, says in (
        ((states, ()), "row 3: qdd[2] = NaN is not finite"),
        ((np.zeros((2, 9)), ()), "a state row has 9 values, the model's has 3n = 12"),
        ((np.zeros((1, 12)), ("nonsense[1]=2",)), "no parameter is named `nonsense`"),
    ):
        with pytest.raises(idim.InverseDynamicsError, match=re.escape(says)):
            joint_torque_regressor(unzipdir, *bad)
    fmi3 = fmu.with_name(fmu.stem + "-fmi3.fmu")
    if idim.platform_folder() != "linux64" or not fmi3.is_file():
        pytest.skip("no linux64 FMI 3.0 library beside the FMU to stand for a library without the export")
    # A fresh copy: the library loaded above stays loaded under its own path.
    old = Path(extract(str(fmu), unzipdir=str(tmp_path / "old")))
    fmi3_dir = Path(extract(str(fmi3), unzipdir=str(tmp_path / "fmi3")))
    (library,) = (old / "binaries" / "linux64").glob("*.so")
    (other,) = [p for p in (fmi3_dir / "binaries").rglob(library.name) if "linux" in str(p.parent)]
    shutil.copy(other, library)
    with pytest.raises(idim.StageUnavailable, match=r"has no stickslip_joint_torque_regressor.*rebuild"):
        joint_torque_regressor(old, np.zeros((1, 12)))
