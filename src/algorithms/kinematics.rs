//! Forward kinematics: the Denavit–Hartenberg transforms A_i, their products
//! B_i = A_1…A_i (study eqs. 3.1, 3.2), and the end point E.

use crate::data::Data;
use crate::math::{sin_cos_near, DhRotation, Mat3, Mat4, ThetaAnchor, Vec3, ANCHOR_REACH};
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

/// The joint-dependent parts of the DH transforms A_i (eq. 3.1) at joint
/// coordinates `q`: the rotations in `data.dh_rotation`, d_i in `data.dh_d`
/// and the link offset p_i = O_i − O_{i−1} resolved in frame i,
/// (a_i, d_i·sin α_i, d_i·cos α_i), in `data.link_offset`. This is all the
/// recursive inverse dynamics needs: it works in the link frames. The sines
/// and cosines of θ_i come from the library and become the anchors of
/// [`joint_transforms_near_anchors`].
#[inline(always)]
pub fn joint_transforms(model: &Model, data: &mut Data, q: &[f64]) {
    dh_joint_parts(model, data, q, false);
    record_transforms(data, q);
}

/// As [`joint_transforms`], but the sine and cosine of a revolute joint
/// within [`ANCHOR_REACH`] of its anchor (its coordinate at the last
/// [`joint_transforms`]) are expanded about it, see [`sin_cos_near`]: a
/// stepper moves q by micro-radians per sub-step, and this is a quarter of
/// the cost of the library's sin_cos, as accurate, and still a function of
/// the anchor and q only.
#[inline(always)]
pub fn joint_transforms_near_anchors(model: &Model, data: &mut Data, q: &[f64]) {
    dh_joint_parts(model, data, q, true);
    record_transforms(data, q);
}

/// Brings the joint transforms in `data` to the coordinates `q`, the way a
/// stepper needs them: by the library's sines ([`joint_transforms`]) when
/// `data` holds none that are current (see [`forget_joint_transforms`]),
/// not at all when q differs from their coordinates by rounding only (a
/// Newton correction moves q by βh²·Δq̈, often below 1e-15), else expanded
/// about the anchors ([`joint_transforms_near_anchors`]). Either way the
/// result is a function of the coordinates of the last library evaluation
/// and of `q` only, so a restored state continues bit for bit.
#[inline(always)]
pub fn update_joint_transforms(model: &Model, data: &mut Data, q: &[f64]) {
    if !data.transforms_current {
        joint_transforms(model, data, q);
        return;
    }
    let moved = q.iter().zip(&data.transforms_q).any(|(a, b)| (a - b).abs() > 1e-15 * (1.0 + a.abs()));
    if moved {
        joint_transforms_near_anchors(model, data, q);
    }
}

/// Marks the joint transforms in `data` as not current: the next
/// [`update_joint_transforms`] computes them by the library's sines.
pub fn forget_joint_transforms(data: &mut Data) {
    data.transforms_current = false;
}

#[inline(always)]
fn record_transforms(data: &mut Data, q: &[f64]) {
    data.transforms_q.copy_from_slice(q);
    data.transforms_current = true;
}

#[inline(always)]
fn dh_joint_parts(model: &Model, data: &mut Data, q: &[f64], near_anchors: bool) {
    let n = model.nq();
    let (rotation, dh_d, link_offset) = (&mut data.dh_rotation[..n], &mut data.dh_d[..n], &mut data.link_offset[..n]);
    let (anchor, q) = (&mut data.theta_anchor[..n], &q[..n]);
    for (i, joint) in model.joints.iter().enumerate().take(n) {
        // The constant θ of a prismatic joint keeps the sines set by `Data::new`.
        if joint.kind == JointKind::Revolute {
            let delta = q[i] - anchor[i].q;
            let (st, ct) = if near_anchors && delta.abs() <= ANCHOR_REACH {
                sin_cos_near(anchor[i].sin_theta, anchor[i].cos_theta, delta)
            } else {
                let (st, ct) = (joint.dh.theta + q[i]).sin_cos();
                anchor[i] = ThetaAnchor { q: q[i], sin_theta: st, cos_theta: ct };
                (st, ct)
            };
            rotation[i].sin_theta = st;
            rotation[i].cos_theta = ct;
        }
        let d = dh_variables(joint, q[i]).1;
        dh_d[i] = d;
        link_offset[i] = Vec3::new(joint.dh.a, d * rotation[i].sin_alpha, d * rotation[i].cos_alpha);
    }
}

/// Fills `data.rotation[i]`, `data.origin[i]` (frame i in frame 0, i = 0…n),
/// the joint frames, and every link's centre of mass and inertia in frame 0,
/// for joint coordinates `q` (length n); it first calls [`joint_transforms`]
/// for `q`. `data` must have been built for `model` (it holds the sines and
/// cosines of the constant DH angles).
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64]) {
    joint_transforms(model, data, q);
    frame_kinematics(model, data);
}

/// [`forward_kinematics`] at the coordinates of the joint transforms in
/// `data` (those the last inverse dynamics used), their sines recomputed by
/// the library.
pub fn forward_kinematics_at_transforms(model: &Model, data: &mut Data) {
    // Taken out and put back: no copy, no allocation.
    let q = std::mem::take(&mut data.transforms_q);
    dh_joint_parts(model, data, &q, false);
    data.transforms_q = q;
    data.transforms_current = true;
    frame_kinematics(model, data);
}

/// The frame-0 part of [`forward_kinematics`] from the joint transforms in `data`.
fn frame_kinematics(model: &Model, data: &mut Data) {
    let n = model.nq();
    // One check up front lets the compiler drop the per-index bounds checks.
    assert!(
        model.links.len() == n
            && data.rotation.len() == n + 1
            && data.origin.len() == n + 1
            && data.joint_rotation.len() == n
            && data.joint_origin.len() == n
            && data.com.len() == n
            && data.inertia.len() == n,
        "forward_kinematics: data must be sized for the model"
    );
    data.rotation[0] = Mat3::identity();
    data.origin[0] = Vec3::zeros();
    for (i, joint) in model.joints.iter().enumerate() {
        let DhRotation { sin_theta: st, cos_theta: ct, sin_alpha: sa, cos_alpha: ca } = data.dh_rotation[i];
        let d = data.dh_d[i];
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

/// O_{i−1} − P for joint `i` (0-based): from its reaction reference point P
/// (see [`reaction_point`]) to the origin of frame i−1, resolved in the joint
/// frame, from the last [`joint_transforms`]. The joint frame's origin is
/// O_{i−1} + d_i·z_{i−1}; frame i's is that plus a_i along the joint frame's x.
#[inline(always)]
pub fn reaction_offset(model: &Model, data: &Data, i: usize) -> Vec3 {
    use crate::model::ContactGeometry;
    let d = data.dh_d[i];
    match model.joints[i].friction.map(|f| f.geometry) {
        // P given in frame i−1: turn it by −θ_i about z.
        Some(ContactGeometry::Bearings { reaction_point, .. }) => -data.dh_rotation[i].parent_to_joint_frame(&reaction_point),
        Some(ContactGeometry::Slider { centre, .. }) => {
            Vec3::new(-model.joints[i].dh.a, 0.0, -d) - data.dh_rotation[i].to_joint_frame(&centre)
        }
        None => Vec3::new(0.0, 0.0, -d),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expansion_about_an_anchor_matches_the_library_sine_and_cosine() {
        // Anchors all around the circle and steps over the whole reach, all
        // binary fractions so that θ₀ + δ is exact and the library's value is
        // the reference: within 3e-16, about one rounding of each.
        let mut worst: f64 = 0.0;
        for k in -200..=200 {
            let theta0 = k as f64 / 64.0;
            let (s0, c0) = theta0.sin_cos();
            for j in -160..=160 {
                let delta = j as f64 / 16384.0;
                assert!(delta.abs() <= ANCHOR_REACH && theta0 + delta - theta0 == delta);
                let (s, c) = sin_cos_near(s0, c0, delta);
                let (s_ref, c_ref) = (theta0 + delta).sin_cos();
                worst = worst.max((s - s_ref).abs()).max((c - c_ref).abs());
            }
        }
        assert!(worst < 3e-16, "largest deviation {worst:e}");
    }
}
