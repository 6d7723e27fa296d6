"""The FMU of a URDF arm (the KUKA LBR iiwa of models/urdf/kuka_iiwa, built by
``scripts/build_fmu.sh --model``, see urdf_fmus.py) as a master sees it, and what a
corrupted or missing packaged URDF does to it.

* fmpy's validation finds no problems; 7 joints, every joint variable indexed 1..7 in
  chain order and its description naming the URDF joint of its index;
* resources/ holds model.toml, naming the URDF packaged beside it, and that URDF byte for
  byte; model.toml is the source model file but for its ``urdf`` line;
* fmpy's simulate_fmu runs a motion of all 7 joints with every output finite, rigid
  joints on their prescribed positions and flexible ones close to them;
* the packaged URDF corrupted (a negative mass, a NaN inertia, truncated, changed but
  valid) or removed, or model.toml naming a path outside resources/: fmi2Instantiate
  returns NULL (fmpy raises), the logged fmi2Error message names the URDF element, the
  file or the GUID mismatch, and the Python process lives on to instantiate the intact
  FMU again.
"""

import re
import zipfile

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave, fmi2Error
from fmpy.validation import validate_fmu

from helpers import LogCapture, scratch_dir
from urdf_fmus import BUILD_SECONDS, IIWA_JOINTS, IIWA_MODEL, IIWA_URDF, require_iiwa_fmu, rezip

# CI's full run only (scripts/test.sh --quick leaves it out): URDF arms' FMUs built
pytestmark = pytest.mark.full

N = 7
# Per-joint families are indexed by joint; x_E by coordinate.
COMPONENT_FAMILIES = {"x_E"}
_INDEXED = re.compile(r"^([A-Za-z_]+)\[(\d+)(?:,(\d+))?\]$")


@pytest.fixture(scope="module")
def fmu():
    path = require_iiwa_fmu()
    print(f"iiwa FMU: {path} (build {BUILD_SECONDS.get('iiwa', 0.0):.1f} s)")
    return path


@pytest.fixture(scope="module")
def md(fmu):
    return read_model_description(str(fmu))


# ---------------------------------------------------------------------------
# the packaged FMU


def test_fmpy_validation_finds_no_problems(fmu):
    assert validate_fmu(str(fmu)) == []


def test_seven_joints_indexed_1_to_7_each_description_names_its_urdf_joint(md):
    families = {}
    for v in md.modelVariables:
        m = _INDEXED.match(v.name)
        if not m or m.group(1) in COMPONENT_FAMILIES:
            continue
        i = int(m.group(2))
        families.setdefault(m.group(1), set()).add(i)
        assert 1 <= i <= N, v.name
        named = re.findall(r"`(lbr_iiwa_joint_\d+)`", v.description or "")
        assert named and set(named) == {IIWA_JOINTS[i - 1]}, f"{v.name}: {v.description!r}"
    # Every joint has its coordinates, inputs and reactions; the drive and friction
    # parameters exist for the joints the model file makes flexible (1, 2, 4).
    for name in ("q", "qd", "qdd", "q_star", "qd_star", "qdd_star", "stick", "F_drive", "N_normal", "m", "f", "n"):
        assert families.get(name) == set(range(1, N + 1)), (name, families.get(name))
    for name in ("k", "h", "mu_k", "mu_s", "d_A", "l_B"):
        assert families.get(name) == {1, 2, 4}, (name, families.get(name))
    assert {v.name for v in md.modelVariables if v.name.startswith("x_E[")} == {"x_E[1]", "x_E[2]", "x_E[3]"}
    assert md.coSimulation.modelIdentifier == "StickSlipManipulator"


def test_resources_hold_the_model_file_naming_the_packaged_urdf_and_the_urdf(fmu):
    with zipfile.ZipFile(fmu) as z:
        resources = sorted(n for n in z.namelist() if n.startswith("resources/"))
        model = z.read("resources/model.toml").decode("utf-8")
        urdf = z.read("resources/kuka_iiwa.urdf")
    assert resources == ["resources/kuka_iiwa.urdf", "resources/model.toml"]
    assert urdf == IIWA_URDF.read_bytes()
    urdf_lines = [line for line in model.splitlines() if re.match(r"\s*urdf\s*=", line)]
    assert len(urdf_lines) == 1 and re.match(r'urdf = "kuka_iiwa.urdf"', urdf_lines[0]), urdf_lines
    # Everything else as the source model file says it.
    source = IIWA_MODEL.read_text(encoding="utf-8")

    def strip(text):
        return [line for line in text.splitlines() if not re.match(r"\s*urdf\s*=", line)]

    assert strip(model) == strip(source)


def _cycloid(t, q0, q1, t0, t1):
    """q, qd, qdd of a cycloid from q0 at t0 to q1 at t1 (held outside)."""
    T = t1 - t0
    s = np.clip((t - t0) / T, 0.0, 1.0)
    inside = (t > t0) & (t < t1)
    q = q0 + (q1 - q0) * (s - np.sin(2 * np.pi * s) / (2 * np.pi))
    qd = np.where(inside, (q1 - q0) / T * (1 - np.cos(2 * np.pi * s)), 0.0)
    qdd = np.where(inside, (q1 - q0) / T**2 * 2 * np.pi * np.sin(2 * np.pi * s), 0.0)
    return q, qd, qdd


def test_simulate_fmu_runs_a_motion_of_all_joints_with_finite_outputs(fmu, md):
    stop, dt = 0.4, 1e-3
    t = np.array([k * dt for k in range(round(stop / dt) + 1)])
    names = [f"{g}[{i}]" for g in ("q_star", "qd_star", "qdd_star") for i in range(1, N + 1)]
    signals = np.zeros(len(t), dtype=[("time", float)] + [(n, float) for n in names])
    signals["time"] = t
    targets = [0.3, 0.5, -0.4, -0.6, 0.4, -0.3, 0.6]
    for i, q1 in enumerate(targets, start=1):
        q, qd, qdd = _cycloid(t, 0.0, q1, 0.02 * i, 0.25 + 0.01 * i)
        signals[f"q_star[{i}]"], signals[f"qd_star[{i}]"], signals[f"qdd_star[{i}]"] = q, qd, qdd
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    result = simulate_fmu(str(fmu), stop_time=stop, output_interval=dt, step_size=dt, input=signals, output=outputs)
    assert len(result) == len(t)
    bad = [n for n in outputs if not np.all(np.isfinite(result[n].astype(float)))]
    assert not bad, f"non-finite outputs: {bad}"
    end = -1
    for i in range(1, N + 1):
        q, q_star = result[f"q[{i}]"], signals[f"q_star[{i}]"]
        # Rigid joints (3, 5, 6, 7) follow their drive; flexible ones (1, 2, 4) lag a little.
        tol = 2e-2 if i in (1, 2, 4) else 1e-3
        assert np.max(np.abs(q - q_star)) < tol, (i, float(np.max(np.abs(q - q_star))))
        assert abs(q[end] - targets[i - 1]) < tol
    # The arm moved, and the end point with it; the reactions carry the arm's weight.
    assert np.linalg.norm([result[f"x_E[{k}]"][end] - result[f"x_E[{k}]"][0] for k in (1, 2, 3)]) > 0.05
    total_mass = 4 + 4 + 3 + 2.7 + 1.7 + 1.8 + 0.3
    f1 = np.linalg.norm([result[f"f[1,{k}]"][0] for k in (1, 2, 3)])
    assert abs(f1 - total_mass * 9.81) < 1e-6 * f1, f1


# ---------------------------------------------------------------------------
# corrupted and missing resources


def _instantiate(fmu_file, name):
    """fmi2Instantiate of ``fmu_file`` through fmpy: (instantiated?, logged fmi2Error messages).
    The instance (or the library) is freed again."""
    md = read_model_description(str(fmu_file))
    unzipdir = extract(str(fmu_file), unzipdir=str(scratch_dir() / f"unzip-{name}"))
    log = LogCapture()
    slave = FMU2Slave(
        guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name
    )
    try:
        slave.instantiate(callbacks=log.callbacks, loggingOn=False)
    except Exception as e:  # noqa: BLE001 -- fmpy raises a bare Exception("Failed to instantiate model")
        assert "instantiate" in str(e).lower(), e
        slave.freeLibrary()
        return False, [m for (_, st, _, m) in log.records if st == fmi2Error], unzipdir
    slave.freeInstance()
    return True, [m for (_, st, _, m) in log.records if st == fmi2Error], unzipdir


URDF_ENTRY = "resources/kuka_iiwa.urdf"
_TEXT = IIWA_URDF.read_text(encoding="utf-8")
LINK_3 = '<link name="lbr_iiwa_link_3">'


def _in_link_3(old, new):
    """The URDF with ``old`` replaced by ``new`` in link 3's inertial only."""
    at = _TEXT.index(LINK_3)
    end = _TEXT.index("</inertial>", at)
    assert old in _TEXT[at:end]
    return (_TEXT[:at] + _TEXT[at:end].replace(old, new, 1) + _TEXT[end:]).encode("utf-8")


# case: (entries replaced, entries removed, words every one of which an fmi2Error message has)
CORRUPTIONS = {
    "negative-mass": (
        {URDF_ENTRY: _in_link_3('<mass value="3"/>', '<mass value="-1"/>')},
        (),
        ["fmi2Instantiate", "URDF kuka_iiwa.urdf", LINK_3 + "<inertial><mass>", "-1 is negative"],
    ),
    "nan-inertia": (
        {URDF_ENTRY: _in_link_3('ixx="0.08"', 'ixx="nan"')},
        (),
        ["fmi2Instantiate", "URDF kuka_iiwa.urdf", LINK_3 + "<inertial><inertia>", "`ixx`", "not finite"],
    ),
    "truncated": (
        {URDF_ENTRY: IIWA_URDF.read_bytes()[: len(IIWA_URDF.read_bytes()) // 2]},
        (),
        ["fmi2Instantiate", "URDF kuka_iiwa.urdf", "not well-formed XML"],
    ),
    "not-utf8": (
        {URDF_ENTRY: IIWA_URDF.read_bytes().replace(b"lbr_iiwa_link_3", b"lbr_iiwa_link_\xff", 1)},
        (),
        ["fmi2Instantiate", "cannot read the URDF", "kuka_iiwa.urdf", "UTF-8"],
    ),
    "empty": ({URDF_ENTRY: b""}, (), ["fmi2Instantiate", "URDF kuka_iiwa.urdf", "no <robot> element"]),
    # A URDF that is valid but not the one the FMU was built from: its GUID says so.
    "changed-but-valid": (
        {URDF_ENTRY: _in_link_3('<mass value="3"/>', '<mass value="3.5"/>')},
        (),
        ["fmi2Instantiate", "does not match", "GUID"],
    ),
    "removed": ({}, (URDF_ENTRY,), ["fmi2Instantiate", "cannot read the URDF", "resources", "kuka_iiwa.urdf"]),
}


@pytest.mark.parametrize("case", list(CORRUPTIONS))
def test_corrupted_or_missing_packaged_urdf_fails_instantiate_cleanly_naming_it(fmu, case, tmp_path):
    replace, remove, words = CORRUPTIONS[case]
    bad = rezip(fmu, tmp_path / f"{case}.fmu", replace=replace, remove=remove)
    assert read_model_description(str(bad)).guid == read_model_description(str(fmu)).guid
    ok, errors, unzipdir = _instantiate(bad, f"corrupt-{case}")
    assert not ok, f"{case}: fmi2Instantiate succeeded"
    assert any(all(w in m for w in words) for m in errors), f"{case}: no fmi2Error message with {words}:\n" + "\n".join(
        errors
    )
    if case == "removed":
        assert any(str(unzipdir) in m for m in errors), errors  # the full path
    # fmpy's one-call simulation raises too, and the process is fine: the intact FMU
    # instantiates again.
    with pytest.raises(Exception, match="Failed to instantiate model"):  # fmpy's bare Exception
        simulate_fmu(str(bad), stop_time=0.01)
    ok, errors, _ = _instantiate(fmu, f"intact-after-{case}")
    assert ok and not errors, errors


@pytest.mark.parametrize("urdf_line", ['urdf = "../kuka_iiwa.urdf"', 'urdf = "/etc/passwd"', 'urdf = ""'])
def test_model_file_naming_a_urdf_outside_resources_is_refused(fmu, urdf_line, tmp_path):
    with zipfile.ZipFile(fmu) as z:
        model = z.read("resources/model.toml").decode("utf-8")
    edited = re.sub(r'(?m)^urdf = "kuka_iiwa.urdf".*$', urdf_line, model)
    assert edited != model
    bad = rezip(fmu, tmp_path / "outside.fmu", replace={"resources/model.toml": edited.encode("utf-8")})
    ok, errors, _ = _instantiate(bad, "outside")
    assert not ok
    assert any("a packaged model names a file in resources/" in m for m in errors), "\n".join(errors)


def test_intact_fmu_instantiates_without_errors(fmu):
    ok, errors, _ = _instantiate(fmu, "intact")
    assert ok and not errors, errors
