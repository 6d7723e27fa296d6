//! Forward kinematics: the joint transforms A_i (study eq. 3.1, written as a
//! constant placement followed by the joint's motion, see
//! [`Joint`](crate::model::Joint)), their products B_i = A_1…A_i (eq. 3.2),
//! and the end point E.

use crate::data::Data;
use crate::math::{sin_cos_near, Mat3, Mat4, ThetaAnchor, Vec3, ANCHOR_REACH};
use crate::model::{ContactGeometry, Joint, JointKind, Model};

/// A_i = P_i · M_i(q): the homogeneous transform from link i's frame to
/// link i−1's, the placement P_i followed by the motion M_i, Rot_z(q +
/// offset) or Trans_z(q + offset) (eq. 3.1 in the engine's form).
pub fn joint_transform(joint: &Joint, q: f64) -> Mat4 {
    let mut m = Mat4::identity();
    match joint.kind {
        JointKind::Revolute => {
            let (s, c) = (joint.offset + q).sin_cos();
            m[(0, 0)] = c;
            m[(0, 1)] = -s;
            m[(1, 0)] = s;
            m[(1, 1)] = c;
        }
        JointKind::Prismatic => m[(2, 3)] = joint.offset + q,
    }
    let mut p = Mat4::identity();
    p.fixed_view_mut::<3, 3>(0, 0).copy_from(&joint.placement.rotation);
    p.fixed_view_mut::<3, 1>(0, 3).copy_from(&joint.placement.translation);
    p * m
}

/// The joint-dependent parts of the transforms A_i at joint coordinates `q`:
/// the rotations R_i in `data.link_rotation`, the offsets p_i = O_i − O_{i−1}
/// in `data.link_offset` (link i−1's frame) and `data.link_offset_child`
/// (link i's frame). This is all the recursive inverse dynamics needs: it
/// works in the link frames. The sines and cosines of the revolute joints'
/// angles come from the library and become the anchors of
/// [`joint_transforms_near_anchors`].
#[inline(always)]
pub fn joint_transforms(model: &Model, data: &mut Data, q: &[f64]) {
    joint_parts(model, data, q, false);
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
    joint_parts(model, data, q, true);
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
fn joint_parts(model: &Model, data: &mut Data, q: &[f64], near_anchors: bool) {
    let n = model.nq();
    let (rotation, offset, offset_child) =
        (&mut data.link_rotation[..n], &mut data.link_offset[..n], &mut data.link_offset_child[..n]);
    let (anchor, local, q) = (&mut data.theta_anchor[..n], &data.origin_in_joint_frame[..n], &q[..n]);
    for (i, joint) in model.joints.iter().enumerate().take(n) {
        let placement = &joint.placement;
        match joint.kind {
            JointKind::Revolute => {
                let delta = q[i] - anchor[i].q;
                let (st, ct) = if near_anchors && delta.abs() <= ANCHOR_REACH {
                    sin_cos_near(anchor[i].sin_theta, anchor[i].cos_theta, delta)
                } else {
                    let (st, ct) = (joint.offset + q[i]).sin_cos();
                    anchor[i] = ThetaAnchor { q: q[i], sin_theta: st, cos_theta: ct };
                    (st, ct)
                };
                // P·Rot_z(θ): the placement's x and y turned by θ, z the axis.
                let (px, py, pz) =
                    (placement.rotation.column(0), placement.rotation.column(1), placement.rotation.column(2));
                rotation[i] = Mat3::from_columns(&[px * ct + py * st, py * ct - px * st, pz.into_owned()]);
                offset[i] = placement.translation;
                // Rot_z(θ)ᵀ·(Pᵀ·p).
                let u = local[i];
                offset_child[i] = Vec3::new(ct * u.x + st * u.y, ct * u.y - st * u.x, u.z);
            }
            JointKind::Prismatic => {
                // The rotation is the placement's (set by `Data::new`).
                let s = joint.offset + q[i];
                offset[i] = placement.translation + placement.rotation.column(2) * s;
                offset_child[i] = local[i] + Vec3::z() * s;
            }
        }
    }
}

/// Fills `data.rotation[i]`, `data.origin[i]` (frame i in frame 0, i = 0…n)
/// and every link's centre of mass and inertia in frame 0, for joint
/// coordinates `q` (length n); it first calls [`joint_transforms`] for `q`.
/// `data` must have been built for `model`.
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
    joint_parts(model, data, &q, false);
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
            && data.link_rotation.len() == n
            && data.link_offset.len() == n
            && data.com.len() == n
            && data.inertia.len() == n,
        "forward_kinematics: data must be sized for the model"
    );
    data.rotation[0] = Mat3::identity();
    data.origin[0] = Vec3::zeros();
    for i in 0..n {
        let parent = data.rotation[i];
        let rot = parent * data.link_rotation[i];
        data.origin[i + 1] = data.origin[i] + parent * data.link_offset[i];
        data.rotation[i + 1] = rot;
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

/// The reaction reference point of joint `i` (0-based) in link i's frame:
/// the bearing reference point (on the axis, where the joint's rotation does
/// not move it), the slider centre, or the joint's origin.
#[inline(always)]
pub fn reaction_point_local(model: &Model, i: usize) -> Vec3 {
    match model.joints[i].friction.map(|f| f.geometry) {
        Some(ContactGeometry::Bearings { reaction_point, .. }) => reaction_point,
        Some(ContactGeometry::Slider { centre, .. }) => centre,
        None => Vec3::zeros(),
    }
}

/// Reaction reference point of joint `i` (0-based) in frame 0, from the last
/// forward kinematics (see [`reaction_point_local`]).
pub fn reaction_point(model: &Model, data: &Data, i: usize) -> Vec3 {
    data.origin[i + 1] + data.rotation[i + 1] * reaction_point_local(model, i)
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
