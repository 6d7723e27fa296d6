"""The FMU archive passes fmpy's validation and has the layout the issue asks for."""

import zipfile

from fmpy.validation import validate_fmu

from helpers import input_names, require_fmu, variables


def test_validate_fmu_returns_no_message():
    """fmpy.validation.validate_fmu (schema, variable names, ModelStructure, start
    values, causality/variability, units) returns an empty list of problems."""
    path = require_fmu()
    problems = validate_fmu(str(path))
    assert problems == [], "\n".join(problems)


def test_archive_layout_and_interface():
    """The archive holds modelDescription.xml, binaries/linux64/StickSlipManipulator.so
    and resources/model.toml; the modelDescription is FMI 2.0 CoSimulation only, with the
    capability flags the tests rely on and the structured interface of the issue, every
    variable described and every physical input/output with its unit."""
    path = require_fmu()
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    assert "modelDescription.xml" in names
    assert "binaries/linux64/StickSlipManipulator.so" in names
    assert "resources/model.toml" in names

    v = variables(str(path))
    md = v.md
    assert md.fmiVersion == "2.0"
    assert md.modelExchange is None
    cs = md.coSimulation
    assert cs.modelIdentifier == "StickSlipManipulator"
    assert cs.canHandleVariableCommunicationStepSize
    assert cs.canInterpolateInputs
    assert cs.canGetAndSetFMUstate
    assert cs.canSerializeFMUstate
    assert cs.canNotUseMemoryManagementFunctions
    assert float(md.defaultExperiment.startTime) == 0.0
    assert float(md.defaultExperiment.stopTime) == 2.0
    assert float(md.defaultExperiment.stepSize) == 1e-3

    for name in input_names():
        assert v.by_name[name].causality == "input", name
    expected_outputs = (
        [
            f"{g}[{i}]"
            for g in ("q", "qd", "qdd", "stick", "F_drive", "F_friction", "N_normal", "eps_joint")
            for i in range(1, 5)
        ]
        + [f"{g}[{i},{k}]" for g in ("f", "n") for i in range(1, 5) for k in range(1, 4)]
        + ["eps", "x_E[1]", "x_E[2]", "x_E[3]", "E_kin", "E_pot", "E_spring", "W_drive", "Q_friction", "Q_damping"]
    )
    for name in expected_outputs:
        assert v.by_name[name].causality == "output", name
    assert v.by_name["stick[1]"].type == "Boolean"
    for name in ["k[1]", "k[3]", "h[1]", "mu_k[3]", "mu_s[3]", "m[1]", "slider_a[3]", "d_A[1]", "l_A[1]"]:
        assert v.by_name[name].causality == "parameter" and v.by_name[name].variability == "tunable", name
    for name in ["h_min", "h_max", "error_tolerance", "newmark_beta", "newmark_gamma", "tolerance"]:
        assert v.by_name[name].variability == "fixed", name
    # The error control's tolerance is the default experiment's (fmi2SetupExperiment sets it).
    assert float(md.defaultExperiment.tolerance) == float(v.by_name["error_tolerance"].start)
    for var in md.modelVariables:
        assert var.description, f"{var.name} has no description"
        # every physical input and output has a unit (counts are dimensionless)
        counts = var.name.startswith("n_stick[") or var.name in ("n_substeps", "n_rejected")
        if var.type == "Real" and var.causality in ("input", "output") and not counts:
            assert var.unit, f"{var.name} has no unit"
    units = {
        "q[1]": "rad",
        "q[3]": "m",
        "qd[3]": "m/s",
        "F_drive[1]": "N.m",
        "F_drive[3]": "N",
        "f[1,1]": "N",
        "n[1,1]": "N.m",
        "eps": "m",
        "x_E[1]": "m",
        "E_kin": "J",
        "q_star[1]": "rad",
        "h_last": "s",
        "h_min": "s",
        "h_max": "s",
    }
    for name, unit in units.items():
        assert v.by_name[name].unit == unit, (name, v.by_name[name].unit)
