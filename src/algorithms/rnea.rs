//! Recursive Newton–Euler inverse dynamics with joint reactions (Luh, Walker
//! and Paul 1980, as cited by the study in section 3), in the link frames:
//! every quantity of link i is resolved in link i's frame, so the recursion
//! needs only the joint transforms A_i of
//! [`joint_transforms`](super::kinematics::joint_transforms) (the rotation
//! R_i and the offset p_i of link i in link i−1) and no frame-0 kinematics.

use super::kinematics::reaction_point_local;
use crate::data::Data;
use crate::math::Vec3;
use crate::model::{JointKind, Model};

/// Inverse dynamics at joint coordinates `q`, velocities `qd` and
/// accelerations `qdd` (each of length n); gravity is the model's.
///
/// Reads the joint transforms of `q` in `data`: the caller brings them to `q`
/// with [`update_joint_transforms`](super::kinematics::update_joint_transforms)
/// (or [`joint_transforms`](super::kinematics::joint_transforms),
/// [`forward_kinematics`](super::kinematics::forward_kinematics)); a stepper
/// that iterates q̈ at fixed q does so once for several calls. Debug builds
/// check that they belong to `q`.
/// Results: `data.tau` (τ = M q̈ + bias, length n), the joint forces
/// `data.force[i]` and moments `data.moment[i]` (about the joint's origin,
/// the origin of link i's frame) exerted by link i−1 on link i, resolved in
/// link i's frame, and the link angular velocities and accelerations and
/// origin accelerations, each in its own frame.
///
/// The forward loop carries velocities and accelerations from link 1 to n,
/// the backward loop the joint forces from joint n to 1.
#[inline(always)]
pub fn rnea(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], qdd: &[f64]) {
    // A check in every build costs 5 % of a sub-step: the hot path keeps it
    // to debug builds (`cargo test` without --release runs it).
    debug_assert!(
        data.transforms_current
            && data.transforms_q.iter().zip(q).all(|(a, b)| (a - b).abs() <= 1e-15 * (1.0 + b.abs())),
        "rnea: the joint transforms in `data` are not those of `q` (call update_joint_transforms first)"
    );
    let n = model.nq();
    // One check up front lets the compiler drop the per-index bounds checks.
    assert!(
        qd.len() == n
            && qdd.len() == n
            && model.links.len() == n
            && data.link_rotation.len() == n
            && data.link_offset.len() == n
            && data.link_offset_child.len() == n
            && data.omega.len() == n + 1
            && data.omega_dot.len() == n + 1
            && data.acceleration.len() == n + 1
            && data.force.len() == n
            && data.moment.len() == n
            && data.tau.len() == n,
        "rnea: data, q̇ and q̈ must be sized for the model"
    );
    data.omega[0] = Vec3::zeros();
    data.omega_dot[0] = Vec3::zeros();
    // Gravity enters as an upward acceleration of the base.
    data.acceleration[0] = -model.gravity;
    for i in 0..n {
        let (r, p) = (&data.link_rotation[i], data.link_offset_child[i]);
        // Link i−1's motion resolved in link i's frame.
        let (w_prev, wd_prev, a_prev) =
            (r.tr_mul(&data.omega[i]), r.tr_mul(&data.omega_dot[i]), r.tr_mul(&data.acceleration[i]));
        let (w, wd, a) = match model.joints[i].kind {
            JointKind::Revolute => {
                // ω + z·q̇, ω̇ + z·q̈ + ω × z·q̇ with ω × z = (ω_y, −ω_x, 0); the
                // joint's origin is a point of link i−1.
                let w = Vec3::new(w_prev.x, w_prev.y, w_prev.z + qd[i]);
                let wd = Vec3::new(wd_prev.x + w_prev.y * qd[i], wd_prev.y - w_prev.x * qd[i], wd_prev.z + qdd[i]);
                (w, wd, a_prev + wd_prev.cross(&p) + w_prev.cross(&w_prev.cross(&p)))
            }
            JointKind::Prismatic => {
                // p turns with link i−1 and grows along the axis z.
                let axis = Vec3::z();
                let a = a_prev
                    + axis * qdd[i]
                    + wd_prev.cross(&p)
                    + w_prev.cross(&(w_prev.cross(&p) + axis * (2.0 * qd[i])));
                (w_prev, wd_prev, a)
            }
        };
        data.omega[i + 1] = w;
        data.omega_dot[i + 1] = wd;
        data.acceleration[i + 1] = a;
    }
    let mut f_next = Vec3::zeros();
    let mut n_next = Vec3::zeros();
    for i in (0..n).rev() {
        let link = &model.links[i];
        let (w, wd) = (data.omega[i + 1], data.omega_dot[i + 1]);
        let c = link.com;
        let a_c = data.acceleration[i + 1] + wd.cross(&c) + w.cross(&w.cross(&c));
        let f_inertial = a_c * link.mass;
        let n_inertial = link.inertia * wd + w.cross(&(link.inertia * w));
        // The child's force and moment (about its joint's origin p'),
        // resolved in link i's frame, the moment moved to O_i.
        let (f_child, n_child) = match (data.link_rotation.get(i + 1), data.link_offset.get(i + 1)) {
            (Some(r), Some(p_next)) => {
                let f_child = r * f_next;
                (f_child, r * n_next + p_next.cross(&f_child))
            }
            _ => (f_next, n_next),
        };
        let f = f_inertial + f_child;
        let m = n_inertial + c.cross(&f_inertial) + n_child;
        data.tau[i] = match model.joints[i].kind {
            JointKind::Revolute => m.z,
            JointKind::Prismatic => f.z,
        };
        data.force[i] = f;
        data.moment[i] = m;
        f_next = f;
        n_next = m;
    }
}

/// Joint reactions of every joint at its reaction reference point, resolved
/// in link i's frame (z along the joint axis), from the last [`rnea`] call:
/// `data.reaction_force[i]` (f_s, or f'_s for a slider) and
/// `data.reaction_moment[i]` (n_s, or n'_s).
pub fn joint_reactions(model: &Model, data: &mut Data) {
    for i in 0..model.nq() {
        joint_reaction(model, data, i);
    }
}

/// The reaction of joint `i` (0-based) only, as in [`joint_reactions`].
#[inline(always)]
pub fn joint_reaction(model: &Model, data: &mut Data, i: usize) {
    let f = data.force[i];
    // Moment about the reaction point P from the moment about the origin.
    data.reaction_force[i] = f;
    data.reaction_moment[i] = data.moment[i] - reaction_point_local(model, i).cross(&f);
}
