//! Joint reactions are reported where the contact models need them.
//!
//! The reference manipulator at rest, arm horizontal, held by its stuck
//! joints: the reaction of joint 1 at its bearing reference point (0, 0, 0.06)
//! carries the whole weight W = Σ m_i·g as thrust f_z and the moment of the
//! weights about that point as bending moment; bearings A and B share that
//! moment as equal and opposite radial loads |n|/l_1; the slider of joint 3
//! carries links 3 and 4 at its centre. Checked against statics by hand to
//! 1e-9 relative.

use stick_slip_manipulator::math::Vec3;
use stick_slip_manipulator::{DriveInputs, Model, Simulator};

#[test]
fn reactions_of_the_resting_arm_balance_the_weights() {
    let model = Model::reference_rrpr();
    let g = 9.81;
    let mut sim = Simulator::new(model.clone()).unwrap();
    let q = [0.0, 0.0, 0.8, 0.0];
    let zero = [0.0; 4];
    sim.initialize(0.0, &DriveInputs { q_star: &q, qd_star: &zero, qdd_star: &zero }, None).unwrap();
    let s = sim.state();
    assert!(s.is_stuck(0) && s.is_stuck(2), "at rest both flexible joints are held");
    // Centres of mass in frame 0 at q = (0, 0, 0.8, 0), from the reference file's frames:
    // link 1 (0, 0, 0.3); link 2 (0.1, 0, 0.6); link 3 (0.4, 0, 0.6); link 4 (0.85, 0, 0.65).
    let com =
        [Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.1, 0.0, 0.6), Vec3::new(0.4, 0.0, 0.6), Vec3::new(0.85, 0.0, 0.65)];
    let masses: Vec<f64> = model.links.iter().map(|l| l.mass).collect();
    let weight: f64 = masses.iter().sum::<f64>() * g;
    let p = Vec3::new(0.0, 0.0, 0.06);
    // The base must supply the opposite of the weights' moment about P.
    let moment: Vec3 = com.iter().zip(&masses).map(|(c, m)| -(c - p).cross(&Vec3::new(0.0, 0.0, -m * g))).sum();
    let (f1, n1) = (s.reaction_force[0], s.reaction_moment[0]);
    assert!((f1 - Vec3::new(0.0, 0.0, weight)).norm() < 1e-9 * weight, "f_1 = {f1}");
    assert!((n1 - moment).norm() < 1e-9 * moment.norm(), "n_1 = {n1}, expected {moment}");
    let radial = moment.norm() / 0.12;
    assert!((s.normal_load[0] - (2.0 * radial + weight)).abs() < 1e-9 * weight, "N_1 = {}", s.normal_load[0]);
    // Joint 3: the slider at x = 0.1 carries links 3 and 4. In the joint frame
    // (axes of frame 2: x2 = z0 up, z2 = x0 along the arm) the weight pushes along −x.
    let (f3, n3) = (s.reaction_force[2], s.reaction_moment[2]);
    let w34 = (masses[2] + masses[3]) * g;
    assert!((f3 - Vec3::new(w34, 0.0, 0.0)).norm() < 1e-9 * w34, "f'_3 = {f3}");
    let centre = Vec3::new(0.1, 0.0, 0.6);
    let m34: Vec3 = (2..4).map(|i| -(com[i] - centre).cross(&Vec3::new(0.0, 0.0, -masses[i] * g))).sum();
    // Resolve the frame-0 moment in the joint frame of joint 3.
    let r2 = {
        let mut data = stick_slip_manipulator::Data::new(&model);
        stick_slip_manipulator::algorithms::kinematics::forward_kinematics(&model, &mut data, &q);
        data.rotation[3]
    };
    assert!((n3 - r2.transpose() * m34).norm() < 1e-9 * m34.norm(), "n'_3 = {n3}");
    // The stuck joints hold with no drive force: the friction carries the axial load (zero here).
    assert!(s.friction_force[2].abs() < 1e-9 * w34);
}
