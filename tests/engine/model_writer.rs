//! A model written back reads back to itself (issue 42, item 4): the model
//! file (and for a URDF model the URDF) that `model_file` writes from a
//! model and the source it was read from gives the engine the same model
//! again. For the reference arm and its motor variant (Denavit–Hartenberg
//! files), the KUKA iiwa and the xArm 6 (URDFs with every axis +z), the
//! reference arm's URDF (axes along y, a link on a fixed joint merged into
//! its moving parent, a slider, a tool frame) and a small URDF with a
//! self-closing link, a link without `<inertial>`, a tilted axis and a link
//! hanging off the chain: written unchanged, read back, every standard
//! parameter π equals the original's to 1e-14 of its group's largest
//! magnitude (mass; first moment; inertia), every drive and friction
//! coefficient is equal bit for bit, the contact geometry, gravity and the
//! end point to 1e-14, and forward kinematics at 50 random q (every frame's
//! rotation and origin, the end point) to 1e-14 m; a URDF without merged
//! links comes back byte for byte, and writing the read-back model again
//! gives the same text (measured: every value bit for bit, π of the small
//! URDF, whose merged body is recombined, 4.4e-17). With random physically
//! valid π (`with_standard_parameters`) and random settings of every tunable
//! parameter the arm has: the same π and settings back to 1e-14, and the
//! inverse dynamics of the read-back model equal the original's at 200
//! random states to 1e-12 of the joint's largest |τ| (measured: all bit for
//! bit); a URDF differs from its source only inside `<inertial>` elements. A model that is not its
//! source's chain is refused, and the FMU library's `stickslip_write_model`
//! gives `model_file`'s text, asks for buffer sizes with status 2 and
//! refuses impossible π naming the link.

use std::ffi::{c_char, CString};

use stick_slip_manipulator::algorithms::inverse_dynamics::{inverse_dynamics, with_settings};
use stick_slip_manipulator::algorithms::kinematics::{end_point, forward_kinematics};
use stick_slip_manipulator::algorithms::regressor::{
    link_parameters, standard_parameters, with_standard_parameters, LINK_PARAMETERS,
};
use stick_slip_manipulator::fmi::stickslip_write_model;
use stick_slip_manipulator::math::Vec3;
use stick_slip_manipulator::model::{
    model_file, ContactGeometry, JointKind, Link, ModelSource, Parameter, WrittenModel,
};
use stick_slip_manipulator::{Data, Model, ModelError};

use crate::common::{random_inertia, Rng};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// A URDF arm with what the shipped ones lack: a self-closing moving link
/// (`l1`, massless in itself) with a link on a fixed joint (`l1b`) and a
/// link hanging off it on a revolute joint (`flap`), a tilted axis, and a
/// prismatic joint whose link has no `<inertial>` (`l2`) and a tool frame.
const SMALL_URDF: &str = r#"<?xml version="1.0"?>
<robot name="small">
  <link name="base"/>
  <joint name="a1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0.1 0 0"/>
    <axis xyz="0.6 0 0.8"/>
  </joint>
  <link name="l1"/>
  <joint name="l1_fix" type="fixed">
    <parent link="l1"/><child link="l1b"/>
    <origin xyz="0.2 0 0" rpy="0 0.3 0"/>
  </joint>
  <link name="l1b">
    <inertial>
      <origin xyz="0.1 0.02 0" rpy="0.2 0 0"/>
      <mass value="3"/>
      <inertia ixx="0.02" ixy="0.001" ixz="0" iyy="0.03" iyz="0" izz="0.025"/>
    </inertial>
  </link>
  <joint name="flap_joint" type="revolute">
    <parent link="l1b"/><child link="flap"/>
    <origin xyz="0 0.1 0"/>
    <axis xyz="1 0 0"/>
  </joint>
  <link name="flap">
    <inertial>
      <mass value="0.5"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>
    </inertial>
  </link>
  <joint name="a2" type="prismatic">
    <parent link="l1b"/><child link="l2"/>
    <origin xyz="0.3 0 0"/>
    <axis xyz="1 0 0"/>
  </joint>
  <link name="l2">
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual>
  </link>
  <joint name="a3" type="revolute">
    <parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.1"/>
    <axis xyz="0 0 -1"/>
  </joint>
  <link name="l3">
    <inertial>
      <origin xyz="0 0 0.05"/>
      <mass value="1.2"/>
      <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.004" iyz="0" izz="0.002"/>
    </inertial>
  </link>
  <joint name="tool" type="fixed">
    <parent link="l3"/><child link="tip"/>
    <origin xyz="0 0 0.12"/>
  </joint>
  <link name="tip"/>
</robot>
"#;

const SMALL_TOML: &str = r#"name = "small"
urdf = "small.urdf"
tip_link = "tip"
end_point = [0.01, 0.0, 0.02]

[joints.a1]
drive = { type = "flexible", k = 2.0e4, h = 3.0 }
friction = { mu_k = 0.05, mu_s = 0.08 }
bearings = { reaction_point = [0.03, 0.0, 0.04], l_a = 0.02, l_b = 0.03, d_a = 0.05, d_b = 0.05, d_c = 0.06 }

[joints.a2]
drive = { type = "motor", k = 5.0e4, gear_ratio = 600.0, rotor_inertia = 1.0e-4 }
friction = { mu_k = 0.1, mu_s = 0.1 }
slider = { centre = [-0.05, 0.01, 0.0], a = 0.1, b = 0.04, c = 0.03 }
"#;

/// The model source of a model file in the repository, with its URDF.
fn source(path: &str) -> ModelSource {
    let path = std::path::Path::new(ROOT).join(path);
    let toml = std::fs::read_to_string(&path).unwrap();
    let urdf = Model::urdf_reference(&toml).map(|name| std::fs::read_to_string(path.with_file_name(name)).unwrap());
    ModelSource { toml, urdf }
}

/// The arms, by name, with their sources.
fn arms() -> Vec<(&'static str, ModelSource)> {
    vec![
        ("reference", source("models/reference_rrpr.toml")),
        ("motor", source("models/reference_rrpr_motor.toml")),
        ("kuka_iiwa", source("models/urdf/kuka_iiwa/kuka_iiwa.toml")),
        ("xarm6", source("models/urdf/xarm6/xarm6.toml")),
        ("reference_urdf", source("models/urdf/reference_rrpr/reference_rrpr.toml")),
        ("small_urdf", ModelSource { toml: SMALL_TOML.into(), urdf: Some(SMALL_URDF.into()) }),
    ]
}

fn write(model: &Model, source: &ModelSource) -> WrittenModel {
    model_file(model, source, "identified.urdf").unwrap()
}

fn read(written: &WrittenModel) -> Model {
    ModelSource { toml: written.toml.clone(), urdf: written.urdf.clone() }.model().unwrap()
}

fn parameters(model: &Model) -> Vec<f64> {
    let mut pi = vec![0.0; LINK_PARAMETERS * model.nq()];
    standard_parameters(model, &mut pi);
    pi
}

/// The largest deviation of π from π0, per link relative to the largest
/// magnitude of its group (mass; first moment; inertia about the origin).
fn pi_deviation(pi0: &[f64], pi: &[f64]) -> f64 {
    let mut worst = 0.0_f64;
    for (a, b) in pi0.chunks(LINK_PARAMETERS).zip(pi.chunks(LINK_PARAMETERS)) {
        for group in [0..1, 1..4, 4..10] {
            let scale = a[group.clone()].iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            for k in group {
                let d = (a[k] - b[k]).abs();
                worst = worst.max(if scale > 0.0 { d / scale } else { d });
            }
        }
    }
    worst
}

/// The largest difference of the contact geometry's lengths, m.
fn geometry_deviation(a: &Model, b: &Model) -> f64 {
    let values = |m: &Model, i: usize| -> Vec<f64> {
        match m.joints[i].friction.map(|f| f.geometry) {
            None => vec![],
            Some(ContactGeometry::Bearings { reaction_point, l_a, l_b, d_a, d_b, d_c }) => {
                reaction_point.iter().copied().chain([l_a, l_b, d_a, d_b, d_c]).collect()
            }
            Some(ContactGeometry::Slider { centre, a, b, c }) => centre.iter().copied().chain([a, b, c]).collect(),
        }
    };
    (0..a.nq())
        .flat_map(|i| {
            let (x, y) = (values(a, i), values(b, i));
            assert_eq!(x.len(), y.len(), "joint {}: the contact geometry's kind", i + 1);
            x.into_iter().zip(y).map(|(p, q)| (p - q).abs()).collect::<Vec<_>>()
        })
        .fold(0.0, f64::max)
}

fn random_q(model: &Model, rng: &mut Rng) -> Vec<f64> {
    model
        .joints
        .iter()
        .map(|j| match j.kind {
            JointKind::Revolute => rng.range(-std::f64::consts::PI, std::f64::consts::PI),
            JointKind::Prismatic => rng.range(-0.5, 0.5),
        })
        .collect()
}

/// The largest difference of the frames' rotations and origins and of the
/// end point at 50 random q, m (rotations: dimensionless).
fn kinematics_deviation(a: &Model, b: &Model) -> f64 {
    let (mut da, mut db) = (Data::new(a), Data::new(b));
    let mut rng = Rng::new(11);
    let mut worst = 0.0_f64;
    for _ in 0..50 {
        let q = random_q(a, &mut rng);
        forward_kinematics(a, &mut da, &q);
        forward_kinematics(b, &mut db, &q);
        for i in 0..=a.nq() {
            worst = worst.max((da.rotation[i] - db.rotation[i]).amax()).max((da.origin[i] - db.origin[i]).amax());
        }
        worst = worst.max((end_point(a, &da) - end_point(b, &db)).amax());
    }
    worst
}

/// Checks everything but the links and the tunable parameters' values: the
/// structure, drives and friction coefficients bit for bit, geometry,
/// kinematics, gravity and the end point to 1e-14; returns the geometry and
/// kinematics deviations.
fn assert_same_chain(name: &str, a: &Model, b: &Model) -> (f64, f64) {
    assert_eq!(a.name, b.name, "{name}");
    assert_eq!(a.joint_names, b.joint_names, "{name}");
    assert_eq!(a.integrator, b.integrator, "{name}");
    assert_eq!(a.gravity, b.gravity, "{name}");
    assert!((a.end_point - b.end_point).amax() <= 1e-14, "{name}: end point {:?} {:?}", a.end_point, b.end_point);
    for (i, (x, y)) in a.joints.iter().zip(&b.joints).enumerate() {
        assert_eq!(x.kind, y.kind, "{name}: joint {}", i + 1);
        assert_eq!(x.drive, y.drive, "{name}: joint {} drive", i + 1);
        assert_eq!(x.friction.map(|f| f.coefficients), y.friction.map(|f| f.coefficients), "{name}: joint {}", i + 1);
    }
    let geometry = geometry_deviation(a, b);
    let kinematics = kinematics_deviation(a, b);
    assert!(geometry <= 1e-14, "{name}: contact geometry off by {geometry:e} m");
    assert!(kinematics <= 1e-14, "{name}: forward kinematics off by {kinematics:e}");
    (geometry, kinematics)
}

#[test]
fn an_unchanged_model_reads_back_to_itself() {
    for (name, source) in arms() {
        let model = source.model().unwrap();
        let written = write(&model, &source);
        let back = read(&written);
        let pi = pi_deviation(&parameters(&model), &parameters(&back));
        let (geometry, kinematics) = assert_same_chain(name, &model, &back);
        eprintln!("{name}: π off by {pi:.1e}, geometry {geometry:.1e} m, kinematics {kinematics:.1e}");
        assert!(pi <= 1e-14, "{name}: π off by {pi:e}");
        assert!(written.toml.contains("# Nothing changed"), "{name}:\n{}", written.toml);
        if matches!(name, "kuka_iiwa" | "xarm6") {
            assert_eq!(written.urdf, source.urdf, "{name}: a URDF without merged links comes back byte for byte");
        }
        // Written again from the read-back model and the written files: the same files.
        let again = model_file(
            &back,
            &ModelSource { toml: written.toml.clone(), urdf: written.urdf.clone() },
            "identified.urdf",
        )
        .unwrap();
        assert_eq!(again.urdf, written.urdf, "{name}");
        if written.urdf.is_none() {
            assert_eq!(again.toml, written.toml, "{name}");
        }
    }
}

/// A random physically valid link near `link`: mass within ±30 %, the
/// centre of mass moved by up to 5 cm, the inertia of a random box.
fn random_link(link: &Link, rng: &mut Rng) -> Link {
    let mass = if link.mass > 0.0 { link.mass * rng.range(0.7, 1.3) } else { rng.range(0.2, 2.0) };
    Link { mass, com: link.com + rng.vec3(0.05), inertia: random_inertia(rng, mass) }
}

/// Settings of every tunable parameter of `model` but the masses (which π
/// sets): each nonzero value moved by ±20 %, the viscous coefficients and
/// the drives' damping set where they are 0, μ_s kept at least μ_k.
fn random_settings(model: &Model, rng: &mut Rng) -> Vec<String> {
    let mut settings = Vec::new();
    let mut probe = model.clone();
    for i in 0..model.nq() {
        for p in Parameter::ALL.into_iter().filter(|&p| p != Parameter::Mass && p != Parameter::MuStatic) {
            let Some(value) = model.parameter(p, i) else { continue };
            let new = match (p, value) {
                (Parameter::Viscous, _) => rng.range(0.1, 0.5),
                (Parameter::Damping, 0.0) => rng.range(1.0, 5.0),
                (_, 0.0) => continue,
                _ => value * rng.range(0.8, 1.2),
            };
            probe.set_parameter(p, i, new).unwrap();
            settings.push(format!("{}[{}]={new:?}", p.name(), i + 1));
        }
        if let Some(mu_s) = model.parameter(Parameter::MuStatic, i) {
            let mu_k = probe.parameter(Parameter::MuKinetic, i).unwrap();
            settings.push(format!("mu_s[{}]={:?}", i + 1, mu_s.max(mu_k) * rng.range(1.0, 1.2)));
        }
    }
    settings
}

/// A random state (q, q̇, q̈).
fn random_state(model: &Model, rng: &mut Rng) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = model.nq();
    (
        random_q(model, rng),
        (0..n).map(|_| rng.range(-2.0, 2.0)).collect(),
        (0..n).map(|_| rng.range(-20.0, 20.0)).collect(),
    )
}

/// The largest deviation of the inverse dynamics of `b` from `a`'s at 200
/// random states, relative to each joint's largest |τ|.
fn inverse_dynamics_deviation(a: &Model, b: &Model) -> f64 {
    let (mut da, mut db) = (Data::new(a), Data::new(b));
    let n = a.nq();
    let (mut scale, mut deviation) = (vec![0.0_f64; n], vec![0.0_f64; n]);
    let mut rng = Rng::new(5);
    for _ in 0..200 {
        let (q, qd, qdd) = random_state(a, &mut rng);
        inverse_dynamics(a, &mut da, &q, &qd, &qdd);
        inverse_dynamics(b, &mut db, &q, &qd, &qdd);
        for i in 0..n {
            scale[i] = scale[i].max(da.tau[i].abs());
            deviation[i] = deviation[i].max((da.tau[i] - db.tau[i]).abs());
        }
    }
    (0..n).map(|i| deviation[i] / scale[i]).fold(0.0, f64::max)
}

/// `text` without its `<inertial>` elements and the comments that replace
/// removed ones.
fn without_inertials(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    loop {
        let next = [("<inertial", "</inertial>"), ("<!-- <inertial> merged", "-->")]
            .into_iter()
            .filter_map(|(open, close)| rest.find(open).map(|at| (at, close)))
            .min_by_key(|(at, _)| *at);
        let Some((at, close)) = next else { break };
        out.push_str(&rest[..at]);
        let end = at + rest[at..].find(close).expect("closed") + close.len();
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

#[test]
fn identified_links_and_settings_read_back() {
    for (seed, (name, source)) in arms().into_iter().enumerate() {
        let mut rng = Rng::new(100 + seed as u64);
        let original = source.model().unwrap();
        let settings = random_settings(&original, &mut rng);
        let settings: Vec<&str> = settings.iter().map(String::as_str).collect();
        let pi: Vec<f64> = original.links.iter().flat_map(|l| link_parameters(&random_link(l, &mut rng))).collect();
        let model = with_standard_parameters(with_settings(original.clone(), &settings).unwrap(), &pi).unwrap();
        let written = write(&model, &source);
        let back = read(&written);
        let pi_off = pi_deviation(&parameters(&model), &parameters(&back));
        let mut settings_off = 0.0_f64;
        for i in 0..model.nq() {
            for p in Parameter::ALL {
                let (a, b) = (model.parameter(p, i), back.parameter(p, i));
                assert_eq!(a.is_some(), b.is_some(), "{name}: {}[{}]", p.name(), i + 1);
                if let (Some(a), Some(b)) = (a, b) {
                    settings_off = settings_off.max((a - b).abs() / a.abs().max(1e-300));
                }
            }
        }
        let (geometry, kinematics) = assert_same_chain(name, &model, &back);
        let tau = inverse_dynamics_deviation(&model, &back);
        eprintln!(
            "{name}: {} settings; π off by {pi_off:.1e}, settings {settings_off:.1e}, geometry {geometry:.1e} m, \
             kinematics {kinematics:.1e}, τ {tau:.1e} of the largest |τ|",
            settings.len()
        );
        assert!(pi_off <= 1e-14, "{name}: π off by {pi_off:e}");
        assert!(settings_off <= 1e-14, "{name}: a setting off by {settings_off:e}");
        assert!(tau <= 1e-12, "{name}: τ off by {tau:e}");
        // The header names what changed.
        let header: String = written.toml.lines().take_while(|l| l.starts_with('#')).collect::<Vec<_>>().join("\n");
        assert!(header.contains("link 1") && header.contains(&format!("link {}", model.nq())), "{name}:\n{header}");
        let first = settings[0].split('=').next().unwrap();
        assert!(header.contains(&format!("#   {first}: ")), "{name}: {first} in\n{header}");
        if let (Some(urdf), Some(original_urdf)) = (&written.urdf, &source.urdf) {
            let (mut a, mut b) = (without_inertials(urdf), without_inertials(original_urdf));
            if name == "small_urdf" {
                // An <inertial> added to a link without one: white space and `<link …/>` opened.
                let squeeze = |s: &str| s.split_whitespace().collect::<String>().replace("></link>", "/>");
                (a, b) = (squeeze(&a), squeeze(&b));
            }
            assert_eq!(a, b, "{name}: only <inertial>s change");
        }
    }
}

#[test]
fn the_merged_links_inertials_move_into_their_moving_link() {
    let source = ModelSource { toml: SMALL_TOML.into(), urdf: Some(SMALL_URDF.into()) };
    let model = source.model().unwrap();
    let written = write(&model, &source);
    let urdf = written.urdf.as_deref().unwrap();
    // l1 (self-closing) now holds body 1: l1 with l1b and the flap.
    let l1 = &urdf[urdf.find("<link name=\"l1\">").expect("l1 opened")..];
    let l1 = &l1[..l1.find("</link>").unwrap()];
    assert!(l1.contains("<mass value=\"3.5\"/>"), "{l1}");
    for merged in ["l1b", "flap"] {
        let at = urdf.find(&format!("<link name=\"{merged}\">")).unwrap();
        let element = &urdf[at..at + urdf[at..].find("</link>").unwrap()];
        assert!(element.contains("<!-- <inertial> merged into link l1 by stickslip identify -->"), "{element}");
        assert!(!element.contains("<mass"), "{element}");
    }
    // l2 has no <inertial> and a massless body: untouched; l3 unchanged: byte for byte.
    let l3 = "<link name=\"l3\">\n    <inertial>\n      <origin xyz=\"0 0 0.05\"/>";
    assert!(urdf.contains("<link name=\"l2\">\n    <visual>") && urdf.contains(l3), "{urdf}");
    assert!(
        written.toml.contains("Link `l1` holds the mass of `l1b`, `flap` too, which the reader merges into it"),
        "{}",
        written.toml
    );
    // l2 given mass: an <inertial> added before </link>.
    let mut pi = parameters(&model);
    pi[10..20].copy_from_slice(&link_parameters(&Link {
        mass: 0.7,
        com: Vec3::new(0.0, 0.01, 0.02),
        inertia: random_inertia(&mut Rng::new(1), 0.7),
    }));
    let heavier = with_standard_parameters(model, &pi).unwrap();
    let written = write(&heavier, &source);
    let back = read(&written);
    assert!(pi_deviation(&parameters(&heavier), &parameters(&back)) <= 1e-14);
    let urdf = written.urdf.unwrap();
    let l2 = &urdf[urdf.find("<link name=\"l2\">").unwrap()..];
    assert!(l2.starts_with("<link name=\"l2\">\n    <visual>"), "{l2}");
    assert!(l2[..l2.find("</link>").unwrap()].contains("<mass value=\"0.7\"/>"), "{l2}");
}

#[test]
fn a_model_that_is_not_its_sources_chain_is_refused() {
    let reference = source("models/reference_rrpr.toml");
    let iiwa = source("models/urdf/kuka_iiwa/kuka_iiwa.toml").model().unwrap();
    let e = model_file(&iiwa, &reference, "x.urdf").unwrap_err();
    assert!(matches!(&e, ModelError::Invalid { reason, .. } if reason.contains("7 joints, its source 4 rows")), "{e}");
    // Other drives on the same chain are the model's to say: the motor arm written from the reference's file.
    let motor = Model::reference_rrpr_motor();
    let back = read(&model_file(&motor, &reference, "x.urdf").unwrap());
    assert_same_chain("motor from the reference's file", &motor, &back);
    let mut moved = reference.model().unwrap();
    moved.joints[1].placement.translation.x += 1e-3;
    let e = model_file(&moved, &reference, "x.urdf").unwrap_err();
    assert!(matches!(&e, ModelError::Invalid { field, .. } if field == "joint[2].placement.translation"), "{e}");
}

/// What `stickslip_write_model` returned.
struct Export {
    status: i32,
    message: String,
    toml: String,
    urdf: String,
    needed: (usize, usize),
}

/// `stickslip_write_model` with buffers of `sizes`.
fn export(source: &ModelSource, settings: &[&str], pi: Option<&[f64]>, sizes: (usize, usize)) -> Export {
    let text = CString::new(source.toml.as_str()).unwrap();
    let urdf = source.urdf.as_ref().map(|u| CString::new(u.as_str()).unwrap());
    let settings: Vec<CString> = settings.iter().map(|s| CString::new(*s).unwrap()).collect();
    let pointers: Vec<*const c_char> = settings.iter().map(|s| s.as_ptr()).collect();
    let file_name = CString::new("identified.urdf").unwrap();
    let (mut toml, mut urdf_out) = (vec![0u8; sizes.0], vec![0u8; sizes.1]);
    let (mut toml_needed, mut urdf_needed) = (usize::MAX, usize::MAX);
    let mut message = vec![0u8; 512];
    let pi = pi.unwrap_or(&[]);
    let status = unsafe {
        stickslip_write_model(
            text.as_ptr(),
            urdf.as_ref().map_or(std::ptr::null(), |u| u.as_ptr()),
            pointers.as_ptr(),
            pointers.len(),
            pi.as_ptr(),
            pi.len(),
            file_name.as_ptr(),
            toml.as_mut_ptr().cast(),
            toml.len(),
            urdf_out.as_mut_ptr().cast(),
            urdf_out.len(),
            &mut toml_needed,
            &mut urdf_needed,
            message.as_mut_ptr().cast(),
            message.len(),
        )
    };
    let text = |bytes: &[u8]| {
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(0);
        String::from_utf8(bytes[..end].to_vec()).unwrap()
    };
    Export {
        status,
        message: text(&message),
        toml: text(&toml),
        urdf: text(&urdf_out),
        needed: (toml_needed, urdf_needed),
    }
}

#[test]
fn the_fmu_library_export_writes_what_model_file_writes() {
    for (name, source) in [
        ("reference", source("models/reference_rrpr.toml")),
        ("kuka_iiwa", source("models/urdf/kuka_iiwa/kuka_iiwa.toml")),
    ] {
        let original = source.model().unwrap();
        let settings = ["mu_k[1]=0.03", "b_v[1]=0.4"];
        let mut rng = Rng::new(9);
        let pi: Vec<f64> = original.links.iter().flat_map(|l| link_parameters(&random_link(l, &mut rng))).collect();
        let model = with_standard_parameters(with_settings(original, &settings).unwrap(), &pi).unwrap();
        let expected = write(&model, &source);
        // Sizes 0: status 2 and the sizes.
        let asked = export(&source, &settings, Some(&pi), (0, 0));
        let urdf_len = expected.urdf.as_ref().map_or(0, |u| u.len() + 1);
        assert_eq!((asked.status, asked.needed), (2, (expected.toml.len() + 1, urdf_len)), "{name}: {}", asked.message);
        assert!(asked.message.contains("the model file needs"), "{}", asked.message);
        let out = export(&source, &settings, Some(&pi), asked.needed);
        assert_eq!((out.status, out.message.as_str()), (0, ""), "{name}");
        assert_eq!(out.toml, expected.toml, "{name}");
        assert_eq!(out.urdf, expected.urdf.unwrap_or_default(), "{name}");
        // No π: the links kept.
        let kept = export(&source, &[], None, (1 << 20, 1 << 20));
        assert_eq!(kept.status, 0, "{name}: {}", kept.message);
        assert!(kept.toml.contains("# Nothing changed"), "{name}");
    }
    let reference = source("models/reference_rrpr.toml");
    let mut pi = parameters(&Model::reference_rrpr());
    // Link 2 with I_xx above I_yy + I_zz about its centre of mass.
    pi[14] += 10.0;
    let refused = export(&reference, &[], Some(&pi), (1 << 16, 0));
    assert_eq!(refused.status, 1);
    assert!(
        refused.message.contains("joint[2].link.inertia") && refused.message.contains("triangle"),
        "{}",
        refused.message
    );
    let refused = export(&reference, &[], Some(&pi[..39]), (1 << 16, 0));
    assert_eq!(refused.status, 1);
    assert!(refused.message.starts_with("n_parameters = 39"), "{}", refused.message);
    let refused = export(&reference, &["mu_k[9]=0.1"], None, (1 << 16, 0));
    assert_eq!(refused.status, 1);
    assert!(refused.message.contains("mu_k[9]"), "{}", refused.message);
}
