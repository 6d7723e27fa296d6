// Model files and parameter changes: a bad model gets one clear error, never a
// panic. The shipped reference file `models/reference_rrpr.toml` must parse to
// the RRPR arm it describes (and equal `Model::reference_rrpr()`); every
// rejected case below is made by one small textual edit of that file and must
// come back as exactly one `ModelError` of the expected variant whose field
// names the offending entry (e.g. `joint[3].drive.k`, with 1-based joint
// numbers as in the file) and whose message carries that field and the reason;
// syntax errors name the key and the line. `Model::set_parameter` must reject
// out-of-range and non-finite values and parameters a joint does not have,
// leaving the model untouched, while relations between parameters are left to
// `Model::validate`. Long generated chains (24 and `MAX_JOINTS` joints) must
// parse and validate, one joint more must not.
//
// Motor drives (`drive = { type = "motor", k, h, clearance, gear_ratio,
// rotor_inertia, motor_viscous, motor_coulomb }`): the shipped
// `models/reference_rrpr_motor.toml` parses with every field to the reference
// arm with motors on joints 1 and 3 (and equals `Model::reference_rrpr_motor()`);
// h, clearance, motor_viscous and motor_coulomb default to 0; missing
// gear_ratio or rotor_inertia, an unknown key, an unknown drive type are
// syntax errors naming the key and the line; values outside GEAR_RATIO
// (0, 1e6], ROTOR_INERTIA (0, 1000], MOTOR_VISCOUS and MOTOR_COULOMB [0, 1e6]
// are refused naming `joint[i].drive.<key>`; the four motor parameters
// (gear_ratio, J_m, b_m, tau_c) exist on motor joints only, are range
// checked by `set_parameter`, and changing them keeps the model's layout.

use stick_slip_manipulator::model::{
    ContactGeometry, Drive, JointKind, Parameter, Range, Rotor, MAX_JOINTS, REFERENCE_RRPR_MOTOR_TOML,
    REFERENCE_RRPR_TOML,
};
use stick_slip_manipulator::{Model, ModelError, Simulator};

const REFERENCE_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models/reference_rrpr.toml");
const MOTOR_REFERENCE_PATH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models/reference_rrpr_motor.toml");
const JOINT_HEADER: &str = "[[joint]]";

// ---------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------

/// The reference text with the first occurrence of `from` replaced by `to`.
#[track_caller]
fn edit(from: &str, to: &str) -> String {
    edit_text(REFERENCE_RRPR_TOML, from, to)
}

#[track_caller]
fn edit_text(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "the text does not contain `{from}`; the edit would be a no-op");
    text.replacen(from, to, 1)
}

/// Byte range of the `[[joint]]` section of joint `number` (1-based) in `text`.
#[track_caller]
fn joint_section(text: &str, number: usize) -> std::ops::Range<usize> {
    let starts: Vec<usize> = text.match_indices(JOINT_HEADER).map(|(i, _)| i).collect();
    assert!(number >= 1 && number <= starts.len(), "the text has no joint {number}");
    let start = starts[number - 1];
    let end = starts.get(number).copied().unwrap_or(text.len());
    start..end
}

/// The reference text with the first occurrence of `from` inside the section
/// of joint `number` (1-based) replaced by `to`.
#[track_caller]
fn edit_joint(number: usize, from: &str, to: &str) -> String {
    let text = REFERENCE_RRPR_TOML;
    let range = joint_section(text, number);
    let section = edit_text(&text[range.clone()], from, to);
    format!("{}{}{}", &text[..range.start], section, &text[range.end..])
}

/// The motor reference text (`models/reference_rrpr_motor.toml`) with the
/// first occurrence of `from` inside the section of joint `number`
/// (1-based) replaced by `to`.
#[track_caller]
fn edit_motor_joint(number: usize, from: &str, to: &str) -> String {
    let text = REFERENCE_RRPR_MOTOR_TOML;
    let range = joint_section(text, number);
    let section = edit_text(&text[range.clone()], from, to);
    format!("{}{}{}", &text[..range.start], section, &text[range.end..])
}

/// The error of a text that must not parse.
#[track_caller]
fn rejected(text: &str) -> ModelError {
    match Model::from_toml_str(text) {
        Ok(_) => panic!("the model was accepted:\n{text}"),
        Err(e) => e,
    }
}

fn same_value(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || a == b
}

/// `e` is `InvalidParameter` for exactly `want_field` with value `want_value`,
/// its reason contains `reason_has`, and the message names the field.
#[track_caller]
fn assert_invalid_parameter(e: &ModelError, want_field: &str, want_value: f64, reason_has: &str) {
    match e {
        ModelError::InvalidParameter { field, value, reason } => {
            assert_eq!(field, want_field, "wrong field in: {e}");
            assert!(same_value(*value, want_value), "value {value} instead of {want_value} in: {e}");
            assert!(reason.contains(reason_has), "reason does not say `{reason_has}`: {e}");
        }
        other => panic!("expected InvalidParameter for `{want_field}`, got {other:?}"),
    }
    let message = e.to_string();
    assert!(message.contains(want_field), "message does not name `{want_field}`: {message}");
}

/// `e` is `Invalid` for exactly `want_field`, its reason contains
/// `reason_has`, and the message names the field.
#[track_caller]
fn assert_invalid(e: &ModelError, want_field: &str, reason_has: &str) {
    match e {
        ModelError::Invalid { field, reason } => {
            assert_eq!(field, want_field, "wrong field in: {e}");
            assert!(reason.contains(reason_has), "reason does not say `{reason_has}`: {e}");
        }
        other => panic!("expected Invalid for `{want_field}`, got {other:?}"),
    }
    let message = e.to_string();
    assert!(message.contains(want_field), "message does not name `{want_field}`: {message}");
}

/// `e` is `Syntax` and its message contains every string of `has` (the key,
/// the parser's reason, the line).
#[track_caller]
fn assert_syntax(e: &ModelError, has: &[&str]) {
    assert!(matches!(e, ModelError::Syntax { .. }), "expected Syntax, got {e:?}");
    let message = e.to_string();
    for s in has {
        assert!(message.contains(s), "message does not contain `{s}`: {message}");
    }
}

/// A chain of `n` joints alternating revolute / prismatic; every third joint
/// has a flexible drive with friction and its contact geometry.
fn chain_toml(n: usize) -> String {
    let mut text = String::from(
        "name = \"chain\"\ngravity = [0.0, 0.0, -9.81]\nend_point = [0.05, 0.0, 0.0]\n\n\
         [integrator]\nh_max = 1e-5\n",
    );
    for i in 1..=n {
        let revolute = i % 2 == 1;
        let flexible = i % 3 == 1;
        text.push_str("\n[[joint]]\n");
        text.push_str(if revolute { "type = \"revolute\"\n" } else { "type = \"prismatic\"\n" });
        text.push_str("theta = 0.0\nd = 0.1\na = 0.05\n");
        text.push_str(if i % 2 == 0 { "alpha = 1.5707963267948966\n" } else { "alpha = 0.0\n" });
        if flexible {
            text.push_str("drive = { type = \"flexible\", k = 1.0e5, h = 2.0, clearance = 1e-4 }\n");
            text.push_str("friction = { mu_k = 0.1, mu_s = 0.15, v_s = 0.01 }\n");
            if revolute {
                text.push_str(
                    "bearings = { reaction_point = [0.0, 0.0, 0.05], l_a = 0.03, l_b = 0.03, \
                     d_a = 0.04, d_b = 0.04, d_c = 0.05 }\n",
                );
            } else {
                text.push_str("slider = { centre = [0.0, 0.0, -0.05], a = 0.1, b = 0.03, c = 0.02 }\n");
            }
        } else {
            text.push_str("drive = { type = \"rigid\" }\n");
        }
        let mass = 1.0 + 0.1 * i as f64;
        text.push_str(&format!(
            "link = {{ mass = {mass:?}, com = [0.0, 0.0, -0.05], \
             inertia = {{ xx = 0.01, yy = 0.012, zz = 0.005, xy = 0.001 }} }}\n"
        ));
    }
    text
}

// ---------------------------------------------------------------------------
// The shipped reference file
// ---------------------------------------------------------------------------

#[test]
fn reference_file_parses_to_the_rrpr_arm() {
    let model = Model::from_file(REFERENCE_PATH).expect("the reference file is valid");
    model.validate().expect("the reference model validates");
    assert_eq!(model.name, "reference_rrpr");
    assert_eq!(model.nq(), 4);
    assert_eq!(model.links.len(), 4);

    let kinds: Vec<JointKind> = model.joints.iter().map(|j| j.kind).collect();
    assert_eq!(kinds, [JointKind::Revolute, JointKind::Revolute, JointKind::Prismatic, JointKind::Revolute]);

    for (i, joint) in model.joints.iter().enumerate() {
        let number = i + 1;
        match number {
            1 | 3 => {
                match joint.drive {
                    Drive::Flexible { stiffness, damping, clearance } => {
                        assert_eq!(stiffness, 1e6, "joint {number}");
                        assert_eq!(damping, 0.0, "joint {number}");
                        assert_eq!(clearance, 0.0, "joint {number}");
                    }
                    other => panic!("joint {number} should have a flexible drive, has {other:?}"),
                }
                let friction = joint.friction.expect("joints 1 and 3 have friction");
                assert_eq!(friction.coefficients.mu_kinetic, 0.2, "joint {number}");
                assert_eq!(friction.coefficients.mu_static, 0.2, "joint {number}");
                assert_eq!(friction.coefficients.stribeck_velocity, 0.0, "joint {number}");
                assert_eq!(friction.coefficients.viscous, 0.0, "joint {number}");
                let geometry_fits = matches!(
                    (joint.kind, friction.geometry),
                    (JointKind::Revolute, ContactGeometry::Bearings { .. })
                        | (JointKind::Prismatic, ContactGeometry::Slider { .. })
                );
                assert!(geometry_fits, "joint {number} has the wrong contact geometry");
            }
            _ => {
                assert_eq!(joint.drive, Drive::Rigid, "joint {number}");
                assert!(joint.friction.is_none(), "joint {number} should be frictionless");
            }
        }
    }

    let masses: Vec<f64> = model.links.iter().map(|l| l.mass).collect();
    assert_eq!(masses, [25.0, 15.0, 8.0, 4.0]);

    assert_eq!(Model::reference_rrpr(), model);
    assert_eq!(Model::from_toml_str(REFERENCE_RRPR_TOML).unwrap(), model);
}

#[test]
fn edit_helper_targets_the_named_joint() {
    // Joints 1 and 3 have identical drive lines; the helper must edit only
    // the section asked for.
    let text = edit_joint(3, "k = 1.0e6", "k = 2.0e6");
    let model = Model::from_toml_str(&text).unwrap();
    assert_eq!(model.parameter(Parameter::Stiffness, 0), Some(1e6));
    assert_eq!(model.parameter(Parameter::Stiffness, 2), Some(2e6));
}

// ---------------------------------------------------------------------------
// Structure and syntax
// ---------------------------------------------------------------------------

#[test]
fn unknown_joint_type_is_a_syntax_error() {
    let e = rejected(&edit_joint(2, "type = \"revolute\"", "type = \"screw\""));
    assert_syntax(&e, &["unknown variant `screw`", "`revolute`", "`prismatic`", "line 40"]);
}

#[test]
fn misspelt_key_is_rejected_not_defaulted() {
    let e = rejected(&edit_joint(3, "k = 1.0e6", "stifness = 1.0e6"));
    assert_syntax(&e, &["unknown field `stifness`", "`k`", "line 55"]);

    let e = rejected(&edit("tolerance = 1e-10", "tolerence = 1e-10"));
    assert_syntax(&e, &["unknown field `tolerence`", "line 22"]);
}

#[test]
fn missing_required_field_is_a_syntax_error() {
    let e = rejected(&edit_joint(1, "mass = 25.0, ", ""));
    assert_syntax(&e, &["missing field `mass`", "line 36"]);

    let e = rejected(&edit_joint(1, "d = 0.6\n", ""));
    assert_syntax(&e, &["missing field `d`"]);

    let e = rejected(&edit("gravity = [0.0, 0.0, -9.81]", ""));
    assert_syntax(&e, &["missing field `gravity`"]);
}

#[test]
fn toml_syntax_error_is_a_syntax_error() {
    let e = rejected(&edit("name = \"reference_rrpr\"", "name = \"reference_rrpr"));
    assert_syntax(&e, &["line 12"]);

    let e = rejected(&edit_joint(1, "d = 0.6", "d = 0.6 +"));
    assert_syntax(&e, &["line 29"]);

    let e = rejected(&edit("max_iterations = 50", "max_iterations = -1"));
    assert_syntax(&e, &["`-1`", "line 23"]);
}

#[test]
fn zero_joints_are_rejected() {
    let header = &REFERENCE_RRPR_TOML[..REFERENCE_RRPR_TOML.find(JOINT_HEADER).unwrap()];
    // No [[joint]] section at all: the chain-length check names it.
    let e = rejected(header);
    assert_invalid(&e, "joint", "0 joints");
    // An explicitly empty chain reaches validation.
    let empty = edit_text(header, "end_point = [0.1, 0.0, 0.0]", "end_point = [0.1, 0.0, 0.0]\njoint = []");
    let e = rejected(&empty);
    assert_invalid(&e, "joint", "0 joints");
}

#[test]
fn more_than_max_joints_are_rejected() {
    let last = &REFERENCE_RRPR_TOML[joint_section(REFERENCE_RRPR_TOML, 4)];
    let with_extra = |extra: usize| format!("{REFERENCE_RRPR_TOML}\n{}", format!("{last}\n").repeat(extra));

    let full = Model::from_toml_str(&with_extra(MAX_JOINTS - 4)).expect("MAX_JOINTS joints are accepted");
    assert_eq!(full.nq(), MAX_JOINTS);

    let e = rejected(&with_extra(MAX_JOINTS - 3));
    assert_invalid(&e, "joint", &format!("{} joints", MAX_JOINTS + 1));
}

#[test]
fn contact_geometry_must_match_the_joint_kind() {
    // Friction on a revolute joint without bearings.
    let e = rejected(&edit_joint(1, "bearings = {", "# bearings = {"));
    assert_invalid(&e, "joint[1].bearings", "friction");

    // Friction on a prismatic joint without a slider.
    let e = rejected(&edit_joint(3, "slider = {", "# slider = {"));
    assert_invalid(&e, "joint[3].slider", "friction");

    // A slider on a revolute joint.
    let e = rejected(&edit_joint(
        4,
        "drive = { type = \"rigid\" }",
        "drive = { type = \"rigid\" }\nslider = { centre = [0.0, 0.0, 0.0], a = 0.1, b = 0.05, c = 0.05 }",
    ));
    assert_invalid(&e, "joint[4].slider", "revolute");

    // Bearings on a prismatic joint.
    let e = rejected(&edit_joint(
        3,
        "slider = { centre = [0.0, 0.0, -0.7], a = 0.2, b = 0.07, c = 0.07 }",
        "bearings = { reaction_point = [0.0, 0.0, 0.0], l_a = 0.06, l_b = 0.06, d_a = 0.1, d_b = 0.1, d_c = 0.1 }",
    ));
    assert_invalid(&e, "joint[3].bearings", "prismatic");

    // Both on one joint.
    let e = rejected(&edit_joint(
        1,
        "friction = {",
        "slider = { centre = [0.0, 0.0, 0.0], a = 0.1, b = 0.05, c = 0.05 }\nfriction = {",
    ));
    assert_invalid(&e, "joint[1]", "both");
}

#[test]
fn bearing_geometry_is_checked() {
    let e = rejected(&edit_joint(1, "reaction_point = [0.0, 0.0, 0.06]", "reaction_point = [0.01, 0.0, 0.06]"));
    assert_invalid(&e, "joint[1].bearings.reaction_point", "axis");

    let e = rejected(&edit_joint(1, "l_a = 0.06, l_b = 0.06", "l_a = 0.0, l_b = 0.0"));
    assert_invalid_parameter(&e, "joint[1].bearings.l_a + bearings.l_b", 0.0, "at least 1e-3");

    let e = rejected(&edit_joint(1, "d_c = 0.1", "d_c = -0.1"));
    assert_invalid_parameter(&e, "joint[1].bearings.d_c", -0.1, "negative");
}

#[test]
fn slider_geometry_is_checked() {
    let e = rejected(&edit_joint(3, "a = 0.2, b", "a = 0.0, b"));
    assert_invalid_parameter(&e, "joint[3].slider.a", 0.0, "positive");

    let e = rejected(&edit_joint(3, "b = 0.07, c = 0.07", "b = 0.0, c = 0.0"));
    assert_invalid_parameter(&e, "joint[3].slider.b + slider.c", 0.0, "at least 1e-3");

    let e = rejected(&edit_joint(3, "c = 0.07", "c = -0.07"));
    assert_invalid_parameter(&e, "joint[3].slider.c", -0.07, "negative");
}

// ---------------------------------------------------------------------------
// Numeric ranges
// ---------------------------------------------------------------------------

#[test]
fn mass_must_be_positive() {
    let e = rejected(&edit_joint(2, "mass = 15.0", "mass = -15.0"));
    assert_invalid_parameter(&e, "joint[2].link.mass", -15.0, "positive");

    let e = rejected(&edit_joint(2, "mass = 15.0", "mass = 0.0"));
    assert_invalid_parameter(&e, "joint[2].link.mass", 0.0, "positive");
}

#[test]
fn inertia_must_be_a_physical_tensor() {
    // Not positive definite.
    let e = rejected(&edit_joint(1, "zz = 0.79 }", "zz = -0.79 }"));
    assert_invalid(&e, "joint[1].link.inertia", "positive definite");

    // All positive, but I1 + I2 < I3.
    let e = rejected(&edit_joint(4, "xx = 0.01, yy = 0.01, zz = 0.01", "xx = 0.01, yy = 0.01, zz = 0.5"));
    assert_invalid(&e, "joint[4].link.inertia", "triangle inequality");

    // Off-diagonal entries making the tensor indefinite.
    let e = rejected(&edit_joint(4, "zz = 0.01 }", "zz = 0.01, xy = 0.02 }"));
    assert_invalid(&e, "joint[4].link.inertia", "positive definite");
    // A non-symmetric tensor cannot be written: the file has one `xy`, `xz`, `yz` each.
}

#[test]
fn drive_parameters_are_checked() {
    let e = rejected(&edit_joint(3, "k = 1.0e6", "k = 0.0"));
    assert_invalid_parameter(&e, "joint[3].drive.k", 0.0, "positive");

    let e = rejected(&edit_joint(3, "k = 1.0e6", "k = -1.0e6"));
    assert_invalid_parameter(&e, "joint[3].drive.k", -1e6, "positive");

    let e = rejected(&edit_joint(1, "h = 0.0", "h = -5.0"));
    assert_invalid_parameter(&e, "joint[1].drive.h", -5.0, "negative");

    let e = rejected(&edit_joint(3, "clearance = 0.0", "clearance = -0.001"));
    assert_invalid_parameter(&e, "joint[3].drive.clearance", -0.001, "negative");
}

#[test]
fn friction_coefficients_are_checked() {
    let e = rejected(&edit_joint(1, "mu_k = 0.2", "mu_k = -0.1"));
    assert_invalid_parameter(&e, "joint[1].friction.mu_k", -0.1, "negative");

    let e = rejected(&edit_joint(3, "mu_k = 0.2, mu_s = 0.2", "mu_k = 0.3, mu_s = 0.2"));
    assert_invalid_parameter(&e, "joint[3].friction.mu_s", 0.2, "mu_k");

    let e = rejected(&edit_joint(1, "v_s = 0.0", "v_s = -0.01"));
    assert_invalid_parameter(&e, "joint[1].friction.v_s", -0.01, "negative");
}

/// The viscous part of the friction (`viscous = b`, N·m·s/rad or N·s/m):
/// read as written, 0 when absent (the study's law), refused naming
/// `joint[i].friction.viscous` when negative, NaN, infinite, above its
/// ceiling 1e9 or not a number; tunable as `b_v[i]` on joints with friction only.
#[test]
fn viscous_friction_is_read_and_checked() {
    let text = edit_joint(3, "v_s = 0.0, viscous = 0.0", "v_s = 0.0, viscous = 120.5");
    let model = Model::from_toml_str(&text).unwrap();
    assert_eq!(model.joints[2].friction.unwrap().coefficients.viscous, 120.5);
    assert_eq!(model.parameter(Parameter::Viscous, 2), Some(120.5));
    assert_eq!(model.parameter(Parameter::Viscous, 0), Some(0.0));
    assert_eq!(model.parameter(Parameter::Viscous, 1), None, "a joint without friction has no b_v");
    let absent = Model::from_toml_str(&edit_joint(1, ", viscous = 0.0", "")).unwrap();
    assert_eq!(absent, Model::reference_rrpr(), "absent is 0");

    for (to, value, reason) in [
        ("viscous = -1.0", -1.0, "negative"),
        ("viscous = nan", f64::NAN, "finite"),
        ("viscous = inf", f64::INFINITY, "finite"),
        ("viscous = -inf", f64::NEG_INFINITY, "finite"),
        ("viscous = 1.0e10", 1e10, "[0, 1e9]"),
    ] {
        let e = rejected(&edit_joint(1, "viscous = 0.0", to));
        assert_invalid_parameter(&e, "joint[1].friction.viscous", value, reason);
    }
    let at = edit_joint(3, "viscous = 0.0", "viscous = 1.0e9");
    assert_ceiling(
        &edit_joint(3, "viscous = 0.0", "viscous = 1.1e9"),
        "joint[3].friction.viscous",
        1.1e9,
        "[0, 1e9]",
        &at,
    );
    let e = rejected(&edit_joint(1, "viscous = 0.0", "viscous = \"2\""));
    assert_syntax(&e, &["invalid type: string \"2\", expected f64", "viscous", "line 33"]);
    let e = rejected(&edit_joint(1, "viscous = 0.0", "viscous_b = 2.0"));
    assert_syntax(&e, &["unknown field `viscous_b`", "`viscous`", "line 33"]);

    let mut model = Model::reference_rrpr();
    let e = model.set_parameter(Parameter::Viscous, 2, -0.5).unwrap_err();
    assert_invalid_parameter(&e, "b_v[3]", -0.5, "negative");
    let e = model.set_parameter(Parameter::Viscous, 0, f64::NAN).unwrap_err();
    assert_invalid_parameter(&e, "b_v[1]", f64::NAN, "finite");
    let e = model.set_parameter(Parameter::Viscous, 3, 1.0).unwrap_err();
    assert_invalid(&e, "b_v[4]", "no such parameter");
    assert_eq!(model, Model::reference_rrpr());
    model.set_parameter(Parameter::Viscous, 2, 1e9).unwrap();
    assert!(model.has_layout_of(&Model::reference_rrpr()), "b_v is tunable: the layout stays");
    assert_eq!(Parameter::Viscous.range(), Range::JOINT_VISCOUS);
    assert_eq!(Range::JOINT_VISCOUS, Range::closed(0.0, 1e9));
}

#[test]
fn nan_and_infinity_are_rejected() {
    let cases: [(usize, &str, &str, &str, f64); 7] = [
        (1, "mass = 25.0", "mass = nan", "joint[1].link.mass", f64::NAN),
        (3, "k = 1.0e6", "k = inf", "joint[3].drive.k", f64::INFINITY),
        (3, "mu_s = 0.2", "mu_s = nan", "joint[3].friction.mu_s", f64::NAN),
        (2, "theta = 1.5707963267948966", "theta = -inf", "joint[2].theta", f64::NEG_INFINITY),
        (4, "com = [0.05, 0.0, -0.05]", "com = [0.05, nan, -0.05]", "joint[4].link.com[2]", f64::NAN),
        (4, "xx = 0.01", "xx = +inf", "joint[4].link.inertia.xx", f64::INFINITY),
        (1, "l_b = 0.06", "l_b = nan", "joint[1].bearings.l_b", f64::NAN),
    ];
    for (joint, from, to, field, value) in cases {
        let e = rejected(&edit_joint(joint, from, to));
        assert_invalid_parameter(&e, field, value, "finite");
    }

    let e = rejected(&edit("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, -inf]"));
    assert_invalid_parameter(&e, "gravity[3]", f64::NEG_INFINITY, "finite");

    let e = rejected(&edit("h_max = 5e-4", "h_max = nan"));
    assert_invalid_parameter(&e, "integrator.h_max", f64::NAN, "finite");

    let e = rejected(&edit("beta = 0.25", "beta = nan"));
    assert_invalid_parameter(&e, "integrator.beta", f64::NAN, "beta");
}

#[test]
fn integrator_settings_are_checked() {
    let e = rejected(&edit("beta = 0.25", "beta = 0.7"));
    assert_invalid_parameter(&e, "integrator.beta", 0.7, "[0, 0.5]");

    let e = rejected(&edit("gamma = 0.5", "gamma = 0.3"));
    assert_invalid_parameter(&e, "integrator.gamma", 0.3, "[0.5, 1]");

    let e = rejected(&edit("h_max = 5e-4", "h_max = 0.0"));
    assert_invalid_parameter(&e, "integrator.h_max", 0.0, "positive");

    let e = rejected(&edit("h_max = 5e-4", "h_max = 0.5"));
    assert_invalid_parameter(&e, "integrator.h_max", 0.5, "at most 0.01");
    let e = rejected(&edit("h_min = 2e-6", "h_min = 1e-3"));
    assert_invalid_parameter(&e, "integrator.h_min", 1e-3, "must not exceed h_max");
    let e = rejected(&edit("error_tolerance = 5e-4", "error_tolerance = 0.0"));
    assert_invalid_parameter(&e, "integrator.error_tolerance", 0.0, "(0, 0.1]");
    let e = rejected(&edit("error_tolerance = 5e-4", "error_tolerance = 0.5"));
    assert_invalid_parameter(&e, "integrator.error_tolerance", 0.5, "(0, 0.1]");
    // h_min = h_max: fixed sub-steps.
    let fixed = Model::from_toml_str(&edit("h_min = 2e-6", "h_min = 5e-4")).unwrap();
    assert!(fixed.integrator.fixed_step());
    assert!(!Model::reference_rrpr().integrator.fixed_step());

    let e = rejected(&edit("tolerance = 1e-10", "tolerance = 0.0"));
    assert_invalid_parameter(&e, "integrator.tolerance", 0.0, "(0, 1e-3]");

    let e = rejected(&edit("max_iterations = 50", "max_iterations = 0"));
    assert_invalid_parameter(&e, "integrator.max_iterations", 0.0, "1..=10000");
}

// ---------------------------------------------------------------------------
// Ceilings: a value just above the largest admissible one is refused with the
// field and its range; the value exactly at the ceiling loads.
// ---------------------------------------------------------------------------

/// `over` is refused: `InvalidParameter` for `field` with `value`, whose
/// reason and message show the admissible `range` (e.g. `(0, 1e6]`); `at`
/// (the same edit with the ceiling itself) loads and validates.
#[track_caller]
fn assert_ceiling(over: &str, field: &str, value: f64, range: &str, at: &str) {
    let e = rejected(over);
    assert_invalid_parameter(&e, field, value, range);
    let message = e.to_string();
    assert!(message.contains(range), "message does not show the range `{range}`: {message}");
    assert!(message.contains("at most"), "message does not say `at most`: {message}");
    let model =
        Model::from_toml_str(at).unwrap_or_else(|e| panic!("the value at the ceiling of `{field}` is refused: {e}"));
    model.validate().unwrap_or_else(|e| panic!("the value at the ceiling of `{field}` does not validate: {e}"));
}

#[test]
fn mass_ceiling_is_1e6_kg() {
    let at = edit_joint(2, "mass = 15.0", "mass = 1.0e6");
    assert_eq!(Model::from_toml_str(&at).unwrap().links[1].mass, 1e6);
    assert_ceiling(&edit_joint(2, "mass = 15.0", "mass = 1e300"), "joint[2].link.mass", 1e300, "(0, 1e6]", &at);
    // The value in short form, as the README quotes it (not the 301 digits of `{}`).
    let e = rejected(&edit_joint(2, "mass = 15.0", "mass = 1e300"));
    assert_eq!(e.to_string(), "`joint[2].link.mass` = 1e300: must be positive and at most 1e6: (0, 1e6]");
    let e = rejected(&edit_joint(2, "mass = 15.0", "mass = -15.0"));
    assert_eq!(e.to_string(), "`joint[2].link.mass` = -15: must be positive and at most 1e6: (0, 1e6]");
    assert_ceiling(
        &edit_joint(2, "mass = 15.0", "mass = 1.0000001e6"),
        "joint[2].link.mass",
        1.0000001e6,
        "(0, 1e6]",
        &at,
    );
    // The smallest double above the ceiling.
    let next = f64::from_bits(1e6f64.to_bits() + 1);
    let text = edit_joint(2, "mass = 15.0", &format!("mass = {next:?}"));
    assert_ceiling(&text, "joint[2].link.mass", next, "(0, 1e6]", &at);
}

#[test]
fn stiffness_ceiling_is_1e12() {
    let at = edit_joint(3, "k = 1.0e6", "k = 1.0e12");
    assert_ceiling(&edit_joint(3, "k = 1.0e6", "k = 1.0e13"), "joint[3].drive.k", 1e13, "(0, 1e12]", &at);
    let next = f64::from_bits(1e12f64.to_bits() + 1);
    assert_ceiling(&edit_joint(3, "k = 1.0e6", &format!("k = {next:?}")), "joint[3].drive.k", next, "(0, 1e12]", &at);
}

#[test]
fn damping_ceiling_is_1e9() {
    let at = edit_joint(1, "h = 0.0", "h = 1.0e9");
    assert_ceiling(&edit_joint(1, "h = 0.0", "h = 1.0e10"), "joint[1].drive.h", 1e10, "[0, 1e9]", &at);
}

#[test]
fn clearance_ceiling_is_1() {
    let at = edit_joint(3, "clearance = 0.0", "clearance = 1.0");
    assert_ceiling(
        &edit_joint(3, "clearance = 0.0", "clearance = 2.0"),
        "joint[3].drive.clearance",
        2.0,
        "[0, 1]",
        &at,
    );
}

#[test]
fn friction_ceilings_are_2_and_1000() {
    let at = edit_joint(1, "mu_k = 0.2, mu_s = 0.2", "mu_k = 2.0, mu_s = 2.0");
    let over = edit_joint(1, "mu_k = 0.2, mu_s = 0.2", "mu_k = 0.2, mu_s = 3.0");
    assert_ceiling(&over, "joint[1].friction.mu_s", 3.0, "[0, 2]", &at);
    let over = edit_joint(1, "mu_k = 0.2, mu_s = 0.2", "mu_k = 3.0, mu_s = 3.0");
    assert_ceiling(&over, "joint[1].friction.mu_k", 3.0, "[0, 2]", &at);

    let at = edit_joint(3, "v_s = 0.0", "v_s = 1000.0");
    assert_ceiling(&edit_joint(3, "v_s = 0.0", "v_s = 1001.0"), "joint[3].friction.v_s", 1001.0, "[0, 1000]", &at);
}

#[test]
fn contact_length_ceiling_is_100_m() {
    // Slider of joint 3: a is positive, b and c may be 0.
    let at = edit_joint(3, "a = 0.2, b = 0.07, c = 0.07", "a = 100.0, b = 100.0, c = 100.0");
    assert_ceiling(&edit_joint(3, "a = 0.2, b", "a = 101.0, b"), "joint[3].slider.a", 101.0, "(0, 100]", &at);
    assert_ceiling(&edit_joint(3, "b = 0.07", "b = 101.0"), "joint[3].slider.b", 101.0, "[0, 100]", &at);
    assert_ceiling(&edit_joint(3, "c = 0.07", "c = 101.0"), "joint[3].slider.c", 101.0, "[0, 100]", &at);

    // Bearings of joint 1.
    let at = edit_joint(
        1,
        "l_a = 0.06, l_b = 0.06, d_a = 0.1, d_b = 0.1, d_c = 0.1",
        "l_a = 100.0, l_b = 100.0, d_a = 100.0, d_b = 100.0, d_c = 100.0",
    );
    let cases = [
        ("l_a = 0.06", "l_a = 101.0", "joint[1].bearings.l_a"),
        ("l_b = 0.06", "l_b = 101.0", "joint[1].bearings.l_b"),
        ("d_a = 0.1", "d_a = 101.0", "joint[1].bearings.d_a"),
        ("d_b = 0.1", "d_b = 101.0", "joint[1].bearings.d_b"),
        ("d_c = 0.1", "d_c = 101.0", "joint[1].bearings.d_c"),
    ];
    for (from, to, field) in cases {
        assert_ceiling(&edit_joint(1, from, to), field, 101.0, "[0, 100]", &at);
    }
}

#[test]
fn inertia_ceiling_is_1e9() {
    let at = edit_joint(4, "xx = 0.01, yy = 0.01, zz = 0.01", "xx = 1.0e9, yy = 1.0e9, zz = 1.0e9");
    let over = edit_joint(4, "xx = 0.01, yy = 0.01, zz = 0.01", "xx = 1.0e10, yy = 1.0e10, zz = 1.0e10");
    assert_ceiling(&over, "joint[4].link.inertia.xx", 1e10, "[-1e9, 1e9]", &at);
    let over = edit_joint(4, "zz = 0.01", "zz = 1.0e10");
    assert_ceiling(&over, "joint[4].link.inertia.zz", 1e10, "[-1e9, 1e9]", &at);
    let over = edit_joint(4, "zz = 0.01 }", "zz = 0.01, xy = -1.0e10 }");
    assert_ceiling(&over, "joint[4].link.inertia.xy", -1e10, "[-1e9, 1e9]", &at);
}

#[test]
fn gravity_ceiling_is_1000() {
    let at = edit("gravity = [0.0, 0.0, -9.81]", "gravity = [1000.0, 0.0, -1000.0]");
    let over = edit("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, -1.0e4]");
    assert_ceiling(&over, "gravity[3]", -1e4, "[-1000, 1000]", &at);
    let over = edit("gravity = [0.0, 0.0, -9.81]", "gravity = [1.0e4, 0.0, -9.81]");
    assert_ceiling(&over, "gravity[1]", 1e4, "[-1000, 1000]", &at);
}

#[test]
fn geometry_ceiling_is_1000() {
    let at = edit_joint(1, "d = 0.6", "d = 1000.0");
    assert_ceiling(&edit_joint(1, "d = 0.6", "d = 1.0e4"), "joint[1].d", 1e4, "[-1000, 1000]", &at);
    let at = edit_joint(4, "d = 0.1", "d = -1000.0");
    assert_ceiling(&edit_joint(4, "d = 0.1", "d = -1.0e4"), "joint[4].d", -1e4, "[-1000, 1000]", &at);
    let at = edit_joint(2, "a = 0.0", "a = 1000.0");
    assert_ceiling(&edit_joint(2, "a = 0.0", "a = 1001.0"), "joint[2].a", 1001.0, "[-1000, 1000]", &at);
    let at = edit("end_point = [0.1, 0.0, 0.0]", "end_point = [1000.0, 0.0, 0.0]");
    assert_ceiling(
        &edit("end_point = [0.1, 0.0, 0.0]", "end_point = [1.0e4, 0.0, 0.0]"),
        "end_point[1]",
        1e4,
        "[-1000, 1000]",
        &at,
    );
    let at = edit_joint(4, "com = [0.05, 0.0, -0.05]", "com = [0.05, 0.0, -1000.0]");
    let over = edit_joint(4, "com = [0.05, 0.0, -0.05]", "com = [0.05, 0.0, -1.0e4]");
    assert_ceiling(&over, "joint[4].link.com[3]", -1e4, "[-1000, 1000]", &at);
}

#[test]
fn missing_file_is_an_io_error_naming_the_path() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/models/does_not_exist.toml");
    let e = Model::from_file(path).expect_err("the file does not exist");
    match &e {
        ModelError::Io { path: p, reason } => {
            assert_eq!(p, path);
            assert!(!reason.is_empty());
        }
        other => panic!("expected Io, got {other:?}"),
    }
    assert!(e.to_string().contains(path), "message does not name the path: {e}");
}

// ---------------------------------------------------------------------------
// set_parameter
// ---------------------------------------------------------------------------

#[test]
fn set_parameter_rejects_bad_values_and_leaves_the_model_alone() {
    let reference = Model::reference_rrpr();
    let mut model = reference.clone();

    let e = model.set_parameter(Parameter::MuKinetic, 0, -0.1).unwrap_err();
    assert_invalid_parameter(&e, "mu_k[1]", -0.1, "negative");

    let e = model.set_parameter(Parameter::MuKinetic, 0, f64::NAN).unwrap_err();
    assert_invalid_parameter(&e, "mu_k[1]", f64::NAN, "finite");

    let e = model.set_parameter(Parameter::Stiffness, 2, 0.0).unwrap_err();
    assert_invalid_parameter(&e, "k[3]", 0.0, "positive");

    let e = model.set_parameter(Parameter::Stiffness, 2, f64::INFINITY).unwrap_err();
    assert_invalid_parameter(&e, "k[3]", f64::INFINITY, "finite");

    let e = model.set_parameter(Parameter::Mass, 3, -4.0).unwrap_err();
    assert_invalid_parameter(&e, "m[4]", -4.0, "positive");

    assert_eq!(model, reference, "a rejected value must not be stored");
}

#[test]
fn set_parameter_rejects_parameters_the_joint_does_not_have() {
    let reference = Model::reference_rrpr();
    let mut model = reference.clone();

    // Joint 2 has a rigid drive: no stiffness.
    let e = model.set_parameter(Parameter::Stiffness, 1, 1e5).unwrap_err();
    assert_invalid(&e, "k[2]", "no such parameter");

    // Joint 1 is revolute: no slider.
    let e = model.set_parameter(Parameter::SliderA, 0, 0.1).unwrap_err();
    assert_invalid(&e, "slider_a[1]", "no such parameter");

    // Joint 3 is prismatic: no bearings.
    let e = model.set_parameter(Parameter::DiameterA, 2, 0.1).unwrap_err();
    assert_invalid(&e, "d_A[3]", "no such parameter");

    // Joint 4 is frictionless.
    let e = model.set_parameter(Parameter::MuKinetic, 3, 0.1).unwrap_err();
    assert_invalid(&e, "mu_k[4]", "no such parameter");

    // There is no joint 5.
    let e = model.set_parameter(Parameter::Mass, 4, 1.0).unwrap_err();
    assert_invalid(&e, "m[5]", "the model has 4 joints");
    // A joint without the parameter is reported as such whatever the value.
    let e = model.set_parameter(Parameter::Stiffness, 1, -1.0).unwrap_err();
    assert_invalid(&e, "k[2]", "no such parameter");

    assert_eq!(model, reference);
}

#[test]
fn set_parameter_accepts_good_values_and_validate_checks_relations() {
    let mut model = Model::reference_rrpr();

    model.set_parameter(Parameter::MuKinetic, 0, 0.5).expect("0.5 is a valid mu_k");
    assert_eq!(model.parameter(Parameter::MuKinetic, 0), Some(0.5));

    // mu_s = 0.2 is now below mu_k = 0.5.
    let e = model.validate().unwrap_err();
    assert_invalid_parameter(&e, "joint[1].friction.mu_s", 0.2, "mu_k");

    model.set_parameter(Parameter::MuStatic, 0, 0.6).expect("0.6 is a valid mu_s");
    model.validate().expect("mu_s >= mu_k again");

    // l_A + l_B = 0 is only caught as a relation.
    model.set_parameter(Parameter::LengthA, 0, 0.0).unwrap();
    model.set_parameter(Parameter::LengthB, 0, 0.0).unwrap();
    let e = model.validate().unwrap_err();
    assert_invalid_parameter(&e, "joint[1].bearings.l_a + bearings.l_b", 0.0, "at least 1e-3");
}

// ---------------------------------------------------------------------------
// Motor drives: the shipped motor reference file, defaults, refusals
// ---------------------------------------------------------------------------

/// The motor drive line of joint 1 of the motor reference file, as written.
const MOTOR_1: &str = "drive = { type = \"motor\", k = 1.0e6, h = 0.0, clearance = 0.0, gear_ratio = 100.0, rotor_inertia = 3.0e-4, motor_viscous = 2.0e-4, motor_coulomb = 0.03 }";

#[test]
fn motor_reference_file_parses_with_every_motor_field() {
    let model = Model::from_file(MOTOR_REFERENCE_PATH).expect("the motor reference file is valid");
    model.validate().expect("the motor reference model validates");
    assert_eq!(model.name, "reference_rrpr_motor");
    assert_eq!(model.nq(), 4);
    assert_eq!(model.motor_joints(), [0, 2]);
    assert_eq!(model.n_coordinates(), 6, "4 joints and 2 rotors");
    let rotor_1 = Rotor { gear_ratio: 100.0, inertia: 3.0e-4, viscous: 2.0e-4, coulomb: 0.03 };
    let rotor_3 = Rotor { gear_ratio: 628.3185307179587, inertia: 1.2e-4, viscous: 1.0e-4, coulomb: 0.02 };
    assert_eq!(model.joints[0].drive, Drive::Motor { stiffness: 1e6, damping: 0.0, clearance: 0.0, rotor: rotor_1 });
    assert_eq!(model.joints[2].drive, Drive::Motor { stiffness: 1e6, damping: 0.0, clearance: 0.0, rotor: rotor_3 });
    // The ball screw's ratio is 2π per 10 mm lead, to the last bit.
    assert_eq!(rotor_3.gear_ratio, 2.0 * std::f64::consts::PI / 0.01);
    for (i, joint) in model.joints.iter().enumerate() {
        assert_eq!(joint.drive.is_motor(), i == 0 || i == 2, "joint {}", i + 1);
        // A motor drive has the spring of a flexible one: its q is a coordinate.
        assert_eq!(joint.drive.is_flexible(), i == 0 || i == 2, "joint {}", i + 1);
    }
    assert_eq!(model.joints[1].drive, Drive::Rigid);
    assert_eq!(model.joints[3].drive, Drive::Rigid);

    assert_eq!(Model::reference_rrpr_motor(), model);
    assert_eq!(Model::from_toml_str(REFERENCE_RRPR_MOTOR_TOML).unwrap(), model);

    // Everything but the drives (and the name) is the reference arm: with
    // flexible drives of the same spring it is `Model::reference_rrpr()`.
    let mut flexible = model.clone();
    for joint in &mut flexible.joints {
        if let Some(s) = joint.drive.spring() {
            joint.drive = Drive::Flexible { stiffness: s.stiffness, damping: s.damping, clearance: s.clearance };
        }
    }
    flexible.name = "reference_rrpr".into();
    assert_eq!(flexible, Model::reference_rrpr());
    assert!(Model::reference_rrpr().motor_joints().is_empty());
    assert_eq!(Model::reference_rrpr().n_coordinates(), 4);
}

#[test]
fn motor_drive_optional_fields_default_to_zero() {
    let text = edit_motor_joint(
        1,
        MOTOR_1,
        "drive = { type = \"motor\", k = 2.0e5, gear_ratio = 50.0, rotor_inertia = 1e-4 }",
    );
    let model = Model::from_toml_str(&text).unwrap();
    let rotor = Rotor { gear_ratio: 50.0, inertia: 1e-4, viscous: 0.0, coulomb: 0.0 };
    assert_eq!(model.joints[0].drive, Drive::Motor { stiffness: 2e5, damping: 0.0, clearance: 0.0, rotor });
    // Fields in another order, the optional ones given: read by name.
    let text = edit_motor_joint(
        1,
        MOTOR_1,
        "drive = { motor_coulomb = 0.5, rotor_inertia = 2.0, clearance = 1e-3, type = \"motor\", motor_viscous = 0.25, gear_ratio = 7.5, h = 3.0, k = 4.0e4 }",
    );
    let model = Model::from_toml_str(&text).unwrap();
    let rotor = Rotor { gear_ratio: 7.5, inertia: 2.0, viscous: 0.25, coulomb: 0.5 };
    assert_eq!(model.joints[0].drive, Drive::Motor { stiffness: 4e4, damping: 3.0, clearance: 1e-3, rotor });
    // A motor drive on a rigid joint of the flexible reference file.
    let text = edit_joint(
        2,
        "drive = { type = \"rigid\" }",
        "drive = { type = \"motor\", k = 1.0e5, gear_ratio = 80.0, rotor_inertia = 5e-5 }",
    );
    let model = Model::from_toml_str(&text).unwrap();
    assert_eq!(model.motor_joints(), [1]);
    assert_eq!(model.n_coordinates(), 5);
}

#[test]
fn motor_drive_missing_required_fields_are_syntax_errors() {
    let e = rejected(&edit_motor_joint(1, "gear_ratio = 100.0, ", ""));
    assert_syntax(&e, &["missing field `gear_ratio`", "line 40"]);
    let e = rejected(&edit_motor_joint(3, "rotor_inertia = 1.2e-4, ", ""));
    assert_syntax(&e, &["missing field `rotor_inertia`", "line 63"]);
    let e = rejected(&edit_motor_joint(1, "k = 1.0e6, ", ""));
    assert_syntax(&e, &["missing field `k`", "line 40"]);
}

#[test]
fn motor_drive_unknown_key_and_unknown_type_are_syntax_errors() {
    let e = rejected(&edit_motor_joint(1, "rotor_inertia = 3.0e-4", "rotor_inertial = 3.0e-4"));
    assert_syntax(&e, &["unknown field `rotor_inertial`", "`rotor_inertia`", "`gear_ratio`", "line 40"]);
    let e = rejected(&edit_motor_joint(3, "type = \"motor\"", "type = \"motr\""));
    assert_syntax(&e, &["unknown variant `motr`", "`rigid`", "`flexible`", "`motor`", "line 63"]);
    // Motor keys on a flexible drive are unknown there, not ignored.
    let e = rejected(&edit_joint(1, "clearance = 0.0 }", "clearance = 0.0, gear_ratio = 100.0 }"));
    assert_syntax(&e, &["unknown field `gear_ratio`", "line 32"]);
    // Not a number.
    let e = rejected(&edit_motor_joint(1, "gear_ratio = 100.0", "gear_ratio = \"100\""));
    assert_syntax(&e, &["invalid type: string \"100\", expected f64", "line 40"]);
}

#[test]
fn motor_drive_values_are_checked_by_field() {
    let cases: [(usize, &str, &str, &str, f64, &str); 14] = [
        (1, "gear_ratio = 100.0", "gear_ratio = 0.0", "joint[1].drive.gear_ratio", 0.0, "positive"),
        (1, "gear_ratio = 100.0", "gear_ratio = -100.0", "joint[1].drive.gear_ratio", -100.0, "positive"),
        (3, "gear_ratio = 628.3185307179587", "gear_ratio = nan", "joint[3].drive.gear_ratio", f64::NAN, "finite"),
        (1, "gear_ratio = 100.0", "gear_ratio = inf", "joint[1].drive.gear_ratio", f64::INFINITY, "finite"),
        (1, "gear_ratio = 100.0", "gear_ratio = -inf", "joint[1].drive.gear_ratio", f64::NEG_INFINITY, "finite"),
        (1, "rotor_inertia = 3.0e-4", "rotor_inertia = 0.0", "joint[1].drive.rotor_inertia", 0.0, "positive"),
        (3, "rotor_inertia = 1.2e-4", "rotor_inertia = -1.2e-4", "joint[3].drive.rotor_inertia", -1.2e-4, "positive"),
        (1, "rotor_inertia = 3.0e-4", "rotor_inertia = nan", "joint[1].drive.rotor_inertia", f64::NAN, "finite"),
        (1, "motor_viscous = 2.0e-4", "motor_viscous = -2.0e-4", "joint[1].drive.motor_viscous", -2e-4, "negative"),
        (3, "motor_viscous = 1.0e-4", "motor_viscous = inf", "joint[3].drive.motor_viscous", f64::INFINITY, "finite"),
        (1, "motor_coulomb = 0.03", "motor_coulomb = -0.03", "joint[1].drive.motor_coulomb", -0.03, "negative"),
        (3, "motor_coulomb = 0.02", "motor_coulomb = nan", "joint[3].drive.motor_coulomb", f64::NAN, "finite"),
        // The spring of a motor drive is checked as a flexible drive's.
        (1, "k = 1.0e6", "k = 0.0", "joint[1].drive.k", 0.0, "positive"),
        (3, "clearance = 0.0", "clearance = -1e-3", "joint[3].drive.clearance", -1e-3, "negative"),
    ];
    for (joint, from, to, field, value, reason) in cases {
        let e = rejected(&edit_motor_joint(joint, from, to));
        assert_invalid_parameter(&e, field, value, reason);
    }
    // The exact message, as for the other fields.
    let e = rejected(&edit_motor_joint(1, "gear_ratio = 100.0", "gear_ratio = 0.0"));
    assert_eq!(e.to_string(), "`joint[1].drive.gear_ratio` = 0: must be positive and at most 1e6: (0, 1e6]");
    // Zero viscous and Coulomb friction are admissible (a free rotor).
    let free =
        edit_motor_joint(1, "motor_viscous = 2.0e-4, motor_coulomb = 0.03", "motor_viscous = 0.0, motor_coulomb = 0.0");
    Model::from_toml_str(&free).unwrap().validate().unwrap();
}

#[test]
fn motor_drive_ceilings() {
    let next = |x: f64| f64::from_bits(x.to_bits() + 1);
    let cases = [
        ("gear_ratio = 100.0", "gear_ratio", 1e6, "(0, 1e6]"),
        ("rotor_inertia = 3.0e-4", "rotor_inertia", 1e3, "(0, 1000]"),
        ("motor_viscous = 2.0e-4", "motor_viscous", 1e6, "[0, 1e6]"),
        ("motor_coulomb = 0.03", "motor_coulomb", 1e6, "[0, 1e6]"),
    ];
    for (from, key, ceiling, range) in cases {
        let at = edit_motor_joint(1, from, &format!("{key} = {ceiling:?}"));
        let field = format!("joint[1].drive.{key}");
        for over in [next(ceiling), 10.0 * ceiling, 1e300] {
            assert_ceiling(&edit_motor_joint(1, from, &format!("{key} = {over:?}")), &field, over, range, &at);
        }
    }
    // The ranges are those of `Range` and of the parameters.
    assert_eq!(Parameter::GearRatio.range(), Range::GEAR_RATIO);
    assert_eq!(Parameter::RotorInertia.range(), Range::ROTOR_INERTIA);
    assert_eq!(Parameter::MotorViscous.range(), Range::MOTOR_VISCOUS);
    assert_eq!(Parameter::MotorCoulomb.range(), Range::MOTOR_COULOMB);
    let shown: Vec<String> = [Range::GEAR_RATIO, Range::ROTOR_INERTIA, Range::MOTOR_VISCOUS, Range::MOTOR_COULOMB]
        .iter()
        .map(|r| r.to_string())
        .collect();
    assert_eq!(shown, ["(0, 1e6]", "(0, 1000]", "[0, 1e6]", "[0, 1e6]"]);
    // The smallest positive double is an admissible gear ratio and rotor inertia.
    for key in ["gear_ratio = 100.0", "rotor_inertia = 3.0e-4"] {
        let (name, _) = key.split_once(" = ").unwrap();
        let text = edit_motor_joint(1, key, &format!("{name} = 5e-324"));
        Model::from_toml_str(&text).unwrap_or_else(|e| panic!("{name} = 5e-324 refused: {e}"));
    }
}

// ---------------------------------------------------------------------------
// Motor parameters: set_parameter, parameter, has_parameter, layout
// ---------------------------------------------------------------------------

const MOTOR_PARAMETERS: [Parameter; 4] =
    [Parameter::GearRatio, Parameter::RotorInertia, Parameter::MotorViscous, Parameter::MotorCoulomb];

#[test]
fn motor_parameters_have_their_names_and_only_the_gear_ratio_is_fixed() {
    let names: Vec<&str> = MOTOR_PARAMETERS.iter().map(|p| p.name()).collect();
    assert_eq!(names, ["gear_ratio", "J_m", "b_m", "tau_c"]);
    for p in Parameter::ALL {
        assert_eq!(p.is_tunable(), p != Parameter::GearRatio, "{p:?}");
    }
    for p in MOTOR_PARAMETERS {
        assert!(Parameter::ALL.contains(&p), "{p:?} is not in Parameter::ALL");
    }
}

#[test]
fn motor_parameters_exist_on_motor_joints_only() {
    let motor = Model::reference_rrpr_motor();
    let expected = [(0, [100.0, 3.0e-4, 2.0e-4, 0.03]), (2, [628.3185307179587, 1.2e-4, 1.0e-4, 0.02])];
    for (joint, values) in expected {
        for (p, value) in MOTOR_PARAMETERS.into_iter().zip(values) {
            assert!(motor.has_parameter(p, joint), "{p:?} of joint {}", joint + 1);
            assert_eq!(motor.parameter(p, joint), Some(value), "{p:?} of joint {}", joint + 1);
        }
        // And the spring's parameters, as on a flexible drive.
        for p in [Parameter::Stiffness, Parameter::Damping, Parameter::Clearance] {
            assert!(motor.has_parameter(p, joint), "{p:?} of joint {}", joint + 1);
        }
    }
    // Rigid joints 2 and 4, the flexible joints of the reference arm, and a joint beyond the chain: none.
    let flexible = Model::reference_rrpr();
    for p in MOTOR_PARAMETERS {
        for joint in [1, 3, 4] {
            assert!(!motor.has_parameter(p, joint), "{p:?} of motor-arm joint {}", joint + 1);
            assert_eq!(motor.parameter(p, joint), None);
        }
        for joint in 0..4 {
            assert!(!flexible.has_parameter(p, joint), "{p:?} of flexible joint {}", joint + 1);
        }
    }
    // set_parameter says so, naming the FMU-style variable; nothing changes.
    let mut model = flexible.clone();
    for (p, name) in MOTOR_PARAMETERS.into_iter().zip(["gear_ratio[1]", "J_m[1]", "b_m[1]", "tau_c[1]"]) {
        let e = model.set_parameter(p, 0, 1.0).unwrap_err();
        assert_invalid(&e, name, "no such parameter");
    }
    assert_eq!(model, flexible);
    let mut model = motor.clone();
    let e = model.set_parameter(Parameter::RotorInertia, 1, 1.0).unwrap_err();
    assert_invalid(&e, "J_m[2]", "no such parameter");
    let e = model.set_parameter(Parameter::MotorCoulomb, 4, 1.0).unwrap_err();
    assert_invalid(&e, "tau_c[5]", "the model has 4 joints");
    assert_eq!(model, motor);
}

#[test]
fn motor_parameters_are_set_within_their_ranges_and_refused_outside() {
    let reference = Model::reference_rrpr_motor();
    let mut model = reference.clone();
    // Refused: the value's own range, by the variable's name; nothing stored.
    let refusals: [(Parameter, usize, f64, &str, &str); 12] = [
        (Parameter::GearRatio, 0, 0.0, "gear_ratio[1]", "positive"),
        (Parameter::GearRatio, 2, -5.0, "gear_ratio[3]", "positive"),
        (Parameter::GearRatio, 0, 1.5e6, "gear_ratio[1]", "at most 1e6"),
        (Parameter::GearRatio, 0, f64::NAN, "gear_ratio[1]", "finite"),
        (Parameter::RotorInertia, 0, 0.0, "J_m[1]", "positive"),
        (Parameter::RotorInertia, 2, 1001.0, "J_m[3]", "at most 1000"),
        (Parameter::RotorInertia, 0, f64::INFINITY, "J_m[1]", "finite"),
        (Parameter::MotorViscous, 0, -1e-9, "b_m[1]", "negative"),
        (Parameter::MotorViscous, 2, 2e6, "b_m[3]", "at most 1e6"),
        (Parameter::MotorCoulomb, 2, -0.01, "tau_c[3]", "negative"),
        (Parameter::MotorCoulomb, 0, 1e300, "tau_c[1]", "at most 1e6"),
        (Parameter::MotorCoulomb, 0, f64::NEG_INFINITY, "tau_c[1]", "finite"),
    ];
    for (p, joint, value, field, reason) in refusals {
        let e = model.set_parameter(p, joint, value).unwrap_err();
        assert_invalid_parameter(&e, field, value, reason);
    }
    assert_eq!(model, reference, "a refused value must not be stored");

    // Accepted, the ceilings and zero friction included; read back exactly.
    let accepted: [(Parameter, usize, f64); 8] = [
        (Parameter::GearRatio, 0, 1e6),
        (Parameter::GearRatio, 2, 50.0),
        (Parameter::RotorInertia, 0, 1e3),
        (Parameter::RotorInertia, 2, 5e-324),
        (Parameter::MotorViscous, 0, 0.0),
        (Parameter::MotorViscous, 2, 1e6),
        (Parameter::MotorCoulomb, 0, 0.0),
        (Parameter::MotorCoulomb, 2, 1e6),
    ];
    for (p, joint, value) in accepted {
        model.set_parameter(p, joint, value).unwrap_or_else(|e| panic!("{p:?}[{}] = {value:e}: {e}", joint + 1));
        assert_eq!(model.parameter(p, joint), Some(value));
    }
    model.validate().expect("every value within its range: no relation involves the motor parameters");
    let rotor = model.joints[2].drive.rotor().unwrap();
    assert_eq!(rotor, Rotor { gear_ratio: 50.0, inertia: 5e-324, viscous: 1e6, coulomb: 1e6 });
    // Only the motor drives changed.
    assert_eq!(model.joints[1], reference.joints[1]);
    assert_eq!(model.links, reference.links);
}

#[test]
fn changing_motor_parameters_keeps_the_layout_changing_the_drive_kind_does_not() {
    let motor = Model::reference_rrpr_motor();
    let mut tuned = motor.clone();
    for (p, value) in MOTOR_PARAMETERS.into_iter().zip([80.0, 1e-3, 0.5, 0.1]) {
        tuned.set_parameter(p, 0, value).unwrap();
        tuned.set_parameter(p, 2, 2.0 * value).unwrap();
    }
    tuned.set_parameter(Parameter::Stiffness, 0, 5e5).unwrap();
    assert_ne!(tuned, motor);
    // The gear ratio is a parameter slot: the same layout, both ways.
    assert!(tuned.has_layout_of(&motor) && motor.has_layout_of(&tuned));
    // A running simulator takes the tuned model (the FMU forbids changing
    // gear_ratio after initialization; the engine leaves that to its caller).
    let mut sim = Simulator::new(motor.clone()).unwrap();
    sim.set_model(tuned.clone()).expect("same layout");
    assert_eq!(sim.model(), &tuned);

    // Motor drives where the reference arm has flexible ones: another layout.
    let flexible = Model::reference_rrpr();
    assert!(!flexible.has_layout_of(&motor) && !motor.has_layout_of(&flexible));
    let e = Simulator::new(motor.clone()).unwrap().set_model(flexible.clone()).unwrap_err();
    assert_invalid(&e, "model", "another chain");
    let e = Simulator::new(flexible).unwrap().set_model(motor.clone()).unwrap_err();
    assert_invalid(&e, "model", "another chain");
    // A motor drive added on another joint: another layout.
    let moved = Model::from_toml_str(&edit_motor_joint(
        2,
        "drive = { type = \"rigid\" }",
        "drive = { type = \"motor\", k = 1.0e6, gear_ratio = 100.0, rotor_inertia = 3.0e-4 }",
    ))
    .unwrap();
    assert_eq!(moved.motor_joints(), [0, 1, 2]);
    assert!(!moved.has_layout_of(&motor) && !motor.has_layout_of(&moved));
}

// ---------------------------------------------------------------------------
// Long chains
// ---------------------------------------------------------------------------

#[test]
fn chain_of_24_joints_parses_and_validates() {
    let text = chain_toml(24);
    let model = Model::from_toml_str(&text).expect("the 24-joint chain is valid");
    model.validate().unwrap();
    assert_eq!(model.nq(), 24);
    assert_eq!(model.links.len(), 24);
    let prismatic = model.joints.iter().filter(|j| j.kind == JointKind::Prismatic).count();
    assert_eq!(prismatic, 12);
    let flexible = model.joints.iter().filter(|j| j.drive.is_flexible()).count();
    assert_eq!(flexible, 8);
    let with_friction = model.joints.iter().filter(|j| j.friction.is_some()).count();
    assert_eq!(with_friction, 8);
    assert_eq!(model.links[23].mass, 1.0 + 0.1 * 24.0);
    assert_eq!(model.integrator.h_max, 1e-5);
    assert_eq!(model.integrator.beta, 0.25, "unset integrator keys take their defaults");

    // The generator itself is sound: the last joint's error names it.
    let last = joint_section(&text, 24);
    let broken = format!("{}{}", &text[..last.start], edit_text(&text[last], "mass = ", "mass = -"));
    let e = rejected(&broken);
    assert_invalid_parameter(&e, "joint[24].link.mass", -(1.0 + 0.1 * 24.0), "positive");
}
