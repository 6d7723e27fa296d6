//! Two formulations of the same equations of motion agree.
//!
//! The study's Lagrange form with the B matrices (eqs. 3.3–3.9) is the
//! reference; the recursive algorithms (composite rigid body mass matrix,
//! recursive Newton–Euler inverse dynamics with joint reactions) must give
//! the same mass matrix, bias forces and generalized forces to 1e-9 relative
//! on random configurations of random chains of 1 to 8 links with mixed joint
//! types. The joint reactions are checked against an independent momentum
//! balance of the subtree beyond each joint, built from the B-matrix
//! derivatives. Energies by (3.3), (3.4) and ½ q̇ᵀMq̇ agree as well.

use crate::common;

use common::{random_chain, Rng};
use stick_slip_manipulator::algorithms::crba::crba;
use stick_slip_manipulator::algorithms::energy::{kinetic_energy, potential_energy};
use stick_slip_manipulator::algorithms::kinematics::{forward_kinematics, reaction_point};
use stick_slip_manipulator::algorithms::lagrange::{self, b_derivative};
use stick_slip_manipulator::algorithms::rnea::{joint_reaction, rnea};
use stick_slip_manipulator::math::{Mat3, MatN, Vec3, Vec4, VecN};
use stick_slip_manipulator::{Data, Model};

const TOL: f64 = 1e-9;

fn random_state(rng: &mut Rng, n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let q = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
    let qd = (0..n).map(|_| rng.range(-3.0, 3.0)).collect();
    let qdd = (0..n).map(|_| rng.range(-10.0, 10.0)).collect();
    (q, qd, qdd)
}

/// |a − b| ≤ TOL·max(|a|, |b|, floor) componentwise; `floor` is the size of
/// the terms the compared values are sums of, for values that cancel to ~0.
fn assert_close_floor(what: &str, a: &[f64], b: &[f64], floor: f64) {
    let scale = a.iter().chain(b).fold(floor, |m, x| m.max(x.abs())).max(1e-300);
    for (k, (x, y)) in a.iter().zip(b).enumerate() {
        assert!((x - y).abs() <= TOL * scale, "{what}[{k}]: {x} vs {y} (scale {scale})");
    }
}

fn assert_close(what: &str, a: &[f64], b: &[f64]) {
    assert_close_floor(what, a, b, 0.0)
}

fn configurations() -> impl Iterator<Item = (Model, Vec<f64>, Vec<f64>, Vec<f64>)> {
    (1..=8).flat_map(|n| {
        (0..6).map(move |seed| {
            let model = random_chain(n, 1000 * n as u64 + seed);
            let mut rng = Rng::new(seed + 77 * n as u64);
            let (q, qd, qdd) = random_state(&mut rng, n);
            (model, q, qd, qdd)
        })
    })
}

#[test]
fn mass_matrix_crba_equals_lagrange_and_is_positive_definite() {
    for (model, q, qd, _) in configurations() {
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        crba(&model, &mut data);
        let reference = lagrange::lagrange_terms(&model, &q, &qd).mass;
        assert_close(&format!("{} M", model.name), data.mass_matrix.as_slice(), reference.as_slice());
        let m = &data.mass_matrix;
        assert_eq!(m, &m.transpose(), "{}: M not symmetric", model.name);
        assert!(m.clone().cholesky().is_some(), "{}: M not positive definite", model.name);
    }
}

#[test]
fn bias_and_generalized_forces_rnea_equal_lagrange() {
    for (model, q, qd, qdd) in configurations() {
        let n = model.nq();
        let mut data = Data::new(&model);
        let terms = lagrange::lagrange_terms(&model, &q, &qd);
        forward_kinematics(&model, &mut data, &q);
        rnea(&model, &mut data, &q, &qd, &vec![0.0; n]);
        let bias: VecN = &terms.velocity_terms + &terms.gravity;
        assert_close(&format!("{} bias", model.name), &data.tau, bias.as_slice());
        rnea(&model, &mut data, &q, &qd, &qdd);
        let tau: VecN = &terms.mass * VecN::from_column_slice(&qdd) + bias;
        assert_close(&format!("{} tau", model.name), &data.tau, tau.as_slice());
    }
}

#[test]
fn gravity_and_velocity_terms_separately() {
    // Zero velocity isolates D_s; zero gravity isolates D_sji q̇_j q̇_i.
    for (mut model, q, qd, _) in configurations().step_by(3) {
        let n = model.nq();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        rnea(&model, &mut data, &q, &vec![0.0; n], &vec![0.0; n]);
        let gravity = lagrange::lagrange_terms(&model, &q, &qd).gravity;
        assert_close("gravity", &data.tau, gravity.as_slice());
        model.gravity = Vec3::zeros();
        rnea(&model, &mut data, &q, &qd, &vec![0.0; n]);
        let terms = lagrange::lagrange_terms(&model, &q, &qd);
        // A single joint has no velocity terms: compare with the size of M·q̇².
        let floor = terms.mass.amax() * qd.iter().fold(0.0f64, |m, x| m.max(x * x));
        assert_close_floor("velocity terms", &data.tau, terms.velocity_terms.as_slice(), floor);
    }
}

#[test]
fn energies_agree_between_formulations() {
    for (model, q, qd, _) in configurations() {
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        crba(&model, &mut data);
        rnea(&model, &mut data, &q, &qd, &vec![0.0; model.nq()]);
        let qd_v = VecN::from_column_slice(&qd);
        let quadratic = 0.5 * qd_v.dot(&(&data.mass_matrix * &qd_v));
        let t_33 = lagrange::kinetic_energy(&model, &q, &qd);
        let t_rec = kinetic_energy(&model, &data, &qd);
        assert!((t_33 - t_rec).abs() <= TOL * t_33, "T (3.3) {t_33} vs recursive {t_rec}");
        assert!((quadratic - t_rec).abs() <= TOL * t_33, "½q̇ᵀMq̇ {quadratic} vs recursive {t_rec}");
        let v_34 = lagrange::potential_energy(&model, &q);
        let v_rec = potential_energy(&model, &data);
        assert!((v_34 - v_rec).abs() <= TOL * v_34.abs().max(1.0), "V (3.4) {v_34} vs recursive {v_rec}");
    }
}

/// Skew part of a 3×3 matrix as a vector: [w]× ↦ w.
fn vee(m: &Mat3) -> Vec3 {
    Vec3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) * 0.5
}

#[test]
fn joint_reactions_balance_the_momentum_of_the_subtree() {
    // f_s = Σ_{l≥s} m_l (ẍ_cl − g), n_s = Σ_{l≥s} [(x_cl − p_s) × m_l (ẍ_cl − g) + I_l ω̇_l + ω_l × I_l ω_l]
    // about the joint's origin p_s (the origin of link s's frame),
    // with positions, velocities and accelerations of every link taken from
    // B_l, Ḃ_l = Σ B_l^j q̇_j and B̈_l = Σ B_l^j q̈_j + Σ Σ B_l^{jk} q̇_j q̇_k.
    for (model, q, qd, qdd) in configurations() {
        let n = model.nq();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        rnea(&model, &mut data, &q, &qd, &qdd);
        for s in 1..=n {
            let p = b_derivative(&model, &q, s, &[]).fixed_view::<3, 1>(0, 3).into_owned();
            let (mut f, mut m) = (Vec3::zeros(), Vec3::zeros());
            for l in s..=n {
                let link = &model.links[l - 1];
                let b = b_derivative(&model, &q, l, &[]);
                let bd: stick_slip_manipulator::math::Mat4 =
                    (1..=l).map(|j| b_derivative(&model, &q, l, &[j]) * qd[j - 1]).sum();
                let mut bdd: stick_slip_manipulator::math::Mat4 =
                    (1..=l).map(|j| b_derivative(&model, &q, l, &[j]) * qdd[j - 1]).sum();
                for j in 1..=l {
                    for k in 1..=l {
                        bdd += b_derivative(&model, &q, l, &[j, k]) * (qd[j - 1] * qd[k - 1]);
                    }
                }
                let rc = Vec4::new(link.com.x, link.com.y, link.com.z, 1.0);
                let x = (b * rc).xyz();
                let xdd = (bdd * rc).xyz();
                let r: Mat3 = b.fixed_view::<3, 3>(0, 0).into_owned();
                let rd: Mat3 = bd.fixed_view::<3, 3>(0, 0).into_owned();
                let rdd: Mat3 = bdd.fixed_view::<3, 3>(0, 0).into_owned();
                let w = vee(&(rd * r.transpose()));
                let wd = vee(&(rdd * r.transpose() + rd * rd.transpose()));
                let inertia = r * link.inertia * r.transpose();
                let force = (xdd - model.gravity) * link.mass;
                f += force;
                m += (x - p).cross(&force) + inertia * wd + w.cross(&(inertia * w));
            }
            let scale = f.norm().max(m.norm()).max(1.0);
            // The recursion resolves them in frame s.
            let (f_rec, m_rec) = (data.rotation[s] * data.force[s - 1], data.rotation[s] * data.moment[s - 1]);
            assert!((f_rec - f).norm() <= TOL * scale, "{} f_{s}: {} vs {}", model.name, f_rec, f);
            assert!((m_rec - m).norm() <= TOL * scale, "{} n_{s}: {} vs {}", model.name, m_rec, m);
            // The reaction at the reaction reference point P in the joint frame,
            // from the frame-0 geometry of eq. (3.2).
            joint_reaction(&model, &mut data, s - 1);
            let rt = data.rotation[s].transpose();
            let point = reaction_point(&model, &data, s - 1);
            let (f_joint, m_joint) = (rt * f, rt * (m + (p - point).cross(&f)));
            let (rf, rm) = (data.reaction_force[s - 1], data.reaction_moment[s - 1]);
            assert!((rf - f_joint).norm() <= TOL * scale, "{} reaction f_{s}: {rf} vs {f_joint}", model.name);
            assert!((rm - m_joint).norm() <= TOL * scale, "{} reaction n_{s}: {rm} vs {m_joint}", model.name);
        }
    }
}

#[test]
fn recursive_frames_equal_the_products_of_eq_3_2() {
    // B_i = A_1…A_i (3.2) as built by the Lagrange reference, against the
    // frames of the recursive forward kinematics.
    for (model, q, _, _) in configurations() {
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        for i in 0..=model.nq() {
            let recursive = stick_slip_manipulator::algorithms::kinematics::frame_transform(&data, i);
            let product = b_derivative(&model, &q, i, &[]);
            assert!((recursive - product).amax() < 1e-12, "{} B_{i}", model.name);
        }
    }
}

#[test]
fn reference_manipulator_geometry_matches_its_description() {
    // shared/reference-manipulator.md: at q = (0, 0, 0.8, 0) the arm is
    // horizontal along +x0 and E is at (0.9, 0, 0.7); positive q2 tilts it up.
    let model = Model::reference_rrpr();
    let mut data = Data::new(&model);
    forward_kinematics(&model, &mut data, &[0.0, 0.0, 0.8, 0.0]);
    let e = stick_slip_manipulator::algorithms::kinematics::end_point(&model, &data);
    assert!((e - Vec3::new(0.9, 0.0, 0.7)).norm() < 1e-12, "E = {e}");
    forward_kinematics(&model, &mut data, &[0.0, 0.2, 0.8, 0.0]);
    // Joint 3 slides along the z axis of link 3's frame.
    let arm_axis: Vec3 = data.rotation[3].column(2).into();
    assert!((arm_axis - Vec3::new(0.2f64.cos(), 0.0, 0.2f64.sin())).norm() < 1e-12, "z2 = {arm_axis}");
    let m: MatN = lagrange::lagrange_terms(&model, &[0.0, 0.0, 0.8, 0.0], &[0.0; 4]).mass;
    assert!(m[(2, 2)] - 12.0 < 1e-12 && m[(2, 2)] > 11.999, "joint 3 moves links 3 and 4: 8 + 4 kg, got {}", m[(2, 2)]);
}

/// `rnea` reads the joint transforms of its `q`: called with other
/// coordinates than those in the workspace, a debug build stops.
#[test]
#[cfg(debug_assertions)]
#[should_panic(expected = "not those of `q`")]
fn rnea_refuses_transforms_of_other_coordinates() {
    let model = Model::reference_rrpr();
    let mut data = Data::new(&model);
    let q = [0.1, 0.2, 0.9, 0.3];
    forward_kinematics(&model, &mut data, &q);
    rnea(&model, &mut data, &[0.2, 0.2, 0.9, 0.3], &[0.0; 4], &[0.0; 4]);
}
