//! Forward kinematics: the Denavit–Hartenberg transforms A_i, their products
//! B_i = A_1…A_i (study eqs. 3.1, 3.2), and the end point E.

use crate::data::Data;
use crate::math::{Mat3, Mat4, Vec3};
use crate::model::{Joint, JointKind, Model};

/// θ_i and d_i of joint `joint` at joint coordinate `q`.
#[inline]
pub fn dh_variables(joint: &Joint, q: f64) -> (f64, f64) {
    match joint.kind {
        JointKind::Revolute => (joint.dh.theta + q, joint.dh.d),
        JointKind::Prismatic => (joint.dh.theta, joint.dh.d + q),
    }
}

/// A_i = Rot_z(θ_i) · Trans_z(d_i) · Trans_x(a_i) · Rot_x(α_i) (eq. 3.1): the
/// homogeneous transform from frame i to frame i−1.
pub fn dh_transform(joint: &Joint, q: f64) -> Mat4 {
    let (theta, d) = dh_variables(joint, q);
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = joint.dh.alpha.sin_cos();
    let a = joint.dh.a;
    Mat4::new(
        ct, -st * ca, st * sa, a * ct, //
        st, ct * ca, -ct * sa, a * st, //
        0.0, sa, ca, d, //
        0.0, 0.0, 0.0, 1.0,
    )
}

/// Fills `data.rotation[i]`, `data.origin[i]` (frame i in frame 0, i = 0…n),
/// the joint frames, and every link's centre of mass and inertia in frame 0,
/// for joint coordinates `q` (length n). `data` must have been built for
/// `model` (it holds the sines and cosines of the constant DH angles).
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64]) {
    let n = model.nq();
    // One check up front lets the compiler drop the per-index bounds checks.
    assert!(
        q.len() == n
            && model.links.len() == n
            && data.rotation.len() == n + 1
            && data.origin.len() == n + 1
            && data.joint_rotation.len() == n
            && data.joint_origin.len() == n
            && data.com.len() == n
            && data.inertia.len() == n
            && data.alpha_sin_cos.len() == n
            && data.theta_sin_cos.len() == n,
        "forward_kinematics: data and q must be sized for the model"
    );
    data.rotation[0] = Mat3::identity();
    data.origin[0] = Vec3::zeros();
    for (i, joint) in model.joints.iter().enumerate() {
        let (st, ct) = match joint.kind {
            JointKind::Revolute => (joint.dh.theta + q[i]).sin_cos(),
            JointKind::Prismatic => data.theta_sin_cos[i],
        };
        let d = dh_variables(joint, q[i]).1;
        let (sa, ca) = data.alpha_sin_cos[i];
        let parent_r = data.rotation[i];
        let (x, y, z) = (parent_r.column(0), parent_r.column(1), parent_r.column(2));
        // Joint frame: Rot_z(θ)·Trans_z(d) applied to frame i−1; z stays the joint axis.
        let jx = x * ct + y * st;
        let jy = y * ct - x * st;
        let joint_p = data.origin[i] + z * d;
        data.joint_rotation[i] = Mat3::from_columns(&[jx, jy, z.into_owned()]);
        data.joint_origin[i] = joint_p;
        // Trans_x(a)·Rot_x(α).
        let rot = Mat3::from_columns(&[jx, jy * ca + z * sa, z * ca - jy * sa]);
        data.rotation[i + 1] = rot;
        data.origin[i + 1] = joint_p + jx * joint.dh.a;
        let link = &model.links[i];
        data.com[i] = data.origin[i + 1] + rot * link.com;
        data.inertia[i] = rot * link.inertia * rot.transpose();
    }
}

/// B_i of eq. (3.2) for frame `i` (0…n) from the last call of
/// [`forward_kinematics`].
pub fn frame_transform(data: &Data, i: usize) -> Mat4 {
    let mut b = Mat4::identity();
    b.fixed_view_mut::<3, 3>(0, 0).copy_from(&data.rotation[i]);
    b.fixed_view_mut::<3, 1>(0, 3).copy_from(&data.origin[i]);
    b
}

/// Position of the end point E in frame 0, from the last call of
/// [`forward_kinematics`].
pub fn end_point(model: &Model, data: &Data) -> Vec3 {
    let n = model.nq();
    data.origin[n] + data.rotation[n] * model.end_point
}

/// Reaction reference point of joint `i` (0-based) in frame 0: the bearing
/// reference point (given in frame i−1) of a revolute joint, the slider centre
/// (given in frame i) of a prismatic joint, else the joint frame's origin.
pub fn reaction_point(model: &Model, data: &Data, i: usize) -> Vec3 {
    use crate::model::ContactGeometry;
    match model.joints[i].friction.map(|f| f.geometry) {
        Some(ContactGeometry::Bearings { reaction_point, .. }) => data.origin[i] + data.rotation[i] * reaction_point,
        Some(ContactGeometry::Slider { centre, .. }) => data.origin[i + 1] + data.rotation[i + 1] * centre,
        None => data.joint_origin[i],
    }
}
