//! Denavit–Hartenberg rows become joint placements that reproduce the
//! study's frames: for random chains and coordinates, the engine's link
//! frame i turned by T_i = Trans_x(a_i)·Rot_x(α_i) is the study's frame
//! B_i = A_1…A_i with A_i of eq. (3.1), multiplied out here independently;
//! the links' centres of mass, the bearing reference points, the slider
//! centres and the end point land where eq. (3.2) puts them (to 1e-12).

use crate::common;

use common::{random_dh_chain, Rng};
use stick_slip_manipulator::algorithms::kinematics::{end_point, forward_kinematics, frame_transform, reaction_point};
use stick_slip_manipulator::math::{Mat4, Vec3, Vec4};
use stick_slip_manipulator::model::{trailing_placement, ContactGeometry, DhRow, IntegratorSettings, JointKind};
use stick_slip_manipulator::{Data, Model};

/// A_i of eq. (3.1) with the joint variable q added to θ or d.
fn study_transform(kind: JointKind, row: &DhRow, q: f64) -> Mat4 {
    let (theta, d) = match kind {
        JointKind::Revolute => (row.theta + q, row.d),
        JointKind::Prismatic => (row.theta, row.d + q),
    };
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = row.alpha.sin_cos();
    Mat4::new(ct, -st * ca, st * sa, row.a * ct, st, ct * ca, -ct * sa, row.a * st, 0.0, sa, ca, d, 0.0, 0.0, 0.0, 1.0)
}

fn point(b: &Mat4, p: &Vec3) -> Vec3 {
    (b * Vec4::new(p.x, p.y, p.z, 1.0)).xyz()
}

#[test]
fn dh_rows_become_placements_that_reproduce_the_frames_of_eq_3_2() {
    let mut worst: f64 = 0.0;
    for seed in 1..=20 {
        let n = 1 + seed as usize % 7;
        let (joints, links) = random_dh_chain(n, seed);
        let end = Vec3::new(0.1, -0.2, 0.3);
        let model =
            Model::from_dh("dh", &joints, &links, Vec3::new(0.0, 0.0, -9.81), end, IntegratorSettings::default())
                .unwrap();
        let mut rng = Rng::new(seed + 100);
        for _ in 0..5 {
            let q: Vec<f64> = (0..n).map(|_| rng.range(-2.0, 2.0)).collect();
            let mut data = Data::new(&model);
            forward_kinematics(&model, &mut data, &q);
            let mut b = Mat4::identity();
            for i in 0..n {
                let previous = b;
                b *= study_transform(joints[i].kind, &joints[i].dh, q[i]);
                let t = trailing_placement(&joints[i].dh);
                let mut t4 = Mat4::identity();
                t4.fixed_view_mut::<3, 3>(0, 0).copy_from(&t.rotation);
                t4.fixed_view_mut::<3, 1>(0, 3).copy_from(&t.translation);
                let engine = frame_transform(&data, i + 1) * t4;
                worst = worst.max((engine - b).amax());
                // The centre of mass of link i, given in the study's frame i.
                worst = worst.max((data.com[i] - point(&b, &links[i].com)).norm());
                // Its inertia tensor, given in the study's frame i, in frame 0.
                let r = b.fixed_view::<3, 3>(0, 0);
                worst = worst
                    .max((data.inertia[i] - r * links[i].inertia * r.transpose()).amax() / links[i].inertia.amax());
                let expected = match joints[i].friction.map(|f| f.geometry) {
                    Some(ContactGeometry::Bearings { reaction_point, .. }) => point(&previous, &reaction_point),
                    Some(ContactGeometry::Slider { centre, .. }) => point(&b, &centre),
                    None => unreachable!("random chains have friction geometry on every joint"),
                };
                worst = worst.max((reaction_point(&model, &data, i) - expected).norm());
            }
            worst = worst.max((end_point(&model, &data) - point(&b, &end)).norm());
        }
    }
    assert!(worst < 1e-12, "largest deviation {worst:e}");
}
