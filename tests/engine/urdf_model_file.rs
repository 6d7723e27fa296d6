//! URDF model files (`urdf = "…"`, `base_link`, `tip_link`, `end_point`,
//! `gravity`, `[joints.<name>]`): every model-file-level refusal with the
//! field and the reason its message gives, the defaults, the warnings of the
//! URDF reaching `Model::warnings`, the joint names in chain order, and that a
//! URDF joint axis other than +z (the reference arm's y axes; x and −z axes of
//! a small arm written for this test) gives the same inverse dynamics as the
//! same arm written with z axes: τ, the joint reactions in the URDF child link
//! frames (turned by `Joint::reported_axes`) and the end point, to 1e-12.
//!
//! The URDF reader's own refusals are tested in tests/engine/urdf_reader.rs; here
//! only that they reach the model file's caller with the URDF's file name.
//!
//! Motor drives in `[joints.<name>]` (`drive = { type = "motor", … }`): on
//! the KUKA iiwa and the reference arm they give `Drive::Motor` with every
//! field and the defaults; their refusals are those of a DH file: syntax
//! errors (missing `gear_ratio`/`rotor_inertia`, unknown key, unknown type)
//! name the key and the model file's line, range refusals name the field by
//! the joint's place in the chain, `joint[i].drive.<key>` (not by its URDF
//! name), a massless chain beyond names `joint[i] (`<name>`).drive`.

use stick_slip_manipulator::algorithms::kinematics::{end_point, forward_kinematics};
use stick_slip_manipulator::algorithms::rnea::{joint_reactions, rnea};
use stick_slip_manipulator::math::{Mat3, Vec3};
use stick_slip_manipulator::model::{ContactGeometry, Drive, Parameter, Rotor};
use stick_slip_manipulator::stepper::MotorTorques;
use stick_slip_manipulator::{Data, DriveInputs, Model, ModelError, Simulator};

const REFERENCE_TOML: &str = include_str!("../../models/urdf/reference_rrpr/reference_rrpr.toml");
const REFERENCE_URDF: &str = include_str!("../../models/urdf/reference_rrpr/reference_rrpr.urdf");
const REFERENCE_URDF_NAME: &str = "reference_rrpr.urdf";
const MODELS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/models/urdf");

// ---------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------

/// A model from its TOML text, the URDF it names supplied as `urdf` (any
/// other name is a missing file).
fn load(toml: &str, urdf_name: &str, urdf: &str) -> Result<Model, ModelError> {
    Model::from_toml_with(toml, &|name| {
        if name == urdf_name {
            Ok(urdf.to_string())
        } else {
            Err(ModelError::Io { path: name.into(), reason: "no such file in this test".into() })
        }
    })
}

/// The reference arm's URDF model file with `edit` applied to its text.
fn reference(toml: &str) -> Result<Model, ModelError> {
    load(toml, REFERENCE_URDF_NAME, REFERENCE_URDF)
}

#[track_caller]
fn edit(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "the text does not contain `{from}`; the edit would be a no-op");
    text.replacen(from, to, 1)
}

#[track_caller]
fn rejected(result: Result<Model, ModelError>) -> ModelError {
    match result {
        Ok(m) => panic!("the model was accepted: {} joints {:?}", m.nq(), m.joint_names),
        Err(e) => e,
    }
}

/// `e` is `Invalid` for exactly `want_field`, its reason contains every one
/// of `reason_has`, and the message shows the field.
#[track_caller]
fn assert_invalid(e: &ModelError, want_field: &str, reason_has: &[&str]) {
    match e {
        ModelError::Invalid { field, reason } => {
            assert_eq!(field, want_field, "wrong field in: {e}");
            for r in reason_has {
                assert!(reason.contains(r), "the reason does not say `{r}`: {e}");
            }
            assert!(e.to_string().contains(want_field), "the message does not name `{want_field}`: {e}");
        }
        other => panic!("expected Invalid for `{want_field}`, got {other:?} ({other})"),
    }
}

/// `e` is a syntax error whose message contains every one of `has`.
#[track_caller]
fn assert_syntax(e: &ModelError, has: &[&str]) {
    match e {
        ModelError::Syntax { .. } => {
            let text = e.to_string();
            for h in has {
                assert!(text.contains(h), "the message does not say `{h}`: {text}");
            }
        }
        other => panic!("expected a syntax error, got {other:?} ({other})"),
    }
}

/// The reference TOML with a `[joints.<name>]` section appended.
fn with_section(name: &str, body: &str) -> String {
    format!("{REFERENCE_TOML}\n[joints.{name}]\n{body}\n")
}

/// The reference TOML with the entry of `j1` (or `j3`) replaced by `body`.
fn with_entry(name: &str, body: &str) -> String {
    let header = format!("[joints.{name}]");
    let start = REFERENCE_TOML.find(&header).expect("the reference file has the entry");
    let rest = &REFERENCE_TOML[start + header.len()..];
    let end = rest.find("\n\n").map_or(REFERENCE_TOML.len(), |e| start + header.len() + e);
    format!("{}{header}\n{body}\n{}", &REFERENCE_TOML[..start], &REFERENCE_TOML[end..])
}

const FLEXIBLE: &str = r#"drive = { type = "flexible", k = 1.0e6, h = 0.0, clearance = 0.0 }"#;
const FRICTION: &str = "friction = { mu_k = 0.2, mu_s = 0.2, v_s = 0.0 }";
const J1_BEARINGS: &str =
    "bearings = { reaction_point = [0.0, -0.54, 0.0], l_a = 0.06, l_b = 0.06, d_a = 0.1, d_b = 0.1, d_c = 0.1 }";
const J3_SLIDER: &str = "slider = { centre = [0.0, 0.0, -0.7], a = 0.2, b = 0.07, c = 0.07 }";

// ---------------------------------------------------------------------------
// The shipped file itself, and the section helpers
// ---------------------------------------------------------------------------

#[test]
fn reference_urdf_model_file_loads_through_the_test_reader() {
    let m = reference(REFERENCE_TOML).unwrap();
    assert_eq!(m.nq(), 4);
    // with_entry with the entry as written changes nothing.
    let same = with_entry("j1", &format!("{FLEXIBLE}\n{FRICTION}\n{J1_BEARINGS}"));
    assert_eq!(reference(&same).unwrap().joints, m.joints);
}

// ---------------------------------------------------------------------------
// Refusals
// ---------------------------------------------------------------------------

#[test]
fn joint_entry_for_a_joint_not_in_the_urdf_is_refused_naming_it() {
    let e = rejected(reference(&with_section("elbow", FLEXIBLE)));
    assert_invalid(&e, "joints.elbow", &["no moving joint of that name", "`base` to `gripper_tip`", "j1, j2, j3, j4"]);
}

#[test]
fn joint_entry_for_a_joint_beyond_the_tip_link_is_refused_naming_it() {
    // j4 exists in the URDF but lies beyond the chain's tip `link_3`.
    let toml = edit(&with_section("j4", FLEXIBLE), r#"tip_link = "gripper_tip""#, r#"tip_link = "link_3""#);
    let e = rejected(reference(&toml));
    assert_invalid(&e, "joints.j4", &["no moving joint of that name", "`base` to `link_3`", "j1, j2, j3)"]);
}

#[test]
fn joint_entry_for_a_fixed_joint_of_the_chain_is_refused_naming_it() {
    for fixed in ["link_2_extension", "tool"] {
        let e = rejected(reference(&with_section(fixed, FLEXIBLE)));
        assert_invalid(&e, &format!("joints.{fixed}"), &["no moving joint of that name"]);
    }
}

#[test]
fn joint_entry_for_a_joint_before_base_link_is_refused_naming_it() {
    // With base_link = link_1 the chain starts after j1.
    let toml = edit(REFERENCE_TOML, r#"base_link = "base""#, r#"base_link = "link_1""#);
    let e = rejected(reference(&toml));
    assert_invalid(&e, "joints.j1", &["`link_1` to `gripper_tip`", "j2, j3, j4)"]);
}

#[test]
fn friction_without_bearings_on_a_revolute_joint_is_refused() {
    let e = rejected(reference(&with_entry("j1", &format!("{FLEXIBLE}\n{FRICTION}"))));
    assert_invalid(&e, "joints.j1.bearings", &["friction on this joint needs its bearing geometry"]);
    // Friction alone, no drive either.
    let e = rejected(reference(&with_section("j2", FRICTION)));
    assert_invalid(&e, "joints.j2.bearings", &["needs its bearing geometry"]);
}

#[test]
fn friction_without_slider_on_a_prismatic_joint_is_refused() {
    let e = rejected(reference(&with_entry("j3", &format!("{FLEXIBLE}\n{FRICTION}"))));
    assert_invalid(&e, "joints.j3.slider", &["friction on this joint needs its slider geometry"]);
}

#[test]
fn bearings_on_a_prismatic_joint_are_refused() {
    let body = format!("{FLEXIBLE}\n{FRICTION}\nbearings = {{ reaction_point = [0.0, 0.0, 0.0], l_a = 0.06, l_b = 0.06, d_a = 0.1, d_b = 0.1, d_c = 0.1 }}");
    let e = rejected(reference(&with_entry("j3", &body)));
    assert_invalid(&e, "joints.j3.bearings", &["belongs to revolute joints", "prismatic", "`slider`"]);
    // Geometry without coefficients is checked the same way.
    let e = rejected(reference(&with_entry(
        "j3",
        "bearings = { reaction_point = [0.0, 0.0, 0.0], l_a = 0.06, l_b = 0.06, d_a = 0.1, d_b = 0.1, d_c = 0.1 }",
    )));
    assert_invalid(&e, "joints.j3.bearings", &["belongs to revolute joints"]);
}

#[test]
fn slider_on_a_revolute_joint_is_refused() {
    let e = rejected(reference(&with_entry("j1", &format!("{FLEXIBLE}\n{FRICTION}\n{J3_SLIDER}"))));
    assert_invalid(&e, "joints.j1.slider", &["belongs to prismatic joints", "revolute", "`bearings`"]);
    let e = rejected(reference(&with_section("j4", J3_SLIDER)));
    assert_invalid(&e, "joints.j4.slider", &["belongs to prismatic joints"]);
}

#[test]
fn bearings_and_slider_together_are_refused() {
    let e = rejected(reference(&with_entry("j1", &format!("{FLEXIBLE}\n{FRICTION}\n{J1_BEARINGS}\n{J3_SLIDER}"))));
    assert_invalid(&e, "joints.j1", &["both `bearings` and `slider`"]);
}

#[test]
fn bearing_reference_point_off_the_axis_is_refused_with_the_axis_and_the_distance() {
    // j1's axis is +y of its joint frame: a point on z (where a DH file puts
    // it) is off the axis, and so is one 1 cm beside it.
    for (point, off) in
        [("[0.0, 0.0, 0.1]", "1.000e-1 m"), ("[0.01, -0.54, 0.0]", "1.000e-2 m"), ("[0.0, -0.54, 1e-9]", "1.000e-9 m")]
    {
        let body = format!("{FLEXIBLE}\n{FRICTION}\n{}", J1_BEARINGS.replace("[0.0, -0.54, 0.0]", point));
        let e = rejected(reference(&with_entry("j1", &body)));
        assert_invalid(&e, "joints.j1.bearings.reaction_point", &["must lie on the joint axis [0, 1, 0]", off]);
    }
    // On the axis, either side of the origin: accepted.
    for point in ["[0.0, 0.3, 0.0]", "[0.0, 0.0, 0.0]", "[0.0, -0.54, 1e-13]"] {
        let body = format!("{FLEXIBLE}\n{FRICTION}\n{}", J1_BEARINGS.replace("[0.0, -0.54, 0.0]", point));
        reference(&with_entry("j1", &body)).unwrap_or_else(|e| panic!("{point}: {e}"));
    }
}

/// Two revolute joints; the second link has no `<inertial>` (massless).
const MASSLESS_TIP_URDF: &str = r#"<robot name="massless_tip">
  <link name="base"/>
  <joint name="a" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/></joint>
  <link name="l1"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
  <joint name="b" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.2 0 0"/><axis xyz="0 1 0"/></joint>
  <link name="l2"/>
  <joint name="flange" type="fixed"><parent link="l2"/><child link="tcp"/><origin xyz="0.05 0 0"/></joint>
  <link name="tcp"/>
</robot>"#;

#[test]
fn flexible_drive_whose_chain_beyond_has_no_mass_is_refused() {
    let toml = format!("urdf = \"m.urdf\"\n[joints.b]\n{FLEXIBLE}\n");
    let e = rejected(load(&toml, "m.urdf", MASSLESS_TIP_URDF));
    assert_invalid(&e, "joint[2] (`b`).drive", &["a flexible drive needs mass in the chain beyond the joint"]);
    // The first joint has the mass of l1 beyond it: accepted; b rigid.
    let toml = format!("urdf = \"m.urdf\"\n[joints.a]\n{FLEXIBLE}\n");
    let m = load(&toml, "m.urdf", MASSLESS_TIP_URDF).unwrap();
    assert!(m.joints[0].drive.is_flexible() && !m.joints[1].drive.is_flexible());
    assert_eq!(m.links[1].mass, 0.0);
}

#[test]
fn urdf_together_with_dh_joint_rows_is_refused() {
    let dh = stick_slip_manipulator::model::REFERENCE_RRPR_TOML;
    let rows = &dh[dh.find("[[joint]]").unwrap()..];
    let toml = format!("urdf = \"{REFERENCE_URDF_NAME}\"\n{rows}");
    let e = rejected(reference(&toml));
    assert_invalid(&e, "joint", &["either a `urdf` or Denavit-Hartenberg `[[joint]]` rows, not both"]);
}

#[test]
fn urdf_keys_in_a_dh_file_are_refused() {
    let dh = stick_slip_manipulator::model::REFERENCE_RRPR_TOML;
    for (key, line) in
        [("base_link", "base_link = \"base\"\n"), ("tip_link", "tip_link = \"tool\"\n"), ("joints", "joints = {}\n")]
    {
        let e = rejected(Model::from_toml_str(&format!("{line}{dh}")));
        assert_invalid(&e, key, &["belongs to a URDF model", "this file has no `urdf`"]);
    }
    // A [joints.x] section after the rows is the same key.
    let e = rejected(Model::from_toml_str(&format!("{dh}\n[joints.j1]\n{FLEXIBLE}\n")));
    assert_invalid(&e, "joints", &["belongs to a URDF model"]);
}

/// A scratch directory of this test process.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("urdf_model_file-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn missing_urdf_file_is_refused_naming_its_path() {
    let dir = scratch("missing");
    let model = dir.join("arm.toml");
    std::fs::write(&model, "urdf = \"robots/no_such_arm.urdf\"\n").unwrap();
    let e = rejected(Model::from_file(&model));
    let want = dir.join("robots/no_such_arm.urdf").display().to_string();
    match &e {
        ModelError::Io { path, reason } => {
            assert_eq!(path, &want);
            assert!(!reason.is_empty());
        }
        other => panic!("expected Io, got {other:?}"),
    }
    assert!(e.to_string().contains(&want), "{e}");
    // Relative to the model file, not to the current directory: the same
    // URDF beside the model file is found.
    std::fs::create_dir_all(dir.join("robots")).unwrap();
    std::fs::write(dir.join("robots/no_such_arm.urdf"), MASSLESS_TIP_URDF).unwrap();
    assert_eq!(Model::from_file(&model).unwrap().nq(), 2);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn urdf_error_is_surfaced_with_the_urdf_file_name_and_element() {
    // A negative mass in link_1.
    let bad = edit(REFERENCE_URDF, r#"<mass value="25"/>"#, r#"<mass value="-1"/>"#);
    let e = rejected(load(REFERENCE_TOML, REFERENCE_URDF_NAME, &bad));
    match &e {
        ModelError::Urdf { element, reason } => {
            assert!(element.starts_with("reference_rrpr.urdf: "), "{e}");
            assert!(element.contains(r#"<link name="link_1">"#), "{e}");
            assert!(!reason.is_empty());
        }
        other => panic!("expected Urdf, got {other:?}"),
    }
    // Truncated XML, and an unknown tip link: the same prefix.
    let truncated = &REFERENCE_URDF[..REFERENCE_URDF.len() / 2];
    for (urdf, toml) in [
        (truncated.to_string(), REFERENCE_TOML.to_string()),
        (REFERENCE_URDF.to_string(), edit(REFERENCE_TOML, r#"tip_link = "gripper_tip""#, r#"tip_link = "gripper""#)),
    ] {
        let e = rejected(load(&toml, REFERENCE_URDF_NAME, &urdf));
        assert!(matches!(e, ModelError::Urdf { .. }), "{e:?}");
        assert!(e.to_string().starts_with("URDF reference_rrpr.urdf: "), "{e}");
    }
    // The file's path as the model file writes it, directories included.
    let toml = edit(REFERENCE_TOML, r#"urdf = "reference_rrpr.urdf""#, r#"urdf = "sub/dir/arm.urdf""#);
    let e = rejected(load(&toml, "sub/dir/arm.urdf", truncated));
    assert!(e.to_string().starts_with("URDF sub/dir/arm.urdf: "), "{e}");
}

#[test]
fn unknown_keys_in_a_joint_entry_are_refused() {
    for (body, key) in [
        (format!("{FLEXIBLE}\nstiffness = 1e6"), "stiffness"),
        (r#"drive = { type = "flexible", k = 1.0e6, damping = 3.0 }"#.to_string(), "damping"),
        (format!("{FLEXIBLE}\nfriction = {{ mu_k = 0.1, mu_s = 0.2, mu_v = 0.0 }}"), "mu_v"),
        (format!("{FLEXIBLE}\nbearing = {{ reaction_point = [0.0, 0.0, 0.0] }}"), "bearing"),
        (format!("{FLEXIBLE}\n{FRICTION}\n{}", J1_BEARINGS.replace("d_c", "d_d")), "d_d"),
    ] {
        let e = rejected(reference(&with_entry("j1", &body)));
        assert_syntax(&e, &["unknown field", key]);
    }
    let e = rejected(reference(&with_section("j2", r#"drive = { type = "elastic", k = 1.0 }"#)));
    assert_syntax(&e, &["elastic"]);
    // And at the top level of a URDF model file.
    let e = rejected(reference(&format!("base = \"base\"\n{REFERENCE_TOML}")));
    assert_syntax(&e, &["unknown field", "base"]);
}

#[test]
fn integrator_settings_of_a_urdf_model_are_validated() {
    let toml = edit(REFERENCE_TOML, "h_min = 2e-6", "h_min = 1e-2");
    let e = rejected(reference(&toml));
    assert!(matches!(&e, ModelError::InvalidParameter { field, .. } if field == "integrator.h_min"), "{e:?}");
}

/// A URDF joint's entry gives the viscous part of its friction by the same
/// key as a Denavit–Hartenberg row (`friction = { …, viscous = b }`), read as
/// written and range checked under the joint's number.
#[test]
fn viscous_friction_of_a_urdf_joint() {
    let friction = FRICTION.replace("v_s = 0.0 }", "v_s = 0.0, viscous = 40.0 }");
    let m = reference(&with_entry("j3", &format!("{FLEXIBLE}\n{friction}\n{J3_SLIDER}"))).unwrap();
    assert_eq!(m.joints[2].friction.unwrap().coefficients.viscous, 40.0);
    assert_eq!(m.parameter(Parameter::Viscous, 2), Some(40.0));
    assert_eq!(m.joints[0].friction.unwrap().coefficients.viscous, 0.0, "absent is 0");
    let friction = FRICTION.replace("v_s = 0.0 }", "v_s = 0.0, viscous = -40.0 }");
    let e = rejected(reference(&with_entry("j3", &format!("{FLEXIBLE}\n{friction}\n{J3_SLIDER}"))));
    assert!(
        matches!(&e, ModelError::InvalidParameter { field, value, .. } if field == "joint[3].friction.viscous" && *value == -40.0),
        "{e:?}"
    );
}

#[test]
fn out_of_range_joint_entry_values_are_refused_by_field() {
    let e = rejected(reference(&with_section("j2", r#"drive = { type = "flexible", k = -1.0 }"#)));
    assert!(matches!(&e, ModelError::InvalidParameter { field, .. } if field == "joint[2].drive.k"), "{e:?}");
    let e = rejected(reference(&with_entry(
        "j1",
        &format!("{FLEXIBLE}\n{}\n{J1_BEARINGS}", FRICTION.replace("mu_s = 0.2", "mu_s = 0.1")),
    )));
    assert!(matches!(&e, ModelError::InvalidParameter { field, .. } if field == "joint[1].friction.mu_s"), "{e:?}");
    let e = rejected(reference(&edit(REFERENCE_TOML, "end_point = [0.0, 0.0, 0.0]", "end_point = [0.0, 0.0, nan]")));
    assert!(matches!(&e, ModelError::InvalidParameter { field, .. } if field.starts_with("end_point")), "{e:?}");
    let e = rejected(reference(&edit(REFERENCE_TOML, "gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, -1e300]")));
    assert!(matches!(&e, ModelError::InvalidParameter { field, .. } if field.starts_with("gravity")), "{e:?}");
}

// ---------------------------------------------------------------------------
// What is accepted
// ---------------------------------------------------------------------------

#[test]
fn drive_only_entry_is_a_frictionless_flexible_joint() {
    let m = reference(&with_section("j2", r#"drive = { type = "flexible", k = 2.0e5, h = 3.0, clearance = 1e-4 }"#))
        .unwrap();
    assert_eq!(m.joints[1].drive, Drive::Flexible { stiffness: 2.0e5, damping: 3.0, clearance: 1e-4 });
    assert!(m.joints[1].friction.is_none());
    // Defaults of a flexible drive: no damping, no clearance.
    let m = reference(&with_section("j4", r#"drive = { type = "flexible", k = 2.0e5 }"#)).unwrap();
    assert_eq!(m.joints[3].drive, Drive::Flexible { stiffness: 2.0e5, damping: 0.0, clearance: 0.0 });
    // An explicitly rigid drive, and an empty entry: what no entry gives.
    let plain = reference(REFERENCE_TOML).unwrap();
    for body in [r#"drive = { type = "rigid" }"#, ""] {
        let m = reference(&with_section("j2", body)).unwrap();
        assert_eq!(m.joints, plain.joints, "{body}");
    }
}

#[test]
fn geometry_without_coefficients_is_a_frictionless_joint_with_its_geometry() {
    let m = reference(&with_entry("j1", &format!("{FLEXIBLE}\n{J1_BEARINGS}"))).unwrap();
    let f = m.joints[0].friction.expect("the geometry is kept");
    assert_eq!(
        (f.coefficients.mu_kinetic, f.coefficients.mu_static, f.coefficients.stribeck_velocity),
        (0.0, 0.0, 0.0)
    );
    match f.geometry {
        // On the axis, at 0.54 m below the joint origin along −y: −0.54 along the engine's z.
        ContactGeometry::Bearings { reaction_point, l_a, d_c, .. } => {
            assert!((reaction_point - Vec3::new(0.0, 0.0, -0.54)).norm() < 1e-15, "{reaction_point:?}");
            assert_eq!((l_a, d_c), (0.06, 0.1));
        }
        other => panic!("{other:?}"),
    }
    let m = reference(&with_entry("j3", J3_SLIDER)).unwrap();
    let f = m.joints[2].friction.expect("the geometry is kept");
    assert_eq!(f.coefficients.mu_static, 0.0);
    assert!(matches!(f.geometry, ContactGeometry::Slider { a, .. } if a == 0.2));
    assert!(!m.joints[2].drive.is_flexible(), "no drive given: rigid");
}

#[test]
fn gravity_and_end_point_default_to_minus_z_and_the_tip_link_origin() {
    let without = edit(&edit(REFERENCE_TOML, "end_point = [0.0, 0.0, 0.0]", ""), "gravity = [0.0, 0.0, -9.81]", "");
    let explicit = reference(REFERENCE_TOML).unwrap();
    let default = reference(&without).unwrap();
    assert_eq!(default.gravity, Vec3::new(0.0, 0.0, -9.81));
    assert_eq!(default.end_point, explicit.end_point);
    assert_eq!(default.joints, explicit.joints);
    // The tip link's origin: 0.1 m along x of link_4 (the fixed joint `tool`).
    let mut data = Data::new(&default);
    forward_kinematics(&default, &mut data, &[0.0; 4]);
    let mut other = Data::new(&default);
    let moved = default.clone();
    let mut with_point = default.clone();
    with_point.end_point = Vec3::zeros();
    forward_kinematics(&with_point, &mut other, &[0.0; 4]);
    let d = end_point(&moved, &data) - end_point(&with_point, &other);
    assert!((d.norm() - 0.1).abs() < 1e-12, "the tool frame is 0.1 m from link_4's origin: {d:?}");
    // The name defaults to the URDF's file stem; the integrator to the defaults.
    let bare =
        reference(&format!("urdf = \"{REFERENCE_URDF_NAME}\"\nbase_link = \"base\"\ntip_link = \"gripper_tip\"\n"))
            .unwrap();
    assert_eq!(bare.name, "reference_rrpr");
    assert_eq!(bare.integrator, stick_slip_manipulator::model::IntegratorSettings::default());
    assert_eq!(bare.gravity, Vec3::new(0.0, 0.0, -9.81));
    // base_link and tip_link default to the root and the single leaf.
    let rootless = reference(&format!("urdf = \"{REFERENCE_URDF_NAME}\"\n")).unwrap();
    assert_eq!(rootless.joints, bare.joints);
    assert_eq!(rootless.end_point, bare.end_point);
}

#[test]
fn xarm6_triangle_inequality_warnings_reach_model_warnings() {
    let m = Model::from_file(format!("{MODELS}/xarm6/xarm6.toml")).unwrap();
    let triangle: Vec<&String> = m.warnings.iter().filter(|w| w.contains("I1 + I2 >= I3")).collect();
    assert_eq!(triangle.len(), 2, "{:#?}", m.warnings);
    assert!(triangle[0].contains("link `link2`") && triangle[0].contains("0.74"), "{}", triangle[0]);
    assert!(triangle[1].contains("link `link3`") && triangle[1].contains("13."), "{}", triangle[1]);
    // The iiwa and the reference arm have none.
    assert!(Model::from_file(format!("{MODELS}/kuka_iiwa/kuka_iiwa.toml")).unwrap().warnings.is_empty());
    assert!(reference(REFERENCE_TOML).unwrap().warnings.is_empty());
}

#[test]
fn joint_names_are_the_urdf_names_in_chain_order() {
    let names =
        |m: &Model| m.joint_names.iter().map(|n| n.clone().expect("a URDF joint has a name")).collect::<Vec<_>>();
    let iiwa = Model::from_file(format!("{MODELS}/kuka_iiwa/kuka_iiwa.toml")).unwrap();
    assert_eq!(names(&iiwa), (1..=7).map(|i| format!("lbr_iiwa_joint_{i}")).collect::<Vec<_>>());
    let xarm = Model::from_file(format!("{MODELS}/xarm6/xarm6.toml")).unwrap();
    assert_eq!(names(&xarm), (1..=6).map(|i| format!("joint{i}")).collect::<Vec<_>>());
    // Entries land on their joints whatever their order in the file (a
    // BTreeMap sorts them by name): iiwa 1, 2, 4 flexible.
    let flexible: Vec<bool> = iiwa.joints.iter().map(|j| j.drive.is_flexible()).collect();
    assert_eq!(flexible[..4], [true, true, false, true]);
    assert!(Model::reference_rrpr().joint_names.iter().all(Option::is_none), "DH joints have no names");
}

// ---------------------------------------------------------------------------
// Motor drives in [joints.<name>]
// ---------------------------------------------------------------------------

const KUKA_TOML: &str = include_str!("../../models/urdf/kuka_iiwa/kuka_iiwa.toml");
const KUKA_URDF: &str = include_str!("../../models/urdf/kuka_iiwa/kuka_iiwa.urdf");
/// The drive line of lbr_iiwa_joint_2 in kuka_iiwa.toml (line 83).
const KUKA_J2_DRIVE: &str = r#"drive = { type = "flexible", k = 7.8e4, h = 31.0, clearance = 0.0 }"#;

fn kuka(toml: &str) -> Result<Model, ModelError> {
    load(toml, "kuka_iiwa.urdf", KUKA_URDF)
}

/// kuka_iiwa.toml with joint 2's drive line replaced by `drive`.
fn kuka_j2(drive: &str) -> String {
    edit(KUKA_TOML, KUKA_J2_DRIVE, drive)
}

/// `e` is `InvalidParameter` for exactly `want_field` with `value`, its
/// reason contains `reason_has`, and the message shows the field.
#[track_caller]
fn assert_invalid_parameter(e: &ModelError, want_field: &str, want_value: f64, reason_has: &str) {
    match e {
        ModelError::InvalidParameter { field, value, reason } => {
            assert_eq!(field, want_field, "wrong field in: {e}");
            assert!(
                value.to_bits() == want_value.to_bits() || (value.is_nan() && want_value.is_nan()),
                "{value} in: {e}"
            );
            assert!(reason.contains(reason_has), "the reason does not say `{reason_has}`: {e}");
            assert!(e.to_string().contains(want_field), "the message does not name `{want_field}`: {e}");
        }
        other => panic!("expected InvalidParameter for `{want_field}`, got {other:?} ({other})"),
    }
}

#[test]
fn motor_drive_entry_on_a_kuka_iiwa_joint_is_a_motor_drive() {
    let plain = Model::from_file(format!("{MODELS}/kuka_iiwa/kuka_iiwa.toml")).unwrap();
    assert_eq!(kuka(KUKA_TOML).unwrap().joints, plain.joints, "the test reader reads the shipped file");
    let toml = kuka_j2(
        r#"drive = { type = "motor", k = 7.8e4, h = 31.0, clearance = 1e-4, gear_ratio = 100.0, rotor_inertia = 6.0e-5, motor_viscous = 1e-4, motor_coulomb = 0.05 }"#,
    );
    let m = kuka(&toml).unwrap();
    let rotor = Rotor { gear_ratio: 100.0, inertia: 6.0e-5, viscous: 1e-4, coulomb: 0.05 };
    assert_eq!(m.joints[1].drive, Drive::Motor { stiffness: 7.8e4, damping: 31.0, clearance: 1e-4, rotor });
    assert_eq!(m.motor_joints(), [1]);
    assert_eq!(m.n_coordinates(), 8);
    // Friction and geometry of the entry kept; every other joint as shipped.
    assert_eq!(m.joints[1].friction, plain.joints[1].friction);
    for i in (0..7).filter(|&i| i != 1) {
        assert_eq!(m.joints[i], plain.joints[i], "joint {}", i + 1);
    }
    assert_eq!(m.links, plain.links);

    // A new entry on a joint the shipped file leaves rigid, only the
    // required fields: the defaults are zero.
    let toml = format!(
        "{toml}\n[joints.lbr_iiwa_joint_3]\ndrive = {{ type = \"motor\", k = 2.0e4, gear_ratio = 120.0, rotor_inertia = 3.0e-5 }}\n"
    );
    let m = kuka(&toml).unwrap();
    let rotor = Rotor { gear_ratio: 120.0, inertia: 3.0e-5, viscous: 0.0, coulomb: 0.0 };
    assert_eq!(m.joints[2].drive, Drive::Motor { stiffness: 2.0e4, damping: 0.0, clearance: 0.0, rotor });
    assert!(m.joints[2].friction.is_none());
    assert_eq!(m.motor_joints(), [1, 2]);
}

#[test]
fn reference_urdf_arm_with_motor_entries_has_the_drives_of_the_dh_motor_file_and_steps() {
    let dh = Model::reference_rrpr_motor();
    let drive = |j: usize| {
        match dh.joints[j].drive {
        Drive::Motor { stiffness, damping, clearance, rotor } => format!(
            "drive = {{ type = \"motor\", k = {stiffness:?}, h = {damping:?}, clearance = {clearance:?}, gear_ratio = {:?}, \
             rotor_inertia = {:?}, motor_viscous = {:?}, motor_coulomb = {:?} }}",
            rotor.gear_ratio, rotor.inertia, rotor.viscous, rotor.coulomb
        ),
        other => panic!("{other:?}"),
    }
    };
    let toml = with_entry("j1", &format!("{}\n{FRICTION}\n{J1_BEARINGS}", drive(0)));
    let toml = {
        let header = "[joints.j3]";
        let start = toml.find(header).unwrap();
        let rest = &toml[start + header.len()..];
        let end = rest.find("\n\n").map_or(toml.len(), |e| start + header.len() + e);
        format!("{}{header}\n{}\n{FRICTION}\n{J3_SLIDER}\n{}", &toml[..start], drive(2), &toml[end..])
    };
    let m = reference(&toml).unwrap();
    assert_eq!(m.motor_joints(), [0, 2]);
    assert_eq!(m.joints[0].drive, dh.joints[0].drive);
    assert_eq!(m.joints[2].drive, dh.joints[2].drive);
    // It steps: 5 ms with 0.5 N·m on joint 1's motor, to a finite state in
    // which that rotor turned forwards.
    let mut sim = Simulator::new(m).unwrap();
    let zero = [0.0; 4];
    let at_rest = DriveInputs { q_star: &zero, qd_star: &zero, qdd_star: &zero };
    sim.set_motor_torques(&MotorTorques { tau_m: &[0.5, 0.0, 0.0, 0.0], tau_m_rate: &zero, tau_m_accel: &zero })
        .unwrap();
    sim.initialize(0.0, &at_rest, None).unwrap();
    for _ in 0..5 {
        sim.advance(&at_rest, 1e-3).unwrap();
        sim.state().check_finite().unwrap();
    }
    assert!(sim.state().omega_m(0) > 0.0 && sim.state().theta_m(0) > 0.0, "{:?}", sim.state());
}

#[test]
fn motor_drive_entry_syntax_errors_name_the_key_and_the_line() {
    let cases = [
        (r#"drive = { type = "motor", k = 7.8e4, rotor_inertia = 1e-4 }"#, "missing field `gear_ratio`"),
        (r#"drive = { type = "motor", k = 7.8e4, gear_ratio = 100.0 }"#, "missing field `rotor_inertia`"),
        (r#"drive = { type = "motor", gear_ratio = 100.0, rotor_inertia = 1e-4 }"#, "missing field `k`"),
        (
            r#"drive = { type = "motor", k = 7.8e4, gear_ratio = 100.0, rotor_inertial = 1e-4 }"#,
            "unknown field `rotor_inertial`",
        ),
        (r#"drive = { type = "motr", k = 7.8e4, gear_ratio = 100.0, rotor_inertia = 1e-4 }"#, "unknown variant `motr`"),
        (r#"drive = { type = "flexible", k = 7.8e4, gear_ratio = 100.0 }"#, "unknown field `gear_ratio`"),
        (
            r#"drive = { type = "motor", k = 7.8e4, gear_ratio = true, rotor_inertia = 1e-4 }"#,
            "invalid type: boolean `true`, expected f64",
        ),
    ];
    for (drive, says) in cases {
        let e = rejected(kuka(&kuka_j2(drive)));
        assert_syntax(&e, &[says, "line 83"]);
    }
    let e = rejected(kuka(&kuka_j2(r#"drive = { type = "motr", k = 7.8e4 }"#)));
    assert_syntax(&e, &["`rigid`", "`flexible`", "`motor`"]);
}

#[test]
fn motor_drive_entry_values_are_refused_by_the_joints_place_in_the_chain() {
    let with = |key_value: &str| {
        kuka_j2(&format!(
            "drive = {{ type = \"motor\", k = 7.8e4, gear_ratio = 100.0, rotor_inertia = 1e-4, motor_viscous = 1e-4, motor_coulomb = 0.05, {key_value} }}"
        ))
    };
    // A key given twice is a TOML error: the cases replace it instead.
    let cases: [(&str, &str, &str, f64, &str); 13] = [
        ("gear_ratio = 100.0", "gear_ratio = 0.0", "gear_ratio", 0.0, "positive"),
        ("gear_ratio = 100.0", "gear_ratio = -3.0", "gear_ratio", -3.0, "positive"),
        ("gear_ratio = 100.0", "gear_ratio = nan", "gear_ratio", f64::NAN, "finite"),
        ("gear_ratio = 100.0", "gear_ratio = inf", "gear_ratio", f64::INFINITY, "finite"),
        ("gear_ratio = 100.0", "gear_ratio = 1.0e7", "gear_ratio", 1e7, "(0, 1e6]"),
        ("rotor_inertia = 1e-4", "rotor_inertia = 0.0", "rotor_inertia", 0.0, "positive"),
        ("rotor_inertia = 1e-4", "rotor_inertia = 2000.0", "rotor_inertia", 2000.0, "(0, 1000]"),
        ("rotor_inertia = 1e-4", "rotor_inertia = -inf", "rotor_inertia", f64::NEG_INFINITY, "finite"),
        ("motor_viscous = 1e-4", "motor_viscous = -1e-4", "motor_viscous", -1e-4, "negative"),
        ("motor_viscous = 1e-4", "motor_viscous = 1.0e7", "motor_viscous", 1e7, "[0, 1e6]"),
        ("motor_coulomb = 0.05", "motor_coulomb = -0.05", "motor_coulomb", -0.05, "negative"),
        ("motor_coulomb = 0.05", "motor_coulomb = 1.0e7", "motor_coulomb", 1e7, "[0, 1e6]"),
        ("motor_coulomb = 0.05", "motor_coulomb = nan", "motor_coulomb", f64::NAN, "finite"),
    ];
    for (from, to, key, value, reason) in cases {
        let toml = with("h = 31.0").replacen(from, to, 1);
        assert!(toml.contains(to), "{to}");
        let e = rejected(kuka(&toml));
        // lbr_iiwa_joint_2 is the chain's joint 2; the field does not carry
        // the URDF name (the range check is the model's, after the chain is built).
        assert_invalid_parameter(&e, &format!("joint[2].drive.{key}"), value, reason);
    }
    // The same on a joint without an entry in the shipped file.
    let toml = format!("{KUKA_TOML}\n[joints.lbr_iiwa_joint_6]\ndrive = {{ type = \"motor\", k = 1.0e4, gear_ratio = 0.0, rotor_inertia = 1e-5 }}\n");
    let e = rejected(kuka(&toml));
    assert_invalid_parameter(&e, "joint[6].drive.gear_ratio", 0.0, "positive");
    // At the ceilings: accepted.
    let toml = kuka_j2(
        r#"drive = { type = "motor", k = 7.8e4, gear_ratio = 1.0e6, rotor_inertia = 1.0e3, motor_viscous = 1.0e6, motor_coulomb = 1.0e6 }"#,
    );
    kuka(&toml).unwrap();
}

#[test]
fn motor_drive_whose_chain_beyond_has_no_mass_is_refused_naming_the_urdf_joint() {
    let motor = r#"drive = { type = "motor", k = 1.0e5, gear_ratio = 50.0, rotor_inertia = 1e-4 }"#;
    let toml = format!("urdf = \"m.urdf\"\n[joints.b]\n{motor}\n");
    let e = rejected(load(&toml, "m.urdf", MASSLESS_TIP_URDF));
    assert_invalid(&e, "joint[2] (`b`).drive", &["needs mass in the chain beyond the joint"]);
    let toml = format!("urdf = \"m.urdf\"\n[joints.a]\n{motor}\n");
    let m = load(&toml, "m.urdf", MASSLESS_TIP_URDF).unwrap();
    assert_eq!(m.motor_joints(), [0]);
}

// ---------------------------------------------------------------------------
// Joint axes other than +z
// ---------------------------------------------------------------------------

/// Inverse dynamics of a model at one state: τ, and per joint the reaction
/// force and moment in the URDF child link frame turned by `turn[i]`, and the
/// end point.
struct Dynamics {
    tau: Vec<f64>,
    force: Vec<Vec3>,
    moment: Vec<Vec3>,
    end: Vec3,
}

fn inverse_dynamics(model: &Model, turn: &[Mat3], q: &[f64], qd: &[f64], qdd: &[f64]) -> Dynamics {
    let mut data = Data::new(model);
    forward_kinematics(model, &mut data, q);
    rnea(model, &mut data, q, qd, qdd);
    joint_reactions(model, &mut data);
    let n = model.nq();
    // Reported (URDF child link frame), then into the compared frame.
    let reported = |i: usize, v: Vec3| turn[i] * (model.joints[i].reported_axes * v);
    Dynamics {
        tau: data.tau.clone(),
        force: (0..n).map(|i| reported(i, data.reaction_force[i])).collect(),
        moment: (0..n).map(|i| reported(i, data.reaction_moment[i])).collect(),
        end: end_point(model, &data),
    }
}

/// A deterministic uniform sample in [-1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
    fn vec(&mut self, n: usize, scale: f64) -> Vec<f64> {
        (0..n).map(|_| scale * self.next()).collect()
    }
}

/// Compares the inverse dynamics of two models at random states (each
/// quantity relative to its largest magnitude over all states, 1e-12).
fn assert_same_dynamics(a: &Model, turn_a: &[Mat3], b: &Model, turn_b: &[Mat3], states: usize) -> f64 {
    assert_eq!(a.nq(), b.nq());
    let n = a.nq();
    let mut rng = Lcg(19);
    let mut pairs = Vec::new();
    for _ in 0..states {
        let (q, qd, qdd) = (rng.vec(n, 2.0), rng.vec(n, 1.5), rng.vec(n, 5.0));
        pairs.push((inverse_dynamics(a, turn_a, &q, &qd, &qdd), inverse_dynamics(b, turn_b, &q, &qd, &qdd)));
    }
    let mut worst = 0.0f64;
    let mut check = |what: String, get: &dyn Fn(&Dynamics) -> f64| {
        let scale = pairs.iter().fold(0.0f64, |m, (x, _)| m.max(get(x).abs()));
        let diff = pairs.iter().fold(0.0f64, |m, (x, y)| m.max((get(x) - get(y)).abs()));
        assert!(scale > 0.0 || diff == 0.0, "{what}: identically zero in one model only");
        let rel = if scale > 0.0 { diff / scale } else { 0.0 };
        assert!(rel <= 1e-12, "{what}: deviates by {rel:.2e} of its largest magnitude {scale:.3e}");
        worst = worst.max(rel);
    };
    for i in 0..n {
        check(format!("tau[{}]", i + 1), &|d| d.tau[i]);
        for k in 0..3 {
            check(format!("f[{},{}]", i + 1, k + 1), &|d| d.force[i][k]);
            check(format!("n[{},{}]", i + 1, k + 1), &|d| d.moment[i][k]);
        }
    }
    for k in 0..3 {
        check(format!("x_E[{}]", k + 1), &|d| d.end[k]);
    }
    worst
}

#[test]
fn reference_arm_with_urdf_y_axes_has_the_inverse_dynamics_of_its_dh_file() {
    let dh = Model::reference_rrpr();
    let urdf = reference(REFERENCE_TOML).unwrap();
    // The URDF arm's axes are y (j1, j2) and z (j3, j4): the alignments are
    // not all the identity, so this compares something.
    assert!(urdf.joints[0].reported_axes != Mat3::identity() && urdf.joints[1].reported_axes != Mat3::identity());
    // Both in the engine's (DH) frames: the URDF's reported reactions turned
    // back by reported_axesᵀ; the DH model's reported_axes are the identity.
    let back: Vec<Mat3> = urdf.joints.iter().map(|j| j.reported_axes.transpose()).collect();
    let same: Vec<Mat3> = dh.joints.iter().map(|j| j.reported_axes.transpose()).collect();
    let worst = assert_same_dynamics(&urdf, &back, &dh, &same, 50);
    eprintln!("reference arm URDF (y axes) vs DH: largest deviation {worst:.2e}");
}

/// How one joint of the test arm is written: its axis in the joint frame,
/// the rpy of the rotation Q that takes the axis to z (the joint frame of
/// the z-axis arm is this one turned by Q: C = C'·Qᵀ) and of Qᵀ, and Qᵀ
/// applied to a vector (exactly, a permutation with signs).
#[derive(Clone, Copy)]
struct AxisWriting {
    axis: &'static str,
    q_rpy: &'static str,
    qt_rpy: &'static str,
    qt: fn([f64; 3]) -> [f64; 3],
    /// Q as a matrix (turns a vector of the turned frame C' into C).
    q: fn() -> Mat3,
}

const Z: AxisWriting = AxisWriting { axis: "0 0 1", q_rpy: "0 0 0", qt_rpy: "0 0 0", qt: |v| v, q: Mat3::identity };
/// Axis x: Q = Ry(−π/2) takes x to z; Qᵀ = Ry(π/2): (x, y, z) -> (z, y, −x).
const X: AxisWriting = AxisWriting {
    axis: "1 0 0",
    q_rpy: "0 -1.5707963267948966 0",
    qt_rpy: "0 1.5707963267948966 0",
    qt: |[x, y, z]| [z, y, -x],
    q: || Mat3::new(0.0, 0.0, -1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0),
};
/// Axis −z: Q = Rx(π) takes −z to z; Qᵀ = Rx(−π): (x, y, z) -> (x, −y, −z).
const MINUS_Z: AxisWriting = AxisWriting {
    axis: "0 0 -1",
    q_rpy: "3.141592653589793 0 0",
    qt_rpy: "-3.141592653589793 0 0",
    qt: |[x, y, z]| [x, -y, -z],
    q: || Mat3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0),
};

fn v3(v: [f64; 3]) -> String {
    format!("{:?} {:?} {:?}", v[0], v[1], v[2])
}

/// A 4-joint arm (revolute, revolute, prismatic, revolute) written as a URDF
/// whose joint i has the axis `w[i].axis`: link i's frame is the z-axis
/// arm's link frame C_i turned by Q_i (C'_i = C_i·Q_i). Every moving joint
/// sits between massless helper links joined by fixed joints that undo and
/// redo the turn, so every rpy is a literal: `pre_i` places the z-axis
/// arm's joint frame, the moving joint turns by Q_i, `post_i` turns back.
/// The inertials are written in C'_i (com Qᵀc, orientation Qᵀ).
fn test_arm_urdf(w: [AxisWriting; 4]) -> String {
    let kinds = ["revolute", "continuous", "prismatic", "revolute"];
    // Placement of the z-axis arm's joint i in C_{i−1}.
    let origins = [
        ("0 0 0.4", "0 0 0.3"),
        ("0.05 0.02 0.1", "1.2 0.1 -0.4"),
        ("0.3 0 0.05", "0.2 1.4 0.3"),
        ("0 0.04 0.5", "-0.3 0.5 2.0"),
    ];
    let masses = [6.0, 4.5, 3.0, 1.5];
    let coms = [[0.02, -0.05, 0.15], [0.2, 0.01, -0.03], [-0.01, 0.02, -0.25], [0.04, 0.0, 0.06]];
    let inertias = [
        r#"ixx="0.09" ixy="0.004" ixz="-0.006" iyy="0.08" iyz="0.003" izz="0.05""#,
        r#"ixx="0.02" ixy="-0.001" ixz="0.002" iyy="0.06" iyz="0.0005" izz="0.055""#,
        r#"ixx="0.07" ixy="0.0" ixz="0.001" iyy="0.07" iyz="-0.002" izz="0.01""#,
        r#"ixx="0.004" ixy="0.0002" ixz="0.0" iyy="0.005" iyz="0.0001" izz="0.003""#,
    ];
    let mut s = String::from("<?xml version=\"1.0\"?>\n<robot name=\"axes\">\n  <link name=\"base\"/>\n");
    let mut parent = "base".to_string();
    for i in 0..4 {
        let (xyz, rpy) = origins[i];
        let n = i + 1;
        s += &format!(
            "  <joint name=\"pre{n}\" type=\"fixed\"><parent link=\"{parent}\"/><child link=\"n{n}\"/><origin xyz=\"{xyz}\" rpy=\"{rpy}\"/></joint>\n  <link name=\"n{n}\"/>\n"
        );
        s += &format!(
            "  <joint name=\"j{n}\" type=\"{}\"><parent link=\"n{n}\"/><child link=\"l{n}\"/><origin xyz=\"0 0 0\" rpy=\"{}\"/><axis xyz=\"{}\"/><limit lower=\"-3\" upper=\"3\" effort=\"100\" velocity=\"2\"/></joint>\n",
            kinds[i], w[i].q_rpy, w[i].axis
        );
        s += &format!(
            "  <link name=\"l{n}\"><inertial><origin xyz=\"{}\" rpy=\"{}\"/><mass value=\"{}\"/><inertia {}/></inertial></link>\n",
            v3((w[i].qt)(coms[i])),
            w[i].qt_rpy,
            masses[i],
            inertias[i]
        );
        s += &format!(
            "  <joint name=\"post{n}\" type=\"fixed\"><parent link=\"l{n}\"/><child link=\"m{n}\"/><origin xyz=\"0 0 0\" rpy=\"{}\"/></joint>\n  <link name=\"m{n}\"/>\n",
            w[i].qt_rpy
        );
        parent = format!("m{n}");
    }
    s += &format!("  <joint name=\"tool\" type=\"fixed\"><parent link=\"{parent}\"/><child link=\"tcp\"/><origin xyz=\"0.1 -0.02 0.08\" rpy=\"0.3 0 0\"/></joint>\n  <link name=\"tcp\"/>\n</robot>\n");
    s
}

/// The model file of the test arm: flexible drives on 1 and 3, bearings on
/// joint 1 (reaction point 0.07 m along the axis), a slider on joint 3 (its
/// centre, given in the z-axis arm's link frame, written in C'_3), friction.
fn test_arm_toml(w: [AxisWriting; 4]) -> String {
    let point = (w[0].qt)([0.0, 0.0, 0.07]);
    let centre = (w[2].qt)([0.01, -0.02, -0.3]);
    format!(
        r#"urdf = "axes.urdf"
base_link = "base"
tip_link = "tcp"
end_point = [0.01, 0.02, 0.03]
gravity = [0.3, -0.2, -9.81]
[joints.j1]
drive = {{ type = "flexible", k = 2.0e4, h = 5.0 }}
friction = {{ mu_k = 0.1, mu_s = 0.15, v_s = 0.01 }}
bearings = {{ reaction_point = [{:?}, {:?}, {:?}], l_a = 0.04, l_b = 0.05, d_a = 0.1, d_b = 0.09, d_c = 0.12 }}
[joints.j3]
drive = {{ type = "flexible", k = 1.0e5 }}
friction = {{ mu_k = 0.1, mu_s = 0.15 }}
slider = {{ centre = [{:?}, {:?}, {:?}], a = 0.2, b = 0.05, c = 0.06 }}
[joints.j4]
drive = {{ type = "flexible", k = 3.0e3 }}
"#,
        point[0], point[1], point[2], centre[0], centre[1], centre[2]
    )
}

#[test]
fn urdf_x_and_minus_z_axes_give_the_inverse_dynamics_of_the_same_arm_with_z_axes() {
    let z_axes = [Z; 4];
    let other = [X, MINUS_Z, X, MINUS_Z];
    let model =
        |w: [AxisWriting; 4]| load(&test_arm_toml(w), "axes.urdf", &test_arm_urdf(w)).unwrap_or_else(|e| panic!("{e}"));
    let (a, b) = (model(z_axes), model(other));
    assert!(a.warnings.is_empty() && b.warnings.is_empty(), "{:?} {:?}", a.warnings, b.warnings);
    assert!(a.joints.iter().all(|j| j.reported_axes == Mat3::identity()));
    assert!(b.joints.iter().all(|j| j.reported_axes != Mat3::identity()));
    // The x-axis arm reports in C'_i = C_i·Q_i: Q_i turns that into C_i.
    let identity = [Mat3::identity(); 4];
    let q_turn: Vec<Mat3> = other.iter().map(|w| (w.q)()).collect();
    let worst = assert_same_dynamics(&a, &identity, &b, &q_turn, 50);
    eprintln!("test arm x/-z axes vs z axes: largest deviation {worst:.2e}");
    // The bearing point and slider centre landed where the z-axis arm has
    // them (in the engine's frames the two arms differ by a turn about z, so
    // compare the axial coordinate and the distance from the axis).
    for i in [0, 2] {
        let point = |m: &Model| match m.joints[i].friction.unwrap().geometry {
            ContactGeometry::Bearings { reaction_point, .. } => reaction_point,
            ContactGeometry::Slider { centre, .. } => centre,
        };
        let (pa, pb) = (point(&a), point(&b));
        assert!((pa.z - pb.z).abs() < 1e-15 && (pa.xy().norm() - pb.xy().norm()).abs() < 1e-15, "{pa:?} {pb:?}");
    }
    // A sanity check that the comparison can fail: the x-axis arm's
    // reactions not turned back by Q differ from the z-axis arm's.
    let n = a.nq();
    let (q, qd, qdd) = (vec![0.3; n], vec![0.2; n], vec![0.1; n]);
    let (da, db) = (inverse_dynamics(&a, &identity, &q, &qd, &qdd), inverse_dynamics(&b, &identity, &q, &qd, &qdd));
    assert!((da.force[0] - db.force[0]).norm() > 1e-3 * da.force[0].norm());
}

#[test]
fn urdf_axis_that_is_not_a_unit_vector_is_normalized() {
    // <axis xyz="0 0 2"> and "0 0 0.5" are the z axis (the URDF
    // specification normalizes it); reader and model agree.
    let z = load(&test_arm_toml([Z; 4]), "axes.urdf", &test_arm_urdf([Z; 4])).unwrap();
    for scaled in ["0 0 2", "0 0 0.5"] {
        let urdf = test_arm_urdf([Z; 4]).replace(r#"<axis xyz="0 0 1"/>"#, &format!(r#"<axis xyz="{scaled}"/>"#));
        match load(&test_arm_toml([Z; 4]), "axes.urdf", &urdf) {
            Ok(m) => {
                let identity = [Mat3::identity(); 4];
                assert_same_dynamics(&z, &identity, &m, &identity, 5);
            }
            Err(e) => assert!(matches!(e, ModelError::Urdf { .. }) && e.to_string().contains("axis"), "{scaled}: {e}"),
        }
    }
}
