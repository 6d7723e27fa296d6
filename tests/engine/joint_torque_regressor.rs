//! The rigid-body inverse dynamics are linear in the links' inertial
//! parameters: τ(q, q̇, q̈) = Y(q, q̇, q̈)·π, with π per link the ten standard
//! parameters [m, m·c, I about the link frame's origin] in the engine's link
//! frame. At 200 random states (q in ±π rad or ±0.5 m, q̇ in ±2, q̈ in ±20) of
//! the reference arm (three revolute joints and a prismatic one), the motor
//! arm, the KUKA iiwa and the xArm 6, Y·π of `joint_torque_regressor` equals
//! `inverse_dynamics`' τ to 1e-10 of the joint's largest |τ| over the
//! states (measured: 5.7e-16). Each column Y_k is what changing that one
//! parameter by δ (a tenth of the mass, a percent of the first moment or of
//! the mean principal moment; set through `with_standard_parameters`) does
//! to τ, at 5 states per arm: |Δτ − δ·Y_k| within 1e-9 of δ times the
//! column's largest entry plus 1e-13 of the largest |τ| (the two τ's
//! rounding; measured: 6.0e-16 of the largest |τ|; the xArm's links 2 and 3,
//! whose published inertias violate the triangle inequality, made consistent
//! first). A block on a tilted slideway gives the closed form
//! Y = [q̈ + g sin α, 0, …]. The setter gives the model back from its own π
//! and refuses an inconsistent link, naming it. The FMU library's
//! `stickslip_joint_torque_regressor` gives the function's numbers bit for
//! bit and π with the settings applied, and refuses bad input with a
//! message.

use std::ffi::{c_char, CString};

use stick_slip_manipulator::algorithms::inverse_dynamics::{inverse_dynamics, with_settings};
use stick_slip_manipulator::algorithms::regressor::{
    joint_torque_regressor, link_parameters, standard_parameters, with_standard_parameters, LINK_PARAMETERS,
};
use stick_slip_manipulator::fmi::stickslip_joint_torque_regressor;
use stick_slip_manipulator::math::{Mat3, MatN};
use stick_slip_manipulator::model::{JointKind, REFERENCE_RRPR_TOML};
use stick_slip_manipulator::{Data, Model, ModelError};

use crate::common::Rng;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The four arms, by name.
fn arms() -> Vec<(&'static str, Model)> {
    let file = |path: &str| Model::from_file(format!("{ROOT}/{path}")).unwrap();
    vec![
        ("reference", Model::reference_rrpr()),
        ("motor", file("models/reference_rrpr_motor.toml")),
        ("kuka_iiwa", file("models/urdf/kuka_iiwa/kuka_iiwa.toml")),
        ("xarm6", file("models/urdf/xarm6/xarm6.toml")),
    ]
}

/// A random state (q, q̇, q̈) of `model`.
fn random_state(model: &Model, rng: &mut Rng) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let q = model
        .joints
        .iter()
        .map(|j| match j.kind {
            JointKind::Revolute => rng.range(-std::f64::consts::PI, std::f64::consts::PI),
            JointKind::Prismatic => rng.range(-0.5, 0.5),
        })
        .collect();
    let n = model.nq();
    (q, (0..n).map(|_| rng.range(-2.0, 2.0)).collect(), (0..n).map(|_| rng.range(-20.0, 20.0)).collect())
}

/// The engine's τ at a state.
fn tau(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
    let mut data = Data::new(model);
    inverse_dynamics(model, &mut data, q, qd, qdd);
    data.tau
}

/// Y at a state.
fn regressor(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> MatN {
    let mut data = Data::new(model);
    joint_torque_regressor(model, &mut data, q, qd, qdd);
    data.regressor
}

fn parameters(model: &Model) -> Vec<f64> {
    let mut pi = vec![0.0; LINK_PARAMETERS * model.nq()];
    standard_parameters(model, &mut pi);
    pi
}

#[test]
fn y_times_pi_is_the_inverse_dynamics() {
    for (name, model) in arms() {
        let n = model.nq();
        let pi = MatN::from_column_slice(10 * n, 1, &parameters(&model));
        let mut rng = Rng::new(42);
        let (mut scale, mut deviation) = (vec![0.0_f64; n], vec![0.0_f64; n]);
        for _ in 0..200 {
            let (q, qd, qdd) = random_state(&model, &mut rng);
            let y = regressor(&model, &q, &qd, &qdd);
            let tau = tau(&model, &q, &qd, &qdd);
            let product = &y * &pi;
            for i in 0..n {
                scale[i] = scale[i].max(tau[i].abs());
                deviation[i] = deviation[i].max((product[(i, 0)] - tau[i]).abs());
            }
        }
        let worst = (0..n).map(|i| deviation[i] / scale[i]).fold(0.0, f64::max);
        eprintln!("{name}: |Y·π − τ| at most {worst:.2e} of the joint's largest |τ|");
        assert!(worst <= 1e-10, "{name}: {worst:e}");
    }
}

/// `model` with every link whose principal moments violate the triangle
/// inequality made consistent: each moment raised by the deficit
/// d = I3 − I1 − I2 and a percent of I3, which leaves I1 + I2 − I3 a percent
/// of I3 and room for the changes below.
fn consistent(mut model: Model) -> Model {
    for link in &mut model.links {
        let moments = Mat3::symmetric_eigenvalues(&link.inertia);
        let deficit = 2.0 * moments.max() - moments.sum();
        if deficit > 0.0 {
            link.inertia += Mat3::identity() * (deficit + 0.01 * moments.max());
        }
    }
    model
}

#[test]
fn each_column_is_the_change_of_tau_per_unit_of_its_parameter() {
    let mut worst: f64 = 0.0;
    for (name, model) in arms() {
        let model = consistent(model);
        let n = model.nq();
        let pi = parameters(&model);
        let mut rng = Rng::new(7);
        for _ in 0..5 {
            let (q, qd, qdd) = random_state(&model, &mut rng);
            let y = regressor(&model, &q, &qd, &qdd);
            let tau0 = tau(&model, &q, &qd, &qdd);
            let tau_scale = tau0.iter().fold(0.0_f64, |a, t| a.max(t.abs()));
            for k in 0..10 * n {
                let link = &model.links[k / 10];
                // A change the link stays consistent with: a tenth more mass
                // (adds a point mass's inertia about the centre of mass), a
                // centimetre-scale shift of the first moment, a percent of the
                // inertia's mean principal moment (either sign).
                let steps = match k % 10 {
                    0 => [0.1 * link.mass; 2],
                    1..=3 => {
                        [0.01 * link.mass * (link.com.norm() + 0.01), -0.01 * link.mass * (link.com.norm() + 0.01)]
                    }
                    _ => [0.01 * link.inertia.trace() / 3.0, -0.01 * link.inertia.trace() / 3.0],
                };
                let (delta, changed) = steps
                    .iter()
                    .find_map(|&d| {
                        let mut p = pi.clone();
                        p[k] += d;
                        with_standard_parameters(model.clone(), &p).ok().map(|m| (d, m))
                    })
                    .unwrap_or_else(|| panic!("{name}: parameter {k} cannot be changed"));
                let tau1 = tau(&changed, &q, &qd, &qdd);
                let column = y.column(k);
                let column_scale = column.amax();
                for i in 0..n {
                    let difference = ((tau1[i] - tau0[i]) / delta - column[i]).abs();
                    // Rounding of the two τ, per unit of the step.
                    let floor = 1e-13 * tau_scale / delta.abs();
                    assert!(
                        difference <= 1e-9 * column_scale + floor,
                        "{name}: Y[{i},{k}] = {} but τ changes by {} per unit",
                        column[i],
                        (tau1[i] - tau0[i]) / delta
                    );
                    worst = worst.max(difference * delta.abs() / tau_scale);
                }
            }
        }
    }
    eprintln!("|Δτ − δ·Y_k| at most {worst:.2e} of the largest |τ|");
}

#[test]
fn a_block_on_a_tilted_slideway_has_the_closed_form_row() {
    // One prismatic joint tilted by α: τ = m·(q̈ + g sin α) whatever the centre
    // of mass and inertia, so the mass's column is q̈ + g sin α and every
    // other column 0.
    let (g, tilt) = (9.81, 0.4_f64);
    let text = format!(
        "name = \"block\"\ngravity = [0.0, {}, {}]\nend_point = [0.0, 0.0, 0.0]\n[[joint]]\ntype = \"prismatic\"\n\
         theta = 0.0\nd = 0.0\na = 0.0\nalpha = 0.0\ndrive = {{ type = \"rigid\" }}\n\
         link = {{ mass = 2.5, com = [0.1, -0.2, 0.3], inertia = {{ xx = 0.01, yy = 0.02, zz = 0.015 }} }}\n",
        -g * tilt.cos(),
        -g * tilt.sin()
    );
    let model = Model::from_toml_str(&text).unwrap();
    for (q, qd, qdd) in [(0.0, 0.0, 0.0), (0.3, -1.5, 4.0), (-0.2, 2.0, -7.5)] {
        let y = regressor(&model, &[q], &[qd], &[qdd]);
        let expected = qdd + g * tilt.sin();
        assert!((y[(0, 0)] - expected).abs() <= 1e-14 * g, "{} vs {expected}", y[(0, 0)]);
        assert!(y.columns(1, 9).iter().all(|&x| x == 0.0), "{y}");
    }
}

#[test]
fn the_setter_gives_the_model_back_from_its_own_parameters() {
    for (name, model) in arms().into_iter().filter(|(name, _)| *name != "xarm6") {
        let back = with_standard_parameters(model.clone(), &parameters(&model)).unwrap();
        for (i, (a, b)) in model.links.iter().zip(&back.links).enumerate() {
            let inertia = (a.inertia - b.inertia).amax() / a.inertia.amax();
            let com = (a.com - b.com).amax() / a.com.amax().max(1e-3);
            assert!(a.mass == b.mass && inertia < 1e-13 && com < 1e-15, "{name} link {}: {a:?} vs {b:?}", i + 1);
        }
        let p = link_parameters(&back.links[0]);
        assert!(p.iter().zip(parameters(&model)).all(|(a, b)| (a - b).abs() <= 1e-14 * b.abs().max(1e-3)));
    }
}

#[test]
fn the_setter_refuses_an_inconsistent_link_by_name() {
    // The xArm 6 as published: link 2's principal moments violate the
    // triangle inequality by 0.74 % (models/urdf/xarm6/xarm6.toml).
    let arms = arms();
    let xarm = &arms[3].1;
    let error = with_standard_parameters(xarm.clone(), &parameters(xarm)).unwrap_err().to_string();
    assert!(error.contains("joint[2] (`joint2`).link.inertia") && error.contains("triangle inequality"), "{error}");
    let reference = Model::reference_rrpr();
    let pi = parameters(&reference);
    let refused = |k: usize, value: f64, says: &str| {
        let mut p = pi.clone();
        p[k] = value;
        let error = with_standard_parameters(reference.clone(), &p).unwrap_err();
        let text = error.to_string();
        assert!(text.contains(says), "expected `{says}` in: {text}");
        error
    };
    assert!(matches!(refused(20, -1.0, "joint[3].link.mass"), ModelError::InvalidParameter { .. }));
    refused(20, 0.0, "needs a positive mass");
    refused(35, f64::NAN, "joint[4].link.I_xy");
    // I_zz about the origin below what the first moment alone gives: I_c has a negative moment.
    refused(9, -pi[9], "joint[1].link.inertia");
    refused(9, -pi[9], "is not positive semidefinite");
    let length = with_standard_parameters(reference.clone(), &pi[..39]).unwrap_err().to_string();
    assert!(length.contains("39 standard parameters for 4 links"), "{length}");
    // All zero: a massless link, as a URDF link without <inertial>.
    let mut p = pi.clone();
    p[30..].fill(0.0);
    assert_eq!(with_standard_parameters(reference.clone(), &p).unwrap().links[3].mass, 0.0);
}

struct Export {
    status: i32,
    message: String,
    regressor: Vec<f64>,
    parameters: Vec<f64>,
}

/// `stickslip_joint_torque_regressor` on `states` (rows of `columns` values)
/// of the model `text` with `settings`, outputs sized for `n` joints.
fn export(text: &str, urdf: Option<&str>, settings: &[&str], states: &[f64], columns: usize, n: usize) -> Export {
    let (text, urdf) = (CString::new(text).unwrap(), urdf.map(|u| CString::new(u).unwrap()));
    let settings: Vec<CString> = settings.iter().map(|s| CString::new(*s).unwrap()).collect();
    let pointers: Vec<*const c_char> = settings.iter().map(|s| s.as_ptr()).collect();
    let rows = states.len() / columns;
    let (mut regressor, mut parameters) = (vec![f64::NAN; rows * n * 10 * n], vec![f64::NAN; 10 * n]);
    let mut message = vec![0u8; 512];
    let status = unsafe {
        stickslip_joint_torque_regressor(
            text.as_ptr(),
            urdf.as_ref().map_or(std::ptr::null(), |u| u.as_ptr()),
            pointers.as_ptr(),
            pointers.len(),
            states.as_ptr(),
            rows,
            columns,
            regressor.as_mut_ptr(),
            regressor.len(),
            parameters.as_mut_ptr(),
            parameters.len(),
            message.as_mut_ptr().cast(),
            message.len(),
        )
    };
    let end = message.iter().position(|&b| b == 0).expect("the message is NUL-terminated");
    Export { status, message: String::from_utf8(message[..end].to_vec()).unwrap(), regressor, parameters }
}

#[test]
fn the_fmu_library_export_gives_the_functions_numbers_bit_for_bit() {
    let settings = ["m[3]=12", "d_A[1]=0.12"];
    let model = with_settings(Model::reference_rrpr(), &settings).unwrap();
    let n = model.nq();
    let mut rng = Rng::new(3);
    let states: Vec<Vec<f64>> = (0..20)
        .map(|_| {
            let (q, qd, qdd) = random_state(&model, &mut rng);
            [q, qd, qdd].concat()
        })
        .collect();
    let out = export(REFERENCE_RRPR_TOML, None, &settings, &states.concat(), 3 * n, n);
    assert_eq!((out.status, out.message.as_str()), (0, ""));
    assert_eq!(out.parameters, parameters(&model), "π with the settings applied");
    assert_eq!(out.parameters[20], 12.0, "m[3]");
    for (r, state) in states.iter().enumerate() {
        let y = regressor(&model, &state[..n], &state[n..2 * n], &state[2 * n..]);
        let block = &out.regressor[r * n * 10 * n..(r + 1) * n * 10 * n];
        for (i, row) in block.chunks(10 * n).enumerate() {
            for (k, value) in row.iter().enumerate() {
                assert_eq!(value.to_bits(), y[(i, k)].to_bits(), "Y[{i},{k}] of row {r}");
            }
        }
    }
    // Rows = 0: π alone, the arrays of the states not looked at.
    let pi_only = export(REFERENCE_RRPR_TOML, None, &[], &[], 3 * n, n);
    assert_eq!((pi_only.status, pi_only.parameters), (0, parameters(&Model::reference_rrpr())));
    // A URDF model with its URDF's text.
    let urdf = std::fs::read_to_string(format!("{ROOT}/models/urdf/kuka_iiwa/kuka_iiwa.urdf")).unwrap();
    let toml = std::fs::read_to_string(format!("{ROOT}/models/urdf/kuka_iiwa/kuka_iiwa.toml")).unwrap();
    let iiwa = export(&toml, Some(&urdf), &[], &[0.1; 21], 21, 7);
    assert_eq!((iiwa.status, iiwa.message.as_str()), (0, ""));
    assert_eq!(iiwa.parameters, parameters(&arms()[2].1));
}

#[test]
fn the_export_refuses_bad_input_with_a_message() {
    let text = REFERENCE_RRPR_TOML;
    let n = 4;
    let mut states: Vec<f64> = (0..2 * 3 * n).map(|k| 0.01 * k as f64).collect();
    let refused = |out: Export, says: &str| {
        assert_eq!(out.status, 1, "{says}: {}", out.message);
        assert!(out.message.contains(says), "expected `{says}` in: {}", out.message);
    };
    refused(export(text, None, &["nonsense[1]=2"], &states, 3 * n, n), "no parameter is named `nonsense`");
    refused(export(text, None, &["m[3]=-1"], &states, 3 * n, n), "m[3]");
    refused(export("name = [", None, &[], &states, 3 * n, n), "the model: model file is malformed");
    refused(export(text, None, &[], &states[..2 * 3 * (n - 1)], 3 * (n - 1), n - 1), "3n = 12");
    refused(export(text, None, &[], &states, 3 * n, n - 1), "size = 180: 2 rows of 4 x 40 need 320");
    states[3 * n + 2 * n + 3] = f64::INFINITY;
    refused(export(text, None, &[], &states, 3 * n, n), "row 2: qdd[4] = inf is not finite");
    let model = CString::new(text).unwrap();
    let mut regressor = vec![0.0; 2 * n * 10 * n];
    let mut long = [0u8; 200];
    let call = |regressor: *mut f64, size: usize, parameters: *mut f64, n_parameters: usize, message: &mut [u8]| unsafe {
        stickslip_joint_torque_regressor(
            model.as_ptr(),
            std::ptr::null(),
            std::ptr::null(),
            0,
            states.as_ptr(),
            2,
            3 * n,
            regressor,
            size,
            parameters,
            n_parameters,
            message.as_mut_ptr().cast(),
            message.len(),
        )
    };
    let (y, size) = (regressor.as_mut_ptr(), regressor.len());
    let mut pi = vec![0.0; 40];
    assert_eq!(call(y, size, pi.as_mut_ptr(), 39, &mut long), 1);
    assert!(long.starts_with(b"n_parameters = 39: 4 links of 10 parameters need 40\0"));
    assert_eq!(call(y, size, y.wrapping_add(size - 20), 40, &mut long), 1);
    assert!(long.starts_with(b"`regressor` and `parameters` overlap\0"));
    assert_eq!(call(y, size, std::ptr::null_mut(), 40, &mut long), 1);
    assert!(long.starts_with(b"`parameters[]` is NULL but has 40 elements\0"));
    assert_eq!(call(std::ptr::null_mut(), size, pi.as_mut_ptr(), 40, &mut long), 1);
    assert!(long.starts_with(b"`regressor[]` is NULL but has 320 elements\0"));
}
