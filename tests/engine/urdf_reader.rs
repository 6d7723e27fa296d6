//! The URDF reader (`model::urdf::read_urdf`): placements, merged and lumped
//! mass properties against hand computations, the rpy convention, and every
//! refusal with the element it names.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Matrix3, Rotation3, Vector3};
use stick_slip_manipulator::model::urdf::{read_urdf, UrdfChain, UrdfInertial, UrdfLimit};
use stick_slip_manipulator::model::JointKind;
use stick_slip_manipulator::ModelError;

type Vec3 = Vector3<f64>;
type Mat3 = Matrix3<f64>;

const TOL: f64 = 1e-12;

fn file(name: &str) -> String {
    let path = format!("{}/tests/urdf/{name}", env!("CARGO_MANIFEST_DIR"));
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"))
}

fn arm() -> UrdfChain {
    read_urdf(&file("arm.urdf"), None, Some("tcp")).expect("arm.urdf reads")
}

fn rx(a: f64) -> Mat3 {
    Rotation3::from_axis_angle(&Vec3::x_axis(), a).into_inner()
}
fn ry(a: f64) -> Mat3 {
    Rotation3::from_axis_angle(&Vec3::y_axis(), a).into_inner()
}
fn rz(a: f64) -> Mat3 {
    Rotation3::from_axis_angle(&Vec3::z_axis(), a).into_inner()
}
/// The URDF convention, written out: R = Rz(yaw)·Ry(pitch)·Rx(roll).
fn rpy(r: f64, p: f64, y: f64) -> Mat3 {
    rz(y) * ry(p) * rx(r)
}

fn assert_mat(what: &str, got: &Mat3, expected: &Mat3) {
    let d = (got - expected).amax();
    assert!(d <= TOL, "{what}: got {got}, expected {expected} (max deviation {d:e})");
}
fn assert_vec(what: &str, got: &Vec3, expected: &Vec3) {
    let d = (got - expected).amax();
    assert!(d <= TOL, "{what}: got {got}, expected {expected} (max deviation {d:e})");
}
fn assert_num(what: &str, got: f64, expected: f64) {
    assert!((got - expected).abs() <= TOL, "{what}: got {got}, expected {expected}");
}

/// The parallel-axis term of a point mass m at offset d from the reference
/// point, component by component: I_xx = m (d_y² + d_z²), I_xy = −m d_x d_y, …
fn steiner(m: f64, d: [f64; 3]) -> Mat3 {
    let [x, y, z] = d;
    Mat3::new(
        m * (y * y + z * z),
        -m * x * y,
        -m * x * z,
        -m * x * y,
        m * (x * x + z * z),
        -m * y * z,
        -m * x * z,
        -m * y * z,
        m * (x * x + y * y),
    )
}

fn diag(a: f64, b: f64, c: f64) -> Mat3 {
    Mat3::from_diagonal(&Vec3::new(a, b, c))
}

/// The element and reason of a refusal, checking the message reads
/// "URDF {element}: {reason}".
fn refusal(xml: &str, base: Option<&str>, tip: Option<&str>) -> (String, String) {
    match read_urdf(xml, base, tip) {
        Ok(chain) => panic!("expected a refusal, read {} joints", chain.joints.len()),
        Err(e @ ModelError::Urdf { .. }) => {
            let text = e.to_string();
            let ModelError::Urdf { element, reason } = e else { unreachable!() };
            assert_eq!(text, format!("URDF {element}: {reason}"));
            (element, reason)
        }
        Err(e) => panic!("expected ModelError::Urdf, got {e:?}"),
    }
}

fn assert_refused(xml: &str, element: &str, reason_part: &str) {
    assert_refused_chain(xml, None, None, element, reason_part);
}

fn assert_refused_chain(xml: &str, base: Option<&str>, tip: Option<&str>, element: &str, reason_part: &str) {
    let (e, r) = refusal(xml, base, tip);
    assert_eq!(e, element, "element of the refusal (reason: {r})");
    assert!(r.contains(reason_part), "reason `{r}` should contain `{reason_part}`");
}

const BOX: &str =
    r#"<inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>"#;

/// A robot of the given links (name, inertial XML) and joints
/// (name, type, parent, child, extra XML).
fn robot(links: &[(&str, &str)], joints: &[(&str, &str, &str, &str, &str)]) -> String {
    let mut s = String::from("<robot name=\"r\">\n");
    for (name, inertial) in links {
        s += &format!("  <link name=\"{name}\">{inertial}</link>\n");
    }
    for (name, kind, parent, child, extra) in joints {
        s += &format!(
            "  <joint name=\"{name}\" type=\"{kind}\"><parent link=\"{parent}\"/><child link=\"{child}\"/>{extra}</joint>\n"
        );
    }
    s + "</robot>\n"
}

/// base —j1 (revolute)→ l1 —j2 (revolute)→ l2, with `extra` XML in j1.
fn two_joints(extra_j1: &str) -> String {
    robot(
        &[("base", ""), ("l1", BOX), ("l2", BOX)],
        &[("j1", "revolute", "base", "l1", extra_j1), ("j2", "revolute", "l1", "l2", "")],
    )
}

/// base —j (revolute)→ l, `l` with the given inertial XML.
fn one_link(inertial: &str) -> String {
    robot(&[("base", ""), ("l", inertial)], &[("j", "revolute", "base", "l", "")])
}

fn inertial_xml(mass: &str, inertia: [&str; 6]) -> String {
    let [ixx, ixy, ixz, iyy, iyz, izz] = inertia;
    format!(
        r#"<inertial><mass value="{mass}"/><inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial>"#
    )
}

// ---------------------------------------------------------------------------
// The hand-written arm (tests/urdf/arm.urdf).

#[test]
fn arm_has_the_moving_joints_of_the_chain_in_order() {
    let c = arm();
    assert_eq!(c.base_link, "base_link");
    assert_eq!(c.tip_link, "tcp");
    let names: Vec<&str> = c.joints.iter().map(|j| j.name.as_str()).collect();
    assert_eq!(names, ["joint1", "joint2", "joint3"]);
    let kinds: Vec<JointKind> = c.joints.iter().map(|j| j.kind).collect();
    assert_eq!(kinds, [JointKind::Revolute, JointKind::Prismatic, JointKind::Revolute]);
    assert_eq!(c.bodies.len(), 3);
}

#[test]
fn first_joint_is_placed_in_base_link_frame_through_the_fixed_joints_before_it() {
    let c = arm();
    // mount_joint (xyz 0.1 0.2 0.3, yaw 90°) then joint1's origin (xyz 0 0 0.5, rpy 0.3 -0.2 0.1).
    let j = &c.joints[0];
    assert_mat("joint1 rotation", &j.rotation, &(rz(FRAC_PI_2) * rpy(0.3, -0.2, 0.1)));
    assert_vec("joint1 translation", &j.translation, &Vec3::new(0.1, 0.2, 0.8));
    assert_vec("joint1 axis", &j.axis, &Vec3::new(0.0, 0.0, 1.0));
}

#[test]
fn base_side_links_carry_no_mass_into_the_bodies() {
    let c = arm();
    // base_link 50 kg, pedestal 10 kg and mount 3 kg are the fixed base.
    let total: f64 = c.bodies.iter().map(|b| b.mass).sum();
    assert_num("total mass", total, 2.0 + 1.5 + 0.5 + 1.0 + 0.1 + 0.1 + 0.2);
    assert_num("body 1 mass", c.bodies[0].mass, 2.0);
}

#[test]
fn body_of_a_single_link_is_its_inertial_exactly() {
    let c = arm();
    // link1; camera_frame (massless, fixed) hangs off it and changes nothing.
    let b = &c.bodies[0];
    assert_eq!(b.mass, 2.0);
    assert_eq!(b.com, Vec3::new(0.05, 0.0, 0.1));
    assert_eq!(b.inertia, diag(0.02, 0.03, 0.04));
}

#[test]
fn prismatic_joint_after_a_moving_joint_is_placed_in_the_previous_body() {
    let c = arm();
    let j = &c.joints[1];
    assert_mat("joint2 rotation", &j.rotation, &rx(FRAC_PI_2));
    assert_vec("joint2 translation", &j.translation, &Vec3::new(0.4, 0.0, 0.0));
    assert_vec("joint2 axis (0 0 2 normalized)", &j.axis, &Vec3::new(0.0, 0.0, 1.0));
}

#[test]
fn fixed_joint_between_moving_joints_merges_mass_com_and_inertia() {
    let c = arm();
    let b = &c.bodies[1];
    // link2: 1.5 kg at (0.1, 0, 0), diag(0.015, 0.02, 0.03).
    // flange: frame at (0.2, 0.05, 0) turned 90° about y (its z is link2's x):
    // 0.5 kg at (0.2, 0.05, 0) + 0.02·x = (0.22, 0.05, 0); its
    // diag(0.0015, 0.0015, 0.002) becomes diag(0.002, 0.0015, 0.0015).
    let (m1, c1, i1) = (1.5, [0.1, 0.0, 0.0], diag(0.015, 0.02, 0.03));
    let (m2, c2, i2) = (0.5, [0.22, 0.05, 0.0], diag(0.002, 0.0015, 0.0015));
    let m = m1 + m2;
    let com = [(m1 * c1[0] + m2 * c2[0]) / m, (m1 * c1[1] + m2 * c2[1]) / m, 0.0];
    assert_num("merged mass", b.mass, 2.0);
    assert_vec("merged com", &b.com, &Vec3::new(0.13, 0.0125, 0.0));
    assert_vec("merged com (formula)", &b.com, &Vec3::from(com));
    let d1 = [c1[0] - com[0], c1[1] - com[1], 0.0];
    let d2 = [c2[0] - com[0], c2[1] - com[1], 0.0];
    let expected = i1 + steiner(m1, d1) + i2 + steiner(m2, d2);
    assert_mat("merged inertia about the merged com", &b.inertia, &expected);
    // The same by hand, component by component.
    // d1 = (-0.03, -0.0125, 0), d2 = (0.09, 0.0375, 0).
    let ixx = 0.015 + 1.5 * 0.0125f64.powi(2) + 0.002 + 0.5 * 0.0375f64.powi(2);
    let iyy = 0.02 + 1.5 * 0.03f64.powi(2) + 0.002 * 0.75 + 0.5 * 0.09f64.powi(2);
    let ixy = -1.5 * (-0.03) * (-0.0125) - 0.5 * 0.09 * 0.0375;
    assert_num("I_xx", b.inertia[(0, 0)], ixx);
    assert_num("I_yy", b.inertia[(1, 1)], iyy);
    assert_num("I_xy", b.inertia[(0, 1)], ixy);
    assert_num("I_yx", b.inertia[(1, 0)], ixy);
}

#[test]
fn joint_after_a_fixed_joint_is_placed_through_it() {
    let c = arm();
    // flange_joint (xyz 0.2 0.05 0, pitch 90°) then joint3 (xyz 0 0 0.1, yaw 0.5).
    let j = &c.joints[2];
    assert_mat("joint3 rotation", &j.rotation, &(ry(FRAC_PI_2) * rz(0.5)));
    assert_vec("joint3 translation", &j.translation, &Vec3::new(0.3, 0.05, 0.0));
    assert_vec("joint3 axis (default 1 0 0)", &j.axis, &Vec3::new(1.0, 0.0, 0.0));
}

#[test]
fn off_chain_links_are_lumped_at_zero_position_with_a_warning() {
    let c = arm();
    let b = &c.bodies[2];
    // link3 1 kg at (0, 0, 0.05); fingers 0.1 kg at (0, ±0.02, 0.1);
    // tool 0.2 kg at (0, 0, 0.15), turned 180° about x (diagonal unchanged).
    let parts: [(f64, [f64; 3], Mat3); 4] = [
        (1.0, [0.0, 0.0, 0.05], diag(0.005, 0.005, 0.002)),
        (0.1, [0.0, 0.02, 0.1], diag(2e-5, 2e-5, 3e-5)),
        (0.1, [0.0, -0.02, 0.1], diag(2e-5, 2e-5, 3e-5)),
        (0.2, [0.0, 0.0, 0.15], diag(2e-4, 2e-4, 3e-4)),
    ];
    let m: f64 = parts.iter().map(|p| p.0).sum();
    let z = parts.iter().map(|p| p.0 * p.1[2]).sum::<f64>() / m;
    assert_num("body 3 mass", b.mass, 1.4);
    assert_vec("body 3 com", &b.com, &Vec3::new(0.0, 0.0, 0.1 / 1.4));
    assert_num("body 3 com z (formula)", b.com.z, z);
    let mut expected = Mat3::zeros();
    for (mi, ci, ii) in parts {
        expected += ii + steiner(mi, [ci[0], ci[1], ci[2] - z]);
    }
    assert_mat("body 3 inertia", &b.inertia, &expected);
    assert_eq!(
        c.warnings,
        ["links `finger_left`, `finger_right` hang off the chain at `link3` and are lumped into it at their joints' zero position"]
    );
}

#[test]
fn tip_placement_composes_the_fixed_joints_after_the_last_moving_joint() {
    let c = arm();
    // tool_joint (xyz 0 0 0.15, roll 180°) then tcp_joint (xyz 0 0 0.05).
    assert_mat("tip rotation", &c.tip_rotation, &rx(PI));
    assert_vec("tip translation", &c.tip_translation, &Vec3::new(0.0, 0.0, 0.1));
}

#[test]
fn tip_at_a_moving_joints_child_is_that_body_frame() {
    let c = read_urdf(&file("arm.urdf"), None, Some("link3")).unwrap();
    assert_eq!(c.tip_rotation, Mat3::identity());
    assert_eq!(c.tip_translation, Vec3::zeros());
    // tool and tcp now hang off the chain at link3, with the fingers.
    assert_eq!(
        c.warnings,
        ["links `finger_left`, `finger_right`, `tool`, `tcp` hang off the chain at `link3` and are lumped into it at their joints' zero position"]
    );
    assert_num("body 3 mass", c.bodies[2].mass, 1.4);
}

#[test]
fn limits_are_returned_as_given() {
    let c = arm();
    let full = UrdfLimit { lower: Some(-2.0), upper: Some(2.0), velocity: Some(1.5), effort: Some(100.0) };
    assert_eq!(c.joints[0].limit, Some(full));
    let partial = UrdfLimit { lower: Some(0.0), upper: Some(0.3), velocity: None, effort: None };
    assert_eq!(c.joints[1].limit, Some(partial));
    assert_eq!(c.joints[2].limit, None);
}

#[test]
fn base_link_option_starts_the_chain_at_that_link() {
    let c = read_urdf(&file("arm.urdf"), Some("link1"), Some("tcp")).unwrap();
    assert_eq!(c.base_link, "link1");
    assert_eq!(c.joints.len(), 2);
    assert_eq!(c.joints[0].name, "joint2");
    assert_mat("joint2 rotation", &c.joints[0].rotation, &rx(FRAC_PI_2));
    assert_vec("joint2 translation", &c.joints[0].translation, &Vec3::new(0.4, 0.0, 0.0));
    // From mount: joint1 placed by its own origin only.
    let c = read_urdf(&file("arm.urdf"), Some("mount"), Some("tcp")).unwrap();
    assert_mat("joint1 rotation", &c.joints[0].rotation, &rpy(0.3, -0.2, 0.1));
    assert_vec("joint1 translation", &c.joints[0].translation, &Vec3::new(0.0, 0.0, 0.5));
}

#[test]
fn mimic_off_the_chain_is_lumped_but_on_the_chain_refused() {
    // finger_right_joint mimics finger_left_joint: off the chain it is lumped;
    // as a joint of the chain it is refused.
    assert!(read_urdf(&file("arm.urdf"), None, Some("tcp")).is_ok());
    assert_refused_chain(
        &file("arm.urdf"),
        None,
        Some("finger_right"),
        "<joint name=\"finger_right_joint\"><mimic>",
        "cannot mimic",
    );
}

// ---------------------------------------------------------------------------
// Conventions.

#[test]
fn rpy_yaw_of_90_degrees_maps_x_to_y() {
    let c = read_urdf(&two_joints(r#"<origin rpy="0 0 1.5707963267948966"/>"#), None, None).unwrap();
    let r = c.joints[0].rotation;
    assert_vec("R x", &(r * Vec3::x()), &Vec3::y());
    assert_vec("R y", &(r * Vec3::y()), &-Vec3::x());
    assert_vec("R z", &(r * Vec3::z()), &Vec3::z());
}

#[test]
fn rpy_is_rz_yaw_times_ry_pitch_times_rx_roll() {
    let c = read_urdf(&two_joints(r#"<origin rpy="0.4 -1.1 2.5"/>"#), None, None).unwrap();
    assert_mat("rotation", &c.joints[0].rotation, &(rz(2.5) * ry(-1.1) * rx(0.4)));
    // Roll 90° then pitch 90° about the fixed axes: y ↦ z ↦ x; the other
    // order of the product differs.
    let c = read_urdf(&two_joints(r#"<origin rpy="1.5707963267948966 1.5707963267948966 0"/>"#), None, None).unwrap();
    let r = c.joints[0].rotation;
    assert_vec("R y", &(r * Vec3::y()), &Vec3::x());
    assert!((r - rx(FRAC_PI_2) * ry(FRAC_PI_2)).amax() > 0.5);
}

#[test]
fn inertial_origin_rotates_the_inertia_into_the_link_frame() {
    // diag(1, 2, 3) in a frame turned 90° about z: its x is the link's y.
    let xml = one_link(
        r#"<inertial><origin xyz="0.1 0.2 0.3" rpy="0 0 1.5707963267948966"/><mass value="2"/>
           <inertia ixx="1" ixy="0" ixz="0" iyy="2" iyz="0" izz="3"/></inertial>"#,
    );
    let b = read_urdf(&xml, None, None).unwrap().bodies[0];
    assert_eq!(b.mass, 2.0);
    assert_vec("com = origin xyz", &b.com, &Vec3::new(0.1, 0.2, 0.3));
    assert_mat("R I Rᵀ", &b.inertia, &diag(2.0, 1.0, 3.0));
    // A general rotation and a full tensor.
    let xml = one_link(
        r#"<inertial><origin rpy="0.3 0.2 -0.4"/><mass value="1"/>
           <inertia ixx="0.3" ixy="0.01" ixz="-0.02" iyy="0.4" iyz="0.03" izz="0.5"/></inertial>"#,
    );
    let b = read_urdf(&xml, None, None).unwrap().bodies[0];
    let i = Mat3::new(0.3, 0.01, -0.02, 0.01, 0.4, 0.03, -0.02, 0.03, 0.5);
    let r = rpy(0.3, 0.2, -0.4);
    assert_mat("R I Rᵀ", &b.inertia, &(r * i * r.transpose()));
    assert_eq!(b.inertia, b.inertia.transpose(), "symmetric");
}

#[test]
fn link_without_inertial_is_massless() {
    let c = read_urdf(&one_link(""), None, None).unwrap();
    assert_eq!(c.bodies[0], UrdfInertial::zero());
    assert!(c.warnings.is_empty());
}

#[test]
fn axis_defaults_to_x_and_is_normalized() {
    let c = read_urdf(&two_joints(r#"<axis xyz="0 3 4"/>"#), None, None).unwrap();
    assert_vec("normalized axis", &c.joints[0].axis, &Vec3::new(0.0, 0.6, 0.8));
    assert_vec("default axis", &c.joints[1].axis, &Vec3::x());
}

#[test]
fn continuous_is_revolute_and_prismatic_is_prismatic() {
    let xml = robot(
        &[("base", ""), ("a", BOX), ("b", BOX)],
        &[("ja", "continuous", "base", "a", ""), ("jb", "prismatic", "a", "b", "")],
    );
    let c = read_urdf(&xml, None, None).unwrap();
    assert_eq!(c.joints[0].kind, JointKind::Revolute);
    assert_eq!(c.joints[1].kind, JointKind::Prismatic);
}

#[test]
fn default_tip_is_the_single_leaf() {
    let c = read_urdf(&two_joints(""), None, None).unwrap();
    assert_eq!(c.tip_link, "l2");
    assert_eq!(c.base_link, "base");
}

#[test]
fn several_leaves_without_tip_link_are_refused_listing_them() {
    let (element, reason) = refusal(&file("arm.urdf"), None, None);
    assert_eq!(element, "tip_link");
    for leaf in ["pedestal", "camera_frame", "finger_left", "finger_right", "tcp"] {
        assert!(reason.contains(&format!("`{leaf}`")), "{reason} should list {leaf}");
    }
    assert!(reason.contains("5 leaves") && reason.contains("name one as tip_link"), "{reason}");
}

#[test]
fn robust_xml_reads_like_the_plain_file() {
    let plain = read_urdf(&file("plain.urdf"), None, None).unwrap();
    let robust = read_urdf(&file("robust.urdf"), None, None).unwrap();
    assert_eq!(plain, robust);
    assert_eq!(robust.tip_link, "a&b");
    assert_eq!(robust.joints.len(), 2);
    assert_eq!(robust.joints[0].limit.unwrap().effort, Some(50.0));
    // Visual and collision origins are not the inertial's.
    assert_vec("com", &robust.bodies[0].com, &Vec3::new(0.1, 0.02, 0.3));
    assert!(robust.warnings.is_empty(), "{:?}", robust.warnings);
}

#[test]
fn byte_order_mark_and_prefixed_robot_are_read() {
    let xml = format!("\u{feff}{}", two_joints(""))
        .replace("<robot", "<u:robot xmlns:u=\"urdf\"")
        .replace("</robot>", "</u:robot>");
    assert_eq!(read_urdf(&xml, None, None).unwrap().joints.len(), 2);
}

#[test]
fn identical_duplicate_elements_are_accepted() {
    let c = read_urdf(&two_joints(r#"<axis xyz="0 0 1"/><axis xyz="0 0 1"/>"#), None, None).unwrap();
    assert_vec("axis", &c.joints[0].axis, &Vec3::z());
}

// ---------------------------------------------------------------------------
// Warnings.

#[test]
fn triangle_inequality_violation_is_accepted_with_a_warning() {
    // 1 + 1 < 2.014: by 0.014/2.014 = 0.695 %.
    let c = read_urdf(&one_link(&inertial_xml("1", ["1", "0", "0", "1", "0", "2.014"])), None, None).unwrap();
    assert_eq!(c.bodies[0].inertia, diag(1.0, 1.0, 2.014));
    assert_eq!(c.warnings.len(), 1, "{:?}", c.warnings);
    let w = &c.warnings[0];
    assert!(w.starts_with("link `l`: principal moments"), "{w}");
    assert!(w.contains("violate I1 + I2 >= I3 by 0.70 %; accepted as given (MuJoCo would need balanceinertia)"), "{w}");
    // At the limit (a thin disc) and within rounding: no warning.
    let c = read_urdf(&one_link(&inertial_xml("1", ["1", "0", "0", "1", "0", "2"])), None, None).unwrap();
    assert!(c.warnings.is_empty(), "{:?}", c.warnings);
}

#[test]
fn mass_zero_with_inertia_is_kept_with_a_warning() {
    let c = read_urdf(&one_link(&inertial_xml("0", ["0.1", "0", "0", "0.1", "0", "0.1"])), None, None).unwrap();
    assert_eq!(c.bodies[0].mass, 0.0);
    assert_eq!(c.bodies[0].inertia, diag(0.1, 0.1, 0.1));
    assert_eq!(c.warnings.len(), 1);
    assert!(c.warnings[0].starts_with("link `l`: mass 0 with a nonzero inertia"), "{:?}", c.warnings);
    // Mass 0 and no inertia: nothing to say.
    let c = read_urdf(&one_link(&inertial_xml("0", ["0"; 6])), None, None).unwrap();
    assert!(c.warnings.is_empty());
}

#[test]
fn inertia_of_base_side_links_is_not_checked() {
    // The base's point mass would be refused in a body; on the fixed base it is ignored.
    let xml = robot(&[("base", &inertial_xml("5", ["0"; 6])), ("l", BOX)], &[("j", "revolute", "base", "l", "")]);
    assert!(read_urdf(&xml, None, None).is_ok());
}

// ---------------------------------------------------------------------------
// Refusals.

#[test]
fn refuses_text_that_is_not_xml() {
    assert_refused("this is not XML at all", "document", "is not XML");
    assert_refused("<robot><link name=\"a\"></robot>", "document", "not well-formed XML");
    assert_refused("<robot><link name=\"a\">", "document", "ends inside <link>");
    assert_refused("", "<robot>", "no <robot> element");
}

#[test]
fn refuses_a_document_without_robot() {
    assert_refused("<?xml version=\"1.0\"?><sdf><model/></sdf>", "<robot>", "root element is <sdf>, not <robot>");
    assert_refused("<robot name=\"r\"/>", "<robot>", "has no <link>");
}

#[test]
fn refuses_floating_and_planar_joints() {
    for kind in ["floating", "planar"] {
        let xml = robot(&[("base", ""), ("l", BOX)], &[("free", kind, "base", "l", "")]);
        assert_refused(&xml, "<joint name=\"free\">", &format!("type `{kind}` is not supported"));
    }
    let xml = robot(&[("base", ""), ("l", BOX)], &[("odd", "screw", "base", "l", "")]);
    assert_refused(&xml, "<joint name=\"odd\">", "unknown joint type `screw`");
}

#[test]
fn refuses_mimic_on_a_chain_joint() {
    assert_refused(&two_joints(r#"<mimic joint="j2" multiplier="1"/>"#), "<joint name=\"j1\"><mimic>", "cannot mimic");
}

#[test]
fn refuses_negative_and_non_finite_mass() {
    let x = one_link(&inertial_xml("-1", ["0.1", "0", "0", "0.1", "0", "0.1"]));
    assert_refused(&x, "<link name=\"l\"><inertial><mass>", "is negative");
    for bad in ["inf", "NaN", "1e400"] {
        let x = one_link(&inertial_xml(bad, ["0.1", "0", "0", "0.1", "0", "0.1"]));
        assert_refused(&x, "<link name=\"l\"><inertial><mass>", "is not finite");
    }
    let x = one_link(&inertial_xml("heavy", ["0.1", "0", "0", "0.1", "0", "0.1"]));
    assert_refused(&x, "<link name=\"l\"><inertial><mass>", "is not a number");
}

#[test]
fn refuses_an_inertia_that_is_not_positive_definite_with_mass() {
    let element = "<link name=\"l\"><inertial><inertia>";
    // A point mass, a rod, and a tensor with a negative principal moment.
    for inertia in [["0"; 6], ["0", "0", "0", "1", "0", "1"], ["1", "2", "0", "1", "0", "1"]] {
        assert_refused(&one_link(&inertial_xml("1", inertia)), element, "is not positive definite");
    }
    assert_refused(
        &one_link(&inertial_xml("0", ["-1", "0", "0", "1", "0", "1"])),
        element,
        "has a negative principal moment",
    );
    assert_refused(
        &one_link(&inertial_xml("1", ["1", "0", "0", "1", "0", "inf"])),
        element,
        "attribute `izz` = \"inf\" is not finite",
    );
    assert_refused(
        &one_link(r#"<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0"/></inertial>"#),
        element,
        "attribute `izz` is missing",
    );
    assert_refused(
        &one_link(r#"<inertial><mass value="1"/></inertial>"#),
        "<link name=\"l\"><inertial>",
        "has no <inertia>",
    );
}

#[test]
fn refuses_malformed_number_lists() {
    let element = "<joint name=\"j1\"><origin>";
    assert_refused(&two_joints(r#"<origin xyz="1 2"/>"#), element, "must be 3 numbers separated by spaces, has 2");
    assert_refused(&two_joints(r#"<origin xyz="1 2 3 4"/>"#), element, "has 4");
    assert_refused(&two_joints(r#"<origin xyz="1,2,3"/>"#), element, "must be 3 numbers");
    assert_refused(&two_joints(r#"<origin xyz="1, 2, 3"/>"#), element, "`1,` is not a finite number");
    assert_refused(&two_joints(r#"<origin rpy="0 nan 0"/>"#), element, "`nan` is not a finite number");
    assert_refused(&two_joints(r#"<origin xyz=""/>"#), element, "has 0");
    assert_refused(
        &two_joints(r#"<limit lower="-1.57." upper="1"/>"#),
        "<joint name=\"j1\"><limit>",
        "is not a number",
    );
}

#[test]
fn refuses_a_zero_axis_on_a_moving_joint() {
    assert_refused(&two_joints(r#"<axis xyz="0 0 0"/>"#), "<joint name=\"j1\"><axis>", "zero vector");
}

#[test]
fn refuses_joints_naming_links_that_do_not_exist() {
    let xml = robot(&[("base", ""), ("l", BOX)], &[("j", "revolute", "bsae", "l", "")]);
    assert_refused(&xml, "<joint name=\"j\"><parent>", "link `bsae` does not exist");
    let xml = robot(&[("base", ""), ("l", BOX)], &[("j", "revolute", "base", "k", "")]);
    assert_refused(&xml, "<joint name=\"j\"><child>", "link `k` does not exist");
    let xml = "<robot><link name=\"a\"/><link name=\"b\"/><joint name=\"j\" type=\"fixed\"><parent link=\"a\"/></joint></robot>";
    assert_refused(xml, "<joint name=\"j\">", "has no <child");
}

#[test]
fn refuses_a_link_that_is_the_child_of_two_joints() {
    let xml = robot(
        &[("base", ""), ("a", BOX), ("b", BOX)],
        &[("ja", "revolute", "base", "a", ""), ("jb", "revolute", "base", "b", ""), ("jc", "revolute", "a", "b", "")],
    );
    assert_refused(&xml, "<link name=\"b\">", "is the child of two joints, `jb` and `jc`");
}

#[test]
fn refuses_two_roots() {
    let xml = robot(&[("base", ""), ("l", BOX), ("stray", BOX)], &[("j", "revolute", "base", "l", "")]);
    assert_refused(&xml, "<robot>", "has 2 root links (`base`, `stray`)");
}

#[test]
fn refuses_a_loop() {
    // base is the root; a -> b -> c -> a is a loop hanging nowhere.
    let xml = robot(
        &[("base", ""), ("a", BOX), ("b", BOX), ("c", BOX)],
        &[("ab", "revolute", "a", "b", ""), ("bc", "revolute", "b", "c", ""), ("ca", "revolute", "c", "a", "")],
    );
    let (element, reason) = refusal(&xml, None, None);
    assert!(element.starts_with("<joint name=\""), "{element}");
    assert!(reason.contains("closes a loop"), "{reason}");
    for j in ["`ab`", "`bc`", "`ca`"] {
        assert!(reason.contains(j), "{reason} should name {j}");
    }
    // A joint from a link to itself.
    let xml =
        robot(&[("base", ""), ("a", BOX)], &[("j", "revolute", "base", "a", ""), ("self", "revolute", "a", "a", "")]);
    assert_refused(&xml, "<link name=\"a\">", "is the child of two joints");
    let xml = robot(&[("a", BOX)], &[("self", "revolute", "a", "a", "")]);
    assert_refused(&xml, "<joint name=\"self\">", "closes a loop");
}

#[test]
fn refuses_unknown_base_and_tip_links() {
    let xml = file("arm.urdf");
    assert_refused_chain(&xml, Some("nowhere"), Some("tcp"), "base_link = \"nowhere\"", "no link named `nowhere`");
    assert_refused_chain(&xml, None, Some("nowhere"), "tip_link = \"nowhere\"", "no link named `nowhere`");
}

#[test]
fn refuses_a_tip_not_below_the_base() {
    let xml = file("arm.urdf");
    assert_refused_chain(&xml, Some("link2"), Some("link1"), "tip_link = \"link1\"", "is not below base_link `link2`");
    assert_refused_chain(&xml, Some("link3"), Some("pedestal"), "tip_link = \"pedestal\"", "is not below");
}

#[test]
fn refuses_a_chain_without_moving_joint() {
    let xml = file("arm.urdf");
    assert_refused_chain(&xml, Some("link2"), Some("flange"), "chain `link2` -> `flange`", "has no moving joint");
    assert_refused_chain(&xml, Some("link2"), Some("link2"), "chain `link2` -> `link2`", "no moving joint");
    assert_refused_chain(&xml, None, Some("pedestal"), "chain `base_link` -> `pedestal`", "has no moving joint");
}

#[test]
fn refuses_duplicate_link_and_joint_names() {
    let xml = robot(&[("base", ""), ("l", BOX), ("l", "")], &[("j", "revolute", "base", "l", "")]);
    assert_refused(&xml, "<link name=\"l\">", "appears twice");
    let xml = robot(
        &[("base", ""), ("a", BOX), ("b", BOX)],
        &[("j", "revolute", "base", "a", ""), ("j", "revolute", "a", "b", "")],
    );
    assert_refused(&xml, "<joint name=\"j\">", "appears twice");
}

#[test]
fn refuses_contradicting_duplicate_elements() {
    assert_refused(
        &two_joints(r#"<axis xyz="0 0 1"/><axis xyz="0 1 0"/>"#),
        "<joint name=\"j1\">",
        "has two <axis> elements that differ",
    );
    assert_refused(
        &two_joints(r#"<parent link="l2"/>"#),
        "<joint name=\"j1\">",
        "has two <parent> elements that differ",
    );
    assert_refused(
        &one_link(
            r#"<inertial><mass value="1"/><mass value="2"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>"#,
        ),
        "<link name=\"l\"><inertial>",
        "has two <mass> elements that differ",
    );
    assert_refused(&one_link(&format!("{BOX}{BOX}")), "<link name=\"l\">", "has two <inertial> elements");
}

#[test]
fn refuses_missing_names_and_types() {
    assert_refused("<robot><link/></robot>", "<link>", "attribute `name` is missing");
    assert_refused(
        "<robot><link name=\"a\"/><joint name=\"j\"><parent link=\"a\"/></joint></robot>",
        "<joint name=\"j\">",
        "attribute `type` is missing",
    );
}
