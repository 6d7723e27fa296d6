"""The engine's URDF arms against Pinocchio loading the *same* URDF file (issue 19).

For both example arms of models/urdf (KUKA LBR iiwa, 7 joints; UFACTORY xArm 6,
6 joints), each as its model file (flexible drives as given there) and as a
variant with every drive rigid (friction and bearings kept):

* random states (seeded; 50 per arm; q uniform within the URDF's limits, q̇ in
  ±2 rad/s, q̈ in ±20 rad/s²) through the engine's ``inverse_dynamics`` binary:
  the generalized forces tau = M q̈ + bias (with gravity) of every joint, which
  for a flexible joint is the left side of its equation of motion; the joint
  reactions at the joint origins (axial force, radial force magnitude, axial
  moment, bending moment magnitude, and the vectors); the end point; the mass
  matrix;
* a simulated motion through the FMU (``package_fmu`` of the model file, fmpy,
  the motion given as a motion file, every joint on a cycloid, 1 s): Pinocchio's
  RNEA at the FMU's own outputs (q, q̇, q̈) against the FMU's reactions at each
  joint's reaction reference point, the bearings' normal loads, the end point and
  the equation of motion of every joint, tau = F_drive − F_friction.

Tolerance: 1e-9 relative, each quantity (per joint) relative to its largest
magnitude over the samples (the mass matrix entry M_ij relative to the largest
sqrt(M_ii M_jj), the end point relative to its largest distance from the base).
The equation of motion of a flexible joint through the FMU holds to the
tolerance of the Newmark iteration that solved it; the 1e-9 comparison runs the
FMU at fixed sub-steps (h_min = h_max = 1e-4 s) with ``tolerance`` = 1e-12.
With the FMU's defaults (error control, whose iteration stops at 1e-4 ×
error_tolerance = 5e-8 relative), :func:`test_fmu_default_settings_equation_of_motion_within_newmark_tolerance`
checks that it holds to 1e-6 and the reactions still to 1e-9.

Pinocchio's convention, checked by hand on a pendulum
(:func:`test_pinocchio_and_engine_reactions_equal_hand_computed_pendulum`):
``data.f[j]`` after ``rnea`` is the force and moment that the parent applies,
through joint j, on the subtree of joint j, gravity included, in joint j's frame
(for a URDF the child link frame), the moment about its origin.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")
from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

from stickslip.fmu import communication_points, initialize, input_references  # noqa: E402
from stickslip.motion import load_motion_for  # noqa: E402
from urdf_reference import (  # noqa: E402
    ARMS,
    bearing_normal_load,
    engine_inverse_dynamics,
    model_file,
    package_fmu,
    pinocchio_dynamics,
    pinocchio_model,
    reaction_quantities,
    rigid_variant,
)

# CI's full run only (scripts/test.sh --quick leaves it out): URDF arms' FMUs built and compared with Pinocchio
pytestmark = pytest.mark.full

REL = 1e-9
SAMPLES = 50
SEED = 19
VARIANTS = ("flexible", "rigid")
QUANTITIES = ("axial force", "radial force", "axial moment", "bending moment")

# Every joint on a cycloid (within the URDF's limits), staggered, at rest from 0.8 s on.
MOTIONS = {
    "kuka_iiwa": [
        ("lbr_iiwa_joint_1", 0.0, 0.8, 0.0, 0.7),
        ("lbr_iiwa_joint_2", 0.3, 0.9, 0.0, 0.7),
        ("lbr_iiwa_joint_3", 0.0, -0.6, 0.1, 0.8),
        ("lbr_iiwa_joint_4", -0.5, -1.2, 0.05, 0.75),
        ("lbr_iiwa_joint_5", 0.0, 0.7, 0.1, 0.6),
        ("lbr_iiwa_joint_6", 0.4, -0.4, 0.0, 0.8),
        ("lbr_iiwa_joint_7", 0.0, 1.0, 0.2, 0.8),
    ],
    "xarm6": [
        ("joint1", 0.0, 0.8, 0.0, 0.7),
        ("joint2", 0.0, 0.6, 0.0, 0.7),
        ("joint3", -0.5, -1.2, 0.05, 0.75),
        ("joint4", 0.0, 0.8, 0.1, 0.8),
        ("joint5", 0.3, 1.0, 0.1, 0.6),
        ("joint6", 0.0, 1.0, 0.2, 0.8),
    ],
}
STOP_TIME = 1.0
STEP = 1e-3
FIXED_SUBSTEPS = {"h_min": 1e-4, "h_max": 1e-4, "tolerance": 1e-12}


# ---------------------------------------------------------------------------
# fixtures


@pytest.fixture(scope="module")
def model_paths(tmp_path_factory):
    """{(arm, variant): model file}: the shipped file ("flexible") and its all-rigid variant."""
    out = {}
    for arm, path in ARMS.items():
        out[(arm, "flexible")] = path
        out[(arm, "rigid")] = rigid_variant(path, tmp_path_factory.mktemp(f"{arm}_rigid"))
    return out


def random_states(model, n: int, seed: int):
    rng = np.random.default_rng(seed)
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit
    assert np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)
    q = rng.uniform(lo, hi, (n, model.nq))
    qd = rng.uniform(-2.0, 2.0, (n, model.nv))
    qdd = rng.uniform(-20.0, 20.0, (n, model.nv))
    return q, qd, qdd


@pytest.fixture(scope="module")
def random_comparison(model_paths, tmp_path_factory):
    """{(arm, variant): (model file, engine's, Pinocchio's)} at the random states."""
    cache = {}

    def get(arm, variant):
        if (arm, variant) not in cache:
            path = model_paths[(arm, variant)]
            mf = model_file(path)
            model = pinocchio_model(mf)
            q, qd, qdd = random_states(model, SAMPLES, SEED + len(arm))
            eng = engine_inverse_dynamics(path, q, qd, qdd, tmp_path_factory.mktemp(f"id_{arm}_{variant}"))
            ref = pinocchio_dynamics(model, mf, q, qd, qdd)
            cache[(arm, variant)] = (mf, eng, ref)
        return cache[(arm, variant)]

    return get


def motion_toml(arm: str) -> str:
    lines = [f"end = {STOP_TIME!r}"]
    for name, q0, q1, t0, t1 in MOTIONS[arm]:
        lines += [
            "[[joint]]",
            f'name = "{name}"',
            f"cycloid = {{ q0 = {q0!r}, q1 = {q1!r}, t0 = {t0!r}, t1 = {t1!r} }}",
        ]
    return "\n".join(lines) + "\n"


def run_fmu(fmu, motion_path, parameters: dict) -> dict:
    """The FMU through fmpy over the motion file, outputs after every communication step."""
    md = read_model_description(str(fmu))
    unzipped = extract(str(fmu))
    n = sum(1 for v in md.modelVariables if v.name.startswith("q_star["))
    names = (
        [
            f"{b}[{i}]"
            for b in ("q", "qd", "qdd", "F_drive", "F_friction", "N_normal", "n_stick")
            for i in range(1, n + 1)
        ]
        + [f"{b}[{i},{k}]" for b in ("f", "n") for i in range(1, n + 1) for k in (1, 2, 3)]
        + [f"x_E[{k}]" for k in (1, 2, 3)]
        + ["n_substeps"]
    )
    vr = {v.name: v.valueReference for v in md.modelVariables}
    descriptions = {v.name: v.description or "" for v in md.modelVariables}
    refs = [vr[x] for x in names]
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="pinocchio"
    )
    slave.instantiate()
    try:
        motion = load_motion_for(motion_path, md)
        inputs = input_references(md)
        initialize(slave, md, parameters, inputs, motion, STEP)
        rows = [slave.getReal(refs) for _ in communication_points(slave, inputs, motion, STOP_TIME, STEP)]
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(unzipped, ignore_errors=True)
    data = np.array(rows, dtype=np.float64)
    out = {name: data[:, c] for c, name in enumerate(names)}
    out["n_joints"] = n
    out["descriptions"] = descriptions
    return out


@pytest.fixture(scope="module")
def fmu_runs(model_paths, tmp_path_factory):
    """{(arm, variant, settings): (model file, FMU outputs, Pinocchio at the FMU's states)}."""
    cache, fmus = {}, {}

    def get(arm, variant, settings="fixed"):
        key = (arm, variant, settings)
        if key not in cache:
            path = model_paths[(arm, variant)]
            mf = model_file(path)
            if (arm, variant) not in fmus:
                d = tmp_path_factory.mktemp(f"fmu_{arm}_{variant}")
                fmus[(arm, variant)] = (package_fmu(path, d / f"{arm}_{variant}.fmu"), d / "motion.toml")
                fmus[(arm, variant)][1].write_text(motion_toml(arm), encoding="utf-8")
            fmu, motion = fmus[(arm, variant)]
            out = run_fmu(fmu, motion, FIXED_SUBSTEPS if settings == "fixed" else {})
            n = out["n_joints"]
            assert n == mf.n
            q, qd, qdd = (np.stack([out[f"{b}[{i}]"] for i in range(1, n + 1)], axis=1) for b in ("q", "qd", "qdd"))
            ref = pinocchio_dynamics(pinocchio_model(mf), mf, q, qd, qdd, reaction_points=True)
            cache[key] = (mf, out, ref)
        return cache[key]

    return get


# ---------------------------------------------------------------------------
# comparison


def relative_deviation(actual, expected, scale_floor: float = 0.0) -> float:
    """max |actual - expected| over the samples / max |expected| over the samples."""
    scale = max(float(np.max(np.abs(expected))), scale_floor)
    return float(np.max(np.abs(np.asarray(actual) - np.asarray(expected)))) / scale


def assert_reactions_agree(mf, eng_f, eng_n, ref_f, ref_n, where: str):
    """Per joint: the four reaction quantities and the vectors, 1e-9 relative to the largest
    magnitude of each over the samples (floored at 1e-12 of the arm's largest force or moment,
    so that a quantity that is zero by symmetry compares absolutely)."""
    f_floor = 1e-12 * float(np.max(np.abs(ref_f)))
    n_floor = 1e-12 * float(np.max(np.abs(ref_n)))
    failures, worst = [], {}
    for i in range(1, mf.n + 1):
        axis = mf.axis(i)
        got = reaction_quantities(eng_f[:, i - 1], eng_n[:, i - 1], axis)
        want = reaction_quantities(ref_f[:, i - 1], ref_n[:, i - 1], axis)
        for name in QUANTITIES:
            dev = relative_deviation(got[name], want[name], f_floor if "force" in name else n_floor)
            worst[name] = max(worst.get(name, 0.0), dev)
            if dev > REL:
                failures.append(
                    f"joint {i} ({mf.names[i - 1]}) {name}: {dev:.3e} relative "
                    f"(largest {np.max(np.abs(want[name])):.6g})"
                )
        for name, a, b, floor in (("force vector", eng_f, ref_f, f_floor), ("moment vector", eng_n, ref_n, n_floor)):
            dev = relative_deviation(a[:, i - 1], b[:, i - 1], floor)
            worst[name] = max(worst.get(name, 0.0), dev)
            if dev > REL:
                failures.append(f"joint {i} ({mf.names[i - 1]}) {name}: {dev:.3e} relative")
    print(f"{where}: worst relative deviations " + ", ".join(f"{k} {v:.2e}" for k, v in worst.items()))
    assert not failures, f"{where}: reactions differ from Pinocchio's beyond {REL:g}:\n" + "\n".join(failures)


# ---------------------------------------------------------------------------
# the convention, by hand

PENDULUM_URDF = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="base"/>
  <joint name="hinge" type="revolute">
    <parent link="base"/>
    <child link="arm"/>
    <origin xyz="0 0 1" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="100" velocity="10"/>
  </joint>
  <link name="arm">
    <inertial>
      <origin xyz="{L} 0 0" rpy="0 0 0"/>
      <mass value="{m}"/>
      <inertia ixx="{I}" ixy="0" ixz="0" iyy="{I}" iyz="0" izz="{I}"/>
    </inertial>
  </link>
</robot>
"""

PENDULUM_TOML = """name = "pendulum"
urdf = "pendulum.urdf"
base_link = "base"
tip_link = "arm"
end_point = [{L}, 0.0, 0.0]
gravity = [0.0, 0.0, -{g}]
"""


def pendulum_by_hand(L, m, inertia, g, q, qd, qdd):
    """A point mass m at (L, 0, 0) of the arm's frame (plus ``inertia`` about it) on a hinge
    about y, 1 m above the base; the arm's frame is Ry(q). The force the base exerts on the
    arm is m (a_c - g), in the arm's frame: a_c = (-qd² L, 0, -qdd L), g = R^T (0, 0, -g) =
    (g sin q, 0, -g cos q); the moment about the hinge is r x f + inertia qdd about y."""
    s, c = math.sin(q), math.cos(q)
    f = m * np.array([-qd * qd * L - s * g, 0.0, -qdd * L + c * g])
    n = np.array([0.0, -L * f[2] + inertia * qdd, 0.0])
    tau = n[1]
    x_e = np.array([L * c, 0.0, 1.0 - L * s])
    return f, n, tau, x_e


def test_pinocchio_and_engine_reactions_equal_hand_computed_pendulum(tmp_path):
    """Pinocchio's data.f[1] (and tau, the end point) and the engine's inverse_dynamics f[1],
    n[1], tau[1], x_E on a one-link URDF pendulum equal the reactions computed by hand: the
    force and moment the parent applies on the child, gravity included, in the child link
    frame, about the joint origin. To 1e-12 relative to the largest magnitude."""
    L, m, inertia, g = 0.7, 3.0, 0.02, 9.81
    (tmp_path / "pendulum.urdf").write_text(PENDULUM_URDF.format(L=L, m=m, I=inertia), encoding="utf-8")
    (tmp_path / "pendulum.toml").write_text(PENDULUM_TOML.format(L=L, g=g), encoding="utf-8")
    mf = model_file(tmp_path / "pendulum.toml")
    model = pinocchio_model(mf)
    states = np.array([[0.0, 0.0, 0.0], [0.4, 1.3, -2.5], [-1.2, -0.8, 7.0], [2.5, 2.0, 3.0]])
    q, qd, qdd = states[:, :1], states[:, 1:2], states[:, 2:]
    ref = pinocchio_dynamics(model, mf, q, qd, qdd)
    eng = engine_inverse_dynamics(tmp_path / "pendulum.toml", q, qd, qdd, tmp_path)
    hand = [pendulum_by_hand(L, m, inertia, g, *row) for row in states]
    hand_f = np.array([h[0] for h in hand])
    hand_n = np.array([h[1] for h in hand])
    hand_tau = np.array([h[2] for h in hand])
    hand_x = np.array([h[3] for h in hand])
    for who, got in (("Pinocchio", ref), ("engine", eng)):
        assert relative_deviation(got["f"][:, 0], hand_f) < 1e-12, (who, got["f"][:, 0], hand_f)
        assert relative_deviation(got["n"][:, 0], hand_n) < 1e-12, (who, got["n"][:, 0], hand_n)
        assert relative_deviation(got["tau"][:, 0], hand_tau) < 1e-12, (who, got["tau"][:, 0], hand_tau)
        assert relative_deviation(got["x_E"], hand_x) < 1e-12, (who, got["x_E"], hand_x)
        assert relative_deviation(got["M"][:, 0, 0], np.full(len(states), m * L * L + inertia)) < 1e-12
    # At q = 0, at rest: the hinge holds the weight (f = (0, 0, m g)) and the moment -m g L about y.
    assert np.allclose(ref["f"][0, 0], [0.0, 0.0, m * g]) and np.isclose(ref["n"][0, 0, 1], -m * g * L)


def test_example_arms_are_pure_chains_that_pinocchio_reads_as_the_engine_chain():
    """Both example URDFs are serial chains (no link off the base_link -> tip_link chain, no
    fixed joint after the tip), so Pinocchio's model of the whole file is the engine's chain:
    the same moving joints in chain order, the same total mass of the moving links."""
    for arm, path in ARMS.items():
        mf = model_file(path)
        model = pinocchio_model(mf)  # asserts the joint order
        import xml.etree.ElementTree as ET

        root = ET.parse(mf.urdf).getroot()
        joints = root.findall("joint")
        parents = [j.find("parent").get("link") for j in joints]
        assert len(parents) == len(set(parents)), f"{arm}: a link with two children"
        moving_mass = sum(model.inertias[j].mass for j in range(1, model.njoints))
        assert moving_mass > 0
        assert model.frames[model.getFrameId(mf.tip_link)].parentJoint == model.njoints - 1


# ---------------------------------------------------------------------------
# random states


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_random_states_generalized_forces_equal_pinocchio_rnea(random_comparison, arm, variant):
    """tau[i] = M q̈ + bias (gravity included) of every joint, the left side of each flexible
    joint's equation of motion, equals pin.rnea at 50 random states to 1e-9 relative (per
    joint, to its largest |tau| over the states)."""
    mf, eng, ref = random_comparison(arm, variant)
    devs = [relative_deviation(eng["tau"][:, i], ref["tau"][:, i]) for i in range(mf.n)]
    print(f"{arm}/{variant}: tau worst relative deviation {max(devs):.2e} (per joint {np.array(devs)})")
    assert max(devs) <= REL, f"{arm}/{variant}: tau per joint {devs}"


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_random_states_joint_reactions_at_joint_origins_equal_pinocchio(random_comparison, arm, variant):
    """f[i], n[i] at the joint origin in the child link frame equal Pinocchio's data.f[i] at 50
    random states: axial force, radial force magnitude, axial moment and bending moment
    magnitude (and the vectors) to 1e-9 relative per joint."""
    mf, eng, ref = random_comparison(arm, variant)
    assert_reactions_agree(mf, eng["f"], eng["n"], ref["f"], ref["n"], f"{arm}/{variant} random states")


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_random_states_end_point_equals_pinocchio_tip_frame(random_comparison, arm, variant):
    """x_E equals Pinocchio's placement of the tip_link frame applied to the model file's
    end_point, to 1e-9 relative to the largest distance of the end point from the base."""
    _, eng, ref = random_comparison(arm, variant)
    scale = float(np.max(np.linalg.norm(ref["x_E"], axis=1)))
    dev = float(np.max(np.abs(eng["x_E"] - ref["x_E"]))) / scale
    print(f"{arm}/{variant}: x_E worst relative deviation {dev:.2e}")
    assert dev <= REL


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_random_states_mass_matrix_equals_pinocchio_crba(random_comparison, arm, variant):
    """M equals pin.crba at 50 random states: M_ij to 1e-9 relative to the largest
    sqrt(M_ii M_jj) over the states (which bounds |M_ij|); M symmetric."""
    _, eng, ref = random_comparison(arm, variant)
    d = np.sqrt(np.einsum("kii->ki", ref["M"]))
    scale = np.max(d[:, :, None] * d[:, None, :], axis=0)
    dev = float(np.max(np.abs(eng["M"] - ref["M"]) / scale))
    print(f"{arm}/{variant}: M worst relative deviation {dev:.2e}")
    assert dev <= REL
    assert (
        np.array_equal(eng["M"], np.transpose(eng["M"], (0, 2, 1)))
        or float(np.max(np.abs(eng["M"] - np.transpose(eng["M"], (0, 2, 1))) / scale)) <= 1e-15
    )


# ---------------------------------------------------------------------------
# a simulated motion through the FMU


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_fmu_motion_reactions_at_reaction_points_equal_pinocchio(fmu_runs, arm, variant):
    """Over a 1 s motion of every joint through the FMU (fixed sub-steps of 1e-4 s), the
    outputs f[i,k], n[i,k] (at the reaction reference point, in the URDF child link frame)
    equal Pinocchio's data.f[i] at the FMU's (q, q̇, q̈) moved to that point (n_P = n_O −
    P × f): axial force, radial force, axial moment, bending moment to 1e-9 relative per
    joint; and every variable description names the URDF joint."""
    mf, out, ref = fmu_runs(arm, variant)
    n = mf.n
    f = np.stack([np.stack([out[f"f[{i},{k}]"] for k in (1, 2, 3)], axis=1) for i in range(1, n + 1)], axis=1)
    m = np.stack([np.stack([out[f"n[{i},{k}]"] for k in (1, 2, 3)], axis=1) for i in range(1, n + 1)], axis=1)
    assert_reactions_agree(mf, f, m, ref["f"], ref["n"], f"{arm}/{variant} FMU motion")
    for i, name in enumerate(mf.names, start=1):
        for var in (f"q[{i}]", f"F_drive[{i}]", f"f[{i},1]", f"n[{i},3]"):
            assert f"`{name}`" in out["descriptions"][var], (var, out["descriptions"][var])


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_fmu_motion_equations_of_motion_equal_pinocchio_rnea(fmu_runs, arm, variant):
    """Over the FMU's 1 s motion (fixed sub-steps of 1e-4 s, Newmark tolerance 1e-12), each
    joint's equation of motion holds with Pinocchio's left side: pin.rnea(q, q̇, q̈)[i] =
    F_drive[i] − F_friction[i] (the generalized force, FMU description of F_friction), to
    1e-9 relative to the joint's largest |tau|: for the flexible joints (drive spring and
    damper, bearing friction, stick-slip) and for the rigid ones (the force the drive
    supplies)."""
    mf, out, ref = fmu_runs(arm, variant)
    assert ("flexible drive" in out["descriptions"]["q[1]"]) == (variant == "flexible")
    devs = []
    for i in range(1, mf.n + 1):
        rhs = out[f"F_drive[{i}]"] - out[f"F_friction[{i}]"]
        devs.append(relative_deviation(rhs, ref["tau"][:, i - 1]))
    flexible = [mf.flexible(i) for i in range(1, mf.n + 1)]

    def worst(sel):
        return (
            ", ".join(f"{i}: {d:.2e}" for i, (d, fl) in enumerate(zip(devs, flexible, strict=True), 1) if fl == sel)
            or "none"
        )

    stiction = [int(out[f"n_stick[{i}]"][-1]) for i in range(1, mf.n + 1)]
    print(
        f"{arm}/{variant} FMU motion: equation of motion relative deviation, flexible joints {worst(True)}; "
        f"rigid joints {worst(False)}; {out['n_substeps'][-1]:.0f} sub-steps, stiction phases per joint {stiction}"
    )
    assert max(devs) <= REL, f"{arm}/{variant}: per joint {devs}"
    # The motion moved every joint and the flexible ones deflected.
    for i in range(1, mf.n + 1):
        assert np.ptp(out[f"q[{i}]"]) > 0.5
        assert np.max(np.abs(out[f"qdd[{i}]"])) > 1.0


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_fmu_motion_end_point_and_bearing_loads_equal_pinocchio(fmu_runs, arm, variant):
    """Over the FMU's motion, x_E equals Pinocchio's tip frame applied to end_point (1e-9
    relative to the largest distance from the base), and each joint's bearing normal load
    N_normal = R_A + R_B + |f_z| equals that load computed from Pinocchio's reactions at the
    reaction point (1e-9 relative to its largest value)."""
    mf, out, ref = fmu_runs(arm, variant)
    x = np.stack([out[f"x_E[{k}]"] for k in (1, 2, 3)], axis=1)
    dev = float(np.max(np.abs(x - ref["x_E"]))) / float(np.max(np.linalg.norm(ref["x_E"], axis=1)))
    devs = {}
    for i in range(1, mf.n + 1):
        b = mf.bearings(i)
        if b is None:
            assert np.all(out[f"N_normal[{i}]"] == 0.0)
            continue
        want = bearing_normal_load(b, ref["f"][:, i - 1], ref["n"][:, i - 1])
        devs[i] = relative_deviation(out[f"N_normal[{i}]"], want)
    print(
        f"{arm}/{variant} FMU motion: x_E {dev:.2e}, N_normal per joint "
        + ", ".join(f"{i}: {d:.2e}" for i, d in devs.items())
    )
    assert dev <= REL
    assert devs and max(devs.values()) <= REL, devs


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_fmu_default_settings_equation_of_motion_within_newmark_tolerance(fmu_runs, arm):
    """With the FMU's default settings (error-controlled sub-steps, error_tolerance 5e-4) the
    Newmark iteration stops at 1e-4 × error_tolerance = 5e-8 relative, so the flexible joints'
    equation of motion holds with Pinocchio's RNEA to 1e-6 relative (per joint, to its largest
    |tau|); the reactions, functions of the state alone, still agree to 1e-9."""
    mf, out, ref = fmu_runs(arm, "flexible", "default")
    devs = [
        relative_deviation(out[f"F_drive[{i}]"] - out[f"F_friction[{i}]"], ref["tau"][:, i - 1])
        for i in range(1, mf.n + 1)
    ]
    print(f"{arm} FMU defaults: equation of motion per joint {np.array(devs)}")
    assert max(devs) <= 1e-6
    n = mf.n
    f = np.stack([np.stack([out[f"f[{i},{k}]"] for k in (1, 2, 3)], axis=1) for i in range(1, n + 1)], axis=1)
    m = np.stack([np.stack([out[f"n[{i},{k}]"] for k in (1, 2, 3)], axis=1) for i in range(1, n + 1)], axis=1)
    assert_reactions_agree(mf, f, m, ref["f"], ref["n"], f"{arm} FMU defaults")


# ---------------------------------------------------------------------------
# the MuJoCo arm of scripts/bench_mujoco.py


def _bench_mujoco():
    import importlib.util

    from urdf_reference import ROOT

    spec = importlib.util.spec_from_file_location("bench_mujoco", ROOT / "scripts" / "bench_mujoco.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_mujoco_bench_arm_has_pinocchio_dynamics_and_model_file_drives(arm):
    """The arm scripts/bench_mujoco.py times is the same URDF arm: MuJoCo's mass matrix and
    bias forces (gravity, Coriolis; damping and friction off) equal Pinocchio's CRBA and RNEA
    at 10 random states to 1e-9 relative (the KUKA iiwa; the xArm 6 only where MuJoCo's
    balanceinertia leaves the URDF's inertias: its total mass), a flexible drive is a
    position actuator with kp = k, kv = h, each dof's damping is zero and its frictionloss is
    positive exactly where the model file gives friction."""
    mujoco = pytest.importorskip("mujoco")
    bench = _bench_mujoco()
    mf = model_file(ARMS[arm])
    m, d, _, _ = bench.mujoco_arm(ARMS[arm], 2e-6)
    model = pinocchio_model(mf)
    assert m.nq == m.nv == mf.n
    assert [m.joint(j).name for j in range(m.njnt)] == mf.names
    assert math.isclose(
        float(np.sum(m.body_mass)), sum(model.inertias[j].mass for j in range(1, model.njoints)), rel_tol=1e-12
    )
    assert np.all(m.dof_damping == 0.0)
    for i, name in enumerate(mf.names, start=1):
        entry = mf.entries.get(name, {})
        assert (m.dof_frictionloss[i - 1] > 0) == ("friction" in entry)
        a = m.actuator(f"drive_{name}")
        if mf.flexible(i):
            assert a.gainprm[0] == entry["drive"]["k"] and a.biasprm[2] == -entry["drive"]["h"]
    if arm != "kuka_iiwa":
        return
    q, qd, _ = random_states(model, 10, SEED)
    m.dof_frictionloss[:] = 0.0
    data = model.createData()
    full = np.zeros((m.nv, m.nv))
    for k in range(len(q)):
        d.qpos[:], d.qvel[:], d.ctrl[:] = q[k], qd[k], q[k]  # actuators at zero deflection: no force
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, full)
        M = pin.crba(model, data, q[k])
        M = np.triu(M) + np.triu(M, 1).T
        assert np.max(np.abs(full - M)) <= REL * np.max(np.abs(M))
        bias = pin.rnea(model, data, q[k], qd[k], np.zeros(mf.n))
        assert np.max(np.abs(d.qfrc_bias - bias)) <= REL * np.max(np.abs(bias))
